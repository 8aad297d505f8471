"""
The follower node over real DDS: what a user sees on its topics, its log and its parameters.

Each test puts the follower and a small client node in one executor on a private Context.
"""

from pathlib import Path
import subprocess
import sys

from conftest import child_environment, NodeHarness
from followbot.follower_node import FOLLOWER_PARAMETERS, FollowerNode
from followbot.image_conversion import array_to_image
from followbot_sim.sim_node import SIMULATOR_PARAMETERS
from geometry_msgs.msg import Twist
import numpy as np
import pytest
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image
import yaml

PARAMETERS_FILE = Path(__file__).resolve().parent.parent / 'config' / 'followbot.yaml'
YELLOW_BGR = (0, 246, 255)
FLOOR_GREY = 116
WIDTH_PX = 640
HEIGHT_PX = 480
LINE_HALF_WIDTH_PX = 30


def camera_frame(line_column_px=None, encoding='bgr8') -> Image:
    """Return a grey camera Image with a vertical yellow line at a column, or no line."""
    bgr = np.full((HEIGHT_PX, WIDTH_PX, 3), FLOOR_GREY, np.uint8)
    if line_column_px is not None:
        bgr[:, line_column_px - LINE_HALF_WIDTH_PX:line_column_px + LINE_HALF_WIDTH_PX] = (
            YELLOW_BGR)
    msg = array_to_image(bgr, 'bgr8')
    msg.encoding = encoding
    msg.header.frame_id = 'camera_rgb_optical_frame'
    return msg


class Harness(NodeHarness):
    """A follower, and a client publishing camera frames and recording what comes back."""

    def __init__(self, context, **follower_options):
        super().__init__(context, FollowerNode(context=context, **follower_options),
                         'follower_test_client')
        self.follower = self.node
        self.images = self.client.create_publisher(Image, 'camera/rgb/image_raw', 10)
        self.cmd_vels = []
        self.debug_images = []
        self.client.create_subscription(Twist, 'cmd_vel', self.cmd_vels.append, 10)
        self.spin_until(lambda: self.images.get_subscription_count() > 0)

    def send(self, msg):
        """Publish a frame and return the command it causes."""
        count = len(self.cmd_vels)
        self.images.publish(msg)
        self.spin_until(lambda: len(self.cmd_vels) > count)
        return self.cmd_vels[-1]


@pytest.fixture
def harness(ros_context):
    harness = Harness(ros_context)
    yield harness
    harness.close()


@pytest.mark.parametrize('line_offset_px', [0, 100, -100, 140])
def test_steers_toward_the_line_like_the_book(harness, line_offset_px):
    line_column_px = WIDTH_PX // 2 + line_offset_px
    command = harness.send(camera_frame(line_column_px))
    assert command.linear.x == pytest.approx(0.2)
    # The book's law: -(cx - w/2) / 100 rad/s; the drawn line's centroid is at column - 0.5.
    expected_radps = -(line_column_px - 0.5 - WIDTH_PX / 2) / 100.0
    assert command.angular.z == pytest.approx(expected_radps, abs=1e-3)


def test_turn_rate_is_bounded(harness):
    command = harness.send(camera_frame(WIDTH_PX // 2 + 250))
    assert command.angular.z == pytest.approx(-1.5)


def test_searches_toward_the_side_last_seen_without_driving(harness):
    harness.send(camera_frame(WIDTH_PX // 2 + 200))
    command = harness.send(camera_frame(None))
    assert command.linear.x == 0.0
    assert command.angular.z < 0.0


def test_bad_frames_are_reported_once_and_never_drive(harness):
    for _ in range(5):
        command = harness.send(camera_frame(WIDTH_PX // 2, encoding='yuv422'))
        assert command.linear.x == 0.0
    harness.spin_until(lambda: harness.errors, timeout_s=2.0)
    for _ in range(20):
        harness.executor.spin_once(timeout_sec=0.01)
    assert len(harness.errors) == 1
    assert 'yuv422' in harness.errors[0]
    # A good frame afterwards is followed as usual: nothing was lost.
    assert harness.send(camera_frame(WIDTH_PX // 2)).linear.x == pytest.approx(0.2)


def test_debug_image_only_while_someone_watches(harness):
    harness.send(camera_frame(WIDTH_PX // 2))
    assert harness.follower.count_subscribers('/follower/debug_image') == 0
    harness.client.create_subscription(
        Image, '/follower/debug_image', harness.debug_images.append, 10)
    harness.spin_until(lambda: harness.follower.count_subscribers('/follower/debug_image'))
    frame = camera_frame(WIDTH_PX // 2)
    frame.header.stamp.sec = 42
    harness.images.publish(frame)
    harness.spin_until(lambda: harness.debug_images)
    debug = harness.debug_images[-1]
    assert (debug.width, debug.height, debug.encoding) == (WIDTH_PX, HEIGHT_PX, 'bgr8')
    assert debug.header.stamp.sec == 42
    assert debug.header.frame_id == 'camera_rgb_optical_frame'
    assert bytes(debug.data) != bytes(frame.data)  # the overlay is drawn


def test_zero_twist_on_shutdown(ros_context):
    harness = Harness(ros_context)
    try:
        assert harness.send(camera_frame(WIDTH_PX // 2)).linear.x > 0.0
        count = len(harness.cmd_vels)
        harness.follower.destroy_node()
        harness.spin_until(lambda: len(harness.cmd_vels) > count)
        assert harness.cmd_vels[-1] == Twist()
    finally:
        harness.executor.shutdown()
        harness.client.destroy_node()


def test_stops_when_the_camera_goes_quiet(harness):
    assert harness.send(camera_frame(WIDTH_PX // 2)).linear.x > 0.0
    count = len(harness.cmd_vels)
    harness.spin_until(lambda: len(harness.cmd_vels) > count, timeout_s=3.0)
    assert harness.cmd_vels[-1] == Twist()


def test_parameters_file_holds_the_code_defaults():
    document = yaml.safe_load(PARAMETERS_FILE.read_text())
    for node_name, specs in (('follower', FOLLOWER_PARAMETERS),
                             ('followbot_sim', SIMULATOR_PARAMETERS)):
        values = document[node_name]['ros__parameters']
        assert values == {name: spec.default for name, spec in specs.items()}


def test_parameters_file_and_overrides_reach_the_node(ros_context, tmp_path):
    document = yaml.safe_load(PARAMETERS_FILE.read_text())
    document['follower']['ros__parameters']['linear_speed_mps'] = 0.35
    tuned = tmp_path / 'tuned.yaml'
    tuned.write_text(yaml.safe_dump(document))
    harness = Harness(ros_context, cli_args=['--ros-args', '--params-file', str(tuned)])
    try:
        assert harness.send(camera_frame(WIDTH_PX // 2)).linear.x == pytest.approx(0.35)
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
