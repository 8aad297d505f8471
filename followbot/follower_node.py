"""
The follower node: camera image in, ``cmd_vel`` out.

Wires :mod:`followbot.image_conversion`, :mod:`followbot.line_detector` and
:mod:`followbot.controller` to ROS: every tunable number of the detector and the controller is a
declared parameter, read once at start-up.
"""

from followbot.controller import (ControllerConfig, LineFollowingController,
                                  LOST_LINE_BEHAVIOURS, VelocityCommand)
from followbot.image_conversion import (array_to_image, image_to_array, ImageConversionError,
                                        to_bgr)
from followbot.line_detector import Detection, DetectorConfig, draw_debug, LineDetector
from followbot.node_runner import run_node
from followbot.parameters import declare_parameters, ParameterSpec, specs_for_config
from geometry_msgs.msg import Twist
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

# Sensor-data QoS with depth 1: a controller must never work through a backlog of stale frames.
IMAGE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.BEST_EFFORT)
# How long the final zero Twist may wait to be acknowledged by the subscribers at shutdown.
STOP_ACK_TIMEOUT = Duration(seconds=0.5)
IMAGE_WATCH_PERIOD_S = 0.1

# Range and meaning (or, for a text, just the meaning) of each detector and controller
# parameter. Defaults come from DetectorConfig and ControllerConfig, so the two can never
# disagree.
DETECTOR_PARAMETERS = {
    'hue_min': (0, 179, 'Lowest hue of the line, OpenCV units (0-179, 2 degrees each).'),
    'hue_max': (0, 179, 'Highest hue of the line, OpenCV units (0-179, 2 degrees each).'),
    'saturation_min': (0, 255, 'Lowest saturation of the line (0-255).'),
    'saturation_max': (0, 255, 'Highest saturation of the line (0-255).'),
    'value_min': (0, 255, 'Lowest brightness (HSV value) of the line (0-255).'),
    'value_max': (0, 255, 'Highest brightness (HSV value) of the line (0-255).'),
    'band_center_fraction': (0.0, 1.0, 'Centre row of the band searched for the line, as a '
                             'fraction of the image height from the top.'),
    'band_height_px': (1, 4096, 'Height of the band of rows searched for the line.'),
    'min_area_px': (1, 1_000_000, 'Fewest line pixels in the band that count as a line.'),
}
CONTROLLER_PARAMETERS = {
    'linear_speed_mps': (0.0, 2.0, 'Forward speed while the line is seen.'),
    'angular_gain_radps': (0.0, 50.0, 'Yaw rate per unit of normalised line offset '
                           '(-1 at the left image edge, +1 at the right).'),
    'max_angular_speed_radps': (0.0, 10.0, 'Largest commanded yaw rate.'),
    'search_angular_speed_radps': (0.0, 10.0, 'Yaw rate while searching for a lost line.'),
    'lost_line_behaviour': ('What to do when the line is lost: '
                            + ' or '.join(LOST_LINE_BEHAVIOURS)
                            + " ('search' turns toward the side it was last seen)."),
}
FOLLOWER_PARAMETERS = {
    **specs_for_config(DetectorConfig(), DETECTOR_PARAMETERS),
    **specs_for_config(ControllerConfig(), CONTROLLER_PARAMETERS),
    'image_timeout_s': ParameterSpec(
        0.5, 'Stop when no camera image came for this long (node clock, so simulated time '
        'under use_sim_time).', 0.05, 10.0),
}


class FollowerNode(Node):
    """Follow a yellow line seen by the camera by publishing velocity commands."""

    def __init__(self, **kwargs):
        """
        Declare the parameters, build the detector and the controller, wire the topics.

        :param kwargs: forwarded to :class:`rclpy.node.Node` (``context``,
            ``parameter_overrides``, ...).
        """
        super().__init__('follower', **kwargs)
        parameters = declare_parameters(self, FOLLOWER_PARAMETERS)
        self._detector = LineDetector(DetectorConfig(
            **{name: parameters[name] for name in DETECTOR_PARAMETERS}))
        self._controller = LineFollowingController(ControllerConfig(
            **{name: parameters[name] for name in CONTROLLER_PARAMETERS}))
        self._image_timeout_s = parameters['image_timeout_s']

        self._cmd_vel_publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self._debug_image_publisher = self.create_publisher(Image, '~/debug_image', 1)
        self._image_subscription = self.create_subscription(
            Image, 'camera/rgb/image_raw', self.image_callback, IMAGE_QOS)
        self._image_watch_timer = self.create_timer(IMAGE_WATCH_PERIOD_S,
                                                    self.image_watch_callback)
        self._last_image_time = self.get_clock().now()
        self._waiting_for_images = True
        self._reported_errors = set()
        self._line_was_found = None
        self.get_logger().info(
            f'Following the line on {self._image_subscription.topic_name}, commanding '
            f'{self._cmd_vel_publisher.topic_name}.')

    def image_callback(self, msg: Image) -> None:
        """Detect the line in a camera frame and publish the command it calls for."""
        self._last_image_time = self.get_clock().now()
        self._waiting_for_images = False
        try:
            image = image_to_array(msg)
        except ImageConversionError as error:
            # Once per distinct problem: a stream of bad frames must not flood the log.
            reason = str(error)
            if reason not in self._reported_errors:
                self._reported_errors.add(reason)
                self.get_logger().error(f'Cannot use camera image: {reason}')
            # Nothing seen: the controller stops or searches, it never drives on blind.
            self._publish(self._controller.update(Detection.nothing_seen()))
            return
        detection = self._detector.detect(image, msg.encoding)
        self._publish(self._controller.update(detection))
        self._report_line_change(detection.found)
        if self._debug_image_publisher.get_subscription_count() > 0:
            overlay = draw_debug(to_bgr(image, msg.encoding), detection)
            debug_msg = array_to_image(overlay, 'bgr8')
            debug_msg.header = msg.header
            self._debug_image_publisher.publish(debug_msg)

    def image_watch_callback(self) -> None:
        """Stop the robot when the camera has gone quiet."""
        if self._waiting_for_images:
            return
        silence = self.get_clock().now() - self._last_image_time
        if silence.nanoseconds * 1e-9 > self._image_timeout_s:
            self._waiting_for_images = True
            self.get_logger().warn(
                f'No camera image for {self._image_timeout_s:g} s: stopping until images '
                'come back.')
            self._publish(LineFollowingController.stop_command())

    def _report_line_change(self, found: bool) -> None:
        if found == self._line_was_found:
            return
        self._line_was_found = found
        if found:
            self.get_logger().info('Line found.')
        else:
            self.get_logger().warn(
                'Line lost: ' + ('searching toward where it was last seen.'
                                 if self._controller.config.lost_line_behaviour == 'search'
                                 else 'stopping.'))

    def _publish(self, command: VelocityCommand) -> None:
        twist = Twist()
        twist.linear.x = float(command.linear_mps)
        twist.angular.z = float(command.angular_radps)
        self._cmd_vel_publisher.publish(twist)

    def destroy_node(self):
        """Stop the robot (a zero Twist, acknowledged if possible), then destroy the node."""
        if self.context.ok():
            self._publish(LineFollowingController.stop_command())
            self._cmd_vel_publisher.wait_for_all_acked(STOP_ACK_TIMEOUT)
        return super().destroy_node()


def main(args=None):
    """Run the follower until Ctrl-C."""
    run_node(FollowerNode, args)


if __name__ == '__main__':
    main()
