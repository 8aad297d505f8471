"""
The simulator node: the MuJoCo follow-bot world wired to ROS 2 topics.

Publishes the Kinect-style RGB camera, ``/clock`` and a ground-truth score on ``/diagnostics``;
obeys ``cmd_vel``. All physics, rendering and scoring live in :mod:`followbot_sim.world` and
:mod:`followbot_sim.course`; this node only turns them into parameters, topics and a timer.
"""

import math
import time

from builtin_interfaces.msg import Time
import cv2
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot.image_conversion import array_to_image
from followbot.node_runner import run_node
from followbot.parameters import declare_parameters, ParameterSpec
from followbot_sim.course import COURSES, LapTracker, make_course
from followbot_sim.diff_drive import (CommandWatchdog, DiffDriveLimits,
                                      KOBUKI_COMMAND_TIMEOUT_S,
                                      KOBUKI_MAX_ANGULAR_SPEED_RADPS,
                                      KOBUKI_MAX_LINEAR_SPEED_MPS, TIME_EPSILON_S)
from followbot_sim.world import (DEFAULT_CAMERA_PITCH_DEG, DEFAULT_HORIZONTAL_FOV_DEG,
                                 FollowbotWorld, RenderingUnavailableError)
from geometry_msgs.msg import Twist
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

CAMERA_FRAME = 'camera_rgb_optical_frame'
WORLD_FRAME = 'world'
SCORE_STATUS_NAME = 'followbot_sim: course score'
SIMULATOR_PARAMETERS = {
    'course': ParameterSpec(
        'book_loop', 'Built-in course to load: ' + ', '.join(sorted(COURSES)) + '.',
        read_only=True),
    'real_time_factor': ParameterSpec(
        1.0, 'Simulated seconds per wall second; 0 runs as fast as possible.', 0.0, 100.0),
    'camera_rate_hz': ParameterSpec(20.0, 'Camera frames per simulated second.', 1.0, 60.0),
    'clock_rate_hz': ParameterSpec(
        100.0, 'Rate of /clock and of cmd_vel sampling, per simulated second.', 20.0, 1000.0),
    'image_width_px': ParameterSpec(640, 'Camera image width.', 16, 1280, read_only=True),
    'image_height_px': ParameterSpec(480, 'Camera image height.', 16, 1280, read_only=True),
    'horizontal_fov_deg': ParameterSpec(
        DEFAULT_HORIZONTAL_FOV_DEG, 'Camera horizontal field of view (Kinect: 60).', 10.0,
        150.0, read_only=True),
    'camera_pitch_deg': ParameterSpec(
        DEFAULT_CAMERA_PITCH_DEG, 'Downward tilt of the camera from level (the book: 0).',
        -30.0, 80.0, read_only=True),
    'command_timeout_s': ParameterSpec(
        KOBUKI_COMMAND_TIMEOUT_S, 'Wheels stop when no cmd_vel came for this long (simulated '
        'time).', 0.05, 10.0),
    'max_linear_speed_mps': ParameterSpec(
        KOBUKI_MAX_LINEAR_SPEED_MPS, 'Kobuki top speed; faster commands are limited.', 0.01,
        2.0, read_only=True),
    'max_angular_speed_radps': ParameterSpec(
        KOBUKI_MAX_ANGULAR_SPEED_RADPS, 'Kobuki top yaw rate; faster commands are limited.',
        0.01, 10.0, read_only=True),
    'score_period_s': ParameterSpec(
        1.0, 'Period of the ground-truth score on /diagnostics (simulated time).', 0.05, 60.0),
    'overview_period_s': ParameterSpec(
        1.0, 'Period of the top-down overview image, rendered only while someone subscribes '
        '(simulated time).', 0.05, 60.0),
    'overview_size_px': ParameterSpec(800, 'Side of the overview image.', 64, 1280),
    'run_duration_s': ParameterSpec(
        0.0, 'Stop the simulator after this much simulated time; 0 runs on.', 0.0, 1e6),
}
# Longest a timer callback may spend catching up with the wall clock before it lets the
# executor serve cmd_vel again.
MAX_CATCH_UP_WALL_S = 0.1
# Fall this far behind the requested real-time factor and the pacing restarts from now
# instead of fast-forwarding through the backlog.
MAX_PACING_LAG_S = 0.5
TRAIL_SPACING_M = 0.01


def _reached(time_s: float, target_s: float) -> bool:
    """Tell whether simulated time has reached a target, allowing for step-sum float drift."""
    return time_s + TIME_EPSILON_S >= target_s


def _stamp(time_s: float) -> Time:
    nanoseconds = round(time_s * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


class SimulatorNode(Node):
    """A TurtleBot 2 with a Kinect on a line course, simulated in MuJoCo."""

    def __init__(self, **kwargs):
        """
        Declare the parameters, build the world and start the simulation timer.

        :param kwargs: forwarded to :class:`rclpy.node.Node` (``context``,
            ``parameter_overrides``, ...).
        """
        super().__init__('followbot_sim', **kwargs)
        parameters = declare_parameters(self, SIMULATOR_PARAMETERS)
        self._real_time_factor = parameters['real_time_factor']
        self._score_period_s = parameters['score_period_s']
        self._overview_period_s = parameters['overview_period_s']
        self._overview_size_px = parameters['overview_size_px']
        self._run_duration_s = parameters['run_duration_s']
        camera_rate_hz = parameters['camera_rate_hz']
        image_width_px = parameters['image_width_px']
        image_height_px = parameters['image_height_px']

        course = make_course(parameters['course'])
        limits = DiffDriveLimits(
            max_linear_speed_mps=parameters['max_linear_speed_mps'],
            max_angular_speed_radps=parameters['max_angular_speed_radps'])
        self._world = FollowbotWorld(
            course, image_width_px, image_height_px, parameters['horizontal_fov_deg'],
            parameters['camera_pitch_deg'], limits=limits)
        self._watchdog = CommandWatchdog(parameters['command_timeout_s'])
        self._lap_tracker = LapTracker(course)
        self._trail_xy = []
        self._tick_s = 1.0 / parameters['clock_rate_hz']
        self._frame_period_s = 1.0 / camera_rate_hz
        self._next_frame_s = self._frame_period_s
        self._next_score_s = self._score_period_s
        self._next_overview_s = 0.0
        self._laps_reported = 0
        self._finished = False
        self._bgr_frame = np.empty((image_height_px, image_width_px, 3), np.uint8)
        self._image_msg = Image()
        self._image_msg.header.frame_id = CAMERA_FRAME
        self._camera_info_msg = self._make_camera_info()
        # Render once now: a machine that cannot render says so at start-up, and the GL
        # context is made on this thread, the one that spins the node.
        self._world.render_camera()

        # REP-2003: sensor publishers are reliable; subscribers pick best effort if they like.
        self._image_publisher = self.create_publisher(Image, 'camera/rgb/image_raw', 10)
        self._camera_info_publisher = self.create_publisher(
            CameraInfo, 'camera/rgb/camera_info', 10)
        self._clock_publisher = self.create_publisher(ClockMsg, '/clock', QoSProfile(depth=10))
        self._diagnostics_publisher = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._overview_publisher = self.create_publisher(Image, 'overview/image', 1)
        self._cmd_vel_subscription = self.create_subscription(
            Twist, 'cmd_vel', self.cmd_vel_callback, 10)

        # Pacing runs on the wall clock: this node is the source of simulated time.
        self._wall_clock = Clock(clock_type=ClockType.STEADY_TIME)
        timer_period_s = 0.0 if self._real_time_factor == 0.0 else (
            self._tick_s / self._real_time_factor)
        self._pacing_origin = None
        self._timer = self.create_timer(timer_period_s, self.timer_callback,
                                        clock=self._wall_clock)
        width_px, height_px = self._world.image_size_px
        pace = (f'real-time factor {self._real_time_factor:g}' if self._real_time_factor
                else 'as fast as possible')
        self.get_logger().info(
            f"Simulating course '{course.name}' ({course.length_m:.1f} m) with a "
            f'{width_px}x{height_px} camera at {camera_rate_hz:g} Hz, {pace}.')

    @property
    def world(self) -> FollowbotWorld:
        """Return the simulated world, the ground truth for tests and tools."""
        return self._world

    @property
    def lap_tracker(self) -> LapTracker:
        """Return the ground-truth score of the robot on the course."""
        return self._lap_tracker

    @property
    def finished(self) -> bool:
        """Return whether ``run_duration_s`` of simulated time has passed."""
        return self._finished

    def _make_camera_info(self) -> CameraInfo:
        fx_px, fy_px, cx_px, cy_px = self._world.camera_intrinsics()
        width_px, height_px = self._world.image_size_px
        info = CameraInfo()
        info.header.frame_id = CAMERA_FRAME
        info.width = width_px
        info.height = height_px
        info.distortion_model = 'plumb_bob'
        info.d = [0.0] * 5
        info.k = [fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [fx_px, 0.0, cx_px, 0.0, 0.0, fy_px, cy_px, 0.0, 0.0, 0.0, 1.0, 0.0]
        return info

    def cmd_vel_callback(self, msg: Twist) -> None:
        """Take a velocity command; a non-finite one is refused and the robot keeps its last."""
        linear_mps, angular_radps = msg.linear.x, msg.angular.z
        if not (math.isfinite(linear_mps) and math.isfinite(angular_radps)):
            self.get_logger().error(
                f'Ignoring cmd_vel with non-finite speeds (linear.x={linear_mps}, '
                f'angular.z={angular_radps}).', throttle_duration_sec=5.0)
            return
        self._watchdog.command(linear_mps, angular_radps, self._world.time_s)

    def timer_callback(self) -> None:
        """Advance the simulation: one tick, or as many as the real-time factor asks for."""
        if self._finished:
            return
        if self._real_time_factor == 0.0:
            self._tick()
            return
        if self._pacing_origin is None:
            # Pace from the end of the first tick: it includes the renderer's start-up.
            self._tick()
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
        deadline_s = now_s + MAX_CATCH_UP_WALL_S
        while (self._world.time_s + self._tick_s / 2.0 < target_sim_s and not self._finished
               and time.monotonic() < deadline_s):
            self._tick()

    def _tick(self) -> None:
        world = self._world
        world.set_twist(*self._watchdog.current(world.time_s))
        world.step(self._tick_s)
        time_s = world.time_s
        x_m, y_m, _ = world.robot_pose()
        self._lap_tracker.update(x_m, y_m, time_s)
        self._record_trail(x_m, y_m)
        stamp = _stamp(time_s)
        self._clock_publisher.publish(ClockMsg(clock=stamp))
        if _reached(time_s, self._next_frame_s):
            self._next_frame_s += self._frame_period_s
            self._publish_camera(stamp)
        if _reached(time_s, self._next_overview_s):
            self._next_overview_s += self._overview_period_s
            if self._overview_publisher.get_subscription_count() > 0:
                self._publish_overview(stamp)
        self._report_laps()
        score_due = _reached(time_s, self._next_score_s)
        if score_due:
            self._next_score_s += self._score_period_s
        finishing = self._run_duration_s > 0.0 and _reached(time_s, self._run_duration_s)
        if score_due or finishing:
            self._publish_score(stamp)
        if finishing:
            self._finished = True
            summary = self._lap_tracker.summary()
            self.get_logger().info(
                f"Run of {time_s:.1f} s simulated time done: {summary['laps_completed']} laps, "
                f"cross-track RMS {100 * summary['rms_distance_from_line_m']:.1f} cm, "
                f"max {100 * summary['max_distance_from_line_m']:.1f} cm.")

    def _record_trail(self, x_m: float, y_m: float) -> None:
        # Every tick would store 100 points a second for as long as the run lasts; a point a
        # centimetre draws the same path in the overview.
        if self._trail_xy:
            last_x_m, last_y_m = self._trail_xy[-1]
            if math.hypot(x_m - last_x_m, y_m - last_y_m) < TRAIL_SPACING_M:
                return
        self._trail_xy.append((x_m, y_m))

    def _publish_camera(self, stamp: Time) -> None:
        rgb = self._world.render_camera()
        cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR, dst=self._bgr_frame)
        msg = array_to_image(self._bgr_frame, 'bgr8', self._image_msg)
        msg.header.stamp = stamp
        self._camera_info_msg.header.stamp = stamp
        self._image_publisher.publish(msg)
        self._camera_info_publisher.publish(self._camera_info_msg)

    def _publish_overview(self, stamp: Time) -> None:
        size_px = self._overview_size_px
        rgb = self._world.render_overview(size_px)
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        if len(self._trail_xy) > 1:
            trail_px = self._world.overview_pixels(np.asarray(self._trail_xy), size_px)
            cv2.polylines(bgr, [np.round(trail_px).astype(np.int32)], isClosed=False,
                          color=(0, 0, 255), thickness=2, lineType=cv2.LINE_AA)
        msg = array_to_image(bgr, 'bgr8')
        msg.header.stamp = stamp
        msg.header.frame_id = WORLD_FRAME
        self._overview_publisher.publish(msg)

    def _report_laps(self) -> None:
        lap_times_s = self._lap_tracker.lap_times_s
        while self._laps_reported < len(lap_times_s):
            self._laps_reported += 1
            self.get_logger().info(
                f'Lap {self._laps_reported} completed in '
                f'{lap_times_s[self._laps_reported - 1]:.1f} s (simulated time).')

    def _publish_score(self, stamp: Time) -> None:
        summary = self._lap_tracker.summary()
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name=SCORE_STATUS_NAME, hardware_id='followbot_sim',
            message=f"{summary['laps_completed']} laps, "
                    f'{100 * self._lap_tracker.distance_from_line_m:.1f} cm from the line')
        status.values = [KeyValue(key=key, value=str(value)) for key, value in summary.items()]
        self._diagnostics_publisher.publish(DiagnosticArray(
            header=Header(stamp=stamp, frame_id=WORLD_FRAME), status=[status]))

    def destroy_node(self):
        """Release the renderer's OpenGL context, then the node."""
        self._world.close()
        return super().destroy_node()


def main(args=None):
    """Run the simulator until Ctrl-C or until ``run_duration_s`` of simulated time."""
    run_node(SimulatorNode, args, startup_errors=(RenderingUnavailableError,))


if __name__ == '__main__':
    main()
