"""
The follower node over real DDS: what a user sees on its topics, its log and its parameters.

Each test puts the follower and a small client node in one executor on a private Context. The
client plays the camera: frames 50 ms apart, and the Kinect's camera_info for the 'path' law.
"""

import subprocess
import sys

from conftest import child_environment
from diagnostic_msgs.msg import DiagnosticArray
from followbot import messages
from followbot.follower_node import FOLLOWER_PARAMETERS, FollowerNode
from followbot_sim.sim_node import SIMULATOR_PARAMETERS
from follower_harness import (BOOK_PARAMETERS_FILE, camera_frame, FLOOR_GREY, FRAME_PERIOD_S,
                              Harness, HEIGHT_PX, PARAMETERS_FILE, SETTLING_FRAMES, WIDTH_PX)
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image
import yaml


@pytest.fixture
def harness(ros_context):
    harness = Harness(ros_context)
    yield harness
    harness.close()


@pytest.fixture
def book_harness(ros_context):
    harness = Harness(ros_context,
                      cli_args=['--ros-args', '--params-file', str(BOOK_PARAMETERS_FILE)])
    yield harness
    harness.close()


@pytest.mark.parametrize('line_offset_px', [0, 100, -100, 140])
def test_book_parameters_steer_like_the_book(book_harness, line_offset_px):
    line_column_px = WIDTH_PX // 2 + line_offset_px
    # The first frame starts from rest; from the second on the book's law holds.
    command = book_harness.send_many(line_column_px, frames=2)
    assert command.linear.x == pytest.approx(0.2)
    # The book's law: -(cx - w/2) / 100 rad/s; the drawn line's centroid is at column - 0.5.
    expected_radps = -(line_column_px - 0.5 - WIDTH_PX / 2) / 100.0
    assert command.angular.z == pytest.approx(expected_radps, abs=1e-3)


def test_stamped_commands_carry_the_stamp_of_the_image_they_answer(ros_context):
    harness = Harness(ros_context, cmd_vel_stamped=True)
    try:
        for _ in range(SETTLING_FRAMES):
            harness.send(camera_frame(WIDTH_PX // 2))
            stamped = harness.stamped_cmd_vels[-1]
            assert stamped.header.stamp == messages.stamp(harness.time_s)
            assert stamped.header.frame_id == 'base_footprint'
        assert stamped.twist.linear.x > 0.3
        assert stamped.twist.angular.z == pytest.approx(0.0, abs=0.02)
    finally:
        harness.close()


def test_drives_straight_along_a_centred_line_after_trusting_it(harness):
    first = harness.send(camera_frame(WIDTH_PX // 2))
    assert first.linear.x == 0.0  # one frame is not yet trusted
    command = harness.send_many(WIDTH_PX // 2)
    assert command.linear.x > 0.3
    assert command.angular.z == pytest.approx(0.0, abs=0.02)


@pytest.mark.parametrize('line_offset_px, side', [(-120, 1.0), (120, -1.0)])
def test_turns_toward_the_line(harness, line_offset_px, side):
    command = harness.send_many(WIDTH_PX // 2 + line_offset_px)
    assert command.linear.x > 0.0
    assert side * command.angular.z > 0.1


def test_speeds_up_within_the_acceleration_limit(harness):
    speeds = [harness.send(camera_frame(WIDTH_PX // 2)).linear.x for _ in range(8)]
    steps = np.diff(speeds)
    assert np.all(steps >= 0.0) and speeds[-1] > 0.0
    limit = harness.follower.get_parameter('max_linear_acceleration_mps2').value
    assert np.all(steps <= limit * FRAME_PERIOD_S + 1e-6)


def test_turn_rate_is_bounded(book_harness):
    book_harness.set_parameters(Parameter('max_angular_speed_radps', value=1.5))
    command = book_harness.send_many(WIDTH_PX // 2 + 250, frames=2)
    assert command.angular.z == pytest.approx(-1.5)


def test_waits_for_camera_info_before_using_the_path_law(ros_context):
    harness = Harness(ros_context, send_camera_info=False)
    try:
        for _ in range(3):
            assert harness.send(camera_frame(WIDTH_PX // 2)) == Twist()
        harness.spin_until(lambda: any('camera_info' in log.msg for log in harness.logs))
        assert sum('camera_info' in log.msg for log in harness.logs) == 1
    finally:
        harness.close()


def test_searches_toward_the_side_last_seen_without_driving(harness):
    harness.send_many(WIDTH_PX // 2 + 200)
    # The line ran on out of the view: on along where it was seen (3 s is well past that, and
    # past the line memory), then the search, in place.
    for _ in range(60):
        command = harness.send(camera_frame(None))
    assert command.linear.x == 0.0
    assert command.angular.z < 0.0


# Where the line ends in the test camera's frames: 0.62 m ahead.
LINE_END_ROW_PX = 240


def odometry(time_s, x_m, linear_mps) -> Odometry:
    """Return a base's Odometry: driving straight along x at a speed, there at a time."""
    msg = Odometry()
    msg.header.stamp = messages.stamp(time_s)
    msg.pose.pose.position.x = x_m
    msg.pose.pose.orientation.w = 1.0
    msg.twist.twist.linear.x = linear_mps
    return msg


def frames_driven_to_a_line_end(harness, with_odometry) -> int:
    """
    Return how many frames the follower drives on after seeing the line end ahead.

    The base goes half as fast as it is told, as a real one may lag its commands; with
    odometry its odom topic says so, stamped with each frame's time.
    """
    publisher = harness.client.create_publisher(Odometry, 'odom', 10)
    harness.spin_until(lambda: publisher.get_subscription_count() > 0)
    x_m = linear_mps = 0.0
    command = Twist()
    frames = [camera_frame(WIDTH_PX // 2)] * SETTLING_FRAMES + [
        camera_frame(WIDTH_PX // 2, line_top_px=LINE_END_ROW_PX)] + [camera_frame(None)] * 60
    driven = 0
    for index, frame in enumerate(frames):
        linear_mps = 0.5 * command.linear.x
        x_m += linear_mps * FRAME_PERIOD_S
        if with_odometry:
            stamp_s = harness.time_s + FRAME_PERIOD_S
            publisher.publish(odometry(stamp_s, x_m, linear_mps))
            harness.spin_until(lambda: harness.follower._odometry is not None
                               and abs(harness.follower._odometry[0] - stamp_s) < 1e-6)
        command = harness.send(frame)
        driven += index > SETTLING_FRAMES and command.linear.x > 0.0
    assert command == Twist()
    return driven


def test_drives_to_a_line_end_by_odometry_where_the_base_lags(ros_context):
    # By its commands the robot would think itself at the line's end halfway there.
    counts = {}
    for with_odometry in (False, True):
        harness = Harness(ros_context)
        try:
            counts[with_odometry] = frames_driven_to_a_line_end(harness, with_odometry)
        finally:
            harness.close()
    assert counts[True] > 1.5 * counts[False]


def test_says_once_what_it_does_at_a_line_end(harness):
    frames_driven_to_a_line_end(harness, with_odometry=False)
    assert [log.msg for log in harness.logs][-3:] == [
        'Line found.', 'Line ends ahead: driving on to its end.', "At the line's end."]


def test_says_once_that_the_line_vanished_and_once_that_it_is_lost(harness):
    harness.send_many(WIDTH_PX // 2)
    for _ in range(60):
        harness.send(camera_frame(None))
    assert [log.msg for log in harness.logs][1:] == [
        'Line found.', 'Line vanished: driving on along where it was seen, then searching.',
        'Line lost: searching toward where it was last seen.']


def test_bad_odometry_is_reported_once_and_the_line_still_followed(harness):
    publisher = harness.client.create_publisher(Odometry, 'odom', 10)
    harness.spin_until(lambda: publisher.get_subscription_count() > 0)
    bad = odometry(1.0, float('nan'), 0.0)
    for _ in range(3):
        publisher.publish(bad)
    assert 'odom' in harness.only_error()
    assert harness.send_many(WIDTH_PX // 2).linear.x > 0.0


def test_drives_on_through_a_short_gap(harness):
    before = harness.send_many(WIDTH_PX // 2)
    during = harness.send(camera_frame(None))
    assert during.linear.x == pytest.approx(before.linear.x, abs=0.06)


def test_bad_frames_are_reported_once_and_never_drive(harness):
    for _ in range(5):
        command = harness.send(camera_frame(WIDTH_PX // 2, encoding='nv21'))
        assert command.linear.x == 0.0
    assert 'nv21' in harness.only_error()
    # Good frames afterwards are followed as usual: nothing was lost.
    assert harness.send_many(WIDTH_PX // 2).linear.x > 0.0


def test_views_only_while_someone_watches(harness):
    harness.send(camera_frame(WIDTH_PX // 2))
    received = {'debug_image': [], 'mask': [], 'status': []}
    for name, received_on_topic in received.items():
        assert harness.follower.count_subscribers(f'/follower/{name}') == 0
        harness.client.create_subscription(
            DiagnosticArray if name == 'status' else Image, f'/follower/{name}',
            received_on_topic.append, 10)
        harness.spin_until(lambda: harness.follower.count_subscribers(f'/follower/{name}'))
    frame = camera_frame(WIDTH_PX // 2 - 100)
    harness.send(frame)
    harness.spin_until(lambda: all(received.values()))
    debug, mask, status = (received[name][-1] for name in ('debug_image', 'mask', 'status'))
    for message in (debug, mask, status):
        assert message.header.stamp == frame.header.stamp
    assert (debug.width, debug.height, debug.encoding) == (WIDTH_PX, HEIGHT_PX, 'bgr8')
    assert debug.header.frame_id == 'camera_rgb_optical_frame'
    assert bytes(debug.data) != bytes(frame.data)  # the overlay is drawn
    # The mask shows the line's pixels in the bands only.
    assert (mask.width, mask.height, mask.encoding) == (WIDTH_PX, HEIGHT_PX, 'mono8')
    mask_px = np.frombuffer(bytes(mask.data), np.uint8).reshape(HEIGHT_PX, WIDTH_PX)
    marked_rows, marked_columns = np.nonzero(mask_px)
    assert set(np.unique(mask_px)) == {0, 255}
    line_px = np.frombuffer(bytes(frame.data), np.uint8).reshape(HEIGHT_PX, WIDTH_PX, 3)
    assert (line_px[marked_rows, marked_columns] != FLOOR_GREY).all()
    assert len(np.unique(marked_rows)) < HEIGHT_PX / 2
    values = {value.key: value.value for value in status.status[0].values}
    assert values['line_found'] == 'True'
    assert float(values['error']) == pytest.approx(-100.5 / (WIDTH_PX / 2), abs=1e-3)
    assert float(values['confidence']) == 1.0
    assert float(values['look_ahead_y_m']) > 0.0  # the line is left of the robot
    assert values['state'] in ('acquiring', 'tracking')
    for key in ('linear_mps', 'angular_radps', 'frames', 'frames_line_lost', 'recoveries'):
        float(values[key])


def test_counts_lost_frames_and_recoveries(harness):
    harness.send_many(WIDTH_PX // 2, frames=3)
    for _ in range(2):
        harness.send(camera_frame(None))
    harness.send_many(WIDTH_PX // 2, frames=3)
    assert harness.follower.line_statistics == {
        'frames': 8, 'frames_line_lost': 2, 'recoveries': 1}


def test_parameter_change_takes_effect_on_the_next_frame(harness):
    assert harness.send_many(WIDTH_PX // 2, frames=30).linear.x == pytest.approx(0.7)
    results = harness.set_parameters(Parameter('linear_speed_mps', value=0.3),
                                     Parameter('max_linear_acceleration_mps2', value=50.0))
    assert all(result.successful for result in results)
    assert harness.send(camera_frame(WIDTH_PX // 2)).linear.x == pytest.approx(0.3)
    assert harness.follower.get_parameter('linear_speed_mps').value == 0.3


@pytest.mark.parametrize('parameter, reason', [
    (Parameter('hue_min', value=60), 'hue_min 60 must not exceed hue_max 40'),
    (Parameter('min_linear_speed_mps', value=0.9),
     'min_linear_speed_mps 0.9 must not exceed linear_speed_mps 0.7'),
    (Parameter('steering_law', value='wobble'), 'steering_law must be one of path, proportional'),
    (Parameter('linear_speed_mps', value=5.0), ''),  # out of its declared range
    (Parameter('band_count', value=2.5), ''),  # wrong type
])
def test_bad_parameter_changes_are_refused_with_a_reason(harness, parameter, reason):
    before = harness.follower.get_parameter(parameter.name).value
    [result] = harness.set_parameters(parameter)
    assert not result.successful
    assert reason in result.reason and result.reason
    assert harness.follower.get_parameter(parameter.name).value == before
    assert harness.send_many(WIDTH_PX // 2).linear.x > 0.0  # still following


def test_zero_twist_on_shutdown(ros_context):
    harness = Harness(ros_context)
    try:
        assert harness.send_many(WIDTH_PX // 2).linear.x > 0.0
        count = len(harness.cmd_vels)
        harness.follower.destroy_node()
        harness.spin_until(lambda: len(harness.cmd_vels) > count)
        assert harness.cmd_vels[-1] == Twist()
    finally:
        harness.executor.shutdown()
        harness.client.destroy_node()


def test_stops_when_the_camera_goes_quiet(harness):
    assert harness.send_many(WIDTH_PX // 2).linear.x > 0.0
    count = len(harness.cmd_vels)
    harness.spin_until(lambda: len(harness.cmd_vels) > count, timeout_s=3.0)
    assert harness.cmd_vels[-1] == Twist()


def test_parameters_file_holds_the_code_defaults():
    document = yaml.safe_load(PARAMETERS_FILE.read_text())
    # Keys with '/**/' reach the nodes in any namespace.
    for node_name, specs in (('/**/follower', FOLLOWER_PARAMETERS),
                             ('/**/followbot_sim', SIMULATOR_PARAMETERS)):
        values = document[node_name]['ros__parameters']
        assert values == {name: spec.default for name, spec in specs.items()}


def test_parameters_file_and_overrides_reach_the_node(ros_context, tmp_path):
    document = yaml.safe_load(PARAMETERS_FILE.read_text())
    document['/**/follower']['ros__parameters']['linear_speed_mps'] = 0.35
    tuned = tmp_path / 'tuned.yaml'
    tuned.write_text(yaml.safe_dump(document))
    harness = Harness(ros_context, cli_args=['--ros-args', '--params-file', str(tuned)])
    try:
        assert harness.send_many(WIDTH_PX // 2, frames=30).linear.x == pytest.approx(0.35)
    finally:
        harness.close()


@pytest.mark.parametrize('name, value', [
    ('hue_max', 300),
    ('linear_speed_mps', -0.1),
    ('band_center_fraction', 1.5),
])
def test_out_of_range_parameters_are_refused(ros_context, name, value):
    with pytest.raises(ParameterException):
        FollowerNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_bad_parameter_on_the_command_line_is_one_clear_line():
    result = subprocess.run(
        [sys.executable, '-m', 'followbot.follower_node', '--ros-args', '-p',
         'lost_line_behaviour:=dance'], capture_output=True, text=True, timeout=60,
        env=child_environment())
    assert result.returncode == 2
    assert "lost_line_behaviour must be one of search, stop, got 'dance'" in result.stderr
    assert 'Traceback' not in result.stderr
