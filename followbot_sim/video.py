"""
A video of a run, in simulated time: the follower's view beside the course from above.

:class:`VideoNode` subscribes to the follower's debug image (the camera with its overlay, which
the follower draws only while someone subscribes), to the simulator's ground truth (the trail)
and to its score (the caption). It asks the simulator which course it runs and how fast its
camera is, draws the top-down view with :mod:`followbot_sim.topdown` and writes one video frame
per ``period_s`` of simulated time, stamped by the camera images, so a lockstep run at any
speed gives a video that plays at real speed. A period with no new camera frame repeats the
previous video frame (and the first frame stands in for the periods before it), so the video
lasts exactly as long as the run. A run can be faster than the video writes, and on a loaded
machine a debug image can be lost on the way and sent again only later: :class:`VideoHold`
tells the launcher when to hold simulated time until the video has caught up, so a lockstep
run's video gets every camera frame.
"""

import math
from pathlib import Path
import time

import cv2
from diagnostic_msgs.msg import DiagnosticArray
from followbot import messages
from followbot.follower_node import NODE_NAME as FOLLOWER_NODE
from followbot.image_conversion import image_to_array, ImageConversionError, to_bgr
from followbot.output_files import check_output_file, output_file_option
from followbot_sim.answered_requests import AnsweredRequests
from followbot_sim.course_file import load_course
from followbot_sim.run_recording import LagHold
from followbot_sim.score import score_values
from followbot_sim.topdown import side_by_side, TopDownView
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image

# FourCC of the codec for each file type: both ship with every OpenCV build (no FFmpeg
# licence question for the user) and play in common players.
CODECS = {'.mp4': 'mp4v', '.avi': 'MJPG'}
# What a video file is called in messages, and its name's endings.
VIDEO_FILE = ('a video', tuple(CODECS))
DEBUG_IMAGE_TOPIC = FOLLOWER_NODE + '/debug_image'
GROUND_TRUTH_TOPIC = 'ground_truth/odom'
# The simulator's parameters the video needs: what it draws and, by default, its frame rate.
SIMULATOR_PARAMETERS = ('course', 'lighting_zones', 'camera_rate_hz')
# Every debug frame and every pose matter to the video: reliable, with room for a burst.
VIDEO_QOS = QoSProfile(depth=20)
POSE_QOS = QoSProfile(depth=100)
# Stamps of a period's boundary and of a camera frame agree to this much (float rounding).
STAMP_TOLERANCE_S = 1e-6
BYTES_PER_MB = 1e6
# Wall seconds between looks for the simulator's parameter service and its answer.
ASK_PERIOD_S = 0.1
# The simulated clock (relative: the robot's own under a namespace); only its newest value.
CLOCK_TOPIC = 'clock'
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
# Time is held while the video's newest camera frame is this far (simulated seconds) behind
# the clock, and let go under VIDEO_RESUME_LAG_S: a few frames, so a debug image lost on the
# way is still in the follower's history (DEBUG_IMAGE_QUEUE_DEPTH) when DDS sends it again.
VIDEO_HOLD_LAG_S = 0.12
VIDEO_RESUME_LAG_S = 0.06
# Wall seconds a held run waits for a video that makes no progress before it runs on without
# waiting for the video again: longer than DDS takes to send a lost sample again (Fast DDS
# asks for it with its heartbeat, every 3 s by default).
VIDEO_STALL_S = 10.0


def check_video_path(path) -> Path:
    """
    Check that a video can be written at a path, before any run starts.

    :param path: the file to write, ending in one of :data:`CODECS`.
    :return: the path, as a Path.
    :raises OutputPathError: with one sentence, for another file type, a missing folder or one
        this user cannot write to.
    """
    return check_output_file(path, *VIDEO_FILE)


# The argparse type of a command's option naming a video to write.
video_path_option = output_file_option(*VIDEO_FILE)


class FrameSchedule:
    """Count the video frames due by a simulated time: one at every multiple of the period."""

    def __init__(self, period_s: float):
        """
        Start with no frame written.

        :param period_s: simulated seconds between video frames.
        :raises ValueError: if the period is not positive and finite.
        """
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f'The video period must be positive, got {period_s!r} s.')
        self._period_s = period_s
        self._frames = 0

    @property
    def frames(self) -> int:
        """Return how many frames were due so far."""
        return self._frames

    def due(self, time_s: float) -> int:
        """
        Advance to a simulated time and tell how many frames fall due.

        :param time_s: simulated time of the newest camera frame.
        :return: the number of multiples of the period in (previous time, time_s], counting
            time 0: the frames to write now, all showing the newest camera frame.
        """
        total = max(0, math.floor((time_s + STAMP_TOLERANCE_S) / self._period_s) + 1)
        count = max(0, total - self._frames)
        self._frames += count
        return count


def _score_caption(score: dict, time_s: float) -> list:
    """Return the caption of the top-down view: time, laps and distance from the line."""
    lines = [f't = {time_s:.1f} s']
    if score:
        lap_times = [float(text) for text in score.get('lap_times_s', '[]').strip('[]')
                     .split(',') if text.strip()]
        lines.append(f"laps {score['laps_completed']}"
                     + (f' (last {lap_times[-1]:.1f} s)' if lap_times else ''))
        lines.append(f"from line {100 * float(score['distance_from_line_m']):.1f} cm "
                     f"(rms {100 * float(score['rms_distance_from_line_m']):.1f})")
    return lines


class VideoNode(Node):
    """Write the follower's view and the course from above into a video file."""

    def __init__(self, path, simulator: str, period_s: float | None = None, **kwargs):
        """
        Subscribe to the images, poses and score and ask the simulator for its course.

        :param path: the video file, checked with :func:`check_video_path`.
        :param simulator: the simulator node's fully qualified name, such as /followbot_sim.
        :param period_s: simulated seconds between video frames; None for one frame per camera
            frame (the simulator's camera_rate_hz).
        :param kwargs: forwarded to :class:`rclpy.node.Node`.
        :raises OutputPathError: if the video cannot be written at ``path``.
        """
        # Its last line comes as the context shuts down, when /rosout can no longer carry it:
        # the terminal only.
        super().__init__('followbot_video', enable_rosout=False, **kwargs)
        self._path = check_video_path(path)
        self._simulator = simulator
        self._period_s = period_s
        self._schedule = None
        self._view = None
        self._writer = None
        self._failed = False
        self._pose = None
        self._score = {}
        self._frame_size = None
        # Camera frames written: the video's other frames repeat one (and time 0 has none).
        self._camera_frames_used = 0
        # Simulated seconds of the newest clock and of the newest camera frame seen.
        self._clock_s = None
        self.frame_time_s = None
        self._debug_image_subscription = self.create_subscription(
            Image, DEBUG_IMAGE_TOPIC, self.debug_image_callback, VIDEO_QOS)
        self.create_subscription(Clock, CLOCK_TOPIC, self.clock_callback, CLOCK_QOS)
        self._ground_truth_subscription = self.create_subscription(
            Odometry, GROUND_TRUTH_TOPIC, self.ground_truth_callback, POSE_QOS)
        self.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics_callback, 10)
        self._parameters_request = AnsweredRequests(
            self.create_client(GetParameters, simulator + '/get_parameters'))
        # Asks as soon as the simulator's service appears (it starts after this node), and
        # again until it answers.
        self._ask_timer = self.create_timer(ASK_PERIOD_S, self.ask_simulator_callback)

    @property
    def ready(self) -> bool:
        """
        Tell whether the video can take the run from its first frame.

        :return: True once the simulator said which course it runs and the follower's view and
            the robot's pose have publishers this node is connected to; True also once the
            video has failed, as the run then goes on without it.
        """
        return not self.waiting_for()

    def waiting_for(self) -> list:
        """
        Say what the video still waits for before the run may start.

        :return: one phrase per missing thing; empty when :attr:`ready`.
        """
        missing = []
        if self._failed:
            return missing
        if self._schedule is None:
            missing.append(f"{self._simulator}'s course")
        for subscription in (self._debug_image_subscription, self._ground_truth_subscription):
            if subscription.get_publisher_count() == 0:
                missing.append(f'a publisher of {subscription.topic_name}')
        return missing

    def ask_simulator_callback(self) -> None:
        """Ask the simulator for its course and camera rate until it answers."""
        if not self._parameters_request.asked:
            self._parameters_request.ask(GetParameters.Request(names=list(SIMULATOR_PARAMETERS)))
        if self._parameters_request.poll():
            self._ask_timer.cancel()
            self._take_simulator_parameters(self._parameters_request.response)

    def _take_simulator_parameters(self, response) -> None:
        if response is None or len(response.values) != len(SIMULATOR_PARAMETERS):
            self._fail(f'The simulator {self._simulator} did not say which course it runs.')
            return
        answers = response.values
        values = {name: parameter_value_to_python(value)
                  for name, value in zip(SIMULATOR_PARAMETERS, answers)}
        try:
            self._course = load_course(values['course'], lighting=values['lighting_zones'])
        except ValueError as error:
            self._fail(f'Cannot draw course {values["course"]!r}: {error}')
            return
        if self._period_s is None:
            self._period_s = 1.0 / values['camera_rate_hz']
        self._schedule = FrameSchedule(self._period_s)

    def clock_callback(self, msg: Clock) -> None:
        """Keep the newest simulated time."""
        self._clock_s = messages.seconds(msg.clock)

    def lag_s(self) -> float:
        """
        Return how far the video's newest camera frame is behind the simulated clock.

        :return: simulated seconds; 0 before the first frame or clock.
        """
        if self._clock_s is None or self.frame_time_s is None:
            return 0.0
        return max(0.0, self._clock_s - self.frame_time_s)

    def ground_truth_callback(self, msg: Odometry) -> None:
        """Extend the trail to the robot's true position."""
        position = msg.pose.pose.position
        orientation = msg.pose.pose.orientation
        yaw_rad = 2.0 * math.atan2(orientation.z, orientation.w)
        self._pose = (position.x, position.y, yaw_rad)
        if self._view is not None:
            self._view.add_trail_point(position.x, position.y)

    def diagnostics_callback(self, msg: DiagnosticArray) -> None:
        """Keep the simulator's latest score for the caption."""
        score = score_values(msg, self._simulator)
        if score is not None:
            self._score = score

    def debug_image_callback(self, msg: Image) -> None:
        """Write the video frames that fall due by this camera frame's stamp."""
        if self._failed or self._schedule is None:
            return
        try:
            camera_bgr = to_bgr(image_to_array(msg), msg.encoding)
        except ImageConversionError as error:
            self._fail(f'Cannot use the follower debug image: {error}')
            return
        if self._writer is None and not self._open(camera_bgr):
            return
        time_s = messages.seconds(msg.header.stamp)
        self.frame_time_s = time_s
        count = self._schedule.due(time_s)
        if count == 0:
            return
        frame = side_by_side(camera_bgr, self._view.draw(self._pose,
                                                         _score_caption(self._score, time_s)))
        if frame.shape[:2] != self._frame_size[::-1]:
            self._fail(f'The camera image changed size to {frame.shape[1]}x{frame.shape[0]}; '
                       f'the video stays {self._frame_size[0]}x{self._frame_size[1]}.')
            return
        for _ in range(count):
            self._writer.write(frame)
        self._camera_frames_used += 1

    def _open(self, camera_bgr) -> bool:
        height_px, width_px = camera_bgr.shape[:2]
        self._view = TopDownView(self._course, height_px)
        if self._pose is not None:
            self._view.add_trail_point(*self._pose[:2])
        self._frame_size = (width_px + height_px, height_px)
        fourcc = cv2.VideoWriter_fourcc(*CODECS[self._path.suffix.lower()])
        self._writer = cv2.VideoWriter(str(self._path), fourcc, 1.0 / self._period_s,
                                       self._frame_size)
        if not self._writer.isOpened():
            self._writer = None
            self._fail(f'OpenCV cannot open {self._path} for writing.')
            return False
        self.get_logger().info(
            f'Writing {self._path}: {self._frame_size[0]}x{self._frame_size[1]}, one frame '
            f'per {self._period_s:g} s of simulated time.')
        return True

    def _fail(self, text: str) -> None:
        # One line, once: the run goes on without its video.
        self._failed = True
        self.get_logger().error(text + ' No video is written.')

    def close(self) -> None:
        """Finish the file and say how long the video is and how big."""
        if self._writer is None:
            if not self._failed:
                self.get_logger().warn(f'No video written to {self._path}: no camera image '
                                       'came from the follower.')
            return
        self._writer.release()
        self._writer = None
        frames = self._schedule.frames
        size_mb = self._path.stat().st_size / BYTES_PER_MB
        # Time 0 comes before the first camera frame: its video frame is the first one's.
        repeated = frames - 1 - self._camera_frames_used
        repeats = (f'; {repeated} repeat the frame before, as the camera frame for them did '
                   'not reach the video in time' if repeated > 0 else '')
        self.get_logger().info(
            f'Video {self._path}: {frames} frames, {frames * self._period_s:.1f} s at '
            f'{1.0 / self._period_s:g} frames/s, {size_mb:.1f} MB{repeats}.')


class VideoHold:
    """When a run should stand still for its video to catch up, and when to stop waiting."""

    def __init__(self, video: VideoNode, clock=time.monotonic):
        """
        Watch a video.

        :param video: the video node.
        :param clock: returns the wall time in seconds (monotonic).
        """
        self._video = video
        self._clock = clock
        self._lag_hold = LagHold(VIDEO_HOLD_LAG_S, VIDEO_RESUME_LAG_S)
        self._progress = (None, clock())
        self.gave_up = False
        self._reported = False

    @property
    def holds(self) -> int:
        """Return how many times time was held for the video."""
        return self._lag_hold.holds

    def update(self) -> bool:
        """
        Tell whether time should stand still now; call it after each spin.

        :return: True while the video lags, unless it has made no progress for VIDEO_STALL_S
            of wall time while held (frames lost on the way): then never again.
        """
        if self.gave_up:
            return False
        now_s = self._clock()
        frame_time_s = self._video.frame_time_s
        if frame_time_s != self._progress[0] or not self._lag_hold.holding:
            self._progress = (frame_time_s, now_s)
        if self._lag_hold.holding and now_s - self._progress[1] > VIDEO_STALL_S:
            self.gave_up = True
            return False
        return self._lag_hold.update(self._video.lag_s())

    def report(self) -> str | None:
        """Return, once, the line saying that the run no longer waits for the video."""
        if not self.gave_up or self._reported:
            return None
        self._reported = True
        return (f'The video made no progress for {VIDEO_STALL_S:g} s while time was held for '
                'it: time runs on without waiting for it.')


def add_video_node(executor, path, simulator: str, period_s: float | None = None) -> VideoNode:
    """
    Add a :class:`VideoNode` to an executor; the file is finished when the context shuts down.

    :param executor: the executor that spins the node, whose context it joins.
    :param path: the video file.
    :param simulator: the simulator node's fully qualified name.
    :param period_s: simulated seconds between video frames; None for the camera's period.
    :return: the node.
    """
    node = VideoNode(path, simulator, period_s, context=executor.context)
    executor.add_node(node)
    executor.context.on_shutdown(node.close)
    return node
