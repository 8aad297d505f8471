"""
The ``followbot`` command: start the simulator and the follower and watch them lap the course.

The two nodes run as separate processes that talk over DDS only, as they would on a robot. This
process supervises them (prefixed logs, Ctrl-C forwarded, no orphans, non-zero exit when a child
fails) and runs a small monitor node that turns the simulator's ground-truth score into
progress lines and, on request, saves pictures of the camera's debug view and of the course.
"""

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import cv2
from diagnostic_msgs.msg import DiagnosticArray
from followbot import calibrate
from followbot import messages
from followbot.follower_node import NODE_NAME as FOLLOWER_NODE
from followbot.image_conversion import image_to_array, to_bgr
from followbot.node_runner import (die_with_parent, init_rclpy, node_name_and_namespace,
                                   ROS_ARGS_END, ROS_ARGS_FLAG, RosStartError, split_ros_arguments,
                                   StopSignals)
from followbot.number_options import number_in, parameter_option
from followbot.output_files import output_folder_option
from followbot.package_files import share_file
from followbot.parameters_file import check_reaches, ParametersFileError
from followbot.recording import RecordingError
from followbot.transport import environment_with_profile, keep_large_buffers, use_package_profile
from followbot_sim import soak
from followbot_sim.answered_requests import SimulatorPause
from followbot_sim.course_file import load_course
from followbot_sim.course_library import COURSES
from followbot_sim.domains import domain_id_option
from followbot_sim.robots import MAX_ROBOTS, robot_names, robot_prefix, SINGLE_ROBOT
from followbot_sim.run_recording import add_record_options, drain, HoldReport, RunRecording
from followbot_sim.score import robot_simulator_name, score_values, SIMULATOR_NODE
from followbot_sim.scorecard import BUILTIN_CONFIGURATIONS, LOCKSTEP_IMAGE_TIMEOUT_S
from followbot_sim.sim_node import SIMULATOR_PARAMETERS
from followbot_sim.video import add_video_node, video_path_option, VideoHold
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Image

STOP_GRACE_S = 5.0
MONITOR_SPIN_S = 0.1
REPORT_TOLERANCE_S = 1e-3
CLOCK_TOPIC = '/clock'
# How long the launcher looks for another simulator's clock before starting its own nodes: the
# time DDS discovery takes to show a running participant on this machine. A new participant
# learns of one that is already running from its periodic announcement (Fast DDS: every 3 s),
# so a running simulator's /clock showed 2.1-3.3 s after a probe started (12 tries, quiet
# 2-core machine); 2 s missed it, and two simulators then shared one clock.
CLOCK_DISCOVERY_S = 4.5
DEBUG_IMAGE_TOPIC = 'follower/debug_image'
OVERVIEW_IMAGE_TOPIC = 'overview/image'
CAMERA_PICTURE = 'camera_debug.png'
OVERVIEW_PICTURE = 'overview.png'
# `followbot calibrate ...` is the calibrate command (followbot.calibrate), not a simulation.
CALIBRATE_COMMAND = 'calibrate'


def parse_arguments(argv=None) -> argparse.Namespace:
    """
    Read the command line.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the parsed options; ``ros_arguments`` holds the ROS sections, for both nodes.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    own_arguments, ros_arguments = split_ros_arguments(argv)
    parser = argparse.ArgumentParser(
        prog='followbot',
        usage='%(prog)s [options] [--ros-args ...]',
        description='Run the MuJoCo simulator and the line follower as two ROS 2 processes '
                    'and report laps, lap times and distance from the line.',
        epilog='ROS arguments after --ros-args go to both nodes, before the options above '
               '(which therefore win over a --params-file): remaps such as '
               '-r __ns:=/robot1 or -r cmd_vel:=cmd_vel_mux/input/teleop, -p name:=value, '
               '--params-file FILE, --log-level. A node ignores parameters it does not '
               'declare; prefix a remap with a node name (follower:, followbot_sim:) to '
               "aim it at one node. `followbot calibrate --help`: the follower's "
               'parameters for a new camera and tape, from one frame.')
    parser.add_argument('--duration', default=240.0, metavar='SECONDS',
                        type=parameter_option(SIMULATOR_PARAMETERS['run_duration_s']),
                        help='simulated seconds to run; 0 runs until Ctrl-C (default: 240)')
    parser.add_argument('--real-time-factor', default=1.0, metavar='FACTOR',
                        type=parameter_option(SIMULATOR_PARAMETERS['real_time_factor']),
                        help='simulated seconds per wall second; 0 = as fast as the machine '
                             'allows (default: 1)')
    parser.add_argument('--lockstep', action='store_true', default=None,
                        help='let the follower drive time: the simulator waits for the '
                             'command answering each camera frame (runs are reproducible)')
    parser.add_argument('--domain-id', type=domain_id_option, default=None, metavar='ID',
                        help="ROS_DOMAIN_ID for both nodes (default: the environment's, or 0)")
    parser.add_argument('--course', default=None,
                        help='a built-in course (' + ', '.join(COURSES) + ') or the path of a '
                             "YAML course file (default: the simulator's course parameter, "
                             'book_loop)')
    parser.add_argument('--lighting', action='store_true', default=None,
                        help='add bright and dim zones of light along the line')
    parser.add_argument('--report-period', type=number_in(0.0, above=True), default=10.0,
                        metavar='SECONDS',
                        help='simulated seconds between progress lines (default: 10)')
    parser.add_argument('--robots', type=number_in(1, MAX_ROBOTS, whole=True), default=None,
                        metavar='N',
                        help=f'race N robots (1..{MAX_ROBOTS}, named r1..rN) on one course in '
                             'one simulator, each with its own follower process under its '
                             'namespace (default: one per --configs entry, else 1)')
    parser.add_argument('--configs', default=None, metavar='NAME,...',
                        help="the followers' configurations, one per robot in order (or one "
                             'for all): ' + ', '.join(BUILTIN_CONFIGURATIONS) + ' or the path '
                             "of a ROS parameters file (default: the follower's own "
                             'parameters)')
    parser.add_argument('--pictures-dir', type=output_folder_option('the pictures'), default=None,
                        metavar='DIR',
                        help=f"save {CAMERA_PICTURE} (camera view with the follower's "
                             f'overlay) and {OVERVIEW_PICTURE} (course from above with the '
                             'path driven) here while running')
    parser.add_argument('--video', type=video_path_option, default=None, metavar='FILE',
                        help="write a video (.mp4 or .avi) of the follower's view with its "
                             'overlay beside the course from above with the path driven, in '
                             'simulated time: it plays at real speed however fast the run')
    parser.add_argument('--video-period-s', type=number_in(0.0, above=True), default=None,
                        metavar='SECONDS',
                        help='simulated seconds between video frames (default: one frame per '
                             'camera frame)')
    parser.add_argument('--soak-period', type=number_in(0.0, above=True), default=None,
                        metavar='SECONDS',
                        help="soak test: sample both nodes' resident memory, open files and "
                             'shared memory every SECONDS of wall time, print the table at the '
                             "end and fail when a node's memory grew by more than "
                             f'{soak.RSS_GROWTH_LIMIT_KB / 1024:g} MiB after the warm-up '
                             f'(the first {100 * soak.WARM_UP_FRACTION:g} %% of the run, at least '
                             f'{soak.WARM_UP_MIN_S:g} s)')
    add_record_options(parser)
    options = parser.parse_args(own_arguments)
    options.ros_arguments = ros_arguments
    if options.soak_period is not None and options.duration == 0:
        parser.error('--soak-period needs a --duration')
    if options.course is not None:
        # Here, once: a bad course file is one line before any node starts.
        try:
            load_course(options.course)
        except ValueError as error:
            parser.error(f'--course: {error}')
    try:
        options.configs = follower_configurations(options.configs)
    except ValueError as error:
        parser.error(str(error))
    if options.robots is None:
        options.robots = max(1, len(options.configs))
    if options.robots > MAX_ROBOTS:
        parser.error(f'--configs names {options.robots} configurations; at most {MAX_ROBOTS} '
                     'robots race')
    if len(options.configs) == 1:
        options.configs = options.configs * options.robots
    elif options.configs and len(options.configs) != options.robots:
        parser.error(f'--configs names {len(options.configs)} configurations for '
                     f'{options.robots} robots: give one per robot, or one for all')
    # A file's follower section must reach each robot's follower, under its namespace.
    name, namespace = node_name_and_namespace(FOLLOWER_NODE, ros_arguments)
    for robot, (_, path) in zip(robot_names(options.robots), options.configs):
        try:
            check_reaches(path, f"{namespace.rstrip('/')}/{robot_prefix(robot)}{name}")
        except ParametersFileError as error:
            parser.error(f'--configs: {error}')
    if options.record and options.robots > 1:
        parser.error('--record records one robot: run several robots without it, or record '
                     'each in a launcher of its own under its namespace (-r __ns:=/robot1)')
    if options.video and options.robots > 1:
        parser.error('--video films one robot: run several robots without it, or film each '
                     'in a launcher of its own under its namespace (-r __ns:=/robot1)')
    return options


def follower_configurations(text: str | None) -> list:
    """
    Read ``--configs``: built-in configuration names or parameters files, comma-separated.

    :param text: the option's value; None for none.
    :return: (name, parameters file path) per entry, in order; empty for None.
    :raises ValueError: for an entry that is neither a built-in name nor an existing file.
    """
    if text is None:
        return []
    configurations = []
    for entry in text.split(','):
        entry = entry.strip()
        if entry in BUILTIN_CONFIGURATIONS:
            configurations.append((entry, share_file('config', BUILTIN_CONFIGURATIONS[entry])))
        elif Path(entry).is_file():
            configurations.append((Path(entry).stem, Path(entry).resolve()))
        else:
            raise ValueError(f'--configs: {entry!r} is neither a built-in configuration ('
                             + ', '.join(BUILTIN_CONFIGURATIONS) + ') nor a parameters file')
    return configurations


class ChildProcess:
    """A node process whose output lines are forwarded with a name prefix."""

    def __init__(self, name: str, command: list, environment: dict):
        """
        Start the process.

        :param name: short name used as the log prefix.
        :param command: the command line.
        :param environment: its environment.
        """
        self.name = name
        self.process = subprocess.Popen(
            command, env=environment, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, bufsize=1, start_new_session=True,
            preexec_fn=die_with_parent)
        self._forwarder = threading.Thread(target=self._forward_output, daemon=True)
        self._forwarder.start()

    def _forward_output(self):
        for line in self.process.stdout:
            print(f'[{self.name}] {line.rstrip()}', flush=True)

    def stop(self) -> int:
        """
        Stop the process with SIGINT, as Ctrl-C would, escalating if it does not end.

        :return: its exit code.
        """
        for stop_signal in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if self.process.poll() is not None:
                break
            self.process.send_signal(stop_signal)
            try:
                self.process.wait(STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                print(f'[followbot] {self.name} did not stop on {stop_signal.name}.', flush=True)
        self._forwarder.join(STOP_GRACE_S)
        return self.process.wait()


class MonitorNode(Node):
    """Print the simulator's ground-truth progress and save pictures."""

    def __init__(self, report_period_s: float, pictures_dir: Path | None, simulator: str,
                 robots: dict | None = None, **kwargs):
        """
        Subscribe to the score and, when pictures are wanted, to the two images.

        :param report_period_s: simulated seconds between progress lines.
        :param pictures_dir: folder for the pictures (made as --pictures-dir is read), or None
            for none.
        :param simulator: the fully qualified name of the simulator whose scores are reported
            (other robots' simulators may score on /diagnostics too).
        :param robots: robot name -> the label of its lines (such as ``r1 (book)``), for a
            simulator of several robots; None for its single, unnamed robot. The camera
            picture is the first robot's.
        :param kwargs: forwarded to :class:`rclpy.node.Node`.
        """
        super().__init__('followbot_monitor', **kwargs)
        robots = robots or {SINGLE_ROBOT: ''}
        # Scored name -> line label: each robot is scored under its own namespace.
        self._labels = {robot_simulator_name(simulator, name): label
                        for name, label in robots.items()}
        self._report_period_s = report_period_s
        self._next_report_s = dict.fromkeys(self._labels, 0.0)
        self._laps_reported = dict.fromkeys(self._labels, 0)
        self.summaries = {}
        self._pictures_dir = pictures_dir
        self.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics_callback, 10)
        if pictures_dir is not None:
            image_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
            self.create_subscription(Image, robot_prefix(next(iter(robots))) + DEBUG_IMAGE_TOPIC,
                                     self.debug_image_callback, image_qos)
            self.create_subscription(Image, OVERVIEW_IMAGE_TOPIC,
                                     self.overview_image_callback, image_qos)
            self._last_camera_save_s = -1.0

    def diagnostics_callback(self, msg: DiagnosticArray) -> None:
        """Keep each robot's latest score and print a progress line when one is due."""
        for scored_name, label in self._labels.items():
            summary = score_values(msg, scored_name)
            if summary is None:
                continue
            self.summaries[label] = summary
            time_s = float(summary['time_s'])
            laps = int(summary['laps_completed'])
            # Score stamps are multiples of the period up to float rounding: allow for it.
            if (laps > self._laps_reported[scored_name]
                    or time_s + REPORT_TOLERANCE_S >= self._next_report_s[scored_name]):
                self._laps_reported[scored_name] = laps
                self._next_report_s[scored_name] = time_s + self._report_period_s
                print(f'[followbot] {label}{": " if label else ""}'
                      + format_progress(summary), flush=True)

    def debug_image_callback(self, msg: Image) -> None:
        """Save the follower's view about once a second of simulated time."""
        stamp_s = messages.seconds(msg.header.stamp)
        if stamp_s - self._last_camera_save_s >= 1.0 or stamp_s < self._last_camera_save_s:
            self._last_camera_save_s = stamp_s
            self._save(msg, CAMERA_PICTURE)

    def overview_image_callback(self, msg: Image) -> None:
        """Save the latest top-down view."""
        self._save(msg, OVERVIEW_PICTURE)

    def _save(self, msg: Image, file_name: str) -> None:
        bgr = to_bgr(image_to_array(msg), msg.encoding)
        path = self._pictures_dir / file_name
        # Write then rename, so a reader never sees half a picture.
        partial = path.with_suffix('.partial.png')
        cv2.imwrite(str(partial), bgr)
        os.replace(partial, path)


def format_progress(summary: dict) -> str:
    """
    Describe the ground-truth score in one line.

    :param summary: the simulator's score, as the string key-values of /diagnostics.
    :return: a line such as ``t= 120.0 s  laps 1 (106.5 s)  next lap  13%  from line 1.2 cm
        (rms 2.6, max 6.7)  off line 0.0 s``.
    """
    lap_times = summary.get('lap_times_s', '[]').strip('[]')
    lap_text = ', '.join(f'{float(lap):.1f} s' for lap in lap_times.split(',') if lap.strip())
    lap_fraction = (float(summary['progress_m']) / float(summary['course_length_m'])) % 1.0
    return (f"t={float(summary['time_s']):6.1f} s  laps {summary['laps_completed']}"
            + (f' ({lap_text})' if lap_text else '')
            + f'  next lap {100 * lap_fraction:3.0f}%'
            + f"  from line {100 * float(summary['distance_from_line_m']):.1f} cm"
            f" (rms {100 * float(summary['rms_distance_from_line_m']):.1f},"
            f" max {100 * float(summary['max_distance_from_line_m']):.1f})"
            f"  off line {float(summary['time_off_line_s']):.1f} s")


def _node_command(module: str, ros_arguments: list, parameters: dict) -> list:
    # The user's ROS arguments first: rcl applies parameters in command-line order, so the
    # options given to this program win over a --params-file.
    command = [sys.executable, '-m', module, *ros_arguments, ROS_ARGS_FLAG]
    for name, value in parameters.items():
        if value is not None:
            command += ['-p', f'{name}:={value}']
    return command


def follower_arguments(namespace: str, robot: str, config: Path | None,
                       node_arguments: list) -> list:
    """
    Return the ROS arguments of one robot's follower: its namespace and configuration first.

    rcl takes the first namespace remap that matches, so the robot's namespace goes before the
    user's; the configuration's parameters go before the user's, which then win over it.

    :param namespace: the launcher's namespace ('/' for none).
    :param robot: the robot's name; empty for the single robot.
    :param config: the configuration's parameters file, or None for the follower's defaults.
    :param node_arguments: the ROS arguments every node gets.
    :return: the follower's ROS arguments.
    """
    own = []
    if robot:
        own += ['-r', f"__ns:={namespace.rstrip('/')}/{robot}"]
    if config is not None:
        own += ['--params-file', str(config)]
    return ([ROS_ARGS_FLAG, *own, ROS_ARGS_END] if own else []) + list(node_arguments)


def follower_parameters(lockstep: bool | None) -> dict:
    """
    Return the parameters the launcher gives each follower.

    :param lockstep: whether the simulator runs in lockstep.
    :return: name -> value as ``-p`` takes it.
    """
    parameters = {'use_sim_time': 'true'}
    if lockstep:
        parameters['image_timeout_s'] = str(LOCKSTEP_IMAGE_TIMEOUT_S)
    return parameters


def _clock_taken(monitor: Node, executor, clock_topic: str) -> bool:
    """Tell whether some node publishes the clock topic, waiting for discovery a moment."""
    deadline = time.monotonic() + CLOCK_DISCOVERY_S
    while time.monotonic() < deadline:
        if monitor.count_publishers(clock_topic) > 0:
            return True
        executor.spin_once(timeout_sec=MONITOR_SPIN_S)
    return False


def _ros_boolean(flag) -> str | None:
    return None if flag is None else str(bool(flag)).lower()


def _soak_sample(elapsed_s: float, children: tuple, summaries: dict) -> soak.SoakSample:
    laps = sum(int(summary.get('laps_completed', 0)) for summary in summaries.values())
    sample = soak.SoakSample(
        elapsed_s, {child.name: soak.sample_process(child.process.pid) for child in children},
        laps)
    print('[soak] ' + soak.format_table([sample])[-1], flush=True)
    return sample


def _report_soak(samples: list) -> bool:
    """Print the soak table and verdicts; return whether every node's memory stayed flat."""
    print('[soak] Resident memory (RSS), open file descriptors and mapped /dev/shm files of '
          'each node over wall time:', flush=True)
    for line in soak.format_table(samples):
        print(line, flush=True)
    warm_up_end_s = soak.warm_up_s(samples[-1].elapsed_s if samples else 0.0)
    try:
        verdicts = soak.memory_verdicts(samples, warm_up_end_s)
    except ValueError as error:
        print(f'[soak] FAILED: {error}', flush=True)
        return False
    for verdict in verdicts:
        print(f'[soak] {soak.format_verdict(verdict)} (warm-up {warm_up_end_s:.0f} s)',
              flush=True)
    passed = all(verdict.passed for verdict in verdicts)
    print(f"[soak] {'PASSED' if passed else 'FAILED'}", flush=True)
    return passed


def main(argv=None) -> int:
    """
    Run the demo: simulator + follower, progress on the terminal; or ``followbot calibrate``.

    :param argv: command-line arguments without the program name.
    :return: the exit code: 0 when both nodes ran and stopped cleanly (for ``calibrate``,
        its own).
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == [CALIBRATE_COMMAND]:
        return calibrate.main(argv[1:], prog=f'followbot {CALIBRATE_COMMAND}')
    options = parse_arguments(argv)
    # The Fast DDS profile for the nodes, which publish the images. This process only listens:
    # it keeps Fast DDS's small default segment (each process's segment takes its full size
    # in /dev/shm, and a launcher killed outright could not remove it).
    environment, profile = environment_with_profile(
        dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0'))
    keep_large_buffers()
    if options.record:
        # The recorder in this process takes every camera frame: through shared memory too.
        use_package_profile()
    if options.domain_id is not None:
        environment['ROS_DOMAIN_ID'] = str(options.domain_id)
    # ROS reads an empty ROS_DOMAIN_ID as the default domain, 0.
    domain_id = int(environment.get('ROS_DOMAIN_ID') or '0')

    # Ctrl-C reaches this process only (children run in their own sessions): forward it.
    interrupted = StopSignals().install()

    context = Context()
    try:
        # The monitor follows the same remaps and namespace as the nodes it watches.
        init_rclpy(['followbot', *options.ros_arguments], context=context,
                   domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    except RosStartError as error:
        print(f'[followbot] {error}', file=sys.stderr, flush=True)
        return 2
    # Under a namespace, the robot's simulated clock is its own: two launchers on one domain
    # would otherwise mix their /clock (the nodes' time source subscribes to /clock).
    _, namespace = node_name_and_namespace(SIMULATOR_NODE, options.ros_arguments)
    simulator_name = namespace.rstrip('/') + '/' + SIMULATOR_NODE
    clock_topic = CLOCK_TOPIC if namespace == '/' else namespace + CLOCK_TOPIC
    node_arguments = list(options.ros_arguments)
    if clock_topic != CLOCK_TOPIC:
        node_arguments += [ROS_ARGS_FLAG, '-r', f'{CLOCK_TOPIC}:={clock_topic}', ROS_ARGS_END]
    names = robot_names(options.robots)
    # Each robot's line says which configuration drives it.
    labels = {name: f'{name} ({config_name})' if options.configs else name
              for name, (config_name, _) in zip(
                  names, options.configs or [(None, None)] * len(names))}
    monitor = MonitorNode(options.report_period, options.pictures_dir, simulator_name,
                          robots=labels if names != (SINGLE_ROBOT,) else None, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(monitor)
    video = None
    if options.video is not None:
        video = add_video_node(executor, options.video, simulator_name, options.video_period_s)
    length = (f'{options.duration:g} s of simulated time' if options.duration
              else 'until Ctrl-C')
    pace = (f'real-time factor {options.real_time_factor:g}' if options.real_time_factor
            else 'as fast as possible')
    if options.lockstep:
        pace += ', in lockstep'
    # Without --course the simulator's parameter (or a --params-file) decides; it says which.
    course = f'course {options.course}; ' if options.course else ''
    race = ('' if names == (SINGLE_ROBOT,) else
            f"{len(names)} robots ({', '.join(labels.values())}); ")
    print(f'[followbot] ROS_DOMAIN_ID={domain_id}; {course}{race}running {length}, {pace}; '
          f'Fast DDS {profile}.', flush=True)
    # Options left out (None) leave the node's own value, or the --params-file's, in force.
    simulator_parameters = {
        'course': options.course,
        'lighting_zones': _ros_boolean(options.lighting),
        'real_time_factor': float(options.real_time_factor),
        'lockstep': _ros_boolean(options.lockstep),
        # A loaded machine can keep a follower from answering a frame for a second (its first
        # frame, above all): in lockstep the simulator waits as long as the follower's own
        # watchdog does, instead of driving on unanswered.
        'lockstep_timeout_s': float(LOCKSTEP_IMAGE_TIMEOUT_S) if options.lockstep else None,
        'run_duration_s': float(options.duration),
        'score_period_s': 1.0,
        # The single robot is left to the simulator's own default (or a --params-file).
        'robots': None if names == (SINGLE_ROBOT,) else '[' + ','.join(names) + ']',
    }
    # A simulator already running under the same namespace on this domain would share this
    # one's clock: ask the graph (discovery takes a moment) before starting anything.
    if _clock_taken(monitor, executor, clock_topic):
        print(f'[followbot] Cannot run: another simulator already publishes {clock_topic} on '
              f'ROS_DOMAIN_ID={domain_id}, and two simulated clocks would mix: run this one '
              'under its own namespace (--ros-args -r __ns:=/robot2) or on another domain '
              '(--domain-id N), or race several robots in one simulator (--robots N '
              '--configs A,B).', file=sys.stderr, flush=True)
        executor.shutdown()
        monitor.destroy_node()
        rclpy.try_shutdown(context=context)
        return 2
    recording = None
    if options.record:
        try:
            recording = RunRecording(options.record, simulator_name, options.record_compressed,
                                     clock_topic, context=context)
        except RecordingError as error:
            print(f'[followbot] {error}', file=sys.stderr, flush=True)
            executor.shutdown()
            monitor.destroy_node()
            rclpy.try_shutdown(context=context)
            return 2
        executor.add_node(recording.recorder)
    # The video and the recording take the run from its first frame: the simulator starts
    # paused and goes once they are connected (a fast lockstep run could be over before).
    start_gate = None
    if recording is not None or video is not None:
        simulator_parameters['start_paused'] = 'true'
        start_gate = SimulatorPause(monitor, simulator_name)
    simulator = ChildProcess('sim', _node_command(
        'followbot_sim.sim_node', node_arguments, simulator_parameters), environment)
    followers = [ChildProcess('follower' + (f' {name}' if name else ''), _node_command(
        'followbot.follower_node', follower_arguments(namespace, name, config, node_arguments),
        follower_parameters(options.lockstep)), environment)
        for name, (_, config) in zip(names, options.configs or [(None, None)] * len(names))]
    children = (simulator, *followers)
    soak_samples = []
    started_s = next_sample_s = time.monotonic()
    video_report = HoldReport('the video')
    video_hold = None if video is None else VideoHold(video)
    # The video gates the start only: at the end of the run the simulator's publishers go
    # before its process ends, and that is no reason to wait.
    video_connected = video is None
    try:
        while not interrupted.is_set() and all(c.process.poll() is None for c in children):
            executor.spin_once(timeout_sec=MONITOR_SPIN_S)
            if options.soak_period is not None and time.monotonic() >= next_sample_s:
                next_sample_s += options.soak_period
                soak_samples.append(_soak_sample(
                    time.monotonic() - started_s, children, monitor.summaries))
            if not video_connected:
                if not video.ready:
                    if report := video_report.line(lambda: ', '.join(video.waiting_for())):
                        print(f'[followbot] {report}', flush=True)
                    continue
                video_connected = True
            video_lags = video_hold is not None and video_hold.update()
            if video_hold is not None and (report := video_hold.report()):
                print(f'[followbot] {report}', flush=True)
            if recording is not None:
                started = recording.started
                if recording.poll(also_hold=video_lags) and not started:
                    print('[followbot] Recorder hears every topic: the simulation starts.',
                          flush=True)
                elif report := recording.wait_report():
                    print(f'[followbot] {report}', flush=True)
            elif start_gate is not None:
                # Started once connected; held while the video lags.
                start_gate.ask_paused(video_lags)
                start_gate.poll()
    finally:
        if simulator.process.poll() is not None:
            # The run ended on its own: the recorder and the video take what the followers
            # sent last (the answer to the last frame) while they still run, before their
            # buffers go.
            if recording is not None:
                recording.drain(executor)
            if video is not None:
                drain(executor, lambda: video.frame_time_s)
        # The simulator ends on its own after --duration; stop the follower first so its
        # final zero Twist still reaches a running simulator on Ctrl-C.
        exit_codes = {child.name: child.stop() for child in (*followers, simulator)}
        if recording is not None:
            recording.drain(executor)
        # Let the last score and pictures arrive, then leave.
        deadline = time.monotonic() + MONITOR_SPIN_S * 5
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=MONITOR_SPIN_S)
        executor.shutdown()
        if recording is not None:
            print(f'[followbot] recorded {recording.close()}', flush=True)
        if video_hold is not None and video_hold.holds:
            print(f'[followbot] time held {video_hold.holds} times for the video to catch up',
                  flush=True)
        monitor.destroy_node()
        rclpy.try_shutdown(context=context)
    for label, summary in monitor.summaries.items():
        print(f'[followbot] final{" " if label else ""}{label}: ' + format_progress(summary),
              flush=True)
    failed = {name: code for name, code in exit_codes.items() if code != 0}
    if failed:
        print(f'[followbot] failed: {failed} (exit codes)', flush=True)
        return 1
    if options.soak_period is not None and not _report_soak(soak_samples):
        return 1
    if options.pictures_dir is not None:
        print(f'[followbot] pictures in {options.pictures_dir}/', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
