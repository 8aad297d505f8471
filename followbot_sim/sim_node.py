"""
The simulator node: the MuJoCo follow-bot world wired to ROS 2 topics, services and time.

Publishes the Kinect-style camera (RGB, depth, point cloud and their camera_info), wheel odometry,
joint states, the robot's transforms, ``/clock`` and a ground-truth score; obeys ``cmd_vel``;
serves pause, step and reset. Physics, rendering, odometry and scoring live in the pure modules
(:mod:`followbot_sim.world`, :mod:`followbot_sim.course`, :mod:`followbot_sim.odometry`);
messages are built in :mod:`followbot.messages`. This node only turns them into parameters,
topics, services and a timer.
"""

import dataclasses
import math
import time

from builtin_interfaces.msg import Time
import cv2
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot import frames
from followbot import messages
from followbot.compressed_image import array_to_compressed
from followbot.image_conversion import (array_to_image, BYTE_DTYPE, dtype_of, from_rgb,
                                        message_pixels, SUPPORTED_ENCODINGS)
from followbot.node_runner import run_node
from followbot.parameters import declare_parameters, ParameterSpec
from followbot_sim.course import LapTracker
from followbot_sim.course_file import course_file_realism, load_course
from followbot_sim.depth import depth_to_points
from followbot_sim.diff_drive import (CommandWatchdog, DiffDriveLimits, KOBUKI_COMMAND_TIMEOUT_S,
                                      KOBUKI_MAX_ANGULAR_SPEED_RADPS, KOBUKI_MAX_LINEAR_SPEED_MPS,
                                      TIME_EPSILON_S)
from followbot_sim.odometry import WheelOdometry
from followbot_sim.realism import CLEAN, PRESET_NAMES, realise
from followbot_sim.robots import (DEFAULT_ROBOT_SPACING_M, MAX_ROBOTS, MIN_ROBOT_SPACING_M,
                                  robot_names, robot_prefix)
from followbot_sim.score import robot_simulator_name, score_status_name, SIMULATOR_NODE
from followbot_sim.steady_condition import MATCH_SETTLE_S, SteadyCondition
from followbot_sim.trail import Trail
from followbot_sim.world import (DEFAULT_CAMERA_PITCH_DEG, DEFAULT_HORIZONTAL_FOV_DEG,
                                 FollowbotWorld, LEFT_WHEEL_JOINT, RenderingUnavailableError,
                                 RIGHT_WHEEL_JOINT, ViewerUnavailableError)
from geometry_msgs.msg import Point32, PolygonStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, JointState, PointCloud2
from std_msgs.msg import Header
from std_srvs.srv import SetBool, Trigger

try:
    from tf2_msgs.msg import TFMessage
except ImportError:  # Not on PyPI: make setup builds config/tf2_msgs; ROS 2 installs have it.
    TFMessage = None

# One call of the step service advances at most this many physics steps (10 s simulated, a few
# seconds of wall time with the camera): the node answers nothing else meanwhile.
MAX_STEP_PHYSICS_STEPS = 5000
# Every 8-bit encoding a camera sends: what the follower must take from a real one.
IMAGE_ENCODINGS = tuple(encoding for encoding in SUPPORTED_ENCODINGS
                        if dtype_of(encoding) == BYTE_DTYPE)
COMPRESSED_SUFFIX = '/compressed'
SIMULATOR_PARAMETERS = {
    'robots': ParameterSpec(
        1, f'Robots in the world: a count (1..{MAX_ROBOTS}; 1 is the single robot with plain '
        'topic and frame names, N > 1 names them r1..rN) or a list of names such as [r1,r2]. '
        "A named robot's topics and /tf frames are prefixed with its name (r1/cmd_vel, "
        'r1/base_footprint); /clock, /diagnostics, overview/image and the services are shared.',
        read_only=True, dynamic_typing=True),
    'robot_spacing_m': ParameterSpec(
        DEFAULT_ROBOT_SPACING_M, 'Robots start one behind the other along the line, this far '
        'apart (centre to centre).', MIN_ROBOT_SPACING_M, 10.0, read_only=True),
    'course': ParameterSpec(
        'book_loop', 'Course to load: a built-in name (see the README) or the path of a YAML '
        'course file.', read_only=True),
    'start_lateral_offset_m': ParameterSpec(
        0.0, 'Robots start this far left of the line at their starts (negative: right), as '
        'if put down by hand: how much a run depends on exactly where it starts.', -0.25,
        0.25, read_only=True),
    'start_heading_offset_deg': ParameterSpec(
        0.0, "Robots start turned this far left of the line's direction (negative: right).",
        -45.0, 45.0, read_only=True),
    'lighting_zones': ParameterSpec(
        False, 'Add bright and dim zones along the line of the course.', read_only=True),
    'camera_noise_stddev_levels': ParameterSpec(
        0.0, 'Standard deviation of Gaussian noise added to every RGB pixel, in 8-bit '
        'intensity levels; 0 for a clean camera.', 0.0, 64.0, read_only=True),
    'random_seed': ParameterSpec(
        0, 'Seed of the camera noise: the same seed and inputs give the same run.', 0,
        2 ** 31 - 1, read_only=True),
    'realism': ParameterSpec(
        '', 'How real the world and camera look: ' + ', '.join(PRESET_NAMES) + ' (see '
        "docs); empty takes the course file's realism.preset, else clean.", read_only=True),
    'realism_seed': ParameterSpec(
        -1, 'Seed of the realistic world (floor, tape, lights, clutter, camera noise): the '
        "same seed gives the same frames; -1 takes the course file's realism.seed, else 0.",
        -1, 2 ** 31 - 1, read_only=True),
    'real_time_factor': ParameterSpec(
        1.0, 'Simulated seconds per wall second; 0 runs as fast as possible.', 0.0, 100.0),
    'lockstep': ParameterSpec(
        False, 'Let the follower drive time: after each camera frame, wait for the cmd_vel '
        'that answers it before simulating on, and hold time while no node subscribes to the '
        'camera or publishes cmd_vel. Runs then give the same trajectory on any machine, '
        'under any load.', read_only=True),
    'lockstep_timeout_s': ParameterSpec(
        1.0, 'Lockstep: longest wait (wall time) for the command answering a camera frame; '
        'after it the robot drives on with its last command.', 0.01, 60.0, read_only=True),
    'lockstep_settle_s': ParameterSpec(
        MATCH_SETTLE_S, 'Lockstep: how long (wall time) a follower must have been connected '
        'before time runs, so that its cmd_vel publisher has matched this node too and the '
        'answer to the first frame is not lost.', 0.0, 10.0, read_only=True),
    'start_paused': ParameterSpec(
        False, 'Start paused: time advances only through the step service until unpaused.',
        read_only=True),
    'step_physics_steps': ParameterSpec(
        1, 'Physics steps (2 ms each) that one call of the step service advances (at most '
        '10 s of simulated time: the node serves nothing else while it steps).', 1,
        MAX_STEP_PHYSICS_STEPS),
    'camera_rate_hz': ParameterSpec(
        20.0, 'Camera frames (RGB and depth) per simulated second.', 1.0, 60.0, read_only=True),
    'clock_rate_hz': ParameterSpec(
        100.0, 'Rate of /clock and of the ground-truth score updates, per simulated second.',
        20.0, 500.0, read_only=True),
    'odom_rate_hz': ParameterSpec(
        50.0, 'Rate of odom, joint_states, ground_truth/odom and /tf, per simulated second.',
        1.0, 500.0, read_only=True),
    'image_width_px': ParameterSpec(640, 'Camera image width.', 16, 1280, read_only=True),
    'image_height_px': ParameterSpec(480, 'Camera image height.', 16, 1280, read_only=True),
    'image_encoding': ParameterSpec(
        'bgr8', "Encoding of camera/rgb/image_raw: bgr8 (as the book's Gazebo Kinect), or "
        'any a real camera sends: ' + ', '.join(
            encoding for encoding in IMAGE_ENCODINGS if encoding != 'bgr8') + '.',
        read_only=True),
    'jpeg_quality': ParameterSpec(
        95, 'JPEG quality of camera/rgb/image_raw/compressed (sensor_msgs/CompressedImage, '
        "as image_transport's compressed plugin publishes it; encoded only while someone "
        'subscribes).', 1, 100),
    'rgb_enabled': ParameterSpec(
        True, 'Publish camera/rgb/image_raw and camera/rgb/camera_info.', read_only=True),
    'depth_enabled': ParameterSpec(
        True, 'Publish camera/depth/image_raw and camera/depth/camera_info.', read_only=True),
    'point_cloud_enabled': ParameterSpec(
        True, 'Publish camera/depth/points.', read_only=True),
    'line_truth_row_step_px': ParameterSpec(
        10, 'Rows between the ground-truth samples of camera/rgb/line_truth (from row 0); '
        'published only while someone subscribes.', 1, 1280, read_only=True),
    'horizontal_fov_deg': ParameterSpec(
        DEFAULT_HORIZONTAL_FOV_DEG, 'Camera horizontal field of view (Kinect: 60).', 10.0,
        150.0, read_only=True),
    'camera_pitch_deg': ParameterSpec(
        DEFAULT_CAMERA_PITCH_DEG, 'Downward tilt of the Kinect from level (the book: 0).',
        -30.0, 80.0, read_only=True),
    'command_timeout_s': ParameterSpec(
        KOBUKI_COMMAND_TIMEOUT_S, 'Wheels stop when no cmd_vel came for this long (simulated '
        'time).', 0.05, 10.0, read_only=True),
    'cmd_vel_stamped': ParameterSpec(
        False, 'Take cmd_vel as geometry_msgs/TwistStamped instead of Twist.', read_only=True),
    'max_linear_speed_mps': ParameterSpec(
        KOBUKI_MAX_LINEAR_SPEED_MPS, 'Kobuki top speed; faster commands are limited.', 0.01,
        2.0, read_only=True),
    'max_angular_speed_radps': ParameterSpec(
        KOBUKI_MAX_ANGULAR_SPEED_RADPS, 'Kobuki top yaw rate; faster commands are limited.',
        0.01, 10.0, read_only=True),
    'publish_tf': ParameterSpec(
        True, "Publish odom -> base_footprint on /tf and the robot's fixed frames on "
        '/tf_static (needs tf2_msgs).', read_only=True),
    'score_period_s': ParameterSpec(
        1.0, 'Period of the ground-truth score on /diagnostics (simulated time).', 0.05, 60.0,
        read_only=True),
    'overview_period_s': ParameterSpec(
        1.0, 'Period of the top-down overview image, rendered only while someone subscribes '
        '(simulated time).', 0.05, 60.0, read_only=True),
    'overview_size_px': ParameterSpec(800, 'Side of the overview image.', 64, 1280),
    'run_duration_s': ParameterSpec(
        0.0, 'Stop the simulator after this much simulated time; 0 runs on.', 0.0, 1e6),
    'viewer': ParameterSpec(
        False, "Open MuJoCo's interactive viewer (needs a display).", read_only=True),
}
# Longest a timer callback may spend catching up with the wall clock before it lets the
# executor serve cmd_vel and services again.
MAX_CATCH_UP_WALL_S = 0.1
# Fall this far behind the requested real-time factor and the pacing restarts from now
# instead of fast-forwarding through the backlog.
MAX_PACING_LAG_S = 0.5
# How often the node looks for cmd_vel publishers of the other message type (wall time).
CMD_VEL_TYPE_CHECK_PERIOD_S = 2.0
# Lockstep: how often a held simulator looks for its follower (wall time).
LOCKSTEP_PARTNER_CHECK_PERIOD_S = 0.05
TWIST_TYPES = {False: 'geometry_msgs/msg/Twist', True: 'geometry_msgs/msg/TwistStamped'}
WHEEL_JOINTS = (LEFT_WHEEL_JOINT, RIGHT_WHEEL_JOINT)
# Longest the simulator waits (wall time) at exit for reliable subscribers to acknowledge what
# it published: a lagging recorder then still gets the last frames.
FINAL_DELIVERY_TIMEOUT_S = 3.0
# Static transforms are latched: late subscribers (RViz, tf2 listeners) still get them.
TF_STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# The overview draws each robot's trail in its own colour (BGR): red, blue, green, magenta...
TRAIL_COLOURS_BGR = ((0, 0, 255), (255, 0, 0), (0, 160, 0), (255, 0, 255), (0, 140, 255),
                     (255, 255, 0), (0, 0, 128), (128, 0, 128))
LINE_TRUTH_TOPIC = 'camera/rgb/line_truth'


def fill_line_truth_polygon(msg: PolygonStamped, truth) -> PolygonStamped:
    """
    Write a frame's line truth into a PolygonStamped, the layout of ``camera/rgb/line_truth``.

    One point per stretch of a sampled row that the paint covers: x = its middle column and
    y = row in pixels of the RGB image (pixel centres at integers), z = its length in pixels
    (> 0). A sampled row where the line is not seen gets one point x = NaN, y = row, z = 0.

    :param msg: the message to fill (its header is left alone).
    :param truth: the frame's :class:`followbot_sim.line_truth.LineTruth`.
    :return: the message.
    """
    points = []
    for row_px, crossings in zip(truth.rows_px, truth.crossings):
        if len(crossings) == 0:
            points.append(Point32(x=math.nan, y=float(row_px), z=0.0))
        for column_px, width_px in crossings:
            points.append(Point32(x=float(column_px), y=float(row_px), z=float(width_px)))
    msg.polygon.points = points
    return msg


def _reached(time_s: float, target_s: float) -> bool:
    """Tell whether simulated time has reached a target, allowing for step-sum float drift."""
    return time_s + TIME_EPSILON_S >= target_s


def _steps_to(time_s: float, event_s: float, timestep_s: float) -> int:
    """Return how many physics steps from ``time_s`` first reach ``event_s`` (at least one)."""
    # Events lie on the step grid up to float drift: the tolerance keeps k steps from becoming
    # k + 1 when k * timestep_s sums to a hair above the event.
    return max(1, math.ceil((event_s - time_s) / timestep_s - 1e-6))


class _Robot:
    """One simulated robot's command, scoring and odometry state, its topics and messages."""

    def __init__(self, index: int, name: str, command_timeout_s: float, course,
                 limits: DiffDriveLimits):
        self.index = index
        self.name = name
        # Topics are relative to the node's namespace; frames are global names on /tf.
        self.prefix = robot_prefix(name)
        self.watchdog = CommandWatchdog(command_timeout_s)
        self.lap_tracker = LapTracker(course)
        self.odometry = WheelOdometry(limits.wheel_radius_m, limits.wheel_separation_m)
        self.trail = Trail()
        self.laps_reported = 0
        self.commands_received = 0
        self.awaiting_command = False
        self.image_publisher = self.compressed_publisher = self.camera_info_publisher = None
        self.line_truth_publisher = self.line_truth_msg = None
        self.depth_publisher = self.depth_info_publisher = self.points_publisher = None

    def frame(self, frame_id: str) -> str:
        """Return the robot's own name of one of its frames (``r1/odom``, or ``odom``)."""
        return self.prefix + frame_id

    def log_prefix(self) -> str:
        """Return what starts the robot's log lines: nothing for the single robot."""
        return f'{self.name}: ' if self.name else ''


@dataclasses.dataclass
class _Periodic:
    """Something the simulator does every ``period_s`` of simulated time."""

    period_s: float
    action: object
    next_s: float = None

    def __post_init__(self):
        if self.next_s is None:
            self.next_s = self.period_s

    def run_if_due(self, time_s: float, stamp: Time) -> None:
        """Run the action, stamped, when its time has come."""
        if _reached(time_s, self.next_s):
            self.next_s += self.period_s
            self.action(stamp)


class SimulatorNode(Node):
    """A TurtleBot 2 with a Kinect on a line course, simulated in MuJoCo."""

    NODE_NAME = SIMULATOR_NODE

    def __init__(self, **kwargs):
        """
        Declare the parameters, build the world, the publishers and services, and start.

        :param kwargs: forwarded to :class:`rclpy.node.Node` (``context``,
            ``parameter_overrides``, ...).
        :raises ValueError: for a parameter value the simulator cannot use (unknown course,
            unreadable course file, unknown image encoding).
        """
        super().__init__(self.NODE_NAME, **kwargs)
        parameters = declare_parameters(self, SIMULATOR_PARAMETERS)
        self._real_time_factor = parameters['real_time_factor']
        self._overview_size_px = parameters['overview_size_px']
        self._run_duration_s = parameters['run_duration_s']
        self._image_encoding = parameters['image_encoding']
        if self._image_encoding not in IMAGE_ENCODINGS:
            raise ValueError(f'image_encoding must be one of {", ".join(IMAGE_ENCODINGS)}, '
                             f'got {self._image_encoding!r}.')
        camera_rate_hz = parameters['camera_rate_hz']
        names = robot_names(parameters['robots'])

        course = load_course(parameters['course'], lighting=parameters['lighting_zones'])
        realism = realise(*self._realism_choice(parameters))
        limits = DiffDriveLimits(
            max_linear_speed_mps=parameters['max_linear_speed_mps'],
            max_angular_speed_radps=parameters['max_angular_speed_radps'])
        self._world = FollowbotWorld(
            course, parameters['image_width_px'], parameters['image_height_px'],
            parameters['horizontal_fov_deg'], parameters['camera_pitch_deg'], limits=limits,
            camera_noise_stddev=parameters['camera_noise_stddev_levels'],
            noise_seed=parameters['random_seed'], robot_names=names,
            robot_spacing_m=parameters['robot_spacing_m'], realism=realism,
            start_lateral_offset_m=parameters['start_lateral_offset_m'],
            start_heading_offset_deg=parameters['start_heading_offset_deg'])
        self._robots = [_Robot(index, name, parameters['command_timeout_s'], course, limits)
                        for index, name in enumerate(names)]
        for robot in self._robots:
            robot.odometry.update(*self._world.wheel_angles(robot.index), self._world.time_s)
        self._last_score_stamp = None
        self._finished = False
        self._paused = parameters['start_paused']
        self._lockstep = parameters['lockstep']
        self._lockstep_timeouts = 0
        self._partner_connected = SteadyCondition(parameters['lockstep_settle_s'])
        self._holding_for_partner = False
        # Render once now: a machine that cannot render says so at start-up, and the GL
        # context is made on this thread, the one that spins the node.
        self._world.render_camera()
        self._open_viewer(parameters['viewer'])

        self._make_publishers(parameters)
        self._cmd_vel_stamped = parameters['cmd_vel_stamped']
        for robot in self._robots:
            self._make_cmd_vel_subscription(robot)
        self._pause_service = self.create_service(SetBool, '~/pause', self.pause_callback)
        self._step_service = self.create_service(Trigger, '~/step', self.step_callback)
        self._reset_service = self.create_service(Trigger, '~/reset', self.reset_callback)

        tick_s = 1.0 / parameters['clock_rate_hz']
        self._schedule = [
            # /clock first: a subscriber on simulated time then knows the time of what follows.
            _Periodic(tick_s, self._publish_clock_and_score_pose),
            _Periodic(1.0 / parameters['odom_rate_hz'], self._publish_robot_state),
            _Periodic(1.0 / camera_rate_hz, self._publish_cameras),
            _Periodic(parameters['overview_period_s'], self._publish_overview, next_s=0.0),
            _Periodic(parameters['score_period_s'], self._publish_score),
        ]
        self._tick_s = tick_s
        # As fast as possible in lockstep, time stops at each camera frame for its answer
        # anyway: one timer call runs up to the next frame, not one executor pass per tick.
        self._fast_step_s = (1.0 / camera_rate_hz if parameters['lockstep'] else tick_s)

        # Pacing runs on the wall clock: this node is the source of simulated time.
        self._wall_clock = Clock(clock_type=ClockType.STEADY_TIME)
        timer_period_s = 0.0 if self._real_time_factor == 0.0 else (
            tick_s / self._real_time_factor)
        self._pacing_origin = None
        self._timer = self.create_timer(timer_period_s, self.timer_callback,
                                        clock=self._wall_clock)
        # Waits are timers that stay cancelled until needed: a waiting simulator sleeps in the
        # executor instead of spinning through a zero-period timer.
        self._lockstep_timeout_timer = self.create_timer(
            parameters['lockstep_timeout_s'], self.lockstep_timeout_callback,
            clock=self._wall_clock)
        self._lockstep_timeout_timer.cancel()
        self._partner_check_timer = self.create_timer(
            LOCKSTEP_PARTNER_CHECK_PERIOD_S, self.partner_check_callback,
            clock=self._wall_clock)
        self._partner_check_timer.cancel()
        if self._paused:
            self._timer.cancel()
        self._cmd_vel_type_timer = self.create_timer(
            CMD_VEL_TYPE_CHECK_PERIOD_S, self.cmd_vel_type_check_callback,
            clock=self._wall_clock)
        self._wrong_cmd_vel_types_reported = set()

        width_px, height_px = self._world.image_size_px
        pace = (f'real-time factor {self._real_time_factor:g}' if self._real_time_factor
                else 'as fast as possible')
        if self._lockstep:
            pace += ', in lockstep with the follower'
        robots = ('' if len(names) == 1 and not names[0] else
                  f"{len(names)} robots ({', '.join(names)}), each ")
        if realism.preset != CLEAN:
            pace += f', realism {realism.preset} (seed {realism.seed}, {realism.floor} floor)'
        self.get_logger().info(
            f"Simulating course '{course.name}' ({course.length_m:.1f} m) with {robots}a "
            f'{width_px}x{height_px} camera at {camera_rate_hz:g} Hz, {pace}'
            f"{', paused' if self._paused else ''}.")

    @staticmethod
    def _realism_choice(parameters: dict) -> tuple:
        """Return (preset, seed): the parameters, falling back on the course file's."""
        from_file = course_file_realism(parameters['course']) or (CLEAN, 0)
        preset = parameters['realism'] or from_file[0]
        seed = parameters['realism_seed'] if parameters['realism_seed'] >= 0 else from_file[1]
        return preset, seed

    def _open_viewer(self, wanted: bool) -> None:
        if not wanted:
            return
        try:
            self._world.open_viewer()
        except ViewerUnavailableError as error:
            self.get_logger().warn(f'{error} Running without the viewer.')

    def _make_publishers(self, parameters: dict) -> None:
        # REP-2003: sensor publishers are reliable; subscribers pick best effort if they like.
        self._line_truth_row_step_px = parameters['line_truth_row_step_px']
        for robot in self._robots:
            self._make_robot_publishers(robot, parameters)
        width_px, height_px = self._world.image_size_px
        self._points_xyz = np.empty((height_px, width_px, 3), np.float32)
        self._clock_publisher = self.create_publisher(ClockMsg, '/clock', QoSProfile(depth=10))
        self._diagnostics_publisher = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._overview_publisher = self.create_publisher(Image, 'overview/image', 1)
        self._tf_publisher = None
        if not parameters['publish_tf']:
            return
        if TFMessage is None:
            self.get_logger().warn(
                'tf2_msgs is not importable (it is not on PyPI), so /tf and /tf_static are not '
                'published; `make setup` builds it into the venv, and a ROS 2 Jazzy install has '
                'it. odom, joint_states and the camera topics are unaffected.')
            return
        self._tf_publisher = self.create_publisher(TFMessage, '/tf', 100)
        self._tf_static_publisher = self.create_publisher(TFMessage, '/tf_static', TF_STATIC_QOS)
        now = messages.stamp(self._world.time_s)
        self._tf_static_publisher.publish(TFMessage(transforms=[
            messages.transform_stamped(transform, now)
            for robot in self._robots for transform in self._world.sensor_frames(robot.index)]))

    def _make_robot_publishers(self, robot: _Robot, parameters: dict) -> None:
        intrinsics = self._world.camera_intrinsics()
        size_px = self._world.image_size_px
        topic = robot.prefix
        rgb_optical_frame = robot.frame(frames.CAMERA_RGB_OPTICAL_FRAME)
        depth_optical_frame = robot.frame(frames.CAMERA_DEPTH_OPTICAL_FRAME)
        rgb_intrinsics, rgb_distortion = self._world.published_camera_model()
        if parameters['rgb_enabled']:
            robot.line_truth_publisher = self.create_publisher(
                PolygonStamped, topic + LINE_TRUTH_TOPIC, 10)
            robot.line_truth_msg = PolygonStamped(header=Header(frame_id=rgb_optical_frame))
            robot.image_publisher = self.create_publisher(
                Image, topic + 'camera/rgb/image_raw', 10)
            robot.compressed_publisher = self.create_publisher(
                CompressedImage, robot.image_publisher.topic_name + COMPRESSED_SUFFIX, 10)
            robot.compressed_msg = CompressedImage(header=Header(frame_id=rgb_optical_frame))
            robot.camera_info_publisher = self.create_publisher(
                CameraInfo, topic + 'camera/rgb/camera_info', 10)
        if parameters['depth_enabled']:
            robot.depth_publisher = self.create_publisher(
                Image, topic + 'camera/depth/image_raw', 10)
            robot.depth_info_publisher = self.create_publisher(
                CameraInfo, topic + 'camera/depth/camera_info', 10)
        if parameters['point_cloud_enabled']:
            robot.points_publisher = self.create_publisher(
                PointCloud2, topic + 'camera/depth/points', 10)
        robot.image_msg = Image(header=Header(frame_id=rgb_optical_frame))
        robot.depth_msg = Image(header=Header(frame_id=depth_optical_frame))
        robot.points_msg = PointCloud2(header=Header(frame_id=depth_optical_frame))
        robot.rgb_info_msg = messages.camera_info(rgb_intrinsics, size_px, rgb_optical_frame)
        # A realistic camera's lens: the raw image is distorted, as camera_info says.
        robot.rgb_info_msg.d = [float(value) for value in rgb_distortion]
        robot.depth_info_msg = messages.camera_info(intrinsics, size_px, depth_optical_frame)
        robot.odom_publisher = self.create_publisher(Odometry, topic + 'odom', 10)
        robot.ground_truth_publisher = self.create_publisher(
            Odometry, topic + 'ground_truth/odom', 10)
        robot.joint_state_publisher = self.create_publisher(
            JointState, topic + 'joint_states', 10)
        base_footprint = robot.frame(frames.BASE_FOOTPRINT_FRAME)
        robot.odom_msg = Odometry(header=Header(frame_id=robot.frame(frames.ODOM_FRAME)),
                                  child_frame_id=base_footprint)
        robot.ground_truth_msg = Odometry(header=Header(frame_id=frames.WORLD_FRAME),
                                          child_frame_id=base_footprint)
        robot.joint_names = tuple(robot.frame(joint) for joint in WHEEL_JOINTS)
        # Scored as a single robot under the namespace <name> would be: one name either way.
        robot.score_name = robot_simulator_name(self.get_fully_qualified_name(), robot.name)

    def _make_cmd_vel_subscription(self, robot: _Robot) -> None:
        topic = robot.prefix + 'cmd_vel'
        if self._cmd_vel_stamped:
            robot.cmd_vel_subscription = self.create_subscription(
                TwistStamped, topic, lambda msg: self._take_command(robot, msg.twist), 10)
        else:
            robot.cmd_vel_subscription = self.create_subscription(
                Twist, topic, lambda msg: self._take_command(robot, msg), 10)

    @property
    def world(self) -> FollowbotWorld:
        """Return the simulated world, the ground truth for tests and tools."""
        return self._world

    @property
    def robot_names(self) -> tuple[str, ...]:
        """Return the robots' names (``('',)`` for the single, unnamed robot)."""
        return self._world.robot_names

    @property
    def lap_tracker(self) -> LapTracker:
        """Return the ground-truth score of the (first) robot on the course."""
        return self._robots[0].lap_tracker

    def lap_tracker_of(self, robot: int) -> LapTracker:
        """
        Return the ground-truth score of a robot on the course.

        :param robot: the robot's index in :attr:`robot_names`.
        :return: its lap tracker.
        """
        return self._robots[robot].lap_tracker

    @property
    def odometry(self) -> WheelOdometry:
        """Return the wheel odometry the node publishes on ``odom`` (the first robot's)."""
        return self._robots[0].odometry

    @property
    def finished(self) -> bool:
        """
        Return whether the run is over: ``run_duration_s`` of simulated time has passed.

        In lockstep the last frame's answer is awaited too (or its lockstep timeout), so that
        every frame of the run has its command, for the robot and for a recording alike.
        """
        return self._finished and not self._awaiting_command

    @property
    def commands_received(self) -> int:
        """Return how many valid velocity commands have arrived on cmd_vel (all robots')."""
        return sum(robot.commands_received for robot in self._robots)

    @property
    def _awaiting_command(self) -> bool:
        return any(robot.awaiting_command for robot in self._robots)

    @property
    def paused(self) -> bool:
        """Return whether time stands still until a step or an unpause."""
        return self._paused

    @property
    def lockstep_timeouts(self) -> int:
        """Return how many camera frames got no answering cmd_vel within the lockstep wait."""
        return self._lockstep_timeouts

    def _take_command(self, robot: _Robot, msg: Twist) -> None:
        """
        Take a robot's velocity command; a non-finite one is refused, the robot keeps its last.

        A stamped command's stamp is not used: its arrival time counts.
        """
        linear_mps, angular_radps = msg.linear.x, msg.angular.z
        if not (math.isfinite(linear_mps) and math.isfinite(angular_radps)):
            self.get_logger().error(
                f'Ignoring {robot.cmd_vel_subscription.topic_name} with non-finite speeds '
                f'(linear.x={linear_mps}, angular.z={angular_radps}).',
                throttle_duration_sec=5.0)
            return
        robot.watchdog.command(linear_mps, angular_radps, self._world.time_s)
        robot.commands_received += 1
        if robot.awaiting_command:
            robot.awaiting_command = False
            # Lockstep: time runs on once every robot answered its frame.
            if not self._awaiting_command:
                self._resume()

    def cmd_vel_type_check_callback(self) -> None:
        """Warn once per type when cmd_vel has publishers this node cannot hear."""
        expected = TWIST_TYPES[self._cmd_vel_stamped]
        for robot in self._robots:
            topic = robot.cmd_vel_subscription.topic_name
            for info in self.get_publishers_info_by_topic(topic):
                if info.topic_type == expected or info.topic_type in (
                        self._wrong_cmd_vel_types_reported):
                    continue
                self._wrong_cmd_vel_types_reported.add(info.topic_type)
                stamped = info.topic_type == TWIST_TYPES[True]
                self.get_logger().error(
                    f'{info.node_namespace.rstrip("/")}/{info.node_name} publishes {topic} as '
                    f'{info.topic_type}, but this simulator takes {expected}: those commands '
                    f'never arrive. Restart with -p cmd_vel_stamped:={str(stamped).lower()} '
                    'or change the publisher.')

    def pause_callback(self, request: SetBool.Request, response: SetBool.Response):
        """Pause (``data: true``) or resume (``data: false``) simulated time."""
        self._paused = bool(request.data)
        self._pacing_origin = None
        if self._paused:
            self._timer.cancel()
        else:
            self._timer.reset()
        response.success = True
        response.message = (f'Paused at {self._world.time_s:.3f} s.' if self._paused
                            else f'Running from {self._world.time_s:.3f} s.')
        return response

    def step_callback(self, request: Trigger.Request, response: Trigger.Response):
        """Advance a paused simulation by ``step_physics_steps`` physics steps."""
        if not self._paused:
            response.success = False
            response.message = 'Not paused: call pause with data: true before stepping.'
            return response
        if self._finished:
            response.success = False
            response.message = f'The run ended at run_duration_s = {self._run_duration_s:g} s.'
            return response
        steps = self.get_parameter('step_physics_steps').value
        # Stepping is the caller driving time: it does not stop for lockstep answers.
        self._stop_awaiting()
        self._lockstep_timeout_timer.cancel()
        self._advance_to(self._world.time_s + steps * self._world.timestep_s,
                         stop_for_commands=False)
        response.success = True
        response.message = f'Stepped to {self._world.time_s:.3f} s.'
        return response

    def reset_callback(self, request: Trigger.Request, response: Trigger.Response):
        """Put the robots back at their starts, at rest, and start the scores afresh."""
        self._world.reset_robot()
        for robot in self._robots:
            robot.watchdog.reset()
            robot.lap_tracker.reset()
            robot.odometry.reset()
            robot.odometry.update(*self._world.wheel_angles(robot.index), self._world.time_s)
            robot.trail.clear()
            robot.laps_reported = 0
        self._finished = False
        response.success = True
        who = 'Robot' if len(self._robots) == 1 else 'Robots'
        response.message = (f'{who} back at the start of {self._world.course.name} at '
                            f'{self._world.time_s:.3f} s; score, odometry and trail restarted.')
        self.get_logger().info(response.message)
        return response

    def timer_callback(self) -> None:
        """Advance the simulation as far as the real-time factor asks for."""
        if self._finished or self._paused or self._awaiting_command:
            return
        if self._lockstep and not self._partner_settled():
            self._hold_for_partner()
            return
        if self._real_time_factor == 0.0:
            self._advance_to(self._world.time_s + self._fast_step_s)
            return
        if self._pacing_origin is None:
            # Pace from the end of the first tick: it includes the renderer's start-up.
            self._advance_to(self._world.time_s + self._tick_s)
            self._pacing_origin = (time.monotonic(), self._world.time_s)
            return
        now_s = time.monotonic()
        origin_wall_s, origin_sim_s = self._pacing_origin
        target_sim_s = origin_sim_s + (now_s - origin_wall_s) * self._real_time_factor
        if target_sim_s - self._world.time_s > MAX_PACING_LAG_S * self._real_time_factor:
            self.get_logger().warn(
                f'The machine cannot keep up with real_time_factor {self._real_time_factor:g}; '
                'simulated time falls behind.', throttle_duration_sec=10.0)
            self._pacing_origin = (now_s, self._world.time_s)
            target_sim_s = self._world.time_s + self._tick_s
        self._advance_to(target_sim_s, deadline_s=now_s + MAX_CATCH_UP_WALL_S)

    def _partner_present(self) -> bool:
        """Tell whether every robot has its follower: a camera subscriber and a commander."""
        return all(self._robot_partner_present(robot) for robot in self._robots)

    def _partner_settled(self) -> bool:
        """Tell whether every follower has been there for lockstep_settle_s, heard both ways."""
        return self._partner_connected.update(self._partner_present())

    def _robot_partner_present(self, robot: _Robot) -> bool:
        return (robot.image_publisher is not None
                and (robot.image_publisher.get_subscription_count() > 0
                     or robot.compressed_publisher.get_subscription_count() > 0)
                and self.count_publishers(robot.cmd_vel_subscription.topic_name) > 0)

    def _hold_for_partner(self) -> None:
        self._timer.cancel()
        self._partner_check_timer.reset()
        if not self._holding_for_partner:
            self._holding_for_partner = True
            waiting_for = ', '.join(
                f'{robot.image_publisher.topic_name if robot.image_publisher else "the camera"}'
                f' and one publishes {robot.cmd_vel_subscription.topic_name}'
                for robot in self._robots if not self._robot_partner_present(robot))
            if not waiting_for:
                # Connected, settling for lockstep_settle_s: too short to be worth a line.
                return
            self.get_logger().info(
                f'Lockstep: holding time at {self._world.time_s:.3f} s until a node subscribes '
                f'to {waiting_for}.')

    def partner_check_callback(self) -> None:
        """Lockstep: let time run again once the follower has been there long enough."""
        if self._partner_settled():
            self._partner_check_timer.cancel()
            self._holding_for_partner = False
            self.get_logger().info('Lockstep: follower connected, time runs.')
            self._timer.reset()

    def lockstep_timeout_callback(self) -> None:
        """Lockstep: no command answered the last frame in time; drive on with the last one."""
        self._lockstep_timeouts += 1
        self.get_logger().warn(
            f'Lockstep: no cmd_vel answered the camera frame of {self._world.time_s:.3f} s '
            f'within lockstep_timeout_s; simulating on with the last command '
            f'({self._lockstep_timeouts} frames so far).', throttle_duration_sec=10.0)
        self._resume()

    def _await_command(self) -> None:
        self._timer.cancel()
        self._lockstep_timeout_timer.reset()

    def _stop_awaiting(self) -> None:
        for robot in self._robots:
            robot.awaiting_command = False

    def _resume(self) -> None:
        self._stop_awaiting()
        self._lockstep_timeout_timer.cancel()
        if not self._paused:
            self._timer.reset()

    def _advance_to(self, target_s: float, deadline_s: float = math.inf,
                    stop_for_commands: bool = True) -> None:
        world = self._world
        timestep_s = world.timestep_s
        half_step_s = timestep_s / 2.0
        while (world.time_s + half_step_s < target_s and not self._finished
               and not (stop_for_commands and self._awaiting_command)
               and time.monotonic() < deadline_s):
            # Run the physics in one call up to the next thing that happens: a publication,
            # the command going stale, the target. Nothing between changes the wheels' command,
            # so this equals stepping one by one, without Python between the steps.
            time_s = world.time_s
            next_event_s = min(periodic.next_s for periodic in self._schedule)
            for robot in self._robots:
                expires_at_s = robot.watchdog.expires_at_s()
                if expires_at_s > time_s + TIME_EPSILON_S:
                    next_event_s = min(next_event_s, expires_at_s)
            if self._run_duration_s > 0.0:
                next_event_s = min(next_event_s, self._run_duration_s)
            self._physics_steps(min(
                _steps_to(time_s, next_event_s, timestep_s),
                # The steps that keep time + half a step short of the target.
                max(1, math.ceil((target_s - time_s) / timestep_s - 0.5 - 1e-6))))

    def _physics_steps(self, steps: int) -> None:
        world = self._world
        for robot in self._robots:
            world.set_twist(*robot.watchdog.current(world.time_s), robot=robot.index)
        world.step(steps * world.timestep_s)
        world.sync_viewer()
        time_s = world.time_s
        stamp = messages.stamp(time_s)
        for periodic in self._schedule:
            periodic.run_if_due(time_s, stamp)
        self._report_laps()
        if self._run_duration_s > 0.0 and _reached(time_s, self._run_duration_s):
            self._finish(stamp)

    def _finish(self, stamp: Time) -> None:
        self._finished = True
        if self._last_score_stamp != stamp:
            self._publish_score(stamp)
        for robot in self._robots:
            summary = robot.lap_tracker.summary()
            self.get_logger().info(
                f'{robot.log_prefix()}Run of {self._world.time_s:.1f} s simulated time done: '
                f"{summary['laps_completed']} laps, cross-track RMS "
                f"{100 * summary['rms_distance_from_line_m']:.1f} cm, "
                f"max {100 * summary['max_distance_from_line_m']:.1f} cm.")

    def _publish_clock_and_score_pose(self, stamp: Time) -> None:
        self._clock_publisher.publish(ClockMsg(clock=stamp))
        for robot in self._robots:
            x_m, y_m, _ = self._world.robot_pose(robot.index)
            robot.lap_tracker.update(x_m, y_m, self._world.time_s)
            robot.trail.add(x_m, y_m)

    def _publish_robot_state(self, stamp: Time) -> None:
        world = self._world
        odom_transforms = []
        for robot in self._robots:
            wheel_angles_rad = world.wheel_angles(robot.index)
            robot.odometry.update(*wheel_angles_rad, world.time_s)
            robot.odom_msg.header.stamp = stamp
            robot.odom_publisher.publish(messages.fill_odometry(
                robot.odom_msg, robot.odometry.pose, robot.odometry.twist))
            robot.ground_truth_msg.header.stamp = stamp
            robot.ground_truth_publisher.publish(messages.fill_odometry(
                robot.ground_truth_msg, world.robot_pose(robot.index),
                world.robot_twist(robot.index), exact=True))
            robot.joint_state_publisher.publish(messages.joint_state(
                robot.joint_names, wheel_angles_rad, world.wheel_speeds(robot.index), stamp))
            odom_transforms.append(messages.transform_stamped(frames.FrameTransform.planar(
                robot.frame(frames.ODOM_FRAME), robot.frame(frames.BASE_FOOTPRINT_FRAME),
                *robot.odometry.pose), stamp))
        if self._tf_publisher is not None:
            self._tf_publisher.publish(TFMessage(transforms=odom_transforms))

    def _publish_cameras(self, stamp: Time) -> None:
        for robot in self._robots:
            self._publish_robot_cameras(robot, stamp)
        if self._awaiting_command:
            self._await_command()

    def _publish_robot_cameras(self, robot: _Robot, stamp: Time) -> None:
        if robot.image_publisher is not None:
            # camera_info first: a follower then knows the intrinsics when the image comes.
            robot.rgb_info_msg.header.stamp = stamp
            robot.camera_info_publisher.publish(robot.rgb_info_msg)
            raw_wanted = robot.image_publisher.get_subscription_count() > 0
            compressed_wanted = robot.compressed_publisher.get_subscription_count() > 0
            if robot.line_truth_publisher.get_subscription_count() > 0:
                # Before rendering: the truth is of the state the frame shows.
                fill_line_truth_polygon(robot.line_truth_msg, self._world.line_truth(
                    self._line_truth_row_step_px, robot=robot.index)).header.stamp = stamp
                robot.line_truth_publisher.publish(robot.line_truth_msg)
            if raw_wanted or compressed_wanted:
                self._publish_rgb(robot, stamp, raw_wanted, compressed_wanted)
                if self._lockstep and not self._paused and self._partner_present():
                    robot.awaiting_command = True
        depth_wanted = (robot.depth_publisher is not None
                        and robot.depth_publisher.get_subscription_count() > 0)
        points_wanted = (robot.points_publisher is not None
                         and robot.points_publisher.get_subscription_count() > 0)
        if depth_wanted or points_wanted:
            self._publish_depth(robot, stamp, depth_wanted, points_wanted)
        if robot.depth_info_publisher is not None:
            robot.depth_info_msg.header.stamp = stamp
            robot.depth_info_publisher.publish(robot.depth_info_msg)

    def _publish_rgb(self, robot: _Robot, stamp: Time, raw: bool = True,
                     compressed: bool = False) -> None:
        rgb = self._world.render_camera(robot.index)
        width_px, height_px = self._world.image_size_px
        if raw:
            # Converted straight into the message: no frame-sized copy of our own.
            from_rgb(rgb, self._image_encoding,
                     message_pixels(robot.image_msg, height_px, width_px,
                                    self._image_encoding))
            robot.image_msg.header.stamp = stamp
            robot.image_publisher.publish(robot.image_msg)
        if compressed:
            array_to_compressed(rgb, 'rgb8', jpeg_quality=self.get_parameter(
                'jpeg_quality').value, msg=robot.compressed_msg)
            robot.compressed_msg.header.stamp = stamp
            robot.compressed_publisher.publish(robot.compressed_msg)

    def _publish_depth(self, robot: _Robot, stamp: Time, depth_wanted: bool,
                       points_wanted: bool) -> None:
        # The first robot is the world's default one: a single robot's calls stay as they were.
        depth_m = self._world.render_depth(*([robot.index] if robot.index else []))
        if depth_wanted:
            msg = array_to_image(depth_m, '32FC1', robot.depth_msg)
            msg.header.stamp = stamp
            robot.depth_publisher.publish(msg)
        if points_wanted:
            depth_to_points(depth_m, *self._world.camera_intrinsics(), out=self._points_xyz)
            msg = messages.fill_point_cloud(self._points_xyz, robot.points_msg)
            msg.header.stamp = stamp
            robot.points_publisher.publish(msg)

    def _publish_overview(self, stamp: Time) -> None:
        if self._overview_publisher.get_subscription_count() == 0:
            return
        size_px = self._overview_size_px
        rgb = self._world.render_overview(size_px)
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        for robot in self._robots:
            if len(robot.trail) > 1:
                trail_px = self._world.overview_pixels(np.asarray(robot.trail.points), size_px)
                cv2.polylines(bgr, [np.round(trail_px).astype(np.int32)], isClosed=False,
                              color=TRAIL_COLOURS_BGR[robot.index % len(TRAIL_COLOURS_BGR)],
                              thickness=2, lineType=cv2.LINE_AA)
        msg = array_to_image(bgr, 'bgr8')
        msg.header.stamp = stamp
        msg.header.frame_id = frames.WORLD_FRAME
        self._overview_publisher.publish(msg)

    def _report_laps(self) -> None:
        for robot in self._robots:
            lap_times_s = robot.lap_tracker.lap_times_s
            while robot.laps_reported < len(lap_times_s):
                robot.laps_reported += 1
                self.get_logger().info(
                    f'{robot.log_prefix()}Lap {robot.laps_reported} completed in '
                    f'{lap_times_s[robot.laps_reported - 1]:.1f} s (simulated time).')

    def _publish_score(self, stamp: Time) -> None:
        self._last_score_stamp = stamp
        statuses = []
        for robot in self._robots:
            summary = robot.lap_tracker.summary()
            status = DiagnosticStatus(
                level=DiagnosticStatus.OK, name=score_status_name(robot.score_name),
                hardware_id=robot.score_name,
                message=f"{summary['laps_completed']} laps, "
                        f'{100 * robot.lap_tracker.distance_from_line_m:.1f} cm from the line')
            status.values = [KeyValue(key=key, value=str(value))
                             for key, value in summary.items()]
            statuses.append(status)
        self._diagnostics_publisher.publish(DiagnosticArray(
            header=Header(stamp=stamp, frame_id=frames.WORLD_FRAME), status=statuses))

    def destroy_node(self):
        """Let reliable subscribers have every message, release the renderer, then the node."""
        # A recorder that lags behind still gets the run's last frames and score: a process
        # that ends takes its unacknowledged messages with it.
        if self.context.ok():
            deadline_s = time.monotonic() + FINAL_DELIVERY_TIMEOUT_S
            for publisher in self.publishers:
                remaining_s = deadline_s - time.monotonic()
                if remaining_s <= 0.0:
                    break
                publisher.wait_for_all_acked(Duration(seconds=remaining_s))
        self._world.close()
        return super().destroy_node()


def main(args=None):
    """Run the simulator until Ctrl-C or until ``run_duration_s`` of simulated time."""
    run_node(SimulatorNode, args, startup_errors=(RenderingUnavailableError,))


if __name__ == '__main__':
    main()
