"""
The simulator node over real DDS: cmd_vel in, motion and time out, as a ROS user drives it.

A client node publishes Twists; the simulator's own world gives the ground truth of the motion.
"""

import math

from conftest import NodeHarness
from followbot_sim.sim_node import SimulatorNode
from geometry_msgs.msg import Twist
import pytest
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter

COMMAND_TIMEOUT_S = 0.6
FORWARD_SPEED_MPS = 0.3
SETTLE_S = 0.3


class SimHarness(NodeHarness):
    """A simulator running as fast as possible and a client that commands it."""

    def __init__(self, context, *overrides):
        super().__init__(context, SimulatorNode(context=context, parameter_overrides=[
            Parameter('real_time_factor', value=0.0), *overrides]), 'sim_test_client')
        self.simulator = self.node
        self.cmd_vel = self.client.create_publisher(Twist, 'cmd_vel', 10)
        self.spin_until(lambda: self.cmd_vel.get_subscription_count() > 0)

    @property
    def world(self):
        return self.simulator.world

    def command(self, linear_mps, angular_radps=0.0):
        """Publish a Twist and spin until the simulator has it (its robot starts moving)."""
        twist = Twist()
        twist.linear.x = linear_mps
        twist.angular.z = angular_radps
        self.cmd_vel.publish(twist)
        self.executor.spin_once(timeout_sec=0.1)
        return self.world.time_s

    def run_until(self, time_s):
        self.spin_until(lambda: self.world.time_s >= time_s)


@pytest.fixture
def harness(ros_context):
    harness = SimHarness(ros_context)
    yield harness
    harness.close()


def test_cmd_vel_drives_then_the_watchdog_stops_the_robot(harness):
    sent_at_s = harness.command(FORWARD_SPEED_MPS)
    harness.run_until(sent_at_s + COMMAND_TIMEOUT_S - 0.1)
    speed_mps, _ = harness.world.robot_twist()
    assert speed_mps == pytest.approx(FORWARD_SPEED_MPS, rel=0.02)
    # 0.6 s of simulated time after the only command the wheels stop, and the robot with them.
    harness.run_until(sent_at_s + COMMAND_TIMEOUT_S + SETTLE_S)
    speed_mps, _ = harness.world.robot_twist()
    assert abs(speed_mps) < 0.01
    assert harness.world.data.ctrl == pytest.approx([0.0, 0.0])


def test_commands_beyond_the_kobuki_limits_are_limited(harness):
    sent_at_s = harness.command(2.0)
    harness.run_until(sent_at_s + COMMAND_TIMEOUT_S - 0.1)
    speed_mps, _ = harness.world.robot_twist()
    assert speed_mps == pytest.approx(0.7, rel=0.03)


def test_non_finite_cmd_vel_is_refused_and_reported_once(harness):
    sent_at_s = harness.command(FORWARD_SPEED_MPS)
    for _ in range(5):
        harness.command(math.nan, 1.0)
    harness.run_until(sent_at_s + 0.4)
    speed_mps, yaw_rate_radps = harness.world.robot_twist()
    assert speed_mps == pytest.approx(FORWARD_SPEED_MPS, rel=0.02)
    assert abs(yaw_rate_radps) < 0.01
    harness.spin_until(lambda: harness.errors)
    assert len(harness.errors) == 1 and 'non-finite' in harness.errors[0]


def test_run_duration_ends_the_run_at_that_simulated_time(ros_context):
    harness = SimHarness(ros_context, Parameter('run_duration_s', value=1.5))
    try:
        harness.spin_until(lambda: harness.simulator.finished)
        assert harness.world.time_s == pytest.approx(1.5, abs=0.011)
        time_s = harness.world.time_s
        for _ in range(10):
            harness.executor.spin_once(timeout_sec=0.01)
        assert harness.world.time_s == time_s
    finally:
        harness.close()


@pytest.mark.parametrize('name, value', [
    ('real_time_factor', -1.0),
    ('camera_rate_hz', 0.0),
    ('course', 'no_such_course'),
])
def test_bad_parameters_are_refused_at_start(ros_context, name, value):
    with pytest.raises((ParameterException, ValueError)) as raised:
        SimulatorNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])
    assert name in str(raised.value) or str(value) in str(raised.value)
