"""Pairing recorded frames with their commands, and judging a replay's commands against them."""

import math

from followbot.command_comparison import (answers_by_order, answers_by_status, Comparison,
                                          FrameResult, LISTED_DIFFERENCES, Velocity)
from followbot.recording import header_stamp_ns
from followbot.replay import odometry_topic
from geometry_msgs.msg import Twist
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CompressedImage


@pytest.mark.parametrize('frames, commands, expected', [
    # One answer after each frame.
    ([10, 20, 30], [12, 22, 32], [0, 1, 2]),
    # Commands listed out of order are still found by their times.
    ([10, 20, 30], [32, 12, 22], [1, 2, 0]),
    # A stop sent after the answer, before the next frame, answers nothing.
    ([10, 20], [12, 15, 22], [0, 2]),
    # The follower skipped a frame: it has no answer.
    ([10, 20, 30], [12, 32], [0, None, 1]),
    # A command sent before the first frame answers no frame.
    ([10, 20], [5, 22], [None, 1]),
    ([10], [], [None]),
])
def test_answers_by_order(frames, commands, expected):
    assert answers_by_order(frames, commands) == expected


@pytest.mark.parametrize('stamps, statuses, commands, expected', [
    # Each status follows its command; the command is the last sent before the status.
    ([1, 2], [(1, 13), (2, 23)], [12, 22], [0, 1]),
    # A compressed frame is sent after the follower answered the raw one: still paired.
    ([1, 2], [(2, 23), (1, 13)], [22, 12], [1, 0]),
    # No status for a frame: the follower did not take it.
    ([1, 2, 3], [(1, 13), (3, 33)], [12, 32], [0, None, 1]),
    # A status before any command pairs with nothing.
    ([1], [(1, 5)], [12], [None]),
])
def test_answers_by_status(stamps, statuses, commands, expected):
    assert answers_by_status(stamps, statuses, commands) == expected


def twist(linear_x: float, angular_z: float) -> Twist:
    """Return a Twist of a forward speed and a yaw rate."""
    msg = Twist()
    msg.linear.x = linear_x
    msg.angular.z = angular_z
    return msg


def test_velocity_takes_all_six_components_of_a_twist():
    msg = twist(0.2, -0.5)
    msg.linear.y = 0.1
    assert Velocity.from_twist(msg) == (0.2, 0.1, 0.0, 0.0, 0.0, -0.5)


@pytest.mark.parametrize('first, second, expected', [
    (Velocity(0.2, angular_z=0.5), Velocity(0.2, angular_z=0.5), 0.0),
    (Velocity(0.2, angular_z=0.5), Velocity(0.25, angular_z=0.4), 0.1),
    (Velocity(0.2), Velocity(math.nan), math.inf),
    (Velocity(math.nan), Velocity(math.nan), math.inf),
])
def test_velocity_difference_is_the_largest_component_gap(first, second, expected):
    assert first.difference(second) == pytest.approx(expected)


def test_a_comparison_counts_identical_differing_and_unanswered_frames():
    comparison = Comparison(tolerance=0.01)
    comparison.add(FrameResult(0, 0.05, Velocity(0.2), Velocity(0.2)))
    comparison.add(FrameResult(1, 0.10, Velocity(0.2), Velocity(0.205)))
    comparison.add(FrameResult(2, 0.15, Velocity(0.2), Velocity(0.3)))
    comparison.add(FrameResult(3, 0.20, Velocity(0.2), None))
    comparison.add(FrameResult(4, 0.25, None, Velocity(0.3)))
    assert len(comparison.compared) == 4
    assert comparison.identical == 1
    assert [frame.index for frame in comparison.differing] == [2, 3]
    assert comparison.unanswered == 1
    assert comparison.max_difference == math.inf
    assert not comparison.matches
    lines = comparison.summary_lines()
    assert lines[0].startswith('5 frames replayed, 4 with a recorded command: 1 identical, '
                               '2 differ by more than 0.01')
    assert lines[1] == ('  frame 2 (t=0.150 s): recorded v=0.2000 m/s w=0.0000 rad/s, '
                        'replayed v=0.3000 m/s w=0.0000 rad/s')
    assert lines[2].endswith('replayed nothing')


def test_a_comparison_within_tolerance_matches():
    comparison = Comparison(tolerance=0.01)
    comparison.add(FrameResult(0, 0.05, Velocity(0.2), Velocity(0.205)))
    assert comparison.matches
    assert comparison.identical == 0


def test_the_summary_lists_a_bounded_number_of_differences():
    comparison = Comparison(tolerance=0.0)
    for index in range(LISTED_DIFFERENCES + 5):
        comparison.add(FrameResult(index, index / 20, Velocity(0.1), Velocity(0.2)))
    lines = comparison.summary_lines()
    assert len(lines) == 1 + LISTED_DIFFERENCES + 1
    assert lines[-1] == '  ... and 5 more'


def test_header_stamp_is_read_from_the_serialised_bytes():
    msg = CompressedImage(format='jpeg', data=b'\xff\xd8')
    msg.header.stamp.sec = 12
    msg.header.stamp.nanosec = 345
    assert header_stamp_ns(serialize_message(msg)) == 12_000_000_345
    assert header_stamp_ns(b'\x00\x01') is None
    assert header_stamp_ns(b'\x00\x07' + bytes(10)) is None


@pytest.mark.parametrize('camera, topics, expected', [
    # The robot's own beside its camera, not another robot's nor the ground truth.
    ('/r1/camera/rgb/image_raw/compressed', ['/r2/odom', '/r1/ground_truth/odom', '/r1/odom'],
     '/r1/odom'),
    ('/camera/rgb/image_raw', ['/ground_truth/odom', '/odom'], '/odom'),
    # A real robot's camera topic: its only wheel odometry.
    ('/image_raw', ['/base/odom'], '/base/odom'),
    # Several, none beside the camera: which is the robot's cannot be told.
    ('/image_raw', ['/r1/odom', '/r2/odom'], None),
    ('/image_raw', ['/ground_truth/odom'], None),
])
def test_a_replay_feeds_the_wheel_odometry_of_the_camera_robot(camera, topics, expected):
    assert odometry_topic(camera, topics) == expected
