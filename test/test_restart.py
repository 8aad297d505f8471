"""
Either node killed outright (SIGKILL) mid-run and started again: the other recovers on its own.

The simulator and the follower run as separate processes, as on a robot; an independent client
watches the commands and the simulator's ground truth. A killed follower sends no last zero
Twist: the simulator's command watchdog must stop the wheels. A killed simulator stops images
and /clock: the follower must stop within ``image_timeout_s`` of wall time and drive again when
a new simulator's images come.
"""

import math
import signal
import subprocess

from conftest import child_environment, kill_leftovers, node_command, spin_until, stop_process
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

DISCOVERY_TIMEOUT_S = 60.0
IMAGE_TIMEOUT_S = 0.5
# The follower's watchdog timer fires within a period of the timeout; allow a loaded machine
# (two cores shared with other work) some scheduling delay on top.
STOP_WITHIN_S = IMAGE_TIMEOUT_S + 2.0
# Wheels stopped: the Kobuki's command watchdog (0.6 s) plus braking, in simulated time.
WHEELS_STOP_WITHIN_S = 10.0
DRIVING_MPS = 0.05
STOPPED_MPS = 0.005
COMMANDS_AFTER_RESTART = 20
# The robot has driven this far before the follower is killed, so that a simulator that reset
# its world would put it visibly back; standing still, it moves less than STILL_M.
FAR_FROM_START_M = 1.0
STILL_M = 0.01


class RobotWatcher:
    """Record cmd_vel and the simulator's ground-truth speed with an independent node."""

    def __init__(self, node):
        self.commands = []
        self.ground_truth = []
        node.create_subscription(Twist, 'cmd_vel', self.commands.append, 50)
        node.create_subscription(Odometry, 'ground_truth/odom', self.ground_truth.append, 50)

    def position(self) -> tuple:
        """Return the robot's latest true (x, y) on the floor."""
        position = self.ground_truth[-1].pose.pose.position
        return position.x, position.y

    @property
    def first_position(self) -> tuple:
        """Return where the simulator first saw the robot."""
        position = self.ground_truth[0].pose.pose.position
        return position.x, position.y

    def speed_mps(self) -> float | None:
        """Return the robot's latest true speed over the floor, or None before any."""
        if not self.ground_truth:
            return None
        linear = self.ground_truth[-1].twist.twist.linear
        return math.hypot(linear.x, linear.y)

    def driving(self) -> bool:
        """Tell whether the robot moves and the last command drives it forward."""
        speed_mps = self.speed_mps()
        return (speed_mps is not None and speed_mps > DRIVING_MPS and bool(self.commands)
                and self.commands[-1].linear.x > 0.0)


def start_simulator(environment: dict) -> subprocess.Popen:
    """Start the simulator at real time, as the followbot command runs it."""
    return subprocess.Popen(node_command('followbot_sim.sim_node', '-p', 'real_time_factor:=1.0'),
                            env=environment)


def start_follower(environment: dict) -> subprocess.Popen:
    """Start the follower on simulated time, with the image timeout this test relies on."""
    return subprocess.Popen(
        node_command('followbot.follower_node', '-p', 'use_sim_time:=true',
                     '-p', f'image_timeout_s:={IMAGE_TIMEOUT_S}'), env=environment)


def kill_outright(process: subprocess.Popen) -> None:
    """Kill a node as a crash or the OOM killer would: no clean-up, no last message."""
    process.send_signal(signal.SIGKILL)
    process.wait()


class Run:
    """The simulator and the follower as processes, and a watcher node spun by its executor."""

    def __init__(self, context):
        """Start both processes and the watcher; :meth:`close` ends whatever still runs."""
        self.environment = child_environment()
        self.simulator = start_simulator(self.environment)
        self.follower = start_follower(self.environment)
        self.node = Node('restart_watcher', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.watcher = RobotWatcher(self.node)

    def spin_until_driving_again(self) -> tuple:
        """
        Spin until the follower drives the robot with COMMANDS_AFTER_RESTART new commands.

        :return: (whether it did in DISCOVERY_TIMEOUT_S, what was seen, for the assertion).
        """
        watcher = self.watcher
        before = len(watcher.commands)
        driving = spin_until(self.executor, lambda: watcher.driving() and len(watcher.commands)
                             >= before + COMMANDS_AFTER_RESTART, DISCOVERY_TIMEOUT_S)
        return driving, f'speed {watcher.speed_mps()}, {len(watcher.commands) - before} commands'

    def close(self) -> None:
        """Kill the processes still running and destroy the watcher."""
        kill_leftovers(self.follower, self.simulator)
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def run(ros_context):
    """Yield a Run on this test run's domain."""
    started = Run(ros_context)
    yield started
    started.close()


def test_a_killed_follower_stops_the_robot_and_a_new_one_drives_it_again(run):
    executor, watcher = run.executor, run.watcher
    assert spin_until(executor, lambda: watcher.driving() and math.dist(
        watcher.position(), watcher.first_position) > FAR_FROM_START_M,
        DISCOVERY_TIMEOUT_S), f'speed {watcher.speed_mps()}, {len(watcher.commands)} commands'
    kill_outright(run.follower)
    # No zero Twist came from the dead follower: the simulator's watchdog stops the wheels.
    assert watcher.commands[-1].linear.x > 0.0
    assert spin_until(executor, lambda: watcher.speed_mps() < STOPPED_MPS,
                      WHEELS_STOP_WITHIN_S), f'speed {watcher.speed_mps()}'
    stopped_at = watcher.position()
    restart_index = len(watcher.ground_truth)
    run.follower = start_follower(run.environment)
    driving, seen = run.spin_until_driving_again()
    assert driving, seen
    assert run.simulator.poll() is None
    # The simulator kept its world: the robot drove on from where it had stopped.
    restarted_at = watcher.ground_truth[restart_index].pose.pose.position
    assert math.dist(stopped_at, (restarted_at.x, restarted_at.y)) < STILL_M
    assert stop_process(run.follower) == 0
    assert stop_process(run.simulator) == 0


def test_a_killed_simulator_stops_the_follower_and_a_new_one_brings_it_back(run):
    executor, watcher = run.executor, run.watcher
    assert spin_until(executor, watcher.driving, DISCOVERY_TIMEOUT_S), (
        f'speed {watcher.speed_mps()}, {len(watcher.commands)} commands')
    kill_outright(run.simulator)
    # The dead simulator's last ground truth must not pass for the new one's.
    watcher.ground_truth.clear()
    commands_before = len(watcher.commands)
    # Neither images nor /clock come now: the follower's wall-time watchdog says stop.
    assert spin_until(executor, lambda: len(watcher.commands) > commands_before
                      and watcher.commands[-1] == Twist(), STOP_WITHIN_S), (
        watcher.commands[commands_before:])
    run.simulator = start_simulator(run.environment)
    # A new world from its start, its clock from zero: the follower drives it all the same.
    driving, seen = run.spin_until_driving_again()
    assert driving, seen
    assert run.follower.poll() is None
    assert stop_process(run.follower) == 0
    assert stop_process(run.simulator) == 0
