"""Every command of the package explains itself with --help and refuses bad arguments clearly."""

import subprocess
import sys

from conftest import child_environment, refusal
from followbot import replay
from followbot.node_runner import split_ros_arguments
from followbot_sim import benchmark, latency_probe, launcher, scorecard
import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node


@pytest.mark.parametrize('command', [launcher, scorecard, benchmark, latency_probe],
                         ids=lambda module: module.__name__)
def test_help_prints_the_usage_and_exits_cleanly(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        command.parse_arguments(['--help'])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.startswith('usage: ')


@pytest.mark.parametrize('argv, own, ros', [
    ([], [], []),
    (['--duration', '5'], ['--duration', '5'], []),
    (['--duration', '5', '--ros-args', '-r', '__ns:=/robot1'],
     ['--duration', '5'], ['--ros-args', '-r', '__ns:=/robot1', '--']),
    (['--ros-args', '-p', 'a:=1', '--', '--lockstep', '--ros-args', '--log-level', 'warn'],
     ['--lockstep'],
     ['--ros-args', '-p', 'a:=1', '--', '--ros-args', '--log-level', 'warn', '--']),
])
def test_followbot_separates_ros_arguments_as_rcl_does(argv, own, ros):
    assert split_ros_arguments(argv) == (own, ros)


def test_followbot_passes_ros_arguments_on_and_keeps_its_options():
    options = launcher.parse_arguments(
        ['--duration', '5', '--ros-args', '--params-file', 'my.yaml', '-r', '__ns:=/robot1'])
    assert options.duration == 5.0
    assert options.ros_arguments == ['--ros-args', '--params-file', 'my.yaml', '-r',
                                     '__ns:=/robot1', '--']
    # Left out, these leave the nodes' own values or the parameters file's in force.
    assert (options.course, options.lighting, options.lockstep) == (None, None, None)


@pytest.mark.parametrize('command', [
    [sys.executable, '-m', 'followbot_sim.launcher', '--ros-args', '-r', 'no_rule'],
    [sys.executable, '-m', 'followbot.follower_node', '--ros-args', '--params-file',
     'missing.yaml'],
    [sys.executable, '-m', 'followbot_sim.sim_node', '--ros-args', '-p', 'no_value'],
], ids=['followbot', 'follower', 'sim'])
def test_invalid_ros_arguments_are_refused_in_one_line(command, tmp_path):
    result = subprocess.run(command, cwd=tmp_path, env=child_environment(), timeout=60,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert result.returncode == 2, result.stdout
    assert 'Invalid ROS arguments: ' in result.stdout
    assert 'Traceback' not in result.stdout


@pytest.mark.parametrize('argv, message', [
    (['--duration', 'nan'], "argument --duration: must be a number in [0, 1e+06], got 'nan'"),
    (['--real-time-factor', '500'], 'argument --real-time-factor: must be a number in [0, 100]'),
    (['--report-period', '0'], "argument --report-period: must be a number > 0, got '0'"),
    (['--domain-id', '300'], 'argument --domain-id: must be a whole number in [0, 232]'),
    (['--course', 'nonesuch'], "--course: unknown course 'nonesuch': give a built-in course"),
    (['--course', 'no/such/course.yaml'], '--course: cannot read course file'),
])
def test_followbot_refuses_bad_values_before_it_starts_a_node(argv, message, capsys):
    error = refusal(launcher.parse_arguments, argv, capsys)
    assert error.startswith('followbot: error:') and message in error


@pytest.mark.parametrize('command', [scorecard, benchmark], ids=lambda module: module.__name__)
def test_tools_that_start_their_own_nodes_refuse_ros_arguments(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        command.parse_arguments(['--ros-args', '-p', 'linear_speed_mps:=0.5'])
    assert exit_info.value.code == 2
    assert 'takes no --ros-args: it starts its own nodes' in capsys.readouterr().err


def test_a_bad_ros_environment_is_not_called_a_bad_argument(tmp_path):
    result = subprocess.run(
        [sys.executable, '-m', 'followbot.follower_node'], cwd=tmp_path, timeout=60,
        env=dict(child_environment(), ROS_DOMAIN_ID='robot1'),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert result.returncode == 2, result.stdout
    assert 'ROS could not start: ROS_DOMAIN_ID is not an integral number' in result.stdout
    assert 'Invalid ROS arguments' not in result.stdout and 'Traceback' not in result.stdout


@pytest.mark.parametrize('argv, robots, configs', [
    ([], 1, []),
    (['--robots', '3'], 3, []),
    (['--configs', 'followbot,book'], 2, ['followbot', 'book']),
    (['--robots', '2', '--configs', 'book'], 2, ['book', 'book']),
])
def test_followbot_races_one_robot_per_configuration(argv, robots, configs):
    options = launcher.parse_arguments(argv)
    assert options.robots == robots
    assert [name for name, _ in options.configs] == configs
    assert all(path.is_file() for _, path in options.configs)


def test_a_parameters_file_is_a_configuration_named_by_its_stem(tmp_path):
    params_file = tmp_path / 'fast.yaml'
    params_file.write_text('/**/follower:\n  ros__parameters:\n    linear_speed_mps: 0.5\n')
    options = launcher.parse_arguments(['--configs', f'book,{params_file}'])
    assert options.configs == [('book', options.configs[0][1]), ('fast', params_file)]


@pytest.mark.parametrize('argv, message', [
    (['--robots', '3', '--configs', 'followbot,book'], '2 configurations for 3 robots'),
    (['--configs', 'followbot,nonesuch'], "'nonesuch' is neither a built-in configuration"),
    (['--robots', '0'], "argument --robots: must be a whole number in [1, 8], got '0'"),
    (['--configs', ','.join(['book'] * 9)], 'at most 8 robots race'),
    (['--robots', '2', '--video', 'race.mp4'], '--video films one robot'),
])
def test_followbot_refuses_robots_and_configs_that_do_not_match(argv, message, capsys):
    assert message in refusal(launcher.parse_arguments, argv, capsys)


def test_each_racing_follower_runs_in_its_robots_namespace_under_the_users():
    # rcl takes the first namespace remap that matches: the robot's must come first, and its
    # configuration's parameters before the user's own -p, which win.
    user_arguments = ['--ros-args', '-r', '__ns:=/team', '-p', 'linear_speed_mps:=0.3', '--']
    book = launcher.follower_configurations('book')[0][1]
    arguments = launcher.follower_arguments('/team', 'r2', book, user_arguments)
    context = Context()
    rclpy.init(args=['follower', *arguments], context=context)
    try:
        node = Node('follower', context=context,
                    automatically_declare_parameters_from_overrides=True)
        assert node.get_namespace() == '/team/r2'
        assert node.get_parameter('linear_speed_mps').value == 0.3
        assert node.get_parameter('band_count').value == 1  # from the book's configuration
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize('lockstep, expected', [
    (None, {'use_sim_time': 'true'}),
    (False, {'use_sim_time': 'true'}),
    (True, {'use_sim_time': 'true', 'image_timeout_s': '10.0'}),
])
def test_followers_of_a_lockstep_run_wait_for_a_loaded_simulator(lockstep, expected):
    # In lockstep the robot moves only after each answer: the wall-time watchdog gets its
    # longest setting there, so that runs do not depend on the machine's load.
    assert launcher.follower_parameters(lockstep) == expected


@pytest.mark.parametrize('option', ['--pictures-dir', '--record', '--video'])
def test_followbot_refuses_a_place_it_cannot_write_before_it_starts(option, tmp_path, capsys):
    blocker = tmp_path / 'file'
    blocker.write_text('not a folder')
    error = refusal(launcher.parse_arguments, [option, str(blocker / 'run.mp4')], capsys)
    assert error.startswith(f'followbot: error: argument {option}: cannot write')


@pytest.mark.parametrize('argv, node', [
    (['--robots', '2'], '/r1/follower'),
    (['--ros-args', '-r', '__ns:=/team'], '/team/follower'),
])
def test_a_configuration_must_reach_each_followers_namespace(argv, node, tmp_path, capsys):
    # Written for `ros2 run followbot follower`: rcl would give a namespaced follower nothing.
    params_file = tmp_path / 'slow.yaml'
    params_file.write_text('follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    assert launcher.parse_arguments(['--configs', str(params_file)]).configs
    error = refusal(launcher.parse_arguments, ['--configs', str(params_file), *argv], capsys)
    assert f'gives nothing to the node {node}' in error and "'/**/follower'" in error
    params_file.write_text('/**/follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    assert launcher.parse_arguments(['--configs', str(params_file), *argv]).configs


def test_a_replay_refuses_parameters_that_would_not_reach_its_follower(tmp_path, capsys):
    params_file = tmp_path / 'slow.yaml'
    params_file.write_text('follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    error = refusal(replay.parse_arguments, ['run.mcap', '--params-file', str(params_file)],
                    capsys)
    assert f'gives nothing to the node {replay.replay_namespace()}/follower' in error
    params_file.write_text('/**/follower:\n  ros__parameters:\n    linear_speed_mps: 0.1\n')
    assert replay.parse_arguments(['run.mcap', '--params-file', str(params_file)]).params_file
