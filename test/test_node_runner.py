"""What every followbot node process shares: stop signals, start-up errors."""

import os
import signal
import subprocess
import sys

from conftest import child_environment
from followbot.node_runner import logger_name, STOP_SIGNALS, StopSignals
import pytest


def test_every_stop_signal_is_recorded_and_the_process_goes_on():
    previous_handlers = {stop_signal: signal.getsignal(stop_signal)
                         for stop_signal in STOP_SIGNALS}
    try:
        stop = StopSignals().install()
        assert not stop.is_set()
        # Several signals in a row, as when a launcher dies and a user presses Ctrl-C too.
        for stop_signal in (*STOP_SIGNALS, *STOP_SIGNALS):
            os.kill(os.getpid(), stop_signal)
        assert stop.is_set()
    finally:
        for stop_signal, handler in previous_handlers.items():
            signal.signal(stop_signal, handler)


def test_a_record_not_installed_is_never_set():
    assert not StopSignals().is_set()


@pytest.mark.parametrize('argv, expected', [
    ([], 'followbot_sim'),
    (['--ros-args', '-r', '__ns:=/robot1'], 'robot1.followbot_sim'),
    (['--ros-args', '--remap', '__ns:=/fleet/robot2/'], 'fleet.robot2.followbot_sim'),
    (['--ros-args', '-r', '__node:=sim2', '-r', '__ns:=/r1'], 'r1.sim2'),
    (['--ros-args', '-r', 'follower:__ns:=/elsewhere'], 'followbot_sim'),
    (['--ros-args', '-r', 'followbot_sim:__ns:=/r3', '--', 'other'], 'r3.followbot_sim'),
    (['-r', '__ns:=/not_ros_arguments'], 'followbot_sim'),
])
def test_startup_errors_are_logged_under_the_name_the_node_would_have(argv, expected):
    assert logger_name('followbot_sim', argv) == expected


def test_a_node_that_cannot_start_says_so_under_its_own_name():
    result = subprocess.run(
        [sys.executable, '-m', 'followbot_sim.sim_node', '--ros-args', '-r', '__ns:=/robot7',
         '-p', 'course:=no_such_course'], capture_output=True, text=True, timeout=60,
        env=child_environment())
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if 'Cannot start' in line]
    assert len(lines) == 1, result.stderr
    assert '[robot7.followbot_sim]' in lines[0]
    assert '[SimulatorNode]' not in result.stderr


def test_a_broken_course_file_stops_the_simulator_with_one_line(tmp_path):
    course_file = tmp_path / 'broken.yaml'
    course_file.write_text('name: x\n  bad: [1, 2\n')
    result = subprocess.run(
        [sys.executable, '-m', 'followbot_sim.sim_node', '--ros-args', '-r', '__ns:=/robot7',
         '-p', f'course:={course_file}'], capture_output=True, text=True, timeout=60,
        env=child_environment())
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        line for line in result.stderr.splitlines() if '[robot7.followbot_sim]' in line]
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert 'is not valid YAML: mapping values are not allowed here (line 2, column 6).' in (
        result.stderr)
