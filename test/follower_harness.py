"""
A follower and a client node that plays its camera, for tests of the follower over real DDS.

The client publishes frames 50 ms apart and the simulated Kinect's camera_info, and records the
commands and the follower's log lines that come back.
"""

import math

from conftest import NodeHarness, PACKAGE_DIR
from followbot import messages
from followbot.follower_node import FollowerNode
from followbot.image_conversion import array_to_image
from geometry_msgs.msg import Twist, TwistStamped
import numpy as np
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from scenes import KINECT, LINE_WIDTH_M
from sensor_msgs.msg import CameraInfo, Image

CONFIG_DIR = PACKAGE_DIR / 'config'
PARAMETERS_FILE = CONFIG_DIR / 'followbot.yaml'
BOOK_PARAMETERS_FILE = CONFIG_DIR / 'book_follower.yaml'
YELLOW_BGR = (0, 246, 255)
FLOOR_GREY = 116
WIDTH_PX = 640
HEIGHT_PX = 480
FRAME_PERIOD_S = 0.05
# The simulated Kinect: 60 degrees across 640 pixels.
FOCAL_PX = (WIDTH_PX / 2) / math.tan(math.radians(30.0))
# Frames it takes the default follower to trust the line and reach a good speed.
SETTLING_FRAMES = 10


def camera_frame(line_column_px=None, encoding='bgr8', line_top_px=0) -> Image:
    """
    Return a grey camera Image with a yellow line standing on a column, or no line.

    The line is as wide, at each row, as the Kinect sees the course's 0.19 m line there, so
    its stripes are the width the follower expects. It ends at row ``line_top_px`` (0: it
    runs on out of the view's top).
    """
    bgr = np.full((HEIGHT_PX, WIDTH_PX, 3), FLOOR_GREY, np.uint8)
    if line_column_px is not None:
        half_widths_px = KINECT.line_width_px(np.arange(HEIGHT_PX), LINE_WIDTH_M) / 2.0
        for row, half_width_px in enumerate(half_widths_px[line_top_px:], line_top_px):
            first = max(int(round(line_column_px - half_width_px)), 0)
            bgr[row, first:int(round(line_column_px + half_width_px))] = YELLOW_BGR
    msg = array_to_image(bgr, 'bgr8')
    msg.encoding = encoding
    msg.header.frame_id = 'camera_rgb_optical_frame'
    return msg


def camera_info() -> CameraInfo:
    """Return the simulated Kinect's CameraInfo."""
    info = CameraInfo(width=WIDTH_PX, height=HEIGHT_PX)
    info.k = [FOCAL_PX, 0.0, (WIDTH_PX - 1) / 2, 0.0, FOCAL_PX, (HEIGHT_PX - 1) / 2,
              0.0, 0.0, 1.0]
    return info


class Harness(NodeHarness):
    """A follower, and a client publishing camera frames and recording what comes back."""

    def __init__(self, context, send_camera_info=True, cmd_vel_stamped=False,
                 **follower_options):
        if cmd_vel_stamped:
            follower_options['parameter_overrides'] = [
                Parameter('cmd_vel_stamped', value=True)]
        super().__init__(context, FollowerNode(context=context, **follower_options),
                         'follower_test_client')
        self.follower = self.node
        self.images = self.client.create_publisher(Image, 'camera/rgb/image_raw', 10)
        self.camera_infos = self.client.create_publisher(
            CameraInfo, 'camera/rgb/camera_info', 10)
        self.parameters = AsyncParameterClient(self.client, 'follower')
        self.time_s = 0.0
        self.cmd_vels = []
        self.stamped_cmd_vels = []
        if cmd_vel_stamped:
            self.client.create_subscription(TwistStamped, 'cmd_vel', self._take_stamped, 10)
        else:
            self.client.create_subscription(Twist, 'cmd_vel', self.cmd_vels.append, 10)
        self.spin_until(lambda: self.images.get_subscription_count() > 0
                        and self.camera_infos.get_subscription_count() > 0)
        if send_camera_info:
            self.camera_infos.publish(camera_info())
            self.spin_until(lambda: self.follower._camera_geometry is not None)

    def _take_stamped(self, msg):
        self.stamped_cmd_vels.append(msg)
        self.cmd_vels.append(msg.twist)

    def send(self, msg):
        """Publish a frame stamped 50 ms after the previous one; return the command it causes."""
        self.time_s += FRAME_PERIOD_S
        msg.header.stamp = messages.stamp(self.time_s)
        count = len(self.cmd_vels)
        self.images.publish(msg)
        self.spin_until(lambda: len(self.cmd_vels) > count)
        return self.cmd_vels[-1]

    def only_error(self) -> str:
        """Wait for the follower to log an error, give it time to log more; return the only one."""
        self.spin_until(lambda: self.errors, timeout_s=2.0)
        for _ in range(20):
            self.executor.spin_once(timeout_sec=0.01)
        assert len(self.errors) == 1, self.errors
        return self.errors[0]

    def send_many(self, line_column_px, frames=SETTLING_FRAMES):
        """Publish frames of a line at a column; return the last command."""
        for _ in range(frames):
            command = self.send(camera_frame(line_column_px))
        return command

    def set_parameters(self, *parameters):
        """Set follower parameters as `ros2 param set` does; return the results."""
        self.spin_until(self.parameters.services_are_ready)
        future = self.parameters.set_parameters(list(parameters))
        self.spin_until(future.done)
        return future.result().results
