"""The run's video: the top-down view, the frame schedule, the file checks and a real run."""

import math
import subprocess
import sys
import time

from conftest import child_environment, run_domain_id, spin_until
import cv2
from followbot.output_files import OutputPathError
from followbot_sim.course_file import load_course
from followbot_sim.run_recording import WAIT_REPORT_S
from followbot_sim.topdown import side_by_side, TopDownView
from followbot_sim.video import (check_video_path, FrameSchedule, VIDEO_HOLD_LAG_S,
                                 VIDEO_RESUME_LAG_S, VIDEO_STALL_S, VideoHold, VideoNode)
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

CAMERA_WIDTH_PX = 640
CAMERA_HEIGHT_PX = 480


def pixel_at(view, image, pose):
    col, row = np.round(view.to_pixels(pose[0], pose[1])).astype(int)
    return image[row, col].astype(int)


def is_red(bgr) -> bool:
    return bgr[2] > 200 and bgr[1] < 80 and bgr[0] < 80


@pytest.fixture(scope='module')
def book_loop():
    return load_course('book_loop')


def test_top_down_view_shows_the_course_line_where_the_course_is(book_loop):
    view = TopDownView(book_loop, 400)
    image = view.draw()
    assert image.shape == (400, 400, 3)
    # The centre line's points land on the line's yellow (B low, G and R high) ...
    x_m, y_m = book_loop.centre_line_xy[::200].T
    cols, rows = np.round(view.to_pixels(x_m, y_m)).astype(int)
    blue, green, red = image[rows, cols].T.astype(int)
    assert (blue < 60).all() and (green > 200).all() and (red > 200).all()
    # ... and the middle of the egg is bare grey floor.
    middle = image[200, 200].astype(int)
    assert abs(middle[0] - middle[2]) < 5


def test_top_down_view_keeps_the_whole_course_in_view(book_loop):
    view = TopDownView(book_loop, 300)
    cols, rows = view.to_pixels(*book_loop.centre_line_xy.T)
    assert cols.min() > 0 and rows.min() > 0
    assert cols.max() < 299 and rows.max() < 299


def test_trail_is_drawn_where_the_robot_went_and_stays(book_loop):
    view = TopDownView(book_loop, 400)
    for arc_m in np.arange(0.0, 3.0, 0.02):
        x_m, y_m, _ = book_loop.point_at(arc_m)
        view.add_trail_point(x_m, y_m)
    image = view.draw()
    assert is_red(pixel_at(view, image, book_loop.point_at(1.5)))
    # Ahead of the robot the line has no trail yet.
    assert not is_red(pixel_at(view, image, book_loop.point_at(6.0)))
    # Drawing the robot does not paint it into the next frame.
    x_m, y_m, _ = book_loop.point_at(10.0)
    with_robot = view.draw((x_m, y_m, 0.0))
    assert not np.array_equal(with_robot, image)
    assert np.array_equal(view.draw(), image)


@pytest.mark.parametrize('size_px', [0, -3, 2.5, True])
def test_top_down_view_refuses_a_size_that_is_not_a_positive_integer(book_loop, size_px):
    with pytest.raises(ValueError, match='size_px'):
        TopDownView(book_loop, size_px)


def test_side_by_side_puts_the_camera_left_and_refuses_other_heights():
    camera = np.zeros((CAMERA_HEIGHT_PX, CAMERA_WIDTH_PX, 3), np.uint8)
    top_down = np.full((CAMERA_HEIGHT_PX, CAMERA_HEIGHT_PX, 3), 255, np.uint8)
    frame = side_by_side(camera, top_down)
    assert frame.shape == (CAMERA_HEIGHT_PX, CAMERA_WIDTH_PX + CAMERA_HEIGHT_PX, 3)
    assert frame[:, :CAMERA_WIDTH_PX].max() == 0 and frame[:, CAMERA_WIDTH_PX:].min() == 255
    with pytest.raises(ValueError, match='must match'):
        side_by_side(camera, top_down[:-1])


@pytest.mark.parametrize('stamps_s, period_s, due', [
    # One frame per camera frame; the first stands in for time 0 too.
    ([0.05, 0.10, 0.15], 0.05, [2, 1, 1]),
    # Every other camera frame.
    ([0.05, 0.10, 0.15, 0.20], 0.1, [1, 1, 0, 1]),
    # A lost camera frame: the next one fills its period.
    ([0.05, 0.15], 0.05, [2, 2]),
    # Float rounding of stamps never skips or doubles a frame.
    ([3 * 0.1, 0.30000000000000004 + 0.1], 0.1, [4, 1]),
])
def test_frame_schedule_gives_one_frame_per_period_of_simulated_time(stamps_s, period_s, due):
    schedule = FrameSchedule(period_s)
    assert [schedule.due(stamp_s) for stamp_s in stamps_s] == due
    assert schedule.frames == sum(due)


@pytest.mark.parametrize('period_s', [0.0, -1.0, math.inf, math.nan])
def test_frame_schedule_refuses_a_period_that_is_not_positive(period_s):
    with pytest.raises(ValueError, match='period'):
        FrameSchedule(period_s)


def test_video_path_takes_mp4_and_avi_only(tmp_path):
    assert check_video_path(tmp_path / 'run.mp4') == tmp_path / 'run.mp4'
    assert check_video_path(tmp_path / 'run.AVI') == tmp_path / 'run.AVI'
    with pytest.raises(OutputPathError, match=r'must end in \.mp4 or \.avi'):
        check_video_path(tmp_path / 'run.mkv')
    with pytest.raises(OutputPathError, match='does not exist'):
        check_video_path(tmp_path / 'missing' / 'run.mp4')


@pytest.mark.parametrize('name, message', [
    ('run.gif', 'must end in .mp4 or .avi'),
    ('no/such/folder/run.mp4', 'does not exist'),
])
def test_followbot_refuses_a_video_it_cannot_write_in_one_line(tmp_path, name, message):
    result = subprocess.run(
        [sys.executable, '-m', 'followbot_sim.launcher', '--duration', '1', '--video',
         str(tmp_path / name)], env=child_environment(), capture_output=True, text=True,
        timeout=60)
    assert result.returncode == 2
    errors = [line for line in result.stderr.splitlines() if 'error:' in line]
    assert len(errors) == 1 and message in errors[0], result.stderr
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize('file_name, period_s', [('run.mp4', None), ('run.avi', 0.1)])
def test_lockstep_run_writes_a_video_as_long_as_the_run(tmp_path, file_name, period_s):
    duration_s = 4.0
    video = tmp_path / file_name
    command = [sys.executable, '-m', 'followbot_sim.launcher', '--domain-id',
               str(run_domain_id()), '--duration', str(duration_s), '--real-time-factor', '0',
               '--lockstep', '--video', str(video)]
    if period_s is not None:
        command += ['--video-period-s', str(period_s)]
    result = subprocess.run(command, env=child_environment(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=180)
    assert result.returncode == 0, result.stdout
    capture = cv2.VideoCapture(str(video))
    try:
        assert capture.isOpened(), result.stdout
        frames = []
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            frames.append(frame)
        frames_per_s = capture.get(cv2.CAP_PROP_FPS)
    finally:
        capture.release()
    # The simulator's 20 Hz camera by default; one frame at time 0 and one per period after.
    period_s = period_s or 0.05
    assert frames_per_s == pytest.approx(1.0 / period_s)
    assert abs(len(frames) - (duration_s / period_s + 1)) <= 1, result.stdout
    # The camera on the left, the square top-down view of its height on the right.
    assert frames[0].shape == (CAMERA_HEIGHT_PX, CAMERA_WIDTH_PX + CAMERA_HEIGHT_PX, 3)
    # The follower's overlay shows: its bands are drawn in green on the camera side.
    camera_side = frames[-1][:, :CAMERA_WIDTH_PX].astype(int)
    greenish = (camera_side[..., 1] > 150) & (camera_side[..., 0] < 100) \
        & (camera_side[..., 2] < 100)
    assert greenish.sum() > 500
    # The robot moved: the last frame differs from the first on both sides.
    assert not np.array_equal(frames[0][:, :CAMERA_WIDTH_PX], frames[-1][:, :CAMERA_WIDTH_PX])
    assert not np.array_equal(frames[0][:, CAMERA_WIDTH_PX:], frames[-1][:, CAMERA_WIDTH_PX:])
    assert f'Video {video}: {len(frames)} frames' in result.stdout


def test_a_video_run_longer_than_the_start_wait_ends_without_a_false_wait_report(tmp_path):
    # The simulator leaves at the end of the run before its process has ended: the video then
    # misses the robot's pose, but the run is over, not waiting to start.
    command = [sys.executable, '-m', 'followbot_sim.launcher', '--domain-id',
               str(run_domain_id()), '--duration', '25', '--real-time-factor', '0',
               '--lockstep', '--video', str(tmp_path / 'run.mp4')]
    started_s = time.monotonic()
    result = subprocess.run(command, env=child_environment(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=300)
    assert result.returncode == 0, result.stdout
    # Long enough for the report, had the run still waited.
    assert time.monotonic() - started_s > WAIT_REPORT_S
    assert 'still waits for' not in result.stdout


class LaggingVideo:
    """Stands for a video node: its newest camera frame and the clock, set by the test."""

    def __init__(self):
        """Start at simulated time 10 s with the frame of that time."""
        self.clock_s = 10.0
        self.frame_time_s = 10.0

    def lag_s(self) -> float:
        """Return how far the frame is behind the clock."""
        return self.clock_s - self.frame_time_s


class WallClock:
    """A wall clock the test moves by hand."""

    def __init__(self):
        """Start at 100 s."""
        self.now_s = 100.0

    def __call__(self) -> float:
        """Return the time now."""
        return self.now_s


def test_time_is_held_while_the_video_lags_and_let_go_once_it_caught_up():
    video, wall = LaggingVideo(), WallClock()
    hold = VideoHold(video, wall)
    # (frame time behind the clock, expected hold) in order: hysteresis between the two.
    steps = [(VIDEO_HOLD_LAG_S - 0.05, False), (VIDEO_HOLD_LAG_S + 0.05, True),
             (VIDEO_RESUME_LAG_S + 0.05, True), (VIDEO_RESUME_LAG_S - 0.05, False)]
    for behind_s, expected in steps:
        video.frame_time_s = video.clock_s - behind_s
        wall.now_s += 1.0
        assert hold.update() == expected, behind_s
    assert hold.holds == 1
    assert hold.report() is None


def test_a_held_run_stops_waiting_for_a_video_that_makes_no_progress():
    video, wall = LaggingVideo(), WallClock()
    hold = VideoHold(video, wall)
    video.frame_time_s = video.clock_s - 2 * VIDEO_HOLD_LAG_S
    assert hold.update()
    # Progress, however slow, keeps the hold.
    for _ in range(3):
        wall.now_s += 0.9 * VIDEO_STALL_S
        video.frame_time_s += 0.01
        assert hold.update()
    # Its frames lost on the way, the video stands still: time runs on, for good.
    wall.now_s += 1.1 * VIDEO_STALL_S
    assert not hold.update()
    assert 'no progress' in hold.report()
    assert hold.report() is None
    video.frame_time_s = video.clock_s - 10 * VIDEO_HOLD_LAG_S
    assert not hold.update()


class ParameterHolder:
    """A node that holds the parameters a video asks a simulator for, over its real service."""

    def __init__(self, context, course):
        """Declare the course, lighting and camera rate a simulator holds, as /sim_stand_in."""
        self.node = Node('sim_stand_in', context=context)
        self.node.declare_parameter('course', course)
        self.node.declare_parameter('lighting_zones', False)
        self.node.declare_parameter('camera_rate_hz', 20.0)


@pytest.mark.parametrize('course, failed', [('book_loop', False), ('no_such_course', True)])
def test_video_says_what_it_waits_for_and_does_not_hold_a_run_it_cannot_film(
        ros_context, tmp_path, course, failed):
    video = VideoNode(tmp_path / 'run.mp4', '/sim_stand_in', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(video)
    assert video.waiting_for() == ["/sim_stand_in's course",
                                   'a publisher of /follower/debug_image',
                                   'a publisher of /ground_truth/odom']
    assert not video.ready
    holder = ParameterHolder(ros_context, course)
    executor.add_node(holder.node)
    try:
        assert spin_until(executor, lambda: "/sim_stand_in's course" not in video.waiting_for())
        if failed:
            # The run goes on without its video: nothing left to wait for.
            assert video.ready
            assert video.waiting_for() == []
        else:
            # Course known; the follower's view and the robot's pose have no publisher here.
            assert video.waiting_for() == ['a publisher of /follower/debug_image',
                                           'a publisher of /ground_truth/odom']
            assert not video.ready
    finally:
        executor.shutdown()
        holder.node.destroy_node()
        video.destroy_node()
