"""
The simulator with several robots over real DDS: each robot's topics, frames and score its own.

A client node commands one robot and listens to both, as a ROS user would with ``ros2 topic``.
"""

from conftest import NodeHarness
from diagnostic_msgs.msg import DiagnosticArray
from followbot_sim.score import score_values
from followbot_sim.sim_node import SimulatorNode
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image

try:
    from tf2_msgs.msg import TFMessage
except ImportError:  # Built by make setup; skipped where it is absent.
    TFMessage = None

ROBOTS = ['r1', 'r2']
FORWARD_SPEED_MPS = 0.3
DRIVE_S = 1.0


class RobotTopics:
    """The latest message of each robot's topics and of /diagnostics."""

    def __init__(self, node):
        self.latest = {}
        self.scores = {}
        for robot in ROBOTS:
            for message_type, topic in ((Image, 'camera/rgb/image_raw'),
                                        (CameraInfo, 'camera/rgb/camera_info'),
                                        (Odometry, 'odom'), (Odometry, 'ground_truth/odom')):
                name = f'{robot}/{topic}'
                node.create_subscription(
                    message_type, name,
                    lambda msg, name=name: self.latest.__setitem__(name, msg), 10)
        node.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics_callback, 10)

    def diagnostics_callback(self, msg: DiagnosticArray) -> None:
        for robot in ROBOTS:
            score = score_values(msg, f'/{robot}/followbot_sim')
            if score is not None:
                self.scores[robot] = score


def start_simulator(context, robots, *overrides) -> NodeHarness:
    """Start a simulator of several robots, as fast as possible, with a client beside it."""
    harness = NodeHarness(context, SimulatorNode(context=context, parameter_overrides=[
        Parameter('real_time_factor', value=0.0), Parameter('robots', value=robots),
        Parameter('depth_enabled', value=False), Parameter('point_cloud_enabled', value=False),
        *overrides]), 'sim_robots_test_client')
    harness.simulator = harness.node
    harness.world = harness.node.world
    return harness


@pytest.fixture
def two_robot_sim(ros_context):
    harness = start_simulator(ros_context, ROBOTS)
    yield harness
    harness.close()


def topic_names(node) -> set:
    return {name for name, _ in node.get_topic_names_and_types()}


def test_a_count_of_robots_names_them_r1_to_rn(ros_context):
    harness = start_simulator(ros_context, 3, Parameter('rgb_enabled', value=False))
    try:
        assert harness.simulator.robot_names == ('r1', 'r2', 'r3')
        harness.spin_until(lambda: '/r3/cmd_vel' in topic_names(harness.client))
        assert '/cmd_vel' not in topic_names(harness.client)
    finally:
        harness.close()


def test_each_robot_publishes_its_own_camera_odometry_and_score(two_robot_sim):
    topics = RobotTopics(two_robot_sim.client)
    two_robot_sim.spin_until(lambda: len(topics.latest) == 8 and len(topics.scores) == 2)
    assert topics.latest['r1/camera/rgb/image_raw'].header.frame_id == (
        'r1/camera_rgb_optical_frame')
    assert topics.latest['r2/camera/rgb/camera_info'].header.frame_id == (
        'r2/camera_rgb_optical_frame')
    assert topics.latest['r2/odom'].header.frame_id == 'r2/odom'
    assert topics.latest['r2/odom'].child_frame_id == 'r2/base_footprint'
    assert topics.latest['r1/ground_truth/odom'].header.frame_id == 'world'
    # Both robots on the one course, the second a spacing behind the first.
    first = topics.latest['r1/ground_truth/odom'].pose.pose.position
    second = topics.latest['r2/ground_truth/odom'].pose.pose.position
    assert ((first.x - second.x) ** 2 + (first.y - second.y) ** 2) ** 0.5 == pytest.approx(
        1.0, abs=0.05)
    for robot in ROBOTS:
        assert topics.scores[robot]['laps_completed'] == '0'


def test_a_command_moves_only_its_robot_and_each_score_follows_its_robot(two_robot_sim):
    topics = RobotTopics(two_robot_sim.client)
    cmd_vel = two_robot_sim.client.create_publisher(Twist, 'r2/cmd_vel', 10)
    two_robot_sim.spin_until(lambda: cmd_vel.get_subscription_count() > 0)
    start_s = two_robot_sim.world.time_s
    while two_robot_sim.world.time_s < start_s + DRIVE_S:
        twist = Twist()
        twist.linear.x = FORWARD_SPEED_MPS
        cmd_vel.publish(twist)
        two_robot_sim.executor.spin_once(timeout_sec=0.01)
    world = two_robot_sim.world
    assert world.robot_twist(1)[0] == pytest.approx(FORWARD_SPEED_MPS, rel=0.05)
    assert abs(world.robot_twist(0)[0]) < 0.01
    two_robot_sim.spin_until(
        lambda: len(topics.scores) == 2
        and float(topics.scores['r2']['progress_m']) > 0.2)
    assert abs(float(topics.scores['r1']['progress_m'])) < 0.01


@pytest.mark.skipif(TFMessage is None, reason='tf2_msgs is not importable')
def test_each_robots_frames_on_tf_carry_its_name(two_robot_sim):
    children = set()
    two_robot_sim.client.create_subscription(
        TFMessage, '/tf',
        lambda msg: children.update((t.header.frame_id, t.child_frame_id)
                                    for t in msg.transforms), 10)
    two_robot_sim.spin_until(lambda: len(children) >= 2)
    assert children == {('r1/odom', 'r1/base_footprint'), ('r2/odom', 'r2/base_footprint')}


def test_a_bad_robots_setting_is_refused_at_start_with_its_reason(ros_context):
    with pytest.raises(ValueError, match='differ'):
        SimulatorNode(context=ros_context,
                      parameter_overrides=[Parameter('robots', value=['r1', 'r1'])])
