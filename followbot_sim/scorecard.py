"""
The ``scorecard`` command: score follower configurations side by side on the built-in courses.

For every (configuration, scenario) pair it runs the simulator and the follower in one process,
headless and as fast as the machine allows, with real nodes talking over real DDS topics, until
the robot completes a lap, runs out of simulated time or gets stuck. The simulator's ground
truth (its LapTracker) and the follower's line statistics give the figures: completion, lap
time, mean speed, distance from the line, frames without the line, recoveries. Runs go to a
pool of worker processes, each on its own ROS domain so concurrent runs never hear each other;
the result is a Markdown table on stdout and a JSON file. A lockstep run is the same on every
machine but not from a start a centimetre away: ``--starts N`` runs each pair from N starts
and adds each figure's mean and range over them, to tell a change from chance.

A configuration is a ROS 2 parameters file: ``followbot`` (the installed defaults) and ``book``
(the book's controller) always exist, ``--params-file`` adds more. The whole file is given to
the run, so a ``followbot_sim:`` section in it applies to the simulator too (its camera, say);
the scenario's course, lighting, noise and seed, and the pacing, are always the scorecard's.
"""

import argparse
import collections
import concurrent.futures
import dataclasses
import datetime
import importlib.metadata
import json
import multiprocessing
import os
from pathlib import Path
import platform
import shlex
import socket
import sys
import time

from followbot.follower_node import FollowerNode, LONGEST_IMAGE_TIMEOUT_S
from followbot.node_runner import refuse_ros_arguments, StopSignals
from followbot.number_options import number_in
from followbot.output_files import output_file_option, output_folder_option
from followbot.package_files import share_file
from followbot.parameters_file import read_sections
from followbot.transport import keep_large_buffers
from followbot_sim.course_file import COURSE_FILE_SUFFIXES, load_course
from followbot_sim.course_library import COURSES
from followbot_sim.domains import domain_id_option, MAX_DOMAIN_ID, reserve_default_domains
from followbot_sim.perception_monitor import PerceptionMonitor
from followbot_sim.plots import write_plots
from followbot_sim.realism import PRESET_NAMES
from followbot_sim.run_recording import add_record_options, RunRecording
from followbot_sim.sim_node import SIMULATOR_PARAMETERS, SimulatorNode
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
import yaml

# The command's name, in its messages and in the command line the footer repeats.
PROGRAM = 'scorecard'
# The configurations every scorecard knows: name -> parameters file in the package's config/.
BUILTIN_CONFIGURATIONS = {'followbot': 'followbot.yaml', 'book': 'book_follower.yaml'}
# The configuration the others' lap times are compared with (the "x book" column).
REFERENCE_CONFIGURATION = 'book'
# The book's forward speed: the default time limit leaves room for a lap at that pace.
BOOK_SPEED_MPS = 0.2
# Default time limit, in laps at the book's speed: slower in bends, plus a margin.
TIME_LIMIT_LAPS = 2.5
# A run is stuck when its progress along the line gained less than this over the stuck window.
STUCK_MIN_PROGRESS_M = 0.05
DEFAULT_STUCK_AFTER_S = 30.0
# Default domains of the workers: a block reserved in this range, apart from every other
# scorecard, benchmark and test run on the machine.
FIRST_DOMAIN_ID = 150
DOMAIN_ID_SPREAD = 40
# Wall seconds the two nodes may take to discover each other before a run gives up.
CONNECT_TIMEOUT_S = 30.0
CONNECT_POLL_S = 0.05
# spin_once returns at once at real-time factor 0; the timeout only bounds a stalled graph.
SPIN_TIMEOUT_S = 1.0
# Both must be connected before simulated time starts: camera to follower, follower to wheels.
IMAGE_TOPIC = 'camera/rgb/image_raw'
CMD_VEL_TOPIC = 'cmd_vel'
# Light and noise of the book_loop_light_noise scenario: pools of light plus a noisy camera.
LIGHT_NOISE_STDDEV_LEVELS = 24.0
LIGHT_NOISE_SEED = 1
# Simulator parameters the scorecard sets for every run; --sim-param may not change them.
SCORECARD_SIM_PARAMETERS = ('course', 'lighting_zones', 'camera_noise_stddev_levels',
                            'random_seed', 'real_time_factor', 'lockstep', 'start_paused',
                            'run_duration_s', 'realism', 'realism_seed')
# The scorecard scores one robot per run, its follower on the single robot's topics.
MULTI_ROBOT_SIM_PARAMETERS = ('robots', 'robot_spacing_m')
# The realistic scenarios: every realism preset on these courses with these seeds.
REALISTIC_COURSES = ('book_loop', 's_bends', 'square_corners')
REALISTIC_SEEDS = (1, 2)
REALISTIC_GROUP = 'realistic'
# ROS log levels for the nodes: quiet by default, as several runs share one terminal.
NODE_LOG_LEVELS = ('debug', 'info', 'warn', 'error', 'fatal')
# Simulated seconds between the samples of a run's distance from the line and speed (plots).
SAMPLE_PERIOD_S = 0.1
# How a --sim-param error names the type a simulator parameter takes.
TYPE_NAMES = {bool: 'a boolean (true or false)', int: 'an integer',
              float: 'a floating-point number', str: 'a string'}
# How a run ended, as the table and the JSON say it.
END_LAP = 'lap completed'
END_TIME_LIMIT = 'time limit'
END_STUCK = 'stuck'
END_LINE_END = 'stopped at line end'
# A run on a line that ends has ended well when it stood still on the paint no farther than
# this before the end: the nearest band sees the floor ~0.35 m ahead of the robot's centre, so
# a follower that stops when the end leaves its view stands about that far before it.
STOPPED_BEFORE_LINE_END_WITHIN_M = 0.6
# Standing still: slower than a millimetre a frame either way.
STANDING_STILL_MPS = 0.02
STANDING_STILL_RADPS = 0.02
END_ERROR = 'error'
END_INTERRUPTED = 'interrupted'
# Shown in the table for a figure a run does not have (no lap, no ratio, an error).
MISSING = '—'
# Longest error text shown in the table; the progress line and the JSON have all of it.
MAX_TABLE_ERROR_CHARS = 80
# The table gives distances from the line in centimetres; the JSON keeps metres.
CM_PER_M = 100.0
# Where --starts puts the robot down: (start_lateral_offset_m, start_heading_offset_deg), as a
# hand would, at most 2 cm beside and 1 degree turned from the course's start. The first is the
# course's own start; --starts N runs the first N. A lockstep lap is the same on every machine
# but not from a start a centimetre away: a change to the follower is told from chance by the
# spread over these.
STARTS = ((0.0, 0.0), (0.01, 0.0), (-0.01, 0.0), (0.02, 0.0), (-0.02, 0.0), (0.0, 1.0),
          (0.0, -1.0), (0.01, 1.0))
START_SIM_PARAMETERS = ('start_lateral_offset_m', 'start_heading_offset_deg')
TABLE_COLUMNS = ('scenario', 'configuration', 'done %', 'lap s', 'mean m/s', 'RMS cm',
                 'max cm', 'off line s', 'lost frames', 'recoveries', 'end', 'wall s', '× book')


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A course and the camera's conditions on it: one row per configuration."""

    name: str
    course: str
    lighting_zones: bool = False
    camera_noise_stddev_levels: float = 0.0
    random_seed: int = 0
    # A realism preset (the simulator's realism:=); '' leaves the simulator's default. A
    # realistic scenario also scores the detector against the ground truth per band.
    realism: str = ''
    realism_seed: int = 0


@dataclasses.dataclass(frozen=True)
class Configuration:
    """A follower configuration: a name and the ROS 2 parameters file that sets it up."""

    name: str
    params_file: Path


# In lockstep, simulated time, and so the robot, moves on only after the follower answers each
# frame: a slow simulator never leaves the robot driving blind. The follower's wall-time camera
# watchdog (0.5 s by default, for real robots and real time) would only stop the robot whenever
# the machine is loaded, and make lockstep runs depend on the load; these runs give it its
# longest setting, so it still catches a simulator that died.
LOCKSTEP_IMAGE_TIMEOUT_S = LONGEST_IMAGE_TIMEOUT_S
SCENARIOS = {
    **{name: Scenario(name, name) for name in COURSES},
    'book_loop_light_noise': Scenario(
        'book_loop_light_noise', 'book_loop', lighting_zones=True,
        camera_noise_stddev_levels=LIGHT_NOISE_STDDEV_LEVELS, random_seed=LIGHT_NOISE_SEED),
}


REALISTIC_SCENARIOS = {
    f'{course}@{preset}#{seed}': Scenario(f'{course}@{preset}#{seed}', course, realism=preset,
                                          realism_seed=seed)
    for preset in PRESET_NAMES for course in REALISTIC_COURSES for seed in REALISTIC_SEEDS}


def _split_names(values) -> list:
    """Flatten repeated, comma-separated option values into names, first occurrence kept."""
    names = []
    for value in values or ():
        for name in value.split(','):
            name = name.strip()
            if name and name not in names:
                names.append(name)
    return names


def select_scenarios(names=None) -> list:
    """
    Pick the scenarios to run.

    :param names: scenario names or YAML course file paths, each possibly a comma-separated
        list (the values of repeated ``--scenarios``); all built-in scenarios when empty.
    :return: the scenarios, in the order given.
    :raises ValueError: for a name that is neither a built-in scenario nor a readable, valid
        course file.
    """
    chosen = _split_names(names)
    if not chosen:
        return list(SCENARIOS.values())
    scenarios = []
    for name in chosen:
        if name in SCENARIOS:
            scenarios.append(SCENARIOS[name])
        elif name in REALISTIC_SCENARIOS:
            scenarios.append(REALISTIC_SCENARIOS[name])
        elif name == REALISTIC_GROUP:
            scenarios.extend(REALISTIC_SCENARIOS.values())
        elif Path(name).suffix.lower() in COURSE_FILE_SUFFIXES:
            # Load it here, once: a bad file is one clear message, not an error in every row.
            load_course(name)
            scenarios.append(Scenario(name, str(Path(name).resolve())))
        else:
            raise ValueError(
                f'Unknown scenario {name!r}: give one of {", ".join(SCENARIOS)}, '
                f'{REALISTIC_GROUP} (every COURSE@PRESET#SEED, e.g. book_loop@lab#1) or the path '
                f'of a course file ending in {" or ".join(COURSE_FILE_SUFFIXES)}.')
    return scenarios


def select_configurations(params_files=(), names=None) -> list:
    """
    Build the configurations to compare.

    :param params_files: further parameters files; each is a configuration named by its stem.
    :param names: configuration names to keep, each possibly a comma-separated list; all when
        empty.
    :return: the configurations: the built-in ones first, then the files in the order given.
    :raises ValueError: for a missing or malformed parameters file, two configurations with the
        same name, or an unknown name in ``names``.
    """
    configurations = [Configuration(name, share_file('config', file_name))
                      for name, file_name in BUILTIN_CONFIGURATIONS.items()]
    for params_file in params_files:
        params_file = Path(params_file)
        read_sections(params_file)
        name = params_file.stem
        if any(configuration.name == name for configuration in configurations):
            raise ValueError(
                f'Parameters file {params_file} would make a second configuration named '
                f'{name!r}: configurations are named by file stem, so rename the file.')
        configurations.append(Configuration(name, params_file.resolve()))
    chosen = _split_names(names)
    known = [configuration.name for configuration in configurations]
    unknown = [name for name in chosen if name not in known]
    if unknown:
        raise ValueError(f'Unknown configuration {unknown[0]!r}: give one of {", ".join(known)} '
                         '(--params-file FILE adds one named after the file).')
    return [configuration for configuration in configurations
            if not chosen or configuration.name in chosen]


def parse_sim_parameter(text: str) -> tuple:
    """
    Read one ``--sim-param NAME:=VALUE``, typed the way ROS reads ``-p NAME:=VALUE``.

    :param text: the option's value.
    :return: the parameter's name and its value (an integer is widened for a floating-point
        parameter).
    :raises ValueError: if the text is not ``NAME:=VALUE``, names no simulator parameter or
        one the scorecard sets itself, or the value has the wrong type or is out of range.
    """
    name, separator, value_text = text.partition(':=')
    name = name.strip()
    if not separator or not name:
        raise ValueError(f'--sim-param takes NAME:=VALUE (such as camera_rate_hz:=30.0), got '
                         f'{text!r}.')
    if name in SCORECARD_SIM_PARAMETERS:
        raise ValueError(f'Simulator parameter {name!r} is set by the scorecard for every run '
                         '(scenario or pacing); choose a scenario instead.')
    if name in MULTI_ROBOT_SIM_PARAMETERS:
        raise ValueError(f'Simulator parameter {name!r} is not for the scorecard, which scores '
                         'one robot per run: race configurations on one course with '
                         '`followbot --robots N --configs A,B` instead.')
    if name not in SIMULATOR_PARAMETERS:
        settable = sorted(set(SIMULATOR_PARAMETERS) - set(SCORECARD_SIM_PARAMETERS)
                          - set(MULTI_ROBOT_SIM_PARAMETERS))
        raise ValueError(f'Unknown simulator parameter {name!r}: give one of '
                         f'{", ".join(settable)}.')
    spec = SIMULATOR_PARAMETERS[name]
    try:
        value = yaml.safe_load(value_text)
    except yaml.YAMLError:
        value = value_text
    if isinstance(spec.default, float) and type(value) is int:
        value = float(value)
    if type(value) is not type(spec.default):
        raise ValueError(f'Simulator parameter {name!r} takes {TYPE_NAMES[type(spec.default)]}, '
                         f'got {value_text!r}.')
    if spec.low is not None and not spec.low <= value <= spec.high:
        raise ValueError(f'Simulator parameter {name!r} must be in {spec.low:g}..{spec.high:g}, '
                         f'got {value!r}.')
    return name, value


def default_time_limit_s(course_length_m: float) -> float:
    """
    Return the default simulated-time limit of a run: room for a lap at the book's speed.

    :param course_length_m: length of the course's centre line.
    :return: the limit in simulated seconds.
    """
    return TIME_LIMIT_LAPS * course_length_m / BOOK_SPEED_MPS


class StuckDetector:
    """Tell when progress along the line has stalled over a window of simulated time."""

    def __init__(self, window_s: float, min_progress_m: float = STUCK_MIN_PROGRESS_M):
        """
        Start with no samples.

        :param window_s: simulated seconds over which progress is measured.
        :param min_progress_m: least progress over the window that is not stuck.
        :raises ValueError: if the window is not positive.
        """
        if not window_s > 0.0:
            raise ValueError(f'The stuck window must be positive, got {window_s} s.')
        self._window_s = window_s
        self._min_progress_m = min_progress_m
        self._samples = collections.deque()

    def update(self, time_s: float, progress_m: float) -> bool:
        """
        Record the progress at a time and tell whether the robot is stuck.

        :param time_s: simulated time, never decreasing.
        :param progress_m: progress along the line at that time.
        :return: whether the progress gained since ``window_s`` ago is below the minimum
            (never true before a whole window has passed).
        """
        self._samples.append((time_s, progress_m))
        window_start_s = time_s - self._window_s
        # Keep the latest sample at or before the window's start as its reference.
        while len(self._samples) > 1 and self._samples[1][0] <= window_start_s:
            self._samples.popleft()
        reference_s, reference_m = self._samples[0]
        return reference_s <= window_start_s and progress_m - reference_m < self._min_progress_m


class RunSamples:
    """The run's progress, distance from the line and speed, every SAMPLE_PERIOD_S."""

    def __init__(self, period_s: float = SAMPLE_PERIOD_S):
        """
        Start with no sample.

        :param period_s: simulated seconds between samples.
        """
        self._period_s = period_s
        self._next_s = 0.0
        self._columns = {'time_s': [], 'progress_m': [], 'distance_from_line_m': [],
                         'speed_mps': []}

    def take(self, world, tracker) -> None:
        """
        Take a sample if one is due by the world's time.

        :param world: the simulated world (its time and the robot's true speed).
        :param tracker: its LapTracker (progress along the line, distance from it).
        """
        if world.time_s + 1e-9 < self._next_s:
            return
        self._next_s = world.time_s + self._period_s
        speed_mps, _ = world.robot_twist()
        for name, value in (('time_s', world.time_s), ('progress_m', tracker.progress_m),
                            ('distance_from_line_m', tracker.distance_from_line_m),
                            ('speed_mps', speed_mps)):
            # A millimetre, a millisecond: the JSON stays small.
            self._columns[name].append(round(float(value), 3))

    def as_dict(self) -> dict:
        """Return the samples as columns: time_s, progress_m, distance_from_line_m, speed_mps."""
        return {name: list(values) for name, values in self._columns.items()}


def run_metrics(summary: dict, line_statistics: dict) -> dict:
    """
    Compute a run's figures from the simulator's score and the follower's line statistics.

    :param summary: ``LapTracker.summary()`` at the end of the run.
    :param line_statistics: ``FollowerNode.line_statistics`` at the end of the run.
    :return: ``completion_percent`` (progress capped to one lap, never below 0),
        ``lap_time_s`` (None without a lap), ``mean_speed_mps`` (course length per lap time,
        else progress per elapsed time; None before any time passed), cross-track
        ``rms_distance_from_line_m`` and ``max_distance_from_line_m``, ``time_off_line_s``,
        ``frames``, ``frames_line_lost``, ``line_lost_percent`` (None without frames) and
        ``recoveries``.
    """
    length_m = summary['course_length_m']
    progress_m = summary['progress_m']
    lap_time_s = summary['lap_times_s'][0] if summary['laps_completed'] >= 1 else None
    if lap_time_s is not None:
        mean_speed_mps = length_m / lap_time_s
    elif summary['elapsed_s'] > 0.0:
        mean_speed_mps = progress_m / summary['elapsed_s']
    else:
        mean_speed_mps = None
    frames = line_statistics['frames']
    frames_line_lost = line_statistics['frames_line_lost']
    return {
        'completion_percent': 100.0 * min(max(progress_m, 0.0), length_m) / length_m,
        'lap_time_s': lap_time_s,
        'mean_speed_mps': mean_speed_mps,
        'rms_distance_from_line_m': summary['rms_distance_from_line_m'],
        'max_distance_from_line_m': summary['max_distance_from_line_m'],
        'time_off_line_s': summary['time_off_line_s'],
        'frames': frames,
        'frames_line_lost': frames_line_lost,
        'line_lost_percent': 100.0 * frames_line_lost / frames if frames else None,
        'recoveries': line_statistics['recoveries'],
    }


def perception_figures(tally) -> dict:
    """
    Summarise a perception tally for the JSON and the realistic table.

    :param tally: a :class:`followbot_sim.perception_score.PerceptionTally`.
    :return: frames and bands scored, and right, false, missed and line-recall percentages.
    """
    return {'frames': tally.frames, 'bands': tally.bands,
            'right_percent': 100.0 * tally.right_share,
            'false_percent': 100.0 * tally.false_share,
            'missed_percent': 100.0 * tally.missed_share,
            'line_recall_percent': 100.0 * tally.line_recall}


STARTS_TABLE_COLUMNS = ('scenario', 'configuration', 'laps', 'lap s', 'max cm', 'RMS cm',
                        'lost frames %')
REALISTIC_TABLE_COLUMNS = ('preset', 'course', 'seed', 'configuration', 'end', 'lap s',
                           'RMS cm', 'max cm', 'lost frames %', 'bands right %',
                           'false %', 'missed %', 'sim s / wall s')


def format_realistic_table(runs: list) -> str:
    """
    Format the realistic runs as a Markdown table: per preset, course and seed.

    :param runs: run records; those without a perception score are left out.
    :return: the table, or an empty string when no run is realistic.
    """
    rows = []
    for run in runs:
        if not run.get('perception'):
            continue
        metrics = run['metrics'] or {}
        perception = run['perception']
        preset, _, seed = run['scenario'].partition('@')[2].partition('#')
        seed = ', '.join(filter(None, (seed, _start_text(run))))
        rows.append([preset, run['course'], seed, run['configuration'], run['end_reason'],
                     number_cell(metrics.get('lap_time_s'), 1),
                     number_cell(metrics.get('rms_distance_from_line_m'), 1, CM_PER_M),
                     number_cell(metrics.get('max_distance_from_line_m'), 1, CM_PER_M),
                     number_cell(metrics.get('line_lost_percent'), 2),
                     number_cell(perception['right_percent'], 1),
                     number_cell(perception['false_percent'], 1),
                     number_cell(perception['missed_percent'], 1),
                     number_cell(run.get('simulated_per_wall'), 2)])
    if not rows:
        return ''
    return markdown_table(REALISTIC_TABLE_COLUMNS, rows)


def run_place(run: dict) -> tuple:
    """Return where a run drove: its scenario and its start (1 unless ``--starts`` gave more)."""
    return run['scenario'], run.get('start', 1)


def _start_text(run: dict) -> str:
    """Return which start a run drove from, such as ``start 3/8``; '' when it had only one."""
    starts = run.get('starts', 1)
    return '' if starts == 1 else f"start {run['start']}/{starts}"


def run_label(run: dict) -> str:
    """Return how the tables name a run's scenario: with its start when there were several."""
    return ' '.join(filter(None, (run['scenario'], _start_text(run))))


def speedups(runs: list) -> dict:
    """
    Compare each configuration's lap time with the book's on the same scenario and start.

    :param runs: run records with ``scenario``, ``configuration``, ``start`` (optional) and,
        for a run that ended, ``metrics``.
    :return: (scenario, start, configuration) -> book lap time / this lap time, for every run
        other than the book's where both lap times exist (above 1: faster than the book).
    """
    book_lap_s = {run_place(run): run['metrics']['lap_time_s'] for run in runs
                  if run['configuration'] == REFERENCE_CONFIGURATION and run.get('metrics')}
    ratios = {}
    for run in runs:
        reference_s = book_lap_s.get(run_place(run))
        lap_s = run['metrics']['lap_time_s'] if run.get('metrics') else None
        if run['configuration'] != REFERENCE_CONFIGURATION and reference_s and lap_s:
            ratios[(*run_place(run), run['configuration'])] = reference_s / lap_s
    return ratios


def _mean_and_range(values: list, digits: int, scale: float) -> str:
    if not values:
        return MISSING
    mean = sum(values) / len(values)
    return (f'{number_cell(mean, digits, scale)} ({number_cell(min(values), digits, scale)}'
            f'–{number_cell(max(values), digits, scale)})')


def format_starts_table(runs: list) -> str:
    """
    Summarise the runs from several starts: per scenario and configuration, over its starts.

    :param runs: run records; those of a single start are left out.
    :return: a Markdown table (laps completed of the starts, then the lap time over the starts
        that lapped and the distances over those that ran, each as mean (least–most)), or an
        empty string when no run had several starts.
    """
    groups = {}
    for run in runs:
        if run.get('starts', 1) > 1:
            groups.setdefault((run['scenario'], run['configuration']), []).append(run)
    rows = []
    for (scenario, configuration), group in groups.items():
        figures = [run['metrics'] for run in group if run.get('metrics')]
        laps_s = [metrics['lap_time_s'] for metrics in figures
                  if metrics['lap_time_s'] is not None]
        lost = [metrics['line_lost_percent'] for metrics in figures
                if metrics['line_lost_percent'] is not None]
        rows.append([
            scenario, configuration, f'{len(laps_s)}/{len(group)}',
            _mean_and_range(laps_s, 2, 1.0),
            _mean_and_range([metrics['max_distance_from_line_m'] for metrics in figures], 2,
                            CM_PER_M),
            _mean_and_range([metrics['rms_distance_from_line_m'] for metrics in figures], 2,
                            CM_PER_M),
            _mean_and_range(lost, 2, 1.0)])
    if not rows:
        return ''
    return markdown_table(STARTS_TABLE_COLUMNS, rows)


def _count(number: int, noun: str) -> str:
    return f'{number} {noun}' + ('' if number == 1 else 's')


def number_cell(value, digits: int = 1, scale: float = 1.0) -> str:
    """Return a table cell of a number times ``scale`` to ``digits`` decimals; None as MISSING."""
    return MISSING if value is None else f'{value * scale:.{digits}f}'


def markdown_table(header, rows) -> str:
    """
    Return a plain Markdown table.

    :param header: the column titles.
    :param rows: the rows, each a sequence of cells (turned into text with ``str``).
    :return: the table's lines, joined.
    """
    lines = ['| ' + ' | '.join(header) + ' |',
             '| ' + ' | '.join('---' for _ in header) + ' |']
    lines += ['| ' + ' | '.join(str(cell) for cell in row) + ' |' for row in rows]
    return '\n'.join(lines)


def _lost_frames_cell(metrics: dict) -> str:
    if metrics['line_lost_percent'] is None:
        return str(metrics['frames_line_lost'])
    return f"{metrics['frames_line_lost']} ({metrics['line_lost_percent']:.1f}%)"


def _table_row(run: dict, ratio) -> list:
    cells = [run_label(run), run['configuration']]
    metrics = run.get('metrics')
    if not metrics:
        blanks = [MISSING] * (len(TABLE_COLUMNS) - len(cells) - 3)
        end = f"{END_ERROR}: {run['error']}" if run.get('error') else run['end_reason']
        if len(end) > MAX_TABLE_ERROR_CHARS:
            end = end[:MAX_TABLE_ERROR_CHARS - 1] + '…'
        # A '|' in an error message would split the Markdown cell.
        return cells + blanks + [end.replace('|', '/'), number_cell(run.get('wall_s'), 0), MISSING]
    return cells + [
        number_cell(metrics['completion_percent'], 0),
        number_cell(metrics['lap_time_s'], 1),
        number_cell(metrics['mean_speed_mps'], 3),
        number_cell(metrics['rms_distance_from_line_m'], 1, CM_PER_M),
        number_cell(metrics['max_distance_from_line_m'], 1, CM_PER_M),
        number_cell(metrics['time_off_line_s'], 1),
        _lost_frames_cell(metrics),
        str(metrics['recoveries']),
        run['end_reason'],
        number_cell(run['wall_s'], 0),
        MISSING if ratio is None else f'{ratio:.2f}×',
    ]


def format_table(runs: list) -> str:
    """
    Lay out the runs as a Markdown table, one row per run, in the order given.

    :param runs: run records (see :func:`run_one`).
    :return: the table as text: header, rule, then one line per run; a failed run shows its
        error in the ``end`` column.
    """
    ratios = speedups(runs)
    rows = [list(TABLE_COLUMNS)]
    rows += [_table_row(run, ratios.get((*run_place(run), run['configuration'])))
             for run in runs]
    widths = [max(len(row[column]) for row in rows) for column in range(len(TABLE_COLUMNS))]
    numeric = [False, False] + [True] * (len(TABLE_COLUMNS) - 2)
    numeric[TABLE_COLUMNS.index('end')] = False

    def line(cells):
        return '| ' + ' | '.join(cell.rjust(width) if right else cell.ljust(width)
                                 for cell, width, right in zip(cells, widths, numeric)) + ' |'

    rule = '| ' + ' | '.join('-' * (width - 1) + (':' if right else '-')
                             for width, right in zip(widths, numeric)) + ' |'
    return '\n'.join([line(rows[0]), rule] + [line(row) for row in rows[1:]])


def format_progress(run: dict, done: int, total: int) -> str:
    """
    Describe a finished run in one line.

    :param run: the run record.
    :param done: how many runs have finished, this one included.
    :param total: how many runs there are.
    :return: a line such as ``[scorecard] 3/14 s_bends / book: lap completed, done 100%,
        lap 121.4 s, RMS 2.9 cm; 58 s wall, 2.1x real time``.
    """
    head = f"[{PROGRAM}] {done}/{total} {run_label(run)} / {run['configuration']}: "
    metrics = run.get('metrics')
    if not metrics:
        return head + f"{run['end_reason']}: {run.get('error') or 'no figures'}"
    lap = MISSING if metrics['lap_time_s'] is None else f"{metrics['lap_time_s']:.1f} s"
    return (head + f"{run['end_reason']}, done {metrics['completion_percent']:.0f}%, lap {lap}, "
            f"RMS {CM_PER_M * metrics['rms_distance_from_line_m']:.1f} cm; "
            f"{run['wall_s']:.0f} s wall, {number_cell(run['simulated_per_wall'], 1)}x real time")


# Set in each worker process by _init_worker.
_worker = {'domain_id': None, 'stop': StopSignals()}


def _init_worker(slots, first_domain_id: int) -> None:
    """Give this worker process its own ROS domain and make Ctrl-C end its run cleanly."""
    _worker['domain_id'] = first_domain_id + slots.get()
    os.environ['ROS_DOMAIN_ID'] = str(_worker['domain_id'])
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    keep_large_buffers()
    _worker['stop'].install()


def _simulator_overrides(scenario: Scenario, sim_parameters) -> list:
    values = {
        **dict(sim_parameters),
        # As fast as the machine allows, every frame answered before time goes on: the
        # figures do not depend on the machine or its load.
        'real_time_factor': 0.0,
        'lockstep': True,
        'start_paused': False,
        'run_duration_s': 0.0,
        'course': scenario.course,
        'lighting_zones': scenario.lighting_zones,
        'camera_noise_stddev_levels': scenario.camera_noise_stddev_levels,
        'random_seed': scenario.random_seed,
    }
    if scenario.realism:
        values.update(realism=scenario.realism, realism_seed=scenario.realism_seed,
                      line_truth_row_step_px=1)
    return [Parameter(name, value=value) for name, value in values.items()]


def _wait_until_connected(executor, simulator, follower, stop_requested,
                          recording: RunRecording | None = None) -> None:
    """Spin until the follower hears the camera, the simulator the follower, a recorder all."""
    deadline_s = time.monotonic() + CONNECT_TIMEOUT_S
    while not (simulator.count_subscribers(IMAGE_TOPIC) > 0
               and follower.count_subscribers(CMD_VEL_TOPIC) > 0
               and (recording is None or recording.recorder.matched)):
        if stop_requested.is_set():
            return  # The run loop ends the run as interrupted.
        if time.monotonic() > deadline_s:
            raise RuntimeError(f'The follower and the simulator did not find each other within '
                               f'{CONNECT_TIMEOUT_S:g} s.')
        executor.spin_once(timeout_sec=CONNECT_POLL_S)


def stopped_at_line_end(world, tracker) -> bool:
    """
    Tell whether the robot stands still on a line that ends, just before its end.

    :param world: the simulator's World.
    :param tracker: its LapTracker, progress counted from the start of the course.
    :return: True on a course whose paint ends, with the robot at rest no farther than
        ``STOPPED_BEFORE_LINE_END_WITHIN_M`` before the end of the paint (and not beyond it).
    """
    painted_interval_m = world.course.painted_interval_m
    if painted_interval_m is None:
        return False
    before_end_m = painted_interval_m[1] - tracker.progress_m
    linear_mps, angular_radps = world.robot_twist()
    return (0.0 <= before_end_m <= STOPPED_BEFORE_LINE_END_WITHIN_M
            and abs(linear_mps) < STANDING_STILL_MPS and abs(angular_radps) < STANDING_STILL_RADPS)


def run_scenario(context: Context, scenario: Scenario, sim_parameters=(),
                 time_limit_s: float | None = None,
                 stuck_after_s: float = DEFAULT_STUCK_AFTER_S,
                 stop_requested: StopSignals | None = None, record_path: str | None = None,
                 record_compressed: bool = False) -> dict:
    """
    Run the simulator and the follower on a scenario until a lap, the time limit or a stop.

    Both nodes are made on the given context, so the follower takes its parameters from the
    context's arguments (``--params-file``) and otherwise its defaults.

    :param context: an initialised rclpy Context, on a domain of its own.
    :param scenario: the course and the camera's conditions.
    :param sim_parameters: further (name, value) simulator parameters.
    :param time_limit_s: simulated seconds at most; None for :func:`default_time_limit_s`.
    :param stuck_after_s: simulated seconds without progress that end the run as stuck.
    :param stop_requested: a StopSignals, or anything with ``is_set()``, that ends the run as
        interrupted when set.
    :param record_path: record the run into this MCAP file; None records nothing.
    :param record_compressed: record the camera as JPEG.
    :return: ``end_reason``, ``time_limit_s``, ``metrics`` (see :func:`run_metrics`),
        ``lap_tracker`` and ``line_statistics`` (the raw figures), ``wall_s`` (the spin
        loop), ``simulated_per_wall``, ``camera`` and, when recorded, ``recording`` (a line
        saying what the file holds).
    :raises RuntimeError: if the nodes do not find each other.
    """
    stop_requested = stop_requested or StopSignals()
    nodes = []
    recording = None
    executor = SingleThreadedExecutor(context=context)
    try:
        simulator = SimulatorNode(context=context, parameter_overrides=_simulator_overrides(
            scenario, sim_parameters))
        nodes.append(simulator)
        follower = FollowerNode(context=context, parameter_overrides=[
            Parameter('use_sim_time', value=True),
            Parameter('image_timeout_s', value=LOCKSTEP_IMAGE_TIMEOUT_S)])
        nodes.append(follower)
        monitor = None
        if scenario.realism:
            monitor = PerceptionMonitor(*(follower.get_parameter(name).value for name in (
                'camera_height_m', 'camera_pitch_deg', 'camera_forward_m')), context=context)
            nodes.append(monitor)
            executor.add_node(monitor)
        # Simulated time starts only once both ends are connected: no lap time is spent
        # waiting for discovery with the robot standing still.
        executor.add_node(follower)
        if record_path is not None:
            # The simulator is not spun before the recorder hears every topic: no frame lost.
            recording = RunRecording(record_path, None, record_compressed, context=context)
            executor.add_node(recording.recorder)
        _wait_until_connected(executor, simulator, follower, stop_requested, recording)
        executor.add_node(simulator)
        world, tracker = simulator.world, simulator.lap_tracker
        time_limit_s = time_limit_s or default_time_limit_s(world.course.length_m)
        stuck = StuckDetector(stuck_after_s)
        samples = RunSamples()
        start_s = time.monotonic()
        while True:
            executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            if recording is not None:
                # Time stands still (the simulator is not spun) while the recorder catches up.
                recording.hold_in(executor, simulator)
            samples.take(world, tracker)
            if tracker.laps_completed >= 1:
                end_reason = END_LAP
            elif world.time_s >= time_limit_s:
                end_reason = END_TIME_LIMIT
            elif stuck.update(world.time_s, tracker.progress_m):
                end_reason = END_LINE_END if stopped_at_line_end(world, tracker) else END_STUCK
            elif stop_requested.is_set():
                end_reason = END_INTERRUPTED
            else:
                continue
            break
        wall_s = time.monotonic() - start_s
        recorded = {}
        if recording is not None:
            # Time stands still while the recorder writes what it still holds.
            if not recording.holding:
                executor.remove_node(simulator)
            recording.drain(executor)
            recorded['recording'], recording = recording.close(), None
        width_px, height_px = world.image_size_px
        summary = tracker.summary()
        line_statistics = dict(follower.line_statistics)
        return {
            'end_reason': end_reason,
            'time_limit_s': time_limit_s,
            'metrics': run_metrics(summary, line_statistics),
            'lap_tracker': summary,
            'line_statistics': line_statistics,
            'wall_s': wall_s,
            'simulated_per_wall': summary['time_s'] / wall_s if wall_s > 0.0 else None,
            'samples': samples.as_dict(),
            'camera': {'width_px': width_px, 'height_px': height_px,
                       'rate_hz': simulator.get_parameter('camera_rate_hz').value,
                       'noise_stddev_levels': world.camera_noise_stddev},
            **recorded,
            'perception': None if monitor is None else perception_figures(monitor.tally),
            'realism': None if world.realism is None else dataclasses.asdict(world.realism),
        }
    finally:
        if recording is not None:
            recording.close()
        executor.shutdown()
        for node in reversed(nodes):
            node.destroy_node()


def run_one(task: dict) -> dict:
    """
    Run one configuration on one scenario in this worker process and score it.

    :param task: ``configuration``, ``params_file`` (str), ``scenario`` (a Scenario as a
        dict), ``start`` and ``starts`` (which of how many starts: the start's offsets are in
        ``sim_parameters``), ``sim_parameters`` (name, value pairs), ``time_limit_s`` (None
        for the default), ``stuck_after_s`` and ``node_log_level``.
    :return: the run record: the task's names and start, ``end_reason``, ``error`` (one
        line, or None), ``metrics`` (see :func:`run_metrics`; None after an error),
        ``lap_tracker`` and ``line_statistics`` (the raw figures), ``time_limit_s``, ``wall_s``
        (the run's spin loop), ``setup_wall_s``, ``simulated_per_wall``, ``camera`` and
        ``domain_id``.
    """
    record = {'scenario': task['scenario']['name'], 'configuration': task['configuration'],
              'params_file': task['params_file'], 'course': task['scenario']['course'],
              'start': task['start'], 'starts': task['starts'],
              'domain_id': _worker['domain_id'], 'end_reason': END_ERROR, 'error': None,
              'metrics': None}
    start_s = time.monotonic()
    if _worker['stop'].is_set():
        record.update(end_reason=END_INTERRUPTED, wall_s=0.0)
        return record
    context = Context()
    try:
        rclpy.init(context=context, domain_id=_worker['domain_id'],
                   args=['--ros-args', '--log-level', task['node_log_level'],
                         '--params-file', task['params_file']],
                   signal_handler_options=SignalHandlerOptions.NO)
        record.update(run_scenario(
            context, Scenario(**task['scenario']), task['sim_parameters'],
            task['time_limit_s'], task['stuck_after_s'], _worker['stop'],
            task['record_path'], task['record_compressed']))
        record['setup_wall_s'] = time.monotonic() - start_s - record['wall_s']
    except Exception as error:  # Any failure is this run's result, reported in its row.
        message = ' '.join(str(error).split()) or 'no message'
        record.update(error=f'{type(error).__name__}: {message}',
                      wall_s=time.monotonic() - start_s)
    finally:
        rclpy.try_shutdown(context=context)
    return record


def parse_arguments(argv=None) -> argparse.Namespace:
    """
    Read and check the command line.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the options, with ``scenarios`` (Scenario list), ``configurations``
        (Configuration list) and ``sim_parameters`` ((name, value) list) resolved.
    """
    parser = argparse.ArgumentParser(
        prog=PROGRAM,
        description='Run the simulator and the follower headless, as fast as possible, on '
                    'the built-in scenarios for several follower configurations; print a '
                    'Markdown table and write JSON.')
    parser.add_argument('--scenarios', action='append', metavar='NAMES',
                        help='scenarios to run, comma-separated or repeated: '
                             + ', '.join(SCENARIOS) + ', or the path of a YAML course file '
                             '(default: all built-in scenarios)')
    parser.add_argument('--params-file', action='append', default=[], type=Path,
                        metavar='FILE',
                        help='a further configuration to compare, named by the file stem: a '
                             'ROS 2 parameters file (its followbot_sim section, if any, applies '
                             'to the simulator); repeatable')
    parser.add_argument('--configs', action='append', metavar='NAMES',
                        help='configurations to run, comma-separated or repeated (default: '
                             + ', '.join(BUILTIN_CONFIGURATIONS) + ' and every --params-file)')
    parser.add_argument('--jobs', type=number_in(1, whole=True), default=os.cpu_count() or 1,
                        metavar='N',
                        help='runs at a time, each in its own process (default: the CPU count)')
    parser.add_argument('--domain-id', type=domain_id_option, default=None, metavar='ID',
                        help='ROS domain of the first worker; worker k uses ID + k (default: '
                             'the first free block in '
                             f'{FIRST_DOMAIN_ID}-{FIRST_DOMAIN_ID + DOMAIN_ID_SPREAD - 1}, '
                             'which no other scorecard, benchmark or test run then takes)')
    parser.add_argument('--time-limit-s', type=number_in(0.0, above=True), default=None,
                        metavar='SECONDS',
                        help='simulated seconds a run may take (default: '
                             f'{TIME_LIMIT_LAPS:g} x course length / {BOOK_SPEED_MPS:g} m/s)')
    parser.add_argument('--stuck-after-s', type=number_in(0.0, above=True),
                        default=DEFAULT_STUCK_AFTER_S, metavar='SECONDS',
                        help='end a run as stuck when it progressed less than '
                             f'{100 * STUCK_MIN_PROGRESS_M:g} cm along the line in this many '
                             f'simulated seconds (default: {DEFAULT_STUCK_AFTER_S:g})')
    parser.add_argument('--starts', type=number_in(1, len(STARTS), whole=True), default=1,
                        metavar='N',
                        help="run each scenario from N starts, the course's own and N - 1 at "
                             'most 2 cm beside it or 1 degree turned, and add a table of each '
                             "figure's mean and range over them (default: 1; at most "
                             f'{len(STARTS)})')
    parser.add_argument('--sim-param', action='append', default=[], metavar='NAME:=VALUE',
                        help='set a simulator parameter for every run, such as '
                             'camera_rate_hz:=30.0, over any params file; repeatable')
    output = parser.add_mutually_exclusive_group()
    output.add_argument('--json', type=output_file_option('the results'),
                        default=Path('scorecard.json'), metavar='PATH',
                        help='where to write the results as JSON (default: scorecard.json)')
    output.add_argument('--no-json', action='store_true', help='write no JSON file')
    parser.add_argument('--plots', type=output_folder_option('the plots'), default=None,
                        metavar='DIR',
                        help='also draw PNG plots here: lap times, and for each scenario the '
                             'distance from the line and the speed along the course (from the '
                             'first start)')
    parser.add_argument('--node-log-level', choices=NODE_LOG_LEVELS, default='error',
                        help="the nodes' ROS log level (default: error)")
    add_record_options(parser, one_file_per_run=True)
    refuse_ros_arguments(parser, argv, 'it starts its own nodes; give follower parameters as a '
                         'configuration (--params-file FILE) and simulator ones with --sim-param.')
    options = parser.parse_args(argv)
    try:
        options.scenarios = select_scenarios(options.scenarios)
        options.configurations = select_configurations(options.params_file, options.configs)
        options.sim_parameters = [parse_sim_parameter(text) for text in options.sim_param]
    except (ValueError, FileNotFoundError) as error:
        parser.error(str(error))
    given_starts = [name for name, _ in options.sim_parameters if name in START_SIM_PARAMETERS]
    if options.starts > 1 and given_starts:
        parser.error(f'--starts {options.starts} puts the robot down at its own starts: give '
                     f'{given_starts[0]} with --sim-param only without --starts.')
    runs = len(options.scenarios) * len(options.configurations) * options.starts
    options.workers = min(options.jobs, runs)
    options.domain_reservation = None
    if options.domain_id is None:
        options.domain_reservation = reserve_default_domains(
            parser, options.workers, FIRST_DOMAIN_ID, max(DOMAIN_ID_SPREAD, options.workers))
        options.domain_id = options.domain_reservation.first
    if options.domain_id + options.workers - 1 > MAX_DOMAIN_ID:
        parser.error(f'--domain-id {options.domain_id} with {options.workers} workers needs '
                     f'domains up to {options.domain_id + options.workers - 1}; the largest is '
                     f'{MAX_DOMAIN_ID}.')
    return options


def _tasks(options: argparse.Namespace) -> list:
    tasks = []
    for scenario in options.scenarios:
        for start, offsets in enumerate(STARTS[:options.starts], start=1):
            sim_parameters = list(options.sim_parameters)
            file_stem = scenario.name
            if options.starts > 1:
                sim_parameters += zip(START_SIM_PARAMETERS, offsets)
                file_stem += f'-start{start}'
            tasks += [{'configuration': configuration.name,
                       'params_file': str(configuration.params_file),
                       'scenario': dataclasses.asdict(scenario), 'start': start,
                       'starts': options.starts, 'sim_parameters': sim_parameters,
                       'time_limit_s': options.time_limit_s,
                       'stuck_after_s': options.stuck_after_s,
                       'node_log_level': options.node_log_level,
                       'record_path': None if options.record is None else str(
                           Path(options.record) / f'{file_stem}-{configuration.name}.mcap'),
                       'record_compressed': options.record_compressed}
                      for configuration in options.configurations]
    return tasks


def _run_all(tasks: list, options: argparse.Namespace) -> list:
    """Run the tasks in a pool of worker processes; return the records in task order."""
    spawn = multiprocessing.get_context('spawn')
    slots = spawn.Queue()
    for slot in range(options.workers):
        slots.put(slot)
    records = [None] * len(tasks)
    with concurrent.futures.ProcessPoolExecutor(
            max_workers=options.workers, mp_context=spawn, initializer=_init_worker,
            initargs=(slots, options.domain_id)) as pool:
        futures = {pool.submit(run_one, task): index for index, task in enumerate(tasks)}
        try:
            for done, future in enumerate(concurrent.futures.as_completed(futures), start=1):
                index = futures[future]
                try:
                    records[index] = future.result()
                except Exception as error:  # A worker died: the pool reports it per task.
                    task = tasks[index]
                    records[index] = {
                        'scenario': task['scenario']['name'],
                        'configuration': task['configuration'],
                        'start': task['start'], 'starts': task['starts'],
                        'params_file': task['params_file'], 'end_reason': END_ERROR,
                        'error': f"{type(error).__name__}: {' '.join(str(error).split())}",
                        'metrics': None}
                print(format_progress(records[index], done, len(tasks)), file=sys.stderr,
                      flush=True)
        except KeyboardInterrupt:
            # The workers got Ctrl-C too and end their runs; drop the runs not started.
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return records


def _package_version(*names) -> str | None:
    for name in names:
        try:
            return importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return None


def _cameras(records: list) -> str:
    cameras = []
    for record in records:
        camera = record.get('camera')
        if camera:
            text = f"{camera['width_px']}x{camera['height_px']} at {camera['rate_hz']:g} Hz"
            if text not in cameras:
                cameras.append(text)
    return ', '.join(cameras) or 'none'


def _metadata(options: argparse.Namespace, argv: list, wall_s: float) -> dict:
    return {
        'date': datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'),
        'hostname': socket.gethostname(),
        'command': shlex.join([PROGRAM, *argv]),
        'python': platform.python_version(),
        'rclpy': _package_version('ros-rclpy', 'rclpy'),
        'rmw_implementation': rclpy.get_rmw_implementation_identifier(),
        'mujoco': _package_version('mujoco'),
        'configurations': {configuration.name: str(configuration.params_file)
                           for configuration in options.configurations},
        'scenarios': [dataclasses.asdict(scenario) for scenario in options.scenarios],
        'options': {
            'jobs': options.jobs, 'workers': options.workers, 'domain_id': options.domain_id,
            'time_limit_s': options.time_limit_s, 'stuck_after_s': options.stuck_after_s,
            'stuck_min_progress_m': STUCK_MIN_PROGRESS_M,
            'default_time_limit': f'{TIME_LIMIT_LAPS:g} x course length / '
                                  f'{BOOK_SPEED_MPS:g} m/s',
            'sim_parameters': dict(options.sim_parameters),
            'starts': options.starts,
            'start_offsets': [dict(zip(START_SIM_PARAMETERS, offsets))
                              for offsets in STARTS[:options.starts]],
            'node_log_level': options.node_log_level,
        },
        'wall_s': wall_s,
    }


def main(argv=None) -> int:
    """
    Score the configurations on the scenarios: table on stdout, JSON file, progress on stderr.

    :param argv: command-line arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the exit code: 0 when every run ran (however well the follower did), 1 when a
        run failed with an error, 130 on Ctrl-C.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    options = parse_arguments(argv)
    tasks = _tasks(options)
    starts = f" x {_count(options.starts, 'start')}" if options.starts > 1 else ''
    print(f"[{PROGRAM}] {_count(len(tasks), 'run')} "
          f"({_count(len(options.configurations), 'configuration')} x "
          f"{_count(len(options.scenarios), 'scenario')}{starts}) on "
          f"{_count(options.workers, 'worker')}, ROS domains {options.domain_id}-"
          f'{options.domain_id + options.workers - 1}.', file=sys.stderr, flush=True)
    start_s = time.monotonic()
    try:
        records = _run_all(tasks, options)
    except KeyboardInterrupt:
        print(f'[{PROGRAM}] interrupted: no table, no JSON.', file=sys.stderr, flush=True)
        return 130
    wall_s = time.monotonic() - start_s
    for record in records:
        if record.get('recording'):
            print(f"[{PROGRAM}] recorded {record['recording']}", file=sys.stderr, flush=True)
    ratios = speedups(records)
    for record in records:
        record['book_lap_time_ratio'] = ratios.get((*run_place(record),
                                                    record['configuration']))
    print(format_table(records))
    print()
    starts_table = format_starts_table(records)
    if starts_table:
        print(starts_table)
        print()
    realistic_table = format_realistic_table(records)
    if realistic_table:
        print(realistic_table)
        print()
    print(f'`{shlex.join([PROGRAM, *argv])}`: camera {_cameras(records)}; '
          f"{_count(len(records), 'run')} in {wall_s:.0f} s of wall time on "
          f"{_count(options.workers, 'worker')}. × book: the book configuration's "
          "lap time over this one's" + (
              ' from the same start. Over the starts: mean (least–most); the lap time of '
              'the starts that lapped.' if options.starts > 1 else '.'))
    if not options.no_json:
        document = {'metadata': _metadata(options, argv, wall_s), 'runs': records}
        try:
            options.json.write_text(json.dumps(document, indent=2) + '\n', encoding='utf-8')
        except OSError as error:
            # The table above holds the figures: say why there is no JSON, and fail.
            print(f'[{PROGRAM}] cannot write the results to {options.json}: '
                  f'{error.strerror or error}.', file=sys.stderr, flush=True)
            return 1
        print(f'[{PROGRAM}] results in {options.json}', file=sys.stderr, flush=True)
    if options.plots is not None:
        paths = write_plots([record for record in records if record['start'] == 1],
                            options.plots)
        print(f'[{PROGRAM}] {_count(len(paths), "plot")} in {options.plots}/', file=sys.stderr,
              flush=True)
    return 1 if any(record['end_reason'] == END_ERROR for record in records) else 0


if __name__ == '__main__':
    sys.exit(main())
