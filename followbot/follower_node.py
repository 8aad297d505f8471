"""
The follower node: camera image in, ``cmd_vel`` out (and the base's ``odom``, when it has one).

Wires :mod:`followbot.image_conversion`, :mod:`followbot.line_detector`,
:mod:`followbot.ground_projection` and :mod:`followbot.controller` to ROS. Every tunable number
is a declared parameter with a description and a range, and can be changed while the node
runs (``ros2 param set``): a new value is checked with the rest, refused with the reason if it
cannot work, and used from the next frame on. ``~/status`` says what the follower sees and
does, ``~/mask`` shows the pixels it took for the line, ``~/debug_image`` the camera view
annotated.
"""

import dataclasses
import math
import time
import traceback

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot import frames
from followbot import messages
from followbot.compressed_image import compressed_to_array
from followbot.controller import (ALONG_VANISHED_LINE, arc_pose, ControllerConfig,
                                  LineFollowingController, LOST_LINE_BEHAVIOURS,
                                  STATE_LINE_END, STATE_LOST, STATE_TRACKING,
                                  STEERING_LAWS, TO_LINE_END, VelocityCommand)
from followbot.frame_clock import FrameClock
from followbot.ground_projection import CameraGeometry, CameraInfoError, CameraIntrinsics
from followbot.image_conversion import array_to_image, image_to_array, ImageConversionError, to_bgr
from followbot.line_colour import LINE_COLOURS
from followbot.line_detector import Detection, DetectorConfig, draw_debug, LineDetector
from followbot.node_runner import run_node
from followbot.parameters import declare_parameters, ParameterSpec, specs_for_config
from followbot.problem_reports import ProblemReports
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

# Sensor-data QoS with depth 1: a controller must never work through a backlog of stale frames
# (nor of stale odometry). Best effort takes a reliable publisher's messages too.
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.BEST_EFFORT)
# How long the final zero Twist may wait to be acknowledged by the subscribers at shutdown.
STOP_ACK_TIMEOUT = Duration(seconds=0.5)
# Debug images kept for a slow subscriber: half a second of a 20 Hz camera, so a video that
# holds the run from that lag on (followbot --video) gets every one.
DEBUG_IMAGE_QUEUE_DEPTH = 10
NODE_NAME = 'follower'
STATUS_NAME = 'followbot: follower'
IMAGE_TOPIC = 'camera/rgb/image_raw'
RAW_TRANSPORT = 'raw'
COMPRESSED_TRANSPORT = 'compressed'
# image_transport's compressed plugin publishes on the base topic plus this.
COMPRESSED_SUFFIX = '/compressed'
# The causes of the problems the follower reports, each at most once per report period.
CAUSE_IMAGE = 'image'
CAUSE_CAMERA_INFO = 'camera_info'
CAUSE_WAITING_FOR_CAMERA_INFO = 'waiting for camera_info'
CAUSE_STAMP = 'stamp'
CAUSE_ODOMETRY = 'odometry'
CAUSE_INTERNAL = 'internal'

# Range and meaning (or, for a text, just the meaning) of each detector and controller
# parameter. Defaults come from DetectorConfig and ControllerConfig, so the two can never
# disagree.
DETECTOR_PARAMETERS = {
    'line_colour': ('Colour of the line: ' + ', '.join(LINE_COLOURS) + ' (the presets judge '
                    'the line against its floor, whatever the white balance and exposure; '
                    "'custom' takes the line's colour from the hue, saturation and value "
                    'bounds below). A mono8 camera shows only white or black tape.'),
    'hue_min': (0, 179, 'Lowest hue of the line, OpenCV units (0-179, 2 degrees each).'),
    'hue_max': (0, 179, 'Highest hue of the line, OpenCV units (0-179, 2 degrees each).'),
    'saturation_min': (0, 255, 'Lowest saturation of the line (0-255).'),
    'saturation_max': (0, 255, 'Highest saturation of the line (0-255).'),
    'value_min': (0, 255, 'Lowest brightness (HSV value) of the line (0-255).'),
    'value_max': (0, 255, 'Highest brightness (HSV value) of the line (0-255).'),
    'band_count': (1, 16, 'Number of bands of rows searched for the line, from the nearest '
                   'upwards (1 = the book).'),
    'band_center_fraction': (0.0, 1.0, 'Centre row of the nearest band, as a fraction of '
                             'the image height from the top.'),
    'band_spacing_fraction': (0.0, 1.0, 'Distance between band centres, as a fraction of '
                              'the image height.'),
    'band_height_px': (1, 4096, 'Height of each band of rows.'),
    'min_area_px': (1, 1_000_000, 'Fewest pixels of one stripe in a band that count as '
                    'the line, whatever the camera geometry (which asks for more where the '
                    'line looks wide); smaller specks are noise.'),
    'line_width_m': (0.005, 2.0, 'Width of the line on the floor: with the camera geometry '
                     'it tells how wide the line must look in each band.'),
    'min_confidence': (0.0, 1.0, 'A detection less confident than this (0-1) reports no line: '
                       'the robot coasts (line_memory_s, or along the line last seen; see '
                       'lost_line_behaviour), then stops or searches.'),
    'max_stripe_jump_m': (0.005, 5.0, "Farthest, on the floor, a band's stripe may lie "
                          'sideways from where the line leads, or from where the band saw '
                          'it in the previous frame.'),
}
CONTROLLER_PARAMETERS = {
    'steering_law': ('How to steer: ' + ' or '.join(STEERING_LAWS) + " ('path' steers along "
                     'the arc to the line point look_ahead_m away on the floor and plans its '
                     "speed on the bends ahead; 'proportional' is the book's "
                     'w = -gain * error on the nearest band at a constant speed).'),
    'linear_speed_mps': (0.0, 2.0, 'Forward speed on a straight line (path law), or always '
                         '(proportional law).'),
    'min_linear_speed_mps': (0.0, 2.0, 'Slowest forward speed while following (path law).'),
    'angular_gain_radps': (0.0, 50.0, 'Proportional law: yaw rate per unit of normalised '
                           'line offset (-1 at the left image edge, +1 at the right).'),
    'look_ahead_m': (0.05, 5.0, 'Path law: distance from the robot of the line point it '
                     'steers for.'),
    'bearing_gain_radps': (0.0, 50.0, 'Path law: yaw rate per radian of bearing to that '
                           'point when this turns faster than the arc to it (sharp corners).'),
    'confidence_for_full_speed': (0.001, 1.0, 'Path law: detection confidence (0-1: the '
                                  'share of the bands that see a well-fitting line) needed '
                                  'for full speed; less slows the robot down.'),

    'max_lateral_acceleration_mps2': (0.001, 100.0, 'Path law: bends are driven no faster '
                                      'than this sideways acceleration allows.'),
    'max_linear_acceleration_mps2': (0.001, 100.0, 'Largest change of forward speed per '
                                     'second (speeding up and slowing down).'),
    'max_angular_acceleration_radps2': (0.001, 1000.0, 'Largest change of yaw rate per '
                                        'second.'),
    'max_angular_speed_radps': (0.0, 10.0, 'Largest commanded yaw rate.'),
    'frames_to_trust': (1, 100, 'Frames in a row that must show the line before a found '
                        'line is followed again.'),
    'line_memory_s': (0.0, 10.0, 'How long to drive on the last command when the line '
                      'disappears (a gap in a dashed line) before it counts as lost.'),
    'search_angular_speed_radps': (0.0, 10.0, 'Yaw rate while searching for a lost line.'),
    'lost_line_behaviour': ('What to do when the line is lost: '
                            + ' or '.join(LOST_LINE_BEHAVIOURS)
                            + " ('search' turns toward the side it was last seen; path law: "
                            'a line that vanished where it was seen running on out of view '
                            'is first driven along as far as it was seen).'),
    'stop_at_line_end': ('Stop (zero Twist) instead of searching when the line is lost '
                         'after the robot saw it end ahead, bare floor beyond it (path law: '
                         'once there, see line_end_stop_short_m).'),
    'turn_side_offset_m': (0.0, 5.0, 'Path law: the farthest band seeing the line at '
                           'least this far to a side means the line turns away to that side, '
                           'where a lost line is searched for first.'),
    'turn_side_memory_s': (0.0, 60.0, 'Path law: how long before the line is lost such a '
                           'turn still counts.'),
    'corner_search_angle_deg': (0.0, 360.0, "Searching ('search'), at a line end seen just "
                                'after the line turned away to a side (a corner sharper than '
                                'the camera sees), turn in place up to this far toward that '
                                'side looking for the line before stopping; 0 stops at once.'),
    'corner_search_angular_speed_radps': (0.0, 10.0, 'Yaw rate of that turn round a corner '
                                          'seen.'),
    'line_end_stop_short_m': (0.0, 5.0, 'Path law, with stop_at_line_end: where the robot saw '
                              'the line end ahead, it drives on along the line last seen (by '
                              'dead reckoning: odometry, else its commands) and stops this far '
                              'short of its end, before stopping or searching there.'),
    'trail_length_m': (0.0, 8.0, "Path law: how much of the robot's own latest path (by dead "
                       'reckoning) counts as the way it came: a line found while searching '
                       'that lies along it is the way back, not taken.'),
    'trail_tolerance_m': (0.0, 1.0, 'Path law: how near that path a found line must lie, '
                          'most of its points, to be the way back; 0 takes any line found.'),
}
# Where the camera is on the robot: the path law needs it to put image points on the floor.
# The defaults are the simulated TurtleBot 2's Kinect (followbot_sim's camera_pitch_deg).
CAMERA_PARAMETERS = {
    'camera_height_m': ParameterSpec(
        0.30, 'Height of the camera above the floor.', 0.01, 10.0),
    'camera_pitch_deg': ParameterSpec(
        30.0, 'Downward tilt of the camera from the horizontal.', -90.0, 90.0),
    'camera_forward_m': ParameterSpec(
        0.10, "Distance of the camera ahead of the robot's centre (base_footprint).",
        -5.0, 5.0),
}
FOLLOWER_PARAMETERS = {
    **specs_for_config(DetectorConfig(), DETECTOR_PARAMETERS),
    **specs_for_config(ControllerConfig(), CONTROLLER_PARAMETERS),
    **CAMERA_PARAMETERS,
    'image_timeout_s': ParameterSpec(
        0.5, 'Stop when no camera image came for this long, in wall-clock time whatever the '
        'time source (a dead simulator stops /clock too).', 0.05, 10.0),
    'odometry_timeout_s': ParameterSpec(
        0.5, 'Path law: the line last seen is driven along (at its end, or where it vanished) '
        'by the wheel odometry on odom (nav_msgs/Odometry) when its stamp is within this '
        "long of the camera frame's, else by the commands given; 0 never uses odometry.",
        0.0, 10.0),
    # Read-only: a publisher's message type cannot change while the node runs.
    'image_transport': ParameterSpec(
        'raw', "How camera images come: 'raw' (sensor_msgs/Image on camera/rgb/image_raw) "
        "or 'compressed' (sensor_msgs/CompressedImage, JPEG or PNG, on the same topic plus "
        '/compressed, as image_transport names it: the usual way images cross Wi-Fi).',
        read_only=True),
    'cmd_vel_stamped': ParameterSpec(
        False, 'Publish cmd_vel as geometry_msgs/TwistStamped, stamped with the camera image '
        "each command answers (as Jazzy's Nav2 and ros2_control take it), instead of Twist.",
        read_only=True),
}
# The camera watchdog's longest setting: for runs whose frames come at the pace of a machine
# rather than of a camera (lockstep simulation, replay), where a stall is no lost camera.
LONGEST_IMAGE_TIMEOUT_S = FOLLOWER_PARAMETERS['image_timeout_s'].high


@dataclasses.dataclass(frozen=True)
class FollowerSettings:
    """Everything the follower's parameters decide, checked as a whole."""

    detector: DetectorConfig
    controller: ControllerConfig
    camera_height_m: float
    camera_pitch_deg: float
    camera_forward_m: float
    image_timeout_s: float
    odometry_timeout_s: float

    @classmethod
    def from_parameters(cls, values: dict):
        """
        Build the settings from parameter values.

        :param values: parameter name -> value, for every follower parameter.
        :return: the settings.
        :raises ValueError: if the values cannot work together (hue_min above hue_max, ...).
        :raises TypeError: if a value has the wrong type.
        """
        return cls(
            detector=DetectorConfig(**{name: values[name] for name in DETECTOR_PARAMETERS}),
            controller=ControllerConfig(
                **{name: values[name] for name in CONTROLLER_PARAMETERS}),
            **{name: values[name] for name in (*CAMERA_PARAMETERS, 'image_timeout_s',
                                               'odometry_timeout_s')})


class FollowerNode(Node):
    """Follow a yellow line seen by the camera by publishing velocity commands."""

    NODE_NAME = NODE_NAME

    def __init__(self, **kwargs):
        """
        Declare the parameters, build the detector and the controller, wire the topics.

        :param kwargs: forwarded to :class:`rclpy.node.Node` (``context``,
            ``parameter_overrides``, ...).
        """
        super().__init__(self.NODE_NAME, **kwargs)
        parameters = declare_parameters(self, FOLLOWER_PARAMETERS)
        self._settings = FollowerSettings.from_parameters(parameters)
        self._cmd_vel_stamped = parameters['cmd_vel_stamped']
        self._detector = LineDetector(self._settings.detector)
        self._controller = LineFollowingController(self._settings.controller)
        self._pending_settings = None
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._camera_intrinsics = None
        self._camera_geometry = None
        self._cmd_vel_publisher = self.create_publisher(
            TwistStamped if self._cmd_vel_stamped else Twist, 'cmd_vel', 10)
        # A video takes every debug image; each is only sent while someone subscribes, and
        # in a fast lockstep run a newer one came before the last was sent.
        self._debug_image_publisher = self.create_publisher(
            Image, '~/debug_image', DEBUG_IMAGE_QUEUE_DEPTH)
        self._mask_publisher = self.create_publisher(Image, '~/mask', 1)
        self._status_publisher = self.create_publisher(DiagnosticArray, '~/status', 10)
        # camera_info is subscribed first: when it and an image are ready together, the
        # executor then takes the intrinsics before the image that needs them.
        self._camera_info_subscription = self.create_subscription(
            CameraInfo, 'camera/rgb/camera_info', self.camera_info_callback, SENSOR_QOS)
        # Odometry too comes before the images: the frame then uses the latest.
        self._odometry = None
        self._odometry_used = False
        self._odometry_messages = 0
        self._odometry_subscription = self.create_subscription(
            Odometry, 'odom', self.odometry_callback, SENSOR_QOS)
        self._image_subscription = self._subscribe_to_images(parameters['image_transport'])
        # The camera watchdog runs on wall time: under use_sim_time a dead simulator stops
        # /clock as well as the images, and a timer on the node's clock would never fire.
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._image_watchdog = self.create_timer(
            self._settings.image_timeout_s, self.image_watchdog_callback,
            clock=self._steady_clock)
        self._image_watchdog.cancel()
        self._stopped_for_silence = False
        self._reports = ProblemReports()
        self._frame_clock = FrameClock()
        self._camera_info = None
        self._line_was_found = None
        self._line_situation = None
        self._frames = 0
        self._frames_line_lost = 0
        self._recoveries = 0
        self._mask_frame = None
        self.get_logger().info(
            f'Following the line on {self._image_subscription.topic_name}, commanding '
            f'{self._cmd_vel_publisher.topic_name}.')

    @property
    def line_statistics(self) -> dict:
        """
        Return the counts of camera frames, frames without the line, and recoveries.

        :return: ``frames``, ``frames_line_lost`` and ``recoveries`` (lost, then found again).
        """
        return {'frames': self._frames, 'frames_line_lost': self._frames_line_lost,
                'recoveries': self._recoveries}

    @property
    def odometry_messages(self) -> int:
        """Return how many odometry messages came, usable or not."""
        return self._odometry_messages

    def _check_parameters(self, parameters: list) -> SetParametersResult:
        # rclpy has already checked each value's type and range; this checks them together
        # with the values that stay as they are.
        values = {name: self.get_parameter(name).value for name in FOLLOWER_PARAMETERS}
        values.update({parameter.name: parameter.value for parameter in parameters})
        try:
            self._pending_settings = FollowerSettings.from_parameters(values)
        except (TypeError, ValueError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list) -> None:
        settings, self._settings = self._settings, self._pending_settings
        if settings.detector != self._settings.detector:
            self._detector = LineDetector(self._settings.detector)
        self._controller.config = self._settings.controller
        if self._camera_intrinsics is not None:
            self._camera_geometry = self._make_camera_geometry(self._camera_intrinsics)
        if settings.image_timeout_s != self._settings.image_timeout_s:
            self._restart_image_watchdog()
        changes = ', '.join(f'{parameter.name}={parameter.value!r}' for parameter in parameters)
        self.get_logger().info(f'Parameters changed: {changes}.')

    def _make_camera_geometry(self, intrinsics: CameraIntrinsics) -> CameraGeometry:
        settings = self._settings
        return CameraGeometry.from_intrinsics(
            intrinsics, settings.camera_height_m, math.radians(settings.camera_pitch_deg),
            settings.camera_forward_m)

    def _restart_image_watchdog(self) -> None:
        active = not self._image_watchdog.is_canceled()
        self.destroy_timer(self._image_watchdog)
        self._image_watchdog = self.create_timer(
            self._settings.image_timeout_s, self.image_watchdog_callback,
            clock=self._steady_clock)
        if not active:
            self._image_watchdog.cancel()

    def camera_info_callback(self, msg: CameraInfo) -> None:
        """Take the camera's intrinsics, which put the line's image points on the floor."""
        try:
            self._take_camera_info(msg)
        except Exception as error:  # noqa: B902 - no message may bring the follower down.
            self._internal_error(error)

    def _take_camera_info(self, msg: CameraInfo) -> None:
        # The same description comes with every frame: only a new one is read.
        description = (tuple(msg.k), tuple(msg.d), msg.distortion_model, msg.width,
                       msg.height, msg.binning_x, msg.binning_y, msg.roi.x_offset,
                       msg.roi.y_offset, msg.roi.width, msg.roi.height)
        if description == self._camera_info:
            return
        try:
            intrinsics = CameraIntrinsics.from_camera_info(msg)
        except CameraInfoError as error:
            # Not used, and what was known is forgotten: a camera whose description turned
            # bad may have changed (a new resolution), and old intrinsics would mislead.
            self._camera_info = self._camera_intrinsics = self._camera_geometry = None
            self._report_error(CAUSE_CAMERA_INFO, f'Cannot use camera_info: {error}')
            return
        self._camera_info = description
        self._camera_intrinsics = intrinsics
        self._camera_geometry = self._make_camera_geometry(intrinsics)

    def odometry_callback(self, msg: Odometry) -> None:
        """Take the robot's odometry: where it is and how it moves, at the message's stamp."""
        self._odometry_messages += 1
        try:
            self._take_odometry(msg)
        except Exception as error:  # noqa: B902 - no message may bring the follower down.
            self._internal_error(error)

    def _take_odometry(self, msg: Odometry) -> None:
        position, rotation = msg.pose.pose.position, msg.pose.pose.orientation
        twist = msg.twist.twist
        stamp_s = messages.seconds(msg.header.stamp)
        pose = (position.x, position.y, frames.yaw_from_quaternion(
            (rotation.x, rotation.y, rotation.z, rotation.w)))
        figures = (*pose, twist.linear.x, twist.angular.z)
        if stamp_s <= 0.0 or not all(math.isfinite(value) for value in figures):
            # Not used, and what was known is forgotten: the route is then driven by the
            # commands, as without odometry.
            self._odometry = None
            self._report_error(
                CAUSE_ODOMETRY, f'Cannot use odometry on {self._odometry_subscription.topic_name}'
                ': it needs a header.stamp and a finite pose and twist; driving by the commands '
                'instead.')
            return
        self._reports.resolved(CAUSE_ODOMETRY)
        self._odometry = (stamp_s, pose, twist.linear.x, twist.angular.z)

    def _odometry_pose(self, time_s: float, stamped: bool):
        """Return the robot's odometry pose at a stamped frame's time, or None if unknown."""
        timeout_s = self._settings.odometry_timeout_s
        if self._odometry is None or not stamped or timeout_s == 0.0:
            return None
        stamp_s, pose, linear_mps, angular_radps = self._odometry
        if abs(time_s - stamp_s) > timeout_s:
            return None
        # Odometry comes at its own rate: carried on its twist to the frame's time.
        pose = arc_pose(pose, linear_mps, angular_radps, time_s - stamp_s)
        return pose if all(math.isfinite(value) for value in pose) else None

    def _subscribe_to_images(self, transport: str):
        """Subscribe to the camera's raw or compressed images, named as image_transport does."""
        if transport == RAW_TRANSPORT:
            return self.create_subscription(Image, IMAGE_TOPIC, self.image_callback, SENSOR_QOS)
        if transport != COMPRESSED_TRANSPORT:
            raise ValueError(f"image_transport must be '{RAW_TRANSPORT}' or "
                             f"'{COMPRESSED_TRANSPORT}', got {transport!r}.")
        # The base topic with its remaps and namespace applied, then image_transport's suffix:
        # remapping camera/rgb/image_raw moves the compressed topic with it.
        topic = self.resolve_topic_name(IMAGE_TOPIC) + COMPRESSED_SUFFIX
        return self.create_subscription(CompressedImage, topic,
                                        self.compressed_image_callback, SENSOR_QOS)

    def image_callback(self, msg: Image) -> None:
        """Detect the line in a camera frame and publish the command it calls for."""
        self._take_frame(msg, _raw_pixels)

    def compressed_image_callback(self, msg: CompressedImage) -> None:
        """Decode a compressed camera frame, then follow as with a raw one."""
        self._take_frame(msg, compressed_to_array)

    def _take_frame(self, msg, decode) -> None:
        # The camera is alive, whatever its frames hold.
        self._image_watchdog.reset()
        self._stopped_for_silence = False
        try:
            self._follow(msg, decode)
        except Exception as error:  # noqa: B902 - no message may bring the follower down.
            self._internal_error(error)
            self._stop_blind(msg.header.stamp)

    def _follow(self, msg, decode) -> None:
        time_s, stamped = self._frame_clock.frame_time(
            messages.seconds(msg.header.stamp), time.monotonic())
        if not stamped:
            self._report_warning(
                CAUSE_STAMP, 'Camera images carry a zero or repeated header.stamp: timing '
                'them by their arrival instead. Stamp them in the camera driver.')
        else:
            self._reports.resolved(CAUSE_STAMP)
        try:
            image, encoding = decode(msg)
            geometry = self._geometry_for(image.shape[1], image.shape[0])
            detection = self._detector.detect(image, encoding, geometry)
        except ImageConversionError as error:
            self._report_error(CAUSE_IMAGE, f'Cannot use camera image: {error}')
            # A frame that cannot be read never drives the robot.
            self._stop_blind(msg.header.stamp)
            return
        self._reports.resolved(CAUSE_IMAGE)
        # Only the path law steers by floor points; the proportional law needs no projection.
        floor_xy_m = None
        if self._settings.controller.steering_law == 'path':
            if geometry is None:
                self._report_info(
                    CAUSE_WAITING_FOR_CAMERA_INFO,
                    f'Waiting for {self._camera_info_subscription.topic_name}: the path law '
                    'needs the camera intrinsics to put the line on the floor.')
                self._publish(LineFollowingController.stop_command(), msg.header.stamp)
                return
            floor_xy_m = self._floor_points(detection, geometry)
        odometry_pose = self._odometry_pose(time_s, stamped)
        self._odometry_used = odometry_pose is not None
        command = self._controller.update(detection, time_s, floor_xy_m, odometry_pose)
        self._publish(command, msg.header.stamp)
        self._count_frame(detection.found)
        self._publish_views(msg.header, image, encoding, detection, command)

    def _geometry_for(self, width_px: int, height_px: int) -> CameraGeometry | None:
        """Return the camera geometry if the last camera_info describes an image of a size."""
        if self._camera_intrinsics is None:
            return None
        try:
            self._camera_intrinsics.check_image_size(width_px, height_px)
        except CameraInfoError as error:
            self._report_error(CAUSE_CAMERA_INFO, f'Cannot use camera_info: {error}')
            return None
        self._reports.resolved(CAUSE_CAMERA_INFO)
        return self._camera_geometry

    def _stop_blind(self, stamp=None) -> None:
        """Stop the robot and forget the line: nothing known may drive it."""
        self._controller.reset()
        self._publish(LineFollowingController.stop_command(), stamp)

    def _internal_error(self, error: Exception) -> None:
        self._report_error(
            CAUSE_INTERNAL, 'Internal error, stopping the robot: '
            + ''.join(traceback.format_exception(error)).rstrip())

    def _floor_points(self, detection: Detection, geometry: CameraGeometry):
        seen = detection.seen_bands
        x_m, y_m = geometry.pixels_to_floor(
            [band.centroid_x_px for band in seen], [band.centroid_y_px for band in seen])
        points = np.stack((x_m, y_m), axis=1)
        return points[np.isfinite(points).all(axis=1)]

    def _publish_views(self, header, image, encoding: str, detection: Detection,
                       command: VelocityCommand) -> None:
        # Each view costs time per frame: made only while someone subscribes.
        if self._status_publisher.get_subscription_count() > 0:
            self._publish_status(header, detection, command)
        if self._mask_publisher.get_subscription_count() > 0:
            self._publish_mask(header, detection)
        if self._debug_image_publisher.get_subscription_count() > 0:
            overlay = draw_debug(to_bgr(image, encoding), detection)
            debug_msg = array_to_image(overlay, 'bgr8')
            debug_msg.header = header
            self._debug_image_publisher.publish(debug_msg)

    def _publish_status(self, header, detection: Detection, command: VelocityCommand) -> None:
        state = self._controller.state
        estimate = self._controller.path_estimate
        figures = {
            'line_found': detection.found,
            'state': state,
            'error': round(detection.error, 4),
            'confidence': round(detection.confidence, 3),
            'look_ahead_x_m': round(estimate.look_ahead_x_m, 3) if estimate else '',
            'look_ahead_y_m': round(estimate.look_ahead_y_m, 3) if estimate else '',
            'heading_deg': round(math.degrees(estimate.heading_rad), 1) if estimate else '',
            'sharpest_curvature_per_m': (round(estimate.sharpest_curvature_per_m, 3)
                                         if estimate else ''),
            'linear_mps': round(command.linear_mps, 3),
            'angular_radps': round(command.angular_radps, 3),
            'odometry_used': self._odometry_used,
            **self.line_statistics,
        }
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK if state == STATE_TRACKING else DiagnosticStatus.WARN,
            name=STATUS_NAME, hardware_id=self.get_fully_qualified_name(),
            message=f'{state}, confidence {detection.confidence:.2f}',
            values=[KeyValue(key=key, value=str(value)) for key, value in figures.items()])
        self._status_publisher.publish(DiagnosticArray(header=header, status=[status]))

    def _publish_mask(self, header, detection: Detection) -> None:
        size = (detection.image_height_px, detection.image_width_px)
        if self._mask_frame is None or self._mask_frame.shape != size:
            self._mask_frame = np.empty(size, dtype=np.uint8)
        mask_msg = array_to_image(self._detector.draw_mask(self._mask_frame), 'mono8')
        mask_msg.header = header
        self._mask_publisher.publish(mask_msg)

    def image_watchdog_callback(self) -> None:
        """Stop the robot when the camera has gone quiet for image_timeout_s of wall time."""
        self._image_watchdog.cancel()
        if self._stopped_for_silence:
            return
        self._stopped_for_silence = True
        self.get_logger().warn(
            f'No camera image for {self._settings.image_timeout_s:g} s: stopping until '
            'images come back.')
        self._controller.reset()
        self._frame_clock.reset()
        self._publish(LineFollowingController.stop_command())

    # One method per severity: rclpy refuses to log at two severities from one line of code.
    def _report_error(self, cause: str, text: str) -> None:
        suffix = self._reports.occurred(cause, time.monotonic())
        if suffix is not None:
            self.get_logger().error(text + suffix)

    def _report_warning(self, cause: str, text: str) -> None:
        suffix = self._reports.occurred(cause, time.monotonic())
        if suffix is not None:
            self.get_logger().warn(text + suffix)

    def _report_info(self, cause: str, text: str) -> None:
        suffix = self._reports.occurred(cause, time.monotonic())
        if suffix is not None:
            self.get_logger().info(text + suffix)

    def _count_frame(self, found: bool) -> None:
        self._frames += 1
        self._frames_line_lost += not found
        if found != self._line_was_found:
            self._recoveries += found and self._line_was_found is False
            self._line_was_found = found
        # What the robot does about the line, logged when it changes. Coasting through a short
        # gap is not worth a line; losing the line after it is.
        situation = 'found' if found else (self._controller.coasting_along or (
            self._controller.state if self._controller.state in (STATE_LINE_END, STATE_LOST)
            else self._line_situation))
        if situation == self._line_situation:
            return
        self._line_situation = situation
        searching = self._settings.controller.lost_line_behaviour == 'search'
        logger = self.get_logger()
        if situation == 'found':
            logger.info('Line found.')
        elif situation == TO_LINE_END:
            logger.info('Line ends ahead: driving on to its end.')
        elif situation == ALONG_VANISHED_LINE:
            logger.warn('Line vanished: driving on along where it was seen, then searching.')
        elif situation == STATE_LINE_END:
            logger.info("At the line's end.")
        else:
            logger.warn('Line lost: ' + ('searching toward where it was last seen.' if searching
                                         else 'stopping.'))

    def _publish(self, command: VelocityCommand, stamp=None) -> None:
        twist = Twist()
        twist.linear.x = float(command.linear_mps)
        twist.angular.z = float(command.angular_radps)
        if not self._cmd_vel_stamped:
            self._cmd_vel_publisher.publish(twist)
            return
        stamped = TwistStamped(twist=twist)
        # The image a command answers stamps it; commands of no image (stops), the clock.
        stamped.header.stamp = stamp if stamp is not None else self.get_clock().now().to_msg()
        stamped.header.frame_id = frames.BASE_FOOTPRINT_FRAME
        self._cmd_vel_publisher.publish(stamped)

    def destroy_node(self):
        """Stop the robot (a zero Twist, acknowledged if possible), then destroy the node."""
        if self.context.ok():
            self._publish(LineFollowingController.stop_command())
            self._cmd_vel_publisher.wait_for_all_acked(STOP_ACK_TIMEOUT)
        return super().destroy_node()


def _raw_pixels(msg: Image) -> tuple:
    """Return a raw Image's pixels and their encoding."""
    return image_to_array(msg), msg.encoding


def main(args=None):
    """Run the follower until Ctrl-C."""
    run_node(FollowerNode, args)


if __name__ == '__main__':
    main()
