"""
The scorecard command: figures, table and option checks, then one real short run of the nodes.

The pure parts are called directly with made-up figures; the end-to-end test runs the real
simulator and follower in worker processes for three seconds of simulated time per run.
"""

import json

from conftest import refusal, run_domain_id
from followbot_sim.scorecard import (format_starts_table, format_table, main,
                                     parse_sim_parameter, run_metrics, SCENARIOS,
                                     select_configurations, select_scenarios, STARTS,
                                     StuckDetector)
import pytest

# A short end-to-end run: long enough for the robot to move and the camera to send frames.
E2E_TIME_LIMIT_S = 3.0
E2E_TIME_TOLERANCE_S = 0.05
COURSE_LENGTH_M = 20.0
# A square course file of 4 x 3 m: small, valid, and quick to load.
SQUARE_COURSE_YAML = 'centre_line:\n  points: [[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]]\n'


def summary(progress_m=10.0, laps_completed=0, lap_times_s=(), elapsed_s=50.0):
    """Return a made-up LapTracker summary on a 20 m course."""
    return {'course': 'made_up', 'course_length_m': COURSE_LENGTH_M, 'time_s': elapsed_s,
            'elapsed_s': elapsed_s, 'max_distance_from_line_m': 0.05,
            'rms_distance_from_line_m': 0.02, 'progress_m': progress_m,
            'laps_completed': laps_completed, 'lap_times_s': list(lap_times_s),
            'time_off_line_s': 1.5, 'arc_jumps': 0}


def statistics(frames=200, frames_line_lost=10, recoveries=2):
    """Return made-up follower line statistics."""
    return {'frames': frames, 'frames_line_lost': frames_line_lost, 'recoveries': recoveries}


@pytest.mark.parametrize('score, line, expected', [
    # A completed lap: full marks for completion, speed from the lap time.
    (summary(progress_m=21.0, laps_completed=1, lap_times_s=[100.0], elapsed_s=105.0),
     statistics(), {'completion_percent': 100.0, 'lap_time_s': 100.0, 'mean_speed_mps': 0.2,
                    'line_lost_percent': 5.0}),
    # Halfway when time ran out: no lap time, speed from progress over elapsed time.
    (summary(progress_m=10.0, elapsed_s=50.0), statistics(),
     {'completion_percent': 50.0, 'lap_time_s': None, 'mean_speed_mps': 0.2,
      'line_lost_percent': 5.0}),
    # Driven backwards: no negative completion.
    (summary(progress_m=-1.0, elapsed_s=10.0), statistics(),
     {'completion_percent': 0.0, 'lap_time_s': None, 'mean_speed_mps': -0.1}),
    # No camera frame and no time at all: nothing to divide by.
    (summary(progress_m=0.0, elapsed_s=0.0), statistics(frames=0, frames_line_lost=0),
     {'completion_percent': 0.0, 'mean_speed_mps': None, 'line_lost_percent': None,
      'frames': 0}),
])
def test_run_metrics(score, line, expected):
    metrics = run_metrics(score, line)
    for name, value in expected.items():
        assert metrics[name] == pytest.approx(value), name
    assert metrics['rms_distance_from_line_m'] == 0.02
    assert metrics['time_off_line_s'] == 1.5
    assert metrics['recoveries'] == line['recoveries']


def run_record(configuration, scenario='book_loop', lap_time_s=None, error=None, start=1,
               starts=1, max_distance_m=0.05):
    """Return a run record as run_one makes it, finished or failed."""
    record = {'scenario': scenario, 'configuration': configuration, 'error': error,
              'start': start, 'starts': starts, 'wall_s': 40.0,
              'end_reason': 'error' if error else 'lap completed', 'metrics': None}
    if not error:
        lap = (lap_time_s,) if lap_time_s else ()
        score = summary(COURSE_LENGTH_M if lap else 5.0, len(lap), lap)
        score['max_distance_from_line_m'] = max_distance_m
        record['metrics'] = run_metrics(score, statistics())
        record['end_reason'] = 'lap completed' if lap else 'time limit'
    return record


def table_rows(table):
    """Return the cells of a Markdown table's body rows."""
    return [[cell.strip() for cell in line.strip('|').split('|')]
            for line in table.splitlines()[2:]]


def test_table_has_a_row_per_run_and_the_lap_time_ratio_to_the_book():
    runs = [run_record('followbot', lap_time_s=50.0), run_record('book', lap_time_s=100.0),
            run_record('fast', lap_time_s=40.0), run_record('followbot', 's_bends'),
            run_record('book', 's_bends', lap_time_s=120.0)]
    table = format_table(runs)
    header = [cell.strip() for cell in table.splitlines()[0].strip('|').split('|')]
    rows = table_rows(table)
    expected = [[run['scenario'], run['configuration']] for run in runs]
    assert [row[:2] for row in rows] == expected
    ratio = {tuple(row[:2]): row[header.index('× book')] for row in rows}
    assert ratio['book_loop', 'followbot'] == '2.00×'
    assert ratio['book_loop', 'fast'] == '2.50×'
    assert ratio['book_loop', 'book'] == '—'
    # No lap, no ratio.
    assert ratio['s_bends', 'followbot'] == '—'
    followbot = dict(zip(header, rows[0]))
    assert followbot['done %'] == '100'
    assert followbot['lap s'] == '50.0'
    assert followbot['RMS cm'] == '2.0'
    assert followbot['max cm'] == '5.0'
    assert followbot['lost frames'] == '10 (5.0%)'
    assert followbot['recoveries'] == '2'


def test_runs_from_several_starts_are_told_apart_and_compared_from_the_same_start():
    runs = [run_record('followbot', lap_time_s=50.0, start=1, starts=2),
            run_record('book', lap_time_s=100.0, start=1, starts=2),
            run_record('followbot', lap_time_s=60.0, start=2, starts=2),
            run_record('book', lap_time_s=90.0, start=2, starts=2)]
    table = format_table(runs)
    header = [cell.strip() for cell in table.splitlines()[0].strip('|').split('|')]
    ratio = {tuple(row[:2]): row[header.index('× book')] for row in table_rows(table)}
    assert ratio['book_loop start 1/2', 'followbot'] == '2.00×'
    assert ratio['book_loop start 2/2', 'followbot'] == '1.50×'


def test_the_starts_table_gives_each_figure_over_the_starts():
    runs = [run_record('followbot', lap_time_s=50.0, start=1, starts=3, max_distance_m=0.05),
            run_record('followbot', lap_time_s=51.0, start=2, starts=3, max_distance_m=0.07),
            run_record('followbot', start=3, starts=3, max_distance_m=0.12),
            run_record('book', 's_bends', error='RuntimeError: boom', start=1, starts=3),
            run_record('book', 's_bends', lap_time_s=120.0, start=2, starts=3),
            run_record('book', 's_bends', lap_time_s=124.0, start=3, starts=3)]
    table = format_starts_table(runs)
    header = [cell.strip() for cell in table.splitlines()[0].strip('|').split('|')]
    rows = [dict(zip(header, row)) for row in table_rows(table)]
    assert [(row['scenario'], row['configuration']) for row in rows] == [
        ('book_loop', 'followbot'), ('s_bends', 'book')]
    # The lap time over the starts that lapped; the distances over every start that ran.
    assert rows[0]['laps'] == '2/3'
    assert rows[0]['lap s'] == '50.50 (50.00–51.00)'
    assert rows[0]['max cm'] == '8.00 (5.00–12.00)'
    assert rows[1]['laps'] == '2/3'
    assert rows[1]['lap s'] == '122.00 (120.00–124.00)'
    # Runs of a single start have no such table.
    assert format_starts_table([run_record('followbot', lap_time_s=50.0)]) == ''


def test_a_failed_run_shows_its_error_in_its_row():
    table = format_table([run_record('book'), run_record('followbot', error='RuntimeError: boom')])
    rows = table_rows(table)
    assert len(rows) == 2
    assert any('RuntimeError: boom' in cell for cell in rows[1])


def test_scenarios_default_to_all_and_keep_the_order_given(tmp_path):
    assert select_scenarios() == list(SCENARIOS.values())
    course_file = tmp_path / 'mine.yaml'
    course_file.write_text(SQUARE_COURSE_YAML, encoding='utf-8')
    chosen = select_scenarios([f's_bends,{course_file}', 'book_loop_light_noise'])
    assert [scenario.name for scenario in chosen] == [
        's_bends', str(course_file), 'book_loop_light_noise']
    assert chosen[1].course == str(course_file)
    assert chosen[2].lighting_zones and chosen[2].camera_noise_stddev_levels == 24.0


@pytest.mark.parametrize('names, message', [
    (['book_loop,no_such_course'], "Unknown scenario 'no_such_course'"),
    (['/nowhere/absent.yaml'], 'cannot read course file'),
])
def test_an_unknown_scenario_is_refused(names, message):
    with pytest.raises(ValueError, match=message):
        select_scenarios(names)


def test_configurations_are_the_builtins_plus_params_files(tmp_path):
    params_file = tmp_path / 'slow.yaml'
    params_file.write_text('follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    names = [configuration.name for configuration in select_configurations([params_file])]
    assert names == ['followbot', 'book', 'slow']
    chosen = select_configurations([params_file], ['slow', 'book'])
    assert [configuration.name for configuration in chosen] == ['book', 'slow']


@pytest.mark.parametrize('file_name, text, names, message', [
    (None, None, ['nobody'], "Unknown configuration 'nobody'"),
    ('absent.yaml', None, None, 'does not exist'),
    ('followbot.yaml', 'follower: {}\n', None, "second configuration named 'followbot'"),
    ('list.yaml', '- 1\n', None, 'must map node names'),
    ('broken.yaml', 'follower: [\n', None, 'not valid YAML'),
])
def test_bad_configurations_are_refused(tmp_path, file_name, text, names, message):
    params_files = [tmp_path / file_name] if file_name else []
    if text is not None:
        params_files[0].write_text(text)
    with pytest.raises(ValueError, match=message):
        select_configurations(params_files, names)


@pytest.mark.parametrize('text, expected', [
    ('camera_rate_hz:=30.0', ('camera_rate_hz', 30.0)),
    ('camera_rate_hz:=30', ('camera_rate_hz', 30.0)),
    ('image_width_px:=320', ('image_width_px', 320)),
    ('depth_enabled:=false', ('depth_enabled', False)),
    ('image_encoding:=rgb8', ('image_encoding', 'rgb8')),
])
def test_sim_parameters_are_typed_like_ros_arguments(text, expected):
    assert parse_sim_parameter(text) == expected


@pytest.mark.parametrize('text, message', [
    ('camera_rate_hz=30.0', 'NAME:=VALUE'),
    ('warp_speed:=9', "Unknown simulator parameter 'warp_speed'"),
    ('course:=s_bends', 'set by the scorecard'),
    ('image_width_px:=wide', 'takes an integer'),
    ('camera_rate_hz:=500.0', 'must be in 1..60'),
    ('robots:=2', 'followbot --robots N'),
])
def test_bad_sim_parameters_are_refused(text, message):
    with pytest.raises(ValueError, match=message):
        parse_sim_parameter(text)


def test_stuck_only_after_a_whole_window_without_progress():
    detector = StuckDetector(window_s=30.0)
    # Moving for 40 s, then standing still.
    assert not any(detector.update(time_s, 0.1 * time_s) for time_s in range(41))
    assert not detector.update(60.0, 4.0)
    assert not detector.update(69.0, 4.0)
    assert detector.update(71.0, 4.0)


@pytest.mark.parametrize('arguments, message', [
    (['--scenarios', 'moon'], "Unknown scenario 'moon'"),
    (['--configs', 'nobody'], "Unknown configuration 'nobody'"),
    (['--params-file', '/nowhere/x.yaml'], 'does not exist'),
    (['--sim-param', 'course:=dashed'], 'set by the scorecard'),
    (['--jobs', '0'], "argument --jobs: must be a whole number >= 1, got '0'"),
    (['--starts', '0'], f'must be a whole number in [1, {len(STARTS)}]'),
    (['--starts', str(len(STARTS) + 1)], f'must be a whole number in [1, {len(STARTS)}]'),
    (['--time-limit-s', 'nan'], "argument --time-limit-s: must be a number > 0, got 'nan'"),
    (['--json', 'no/such/folder/s.json'], 'folder no/such/folder does not exist'),
    (['--starts', '2', '--sim-param', 'start_lateral_offset_m:=0.01'],
     'give start_lateral_offset_m with --sim-param only without --starts'),
])
def test_bad_options_end_with_one_clear_line(capsys, arguments, message):
    error = refusal(main, arguments, capsys)
    assert error.startswith('scorecard: error:') and message in error


def test_scorecard_runs_the_nodes_and_writes_the_table_and_json(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    params_file = tmp_path / 'careful.yaml'
    params_file.write_text('follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    json_path = tmp_path / 'scorecard.json'
    domain_id = run_domain_id()

    exit_code = main(['--scenarios', 'book_loop', '--time-limit-s', str(E2E_TIME_LIMIT_S),
                      '--jobs', '2', '--domain-id', str(domain_id), '--params-file',
                      str(params_file), '--configs', 'followbot,book,careful',
                      '--json', str(json_path)])

    assert exit_code == 0
    runs = json.loads(json_path.read_text())['runs']
    assert sorted(run['configuration'] for run in runs) == ['book', 'careful', 'followbot']
    for run in runs:
        assert run['error'] is None
        assert run['end_reason'] == 'time limit'
        assert run['lap_tracker']['time_s'] == pytest.approx(E2E_TIME_LIMIT_S,
                                                             abs=E2E_TIME_TOLERANCE_S)
        assert run['line_statistics']['frames'] > 0
        assert 0.0 < run['metrics']['completion_percent'] < 100.0
    # The careful configuration's file took effect: half the book's speed, so less progress.
    progress_m = {run['configuration']: run['lap_tracker']['progress_m'] for run in runs}
    assert progress_m['careful'] < progress_m['book']
    stdout = capsys.readouterr().out
    assert '| scenario' in stdout
    assert len([line for line in stdout.splitlines() if line.startswith('| book_loop')]) == 3


def test_each_start_puts_the_robot_down_where_it_says(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    json_path = tmp_path / 'scorecard.json'
    record_folder = tmp_path / 'runs'

    exit_code = main(['--scenarios', 'book_loop', '--configs', 'followbot', '--starts', '2',
                      '--time-limit-s', str(E2E_TIME_LIMIT_S), '--jobs', '2',
                      '--domain-id', str(run_domain_id()), '--json', str(json_path),
                      '--record', str(record_folder)])

    assert exit_code == 0
    document = json.loads(json_path.read_text())
    runs = {run['start']: run for run in document['runs']}
    assert sorted(runs) == [1, 2]
    assert all(run['error'] is None and run['starts'] == 2 for run in runs.values())
    # The first start is the course's own, on the line; the second is 1 cm beside it.
    lateral_m, heading_deg = STARTS[1]
    assert document['metadata']['options']['start_offsets'][1] == {
        'start_lateral_offset_m': lateral_m, 'start_heading_offset_deg': heading_deg}
    assert runs[1]['metrics']['max_distance_from_line_m'] < 0.5 * lateral_m
    assert runs[2]['metrics']['max_distance_from_line_m'] >= 0.9 * lateral_m
    assert sorted(path.name for path in record_folder.iterdir()) == [
        'book_loop-start1-followbot.mcap', 'book_loop-start2-followbot.mcap']
    stdout = capsys.readouterr().out
    assert any(line.startswith('| book_loop start 2/2') for line in stdout.splitlines())
    assert '| book_loop | followbot | 0/2 |' in stdout
