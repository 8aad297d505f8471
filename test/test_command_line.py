"""Every command of the package explains itself with --help and refuses bad arguments clearly."""

import subprocess
import sys

from conftest import child_environment
from followbot.node_runner import split_ros_arguments
from followbot_sim import benchmark, latency_probe, launcher, scorecard
import pytest


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
