"""
Tests of the MuJoCo world: the model steps cleanly, drives like a Kobuki and renders the course.

Physics tests share one world per module and reset it before each test; rendering tests skip
where no OpenGL context can be made for ``mujoco.Renderer``. The sensor tests check the robot's
frames against what MuJoCo draws: a floor point taken through ``world -> base_footprint``, the
world's sensor frames and the camera intrinsics must land where the rendered images show it.
"""

import math
import shutil

from followbot.frames import BASE_FOOTPRINT_FRAME
from followbot.frames import BASE_LINK_FRAME
from followbot.frames import CAMERA_DEPTH_FRAME
from followbot.frames import CAMERA_DEPTH_OPTICAL_FRAME
from followbot.frames import CAMERA_LINK_FRAME
from followbot.frames import CAMERA_RGB_FRAME
from followbot.frames import CAMERA_RGB_OPTICAL_FRAME
from followbot.frames import chain_transforms
from followbot.frames import FrameTransform
from followbot.frames import quaternion_from_rpy
from followbot.frames import WORLD_FRAME
from followbot_sim.course import Course
from followbot_sim.course import COURSES
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.depth import project_points_px
from followbot_sim.diff_drive import KOBUKI_MAX_LINEAR_SPEED_MPS
from followbot_sim.world import CAMERA_NAME
from followbot_sim.world import DEFAULT_CAMERA_PITCH_DEG
from followbot_sim.world import DEFAULT_HORIZONTAL_FOV_DEG
from followbot_sim.world import DEFAULT_IMAGE_HEIGHT_PX
from followbot_sim.world import DEFAULT_IMAGE_WIDTH_PX
from followbot_sim.world import DEPTH_CAMERA_NAME
from followbot_sim.world import FLOOR_GEOM
from followbot_sim.world import focal_length_px
from followbot_sim.world import FollowbotWorld
from followbot_sim.world import KINECT_MAX_DEPTH_M
from followbot_sim.world import KINECT_MIN_DEPTH_M
from followbot_sim.world import models_directory
from followbot_sim.world import ROBOT_BODY
from followbot_sim.world import SCENE_FILE
from followbot_sim.world import ViewerUnavailableError
import mujoco
import numpy as np
import pytest

COURSE_NAME = 'book_loop'
# Every mjtWarning except the count of them.
WARNING_NAMES = tuple(name for name in mujoco.mjtWarning.__members__ if name != 'mjNWARNING')
MODEL_TEST_DURATION_S = 2.0
SETTLE_S = 1.0
UPRIGHT_HEIGHT_TOLERANCE_M = 1e-3
UPRIGHT_TILT_TOLERANCE_RAD = 0.01

DRIVE_S = 3.0
# Speeds are measured after this much acceleration from rest.
ACCELERATION_S = 0.5
CRUISE_SPEED_MPS = 0.3
SPEED_TOLERANCE = 0.02
SPIN_RATE_RADPS = 1.0
YAW_RATE_TOLERANCE = 0.03
HEADING_TOLERANCE_RAD = 0.02
SPIN_DRIFT_TOLERANCE_M = 0.02
TOO_FAST_SPEED_MPS = 2.0

# 640 px across a 60 degree field of view.
DEFAULT_FOCAL_LENGTH_PX = 320.0 / math.tan(math.radians(30.0))
IMAGE_SIZES_PX = [(DEFAULT_IMAGE_WIDTH_PX, DEFAULT_IMAGE_HEIGHT_PX), (320, 240), (1280, 720)]
# Before looking, the robot turns left so the line ahead lies right of the image centre: a
# mirrored image would then show the line on the wrong side.
LOOK_TURN_RATE_RADPS = 1.0
LOOK_TURN_S = 0.35
LOOK_STOP_S = 0.2
LINE = 'line'
FLOOR = 'floor'
PAINT_RGB = {LINE: LINE_RGB, FLOOR: (FLOOR_GREY, FLOOR_GREY, FLOOR_GREY)}
COLOUR_TOLERANCE = 30
# (arc length ahead of the start m, offset left of the centre line m, paint expected there).
# The line is 0.19 m wide: offsets of 0.06 m lie 3.5 cm inside its edge, 0.13 m 3.5 cm outside.
CAMERA_FLOOR_POINTS = [
    (0.5, 0.0, LINE),
    (0.5, 0.06, LINE),
    (0.5, -0.06, LINE),
    (0.5, 0.13, FLOOR),
    (0.5, 0.3, FLOOR),
    (0.7, -0.06, LINE),
    (1.0, 0.0, LINE),
    (1.0, -0.15, FLOOR),
    (1.2, 0.5, FLOOR),
]
OVERVIEW_SIZE_PX = 400
# (fraction of the course length from the start, offset left of the centre line m, paint).
OVERVIEW_FLOOR_POINTS = [
    (fraction, offset_m, LINE if offset_m == 0.0 else FLOOR)
    for fraction in (0.25, 0.5, 0.75) for offset_m in (0.0, 0.5, -0.5)
]
SMALL_TEXTURE_PX = 64

# Model test: every built-in course (looked up when the tests are collected, so courses added
# later are covered) and every MJCF file, driven for a while and rendered once, small.
MODEL_FILES = sorted(models_directory().glob('*.xml'))
MODEL_TEST_IMAGE_SIZE_PX = (64, 48)
MODEL_TEST_TWIST = (0.3, 0.5)
# Fraction of each actuator's control range commanded when a bare model file is driven.
MODEL_TEST_CONTROL_FRACTION = 0.3

# Sensor-frame tests run on a rectangular loop: its straight sides make the centre of the
# painted stripe across an image row exactly the image of the centre line there. The robot
# starts at the origin of the bottom side heading east, then turns left a little.
RECTANGLE_LOOP_XY = [(0.0, -3.0), (4.0, -3.0), (4.0, 3.0), (-4.0, 3.0), (-4.0, -3.0)]
SENSOR_TURN_S = 0.2
# Arc lengths ahead of the start whose centre-line points the cameras must see on the line.
SENSOR_ARCS_M = [0.6, 1.0, 1.5, 2.5]
SENSOR_CAMERAS = [(CAMERA_NAME, CAMERA_RGB_OPTICAL_FRAME),
                  (DEPTH_CAMERA_NAME, CAMERA_DEPTH_OPTICAL_FRAME)]
# Centre-line stretch either side of a point, projected to find where the line crosses a row.
CROSSING_SEARCH_M = 0.3
CROSSING_SAMPLES = 121
LINE_CENTRE_TOLERANCE_PX = 1.0
KINECT_DEPTH_OFFSET_LEFT_M = 0.025
CAMERA_LINK_XYZ_M = (0.10, 0.0, 0.30)

DEPTH_TOLERANCE_M = 0.01
# The follower's band of rows at 3/4 of a 480-row image: the tilted camera sees the floor there
# ~0.44 m away, nearer than a real Kinect's minimum range.
FOLLOWER_BAND_ROWS = slice(350, 371)
DEPTH_ROWS_PX = [0, 100, 240, 360, 370, 380, 479]
DEPTH_COLUMNS_PX = [0, 320, 639]
# A box standing on the floor across the robot's path, (centre x, y, z) and half sizes in
# metres, in a copy of the scene.
OBSTACLE_CENTRE_M = (1.0, -3.0, 0.15)
OBSTACLE_HALF_SIZE_M = (0.05, 0.3, 0.15)
# Points on the box's face towards the robot, as heights above the floor and offsets left; the
# camera, pitched down, sees the face up to ~0.2 m high.
OBSTACLE_FACE_POINTS_M = [(0.04, 0.0), (0.08, 0.15), (0.12, -0.2)]

NOISE_IMAGE_SIZE_PX = (160, 120)
NOISE_STDDEV = 8.0
NOISE_STDDEV_TOLERANCE = 0.3
# Pixels this far from 0 and 255 do not saturate at the noise level tested (over 5 sigma).
NOISE_UNSATURATED_MARGIN = 45
NOISE_SEED = 7
DETERMINISM_STEPS = 5
DETERMINISM_STEP_S = 0.1

# Courses on floors of other sizes, with a loop of half the floor's width.
FLOOR_SIZES_M = [6.0, 14.0]
FLOOR_TEST_TEXTURE_PX = 512
# Floor corners are checked this far inside the edge, as a fraction of the half size.
FLOOR_CORNER_FRACTION = 0.97


@pytest.fixture(scope='module')
def course():
    """Build the default course once."""
    return make_course(COURSE_NAME)


@pytest.fixture(scope='module')
def shared_world(course):
    """Build the world once for the module's physics tests."""
    world = FollowbotWorld(course)
    yield world
    world.close()


@pytest.fixture
def world(shared_world):
    """Give a test the shared world, reset to the course start."""
    shared_world.reset()
    return shared_world


@pytest.fixture(scope='module', params=IMAGE_SIZES_PX, ids=lambda size: '{}x{}'.format(*size))
def camera_view(request, opengl, course):
    """
    Turn the robot a little to the left, render its camera and keep the world for projecting.

    :return: the world and a copy of its camera image.
    """
    width_px, height_px = request.param
    world = FollowbotWorld(course, image_width_px=width_px, image_height_px=height_px)
    world.set_twist(0.0, LOOK_TURN_RATE_RADPS)
    world.step(LOOK_TURN_S)
    world.set_twist(0.0, 0.0)
    world.step(LOOK_STOP_S)
    image = world.render_camera().copy()
    yield world, image
    world.close()


@pytest.fixture(scope='module')
def overview_image(shared_world, opengl):
    """Render the overview of the world with the robot at the start."""
    shared_world.reset()
    return shared_world.render_overview(OVERVIEW_SIZE_PX).copy()


def warning_counts(world):
    """
    Count MuJoCo's warnings of each kind since the last reset.

    :param world: the world to inspect.
    :return: a dict from warning name to count.
    """
    return {name: int(world.data.warning[int(getattr(mujoco.mjtWarning, name))].number)
            for name in WARNING_NAMES}


def angle_difference_rad(to_rad, from_rad):
    """
    Return the signed angle from one heading to another, wrapped to [-pi, pi].

    :param to_rad: final heading in radians.
    :param from_rad: initial heading in radians.
    :return: the difference in radians.
    """
    return math.remainder(to_rad - from_rad, 2.0 * math.pi)


def measure_after_acceleration(world, linear_mps, angular_radps):
    """
    Drive from rest for ``DRIVE_S`` and return the mean motion after ``ACCELERATION_S``.

    :param world: a world at rest.
    :param linear_mps: commanded forward speed in m/s.
    :param angular_radps: commanded yaw rate in rad/s.
    :return: (distance travelled / time in m/s, heading change / time in rad/s).
    """
    world.set_twist(linear_mps, angular_radps)
    world.step(ACCELERATION_S)
    x0_m, y0_m, yaw0_rad = world.robot_pose()
    start_s = world.time_s
    yaw_change_rad = 0.0
    previous_yaw_rad = yaw0_rad
    while world.time_s < DRIVE_S - world.timestep_s / 2.0:
        world.step(world.timestep_s)
        _, _, yaw_rad = world.robot_pose()
        yaw_change_rad += angle_difference_rad(yaw_rad, previous_yaw_rad)
        previous_yaw_rad = yaw_rad
    x1_m, y1_m, _ = world.robot_pose()
    elapsed_s = world.time_s - start_s
    return math.hypot(x1_m - x0_m, y1_m - y0_m) / elapsed_s, yaw_change_rad / elapsed_s


def floor_point_beside_line(course, arc_m, left_m):
    """
    Return a floor point at an offset from the centre line, square to the direction of travel.

    :param course: the course.
    :param arc_m: arc length of the centre-line point in metres.
    :param left_m: offset to the left of the direction of travel in metres.
    :return: (x, y, z) in metres, z = 0 on the floor.
    """
    x_m, y_m, _ = course.point_at(arc_m, left_m)
    return np.array([x_m, y_m, 0.0])


def project_to_camera_px(world, point_xyz_m):
    """
    Project a world point into the robot camera image with the world's pinhole intrinsics.

    MuJoCo cameras look along their -z axis with +y up and +x right; the image has x right and
    y down, pixel centres at integers.

    :param world: the world, with its camera pose computed in ``world.data``.
    :param point_xyz_m: the point in world coordinates in metres.
    :return: (column, row) in pixels.
    """
    camera_id = world.model.camera(CAMERA_NAME).id
    rotation = world.data.cam_xmat[camera_id].reshape(3, 3)
    right_m, up_m, back_m = rotation.T @ (point_xyz_m - world.data.cam_xpos[camera_id])
    depth_m = -back_m
    assert depth_m > 0.0, 'point is behind the camera'
    fx_px, fy_px, cx_px, cy_px = world.camera_intrinsics()
    return cx_px + fx_px * right_m / depth_m, cy_px - fy_px * up_m / depth_m


def pixel_at(image, column_px, row_px):
    """
    Return the pixel nearest to continuous image coordinates, which must lie in the image.

    :param image: an (H, W, 3) image.
    :param column_px: column, pixel centres at integers.
    :param row_px: row, pixel centres at integers.
    :return: the RGB pixel as an int array.
    """
    column, row = int(round(column_px)), int(round(row_px))
    height_px, width_px = image.shape[:2]
    assert 0 <= column < width_px and 0 <= row < height_px, f'({column}, {row}) is off-image'
    return image[row, column].astype(int)


def has_paint(pixel, paint):
    """
    Tell whether a rendered pixel shows the given paint of the course.

    :param pixel: an RGB pixel.
    :param paint: ``LINE`` or ``FLOOR``.
    :return: True if every channel is within ``COLOUR_TOLERANCE`` of the paint's colour.
    """
    return bool(np.all(np.abs(pixel - np.array(PAINT_RGB[paint])) <= COLOUR_TOLERANCE))


def robot_world_transform(world):
    """Return ``world -> base_footprint`` from the world's true planar pose."""
    return FrameTransform.planar(WORLD_FRAME, BASE_FOOTPRINT_FRAME, *world.robot_pose())


def project_through_frames(world, optical_frame, points_xyz_m):
    """
    Project world points into a camera through the sensor frames and the intrinsics.

    :param world: the world, whose robot pose and sensor frames are used.
    :param optical_frame: the camera's optical frame.
    :param points_xyz_m: (..., 3) points in the world frame, metres.
    :return: ((..., 2) pixel coordinates (column, row), (...) depths in metres).
    """
    transforms = world.sensor_frames() + [robot_world_transform(world)]
    camera_from_world = chain_transforms(transforms, optical_frame, WORLD_FRAME)
    points_camera_m = camera_from_world.transform_points(points_xyz_m)
    return project_points_px(points_camera_m, *world.camera_intrinsics()), points_camera_m[..., 2]


def line_centre_in_row(image, column_px, row):
    """
    Find the centre of the painted stripe running through a pixel of an image row.

    Pixels are weighted by how far their blue channel lies from the floor's towards the line's
    (the line has no blue), so anti-aliased edges count in proportion.

    :param image: an RGB image.
    :param column_px: a column inside the stripe.
    :param row: the image row.
    :return: the weighted mean column of the stripe.
    """
    floor_blue, line_blue = PAINT_RGB[FLOOR][2], PAINT_RGB[LINE][2]
    weights = np.clip((floor_blue - image[row, :, 2].astype(float)) / (floor_blue - line_blue),
                      0.0, 1.0)
    first = last = int(round(column_px))
    while first > 0 and weights[first - 1] > 0.0:
        first -= 1
    while last < len(weights) - 1 and weights[last + 1] > 0.0:
        last += 1
    assert 0 < first and last < len(weights) - 1, 'the stripe runs off the image'
    columns = np.arange(first, last + 1)
    return float(np.sum(weights[first:last + 1] * columns) / np.sum(weights[first:last + 1]))


def floor_depth_m(world, row_px):
    """
    Return the depth of the floor seen by a row of the level-mounted, pitched depth camera.

    The ray through row v has slope t = (v - cy) / fy below the optical axis, which points
    down at the pitch p; it falls by z (sin p + t cos p) over a depth z, so it meets the floor,
    h below the camera, at z = h / (sin p + t cos p), or never when that is not positive.

    :param world: the world, robot upright on the floor.
    :param row_px: the image row.
    :return: the depth in metres, NaN above the horizon.
    """
    transforms = world.sensor_frames() + [robot_world_transform(world)]
    height_m = chain_transforms(transforms, WORLD_FRAME,
                                CAMERA_DEPTH_OPTICAL_FRAME).translation_m[2]
    pitch_rad = math.radians(world.camera_pitch_deg)
    _, fy_px, _, cy_px = world.camera_intrinsics()
    falling = math.sin(pitch_rad) + math.cos(pitch_rad) * (row_px - cy_px) / fy_px
    return height_m / falling if falling > 0.0 else math.nan


@pytest.fixture(scope='module')
def rectangle_course():
    """Build a course with long straight sides."""
    return Course(RECTANGLE_LOOP_XY, name='rectangle')


@pytest.fixture(scope='module')
def sensor_view(opengl, rectangle_course):
    """
    Turn the robot a little left on the rectangle and render what both Kinect cameras see.

    The depth camera's colour image comes from a renderer of the test's own: the world renders
    only depth from it.

    :return: the world and a dict from camera name to its RGB image.
    """
    world = FollowbotWorld(rectangle_course, min_depth_m=0.0)
    world.set_twist(0.0, LOOK_TURN_RATE_RADPS)
    world.step(SENSOR_TURN_S)
    world.set_twist(0.0, 0.0)
    world.step(LOOK_STOP_S)
    width_px, height_px = world.image_size_px
    images = {CAMERA_NAME: world.render_camera().copy()}
    with mujoco.Renderer(world.model, height_px, width_px) as renderer:
        renderer.update_scene(world.data, camera=DEPTH_CAMERA_NAME)
        images[DEPTH_CAMERA_NAME] = renderer.render().copy()
    yield world, images
    world.close()


@pytest.fixture(scope='module')
def depth_world(opengl, course):
    """Build a world at the course start whose depth keeps every range."""
    world = FollowbotWorld(course, texture_size_px=SMALL_TEXTURE_PX, min_depth_m=0.0,
                           max_depth_m=math.inf)
    yield world
    world.close()


@pytest.fixture
def obstacle_models_dir(tmp_path):
    """Write a copy of the scene with a box on the floor ahead of the rectangle's start."""
    scene = (models_directory() / SCENE_FILE).read_text()
    box = ('<geom name="obstacle" type="box" pos="{} {} {}" size="{} {} {}" rgba="0.8 0.2 0.2 1"/>'
           .format(*OBSTACLE_CENTRE_M, *OBSTACLE_HALF_SIZE_M))
    (tmp_path / SCENE_FILE).write_text(scene.replace('</worldbody>', box + '</worldbody>', 1))
    for model_file in MODEL_FILES:
        if model_file.name != SCENE_FILE:
            shutil.copy(model_file, tmp_path / model_file.name)
    return tmp_path


@pytest.fixture(scope='module')
def shared_noisy_world(opengl, course):
    """Build one small world whose camera adds noise, for the noise tests."""
    world = noisy_world(course)
    yield world
    world.close()


@pytest.fixture
def noisy(shared_noisy_world):
    """Give a test the shared noisy world, reset: at the start, its noise restarted."""
    shared_noisy_world.reset()
    return shared_noisy_world


def small_world(course, **arguments):
    """Build a world with small images and texture, for tests that need many worlds."""
    width_px, height_px = MODEL_TEST_IMAGE_SIZE_PX
    return FollowbotWorld(course, image_width_px=width_px, image_height_px=height_px,
                          texture_size_px=SMALL_TEXTURE_PX, **arguments)


def noisy_world(course, seed=NOISE_SEED, stddev=NOISE_STDDEV):
    """Build a small world whose camera adds noise."""
    width_px, height_px = NOISE_IMAGE_SIZE_PX
    return FollowbotWorld(course, image_width_px=width_px, image_height_px=height_px,
                          texture_size_px=SMALL_TEXTURE_PX, camera_noise_stddev=stddev,
                          noise_seed=seed)


def circle_course(floor_size_m):
    """Build a circular loop of half the floor's width on a floor of the given size."""
    angle_rad = np.linspace(0.0, 2.0 * math.pi, 400, endpoint=False)
    radius_m = floor_size_m / 4.0
    return Course(np.stack([radius_m * np.cos(angle_rad), radius_m * np.sin(angle_rad)], axis=1),
                  floor_size_m=floor_size_m, name=f'circle_{floor_size_m:g}m')


@pytest.mark.parametrize('linear_mps, angular_radps', [
    (KOBUKI_MAX_LINEAR_SPEED_MPS, 0.0),
    (-KOBUKI_MAX_LINEAR_SPEED_MPS, 0.0),
    (0.3, 1.0),
    (0.0, -math.pi),
])
def test_scene_steps_without_warnings(world, linear_mps, angular_radps):
    world.set_twist(linear_mps, angular_radps)
    world.step(MODEL_TEST_DURATION_S)
    assert warning_counts(world) == dict.fromkeys(WARNING_NAMES, 0)
    assert np.all(np.isfinite(world.data.qpos))
    assert np.all(np.isfinite(world.data.qvel))


def test_robot_starts_at_course_start(world, course):
    assert world.robot_pose() == pytest.approx(course.start_pose())


def test_a_start_offset_puts_the_robot_beside_the_line_turned_and_back_there(course):
    world = FollowbotWorld(course, start_lateral_offset_m=0.02, start_heading_offset_deg=-3.0)
    try:
        x_m, y_m, yaw_rad = course.start_pose()
        # 2 cm to the left of the line, turned 3 degrees to the right of it.
        beside = (x_m - 0.02 * math.sin(yaw_rad), y_m + 0.02 * math.cos(yaw_rad),
                  yaw_rad - math.radians(3.0))
        assert world.robot_pose() == pytest.approx(beside)
        world.set_twist(CRUISE_SPEED_MPS, 0.5)
        world.step(1.0)
        world.reset_robot()
        assert world.robot_pose() == pytest.approx(beside)
        world.reset()
        assert world.robot_pose() == pytest.approx(beside)
    finally:
        world.close()


def test_robot_starts_at_rest(world):
    assert world.time_s == 0.0
    assert world.robot_twist() == pytest.approx((0.0, 0.0))
    assert world.wheel_speeds() == pytest.approx((0.0, 0.0))


def test_robot_settles_upright_where_it_starts(world, course):
    world.step(SETTLE_S)
    base = world.data.body(ROBOT_BODY)
    assert abs(base.xpos[2]) < UPRIGHT_HEIGHT_TOLERANCE_M
    # The body's z axis is the third column of its rotation matrix.
    assert base.xmat[8] > math.cos(UPRIGHT_TILT_TOLERANCE_RAD)
    assert world.robot_pose() == pytest.approx(course.start_pose(), abs=1e-4)


def test_forward_twist_drives_at_commanded_speed(world):
    speed_mps, yaw_rate_radps = measure_after_acceleration(world, CRUISE_SPEED_MPS, 0.0)
    assert speed_mps == pytest.approx(CRUISE_SPEED_MPS, rel=SPEED_TOLERANCE)
    assert abs(yaw_rate_radps) * (DRIVE_S - ACCELERATION_S) < HEADING_TOLERANCE_RAD


def test_forward_twist_drives_along_heading(world):
    world.set_twist(CRUISE_SPEED_MPS, 0.0)
    world.step(ACCELERATION_S)
    x0_m, y0_m, yaw_rad = world.robot_pose()
    world.step(DRIVE_S - ACCELERATION_S)
    x1_m, y1_m, _ = world.robot_pose()
    travel_heading_rad = math.atan2(y1_m - y0_m, x1_m - x0_m)
    assert abs(angle_difference_rad(travel_heading_rad, yaw_rad)) < HEADING_TOLERANCE_RAD


def test_forward_twist_from_rest_keeps_start_heading(world, course):
    world.set_twist(CRUISE_SPEED_MPS, 0.0)
    world.step(DRIVE_S)
    _, _, yaw_rad = world.robot_pose()
    assert abs(angle_difference_rad(yaw_rad, course.start_pose()[2])) < HEADING_TOLERANCE_RAD


def test_wheels_accelerate_without_overshooting_top_speed(world):
    world.set_twist(CRUISE_SPEED_MPS, 0.0)
    fastest_radps = 0.0
    for _ in range(round(ACCELERATION_S / world.timestep_s)):
        world.step(world.timestep_s)
        fastest_radps = max(fastest_radps, *(abs(speed) for speed in world.wheel_speeds()))
    assert fastest_radps <= world.limits.max_wheel_speed_radps


def test_spin_twist_turns_at_commanded_rate(world):
    _, yaw_rate_radps = measure_after_acceleration(world, 0.0, SPIN_RATE_RADPS)
    assert yaw_rate_radps == pytest.approx(SPIN_RATE_RADPS, rel=YAW_RATE_TOLERANCE)


def test_spin_twist_turns_left_in_place(world, course):
    _, yaw_rate_radps = measure_after_acceleration(world, 0.0, SPIN_RATE_RADPS)
    x_m, y_m, _ = world.robot_pose()
    start_x_m, start_y_m, _ = course.start_pose()
    assert yaw_rate_radps > 0.0
    assert math.hypot(x_m - start_x_m, y_m - start_y_m) < SPIN_DRIFT_TOLERANCE_M


@pytest.mark.parametrize('linear_mps', [TOO_FAST_SPEED_MPS, -TOO_FAST_SPEED_MPS])
def test_speed_is_limited_to_kobuki_top_speed(world, linear_mps):
    speed_mps, _ = measure_after_acceleration(world, linear_mps, 0.0)
    assert speed_mps <= KOBUKI_MAX_LINEAR_SPEED_MPS
    assert speed_mps == pytest.approx(KOBUKI_MAX_LINEAR_SPEED_MPS, rel=SPEED_TOLERANCE)


def test_reset_returns_robot_to_start(world, course):
    world.set_twist(CRUISE_SPEED_MPS, 0.5)
    world.step(1.0)
    world.reset()
    assert world.time_s == 0.0
    assert world.robot_pose() == pytest.approx(course.start_pose())
    assert world.robot_twist() == pytest.approx((0.0, 0.0))


def test_reset_stops_the_motors(world, course):
    world.set_twist(CRUISE_SPEED_MPS, 0.0)
    world.step(1.0)
    world.reset()
    world.step(1.0)
    assert world.robot_pose() == pytest.approx(course.start_pose(), abs=1e-4)


def test_default_focal_length_gives_60_degree_horizontal_fov(world):
    fx_px, fy_px, cx_px, cy_px = world.camera_intrinsics()
    assert fx_px == pytest.approx(DEFAULT_FOCAL_LENGTH_PX)
    assert fx_px == pytest.approx(554.26, abs=0.01)
    assert fy_px == fx_px
    assert (cx_px, cy_px) == (319.5, 239.5)


def test_camera_image_has_requested_shape(camera_view):
    world, image = camera_view
    width_px, height_px = world.image_size_px
    assert image.shape == (height_px, width_px, 3)
    assert image.dtype == np.uint8


def test_camera_keeps_horizontal_fov_at_any_size(camera_view):
    world, _ = camera_view
    width_px, height_px = world.image_size_px
    fx_px, fy_px, _, _ = world.camera_intrinsics()
    camera_fovy_deg = world.model.camera(CAMERA_NAME).fovy[0]
    assert fx_px == pytest.approx(focal_length_px(width_px, DEFAULT_HORIZONTAL_FOV_DEG))
    assert fx_px == pytest.approx((width_px / 2.0) / math.tan(math.radians(30.0)))
    assert camera_fovy_deg == pytest.approx(
        math.degrees(2.0 * math.atan((height_px / 2.0) / fy_px)))


@pytest.mark.parametrize('arc_m, left_m, paint', CAMERA_FLOOR_POINTS)
def test_camera_sees_the_course_where_it_is_painted(camera_view, course, arc_m, left_m, paint):
    world, image = camera_view
    point_xyz_m = floor_point_beside_line(course, arc_m, left_m)
    pixel = pixel_at(image, *project_to_camera_px(world, point_xyz_m))
    assert has_paint(pixel, paint), f'{pixel} is not {paint}'


def test_camera_sees_line_right_of_centre_after_turning_left(camera_view, course):
    world, _ = camera_view
    column_px, _ = project_to_camera_px(world, floor_point_beside_line(course, 0.5, 0.0))
    _, _, cx_px, _ = world.camera_intrinsics()
    assert column_px > cx_px


def test_overview_has_requested_shape(overview_image):
    assert overview_image.shape == (OVERVIEW_SIZE_PX, OVERVIEW_SIZE_PX, 3)
    assert overview_image.dtype == np.uint8


@pytest.mark.parametrize('fraction, left_m, paint', OVERVIEW_FLOOR_POINTS)
def test_overview_pixels_land_on_the_course(shared_world, overview_image, course, fraction,
                                            left_m, paint):
    point_xyz_m = floor_point_beside_line(course, fraction * course.length_m, left_m)
    column_px, row_px = shared_world.overview_pixels(point_xyz_m[np.newaxis, :2],
                                                     OVERVIEW_SIZE_PX)[0]
    pixel = pixel_at(overview_image, column_px, row_px)
    assert has_paint(pixel, paint), f'{pixel} is not {paint}'


def test_overview_shows_robot_on_the_start(shared_world, overview_image, course):
    # The robot stands on the start of the line, so its top plate hides the paint there.
    start_xy_m = np.array([course.start_pose()[:2]])
    column_px, row_px = shared_world.overview_pixels(start_xy_m, OVERVIEW_SIZE_PX)[0]
    pixel = pixel_at(overview_image, column_px, row_px)
    assert not has_paint(pixel, LINE)
    assert not has_paint(pixel, FLOOR)


@pytest.mark.parametrize('arguments', [
    {'image_width_px': 0},
    {'image_height_px': 0},
    {'image_width_px': -640},
    {'horizontal_fov_deg': 0.0},
    {'horizontal_fov_deg': 180.0},
    {'camera_pitch_deg': 100.0},
    {'camera_pitch_deg': -100.0},
    {'start_lateral_offset_m': math.nan},
    {'start_heading_offset_deg': math.inf},
])
def test_bad_arguments_are_rejected(course, arguments):
    with pytest.raises(ValueError):
        FollowbotWorld(course, **arguments)


def test_close_twice_is_harmless(course):
    world = FollowbotWorld(course, texture_size_px=SMALL_TEXTURE_PX)
    world.close()
    world.close()


def test_close_twice_after_rendering_is_harmless(course, opengl):
    world = FollowbotWorld(course, image_width_px=64, image_height_px=48,
                           texture_size_px=SMALL_TEXTURE_PX)
    world.render_camera()
    world.render_overview(64)
    world.close()
    world.close()


@pytest.mark.parametrize('course_name', sorted(COURSES))
def test_every_course_steps_and_renders_without_warnings(opengl, course_name):
    world = small_world(make_course(course_name))
    try:
        world.set_twist(*MODEL_TEST_TWIST)
        world.step(MODEL_TEST_DURATION_S)
        assert warning_counts(world) == dict.fromkeys(WARNING_NAMES, 0)
        assert np.all(np.isfinite(world.data.qpos))
        width_px, height_px = MODEL_TEST_IMAGE_SIZE_PX
        assert world.render_camera().shape == (height_px, width_px, 3)
        depth_m = world.render_depth()
        assert depth_m.shape == (height_px, width_px)
        assert np.any(np.isfinite(depth_m)), 'the depth camera sees no floor'
    finally:
        world.close()


@pytest.mark.parametrize('model_file', MODEL_FILES, ids=lambda path: path.name)
def test_every_model_file_steps_and_renders_without_warnings(opengl, model_file):
    model = mujoco.MjModel.from_xml_path(str(model_file))
    data = mujoco.MjData(model)
    data.ctrl[:] = MODEL_TEST_CONTROL_FRACTION * model.actuator_ctrlrange[:, 1]
    mujoco.mj_step(model, data, nstep=round(MODEL_TEST_DURATION_S / model.opt.timestep))
    assert {name: int(data.warning[int(getattr(mujoco.mjtWarning, name))].number)
            for name in WARNING_NAMES} == dict.fromkeys(WARNING_NAMES, 0)
    assert np.all(np.isfinite(data.qpos))
    width_px, height_px = MODEL_TEST_IMAGE_SIZE_PX
    with mujoco.Renderer(model, height_px, width_px) as renderer:
        renderer.update_scene(data)
        assert renderer.render().shape == (height_px, width_px, 3)
        renderer.enable_depth_rendering()
        assert renderer.render().shape == (height_px, width_px)


def test_sensor_frames_form_the_kinect_chain(world):
    assert [(transform.parent, transform.child) for transform in world.sensor_frames()] == [
        (BASE_FOOTPRINT_FRAME, BASE_LINK_FRAME),
        (BASE_LINK_FRAME, CAMERA_LINK_FRAME),
        (CAMERA_LINK_FRAME, CAMERA_RGB_FRAME),
        (CAMERA_RGB_FRAME, CAMERA_RGB_OPTICAL_FRAME),
        (CAMERA_LINK_FRAME, CAMERA_DEPTH_FRAME),
        (CAMERA_DEPTH_FRAME, CAMERA_DEPTH_OPTICAL_FRAME),
    ]


def test_whole_kinect_is_pitched_down(world):
    camera_link = chain_transforms(world.sensor_frames(), BASE_LINK_FRAME, CAMERA_LINK_FRAME)
    assert camera_link.translation_m == pytest.approx(CAMERA_LINK_XYZ_M)
    assert camera_link.rotation_xyzw == pytest.approx(
        quaternion_from_rpy(0.0, math.radians(DEFAULT_CAMERA_PITCH_DEG), 0.0))


def test_depth_camera_sits_left_of_rgb_camera(world):
    depth_in_rgb = chain_transforms(world.sensor_frames(), CAMERA_RGB_FRAME, CAMERA_DEPTH_FRAME)
    assert depth_in_rgb.translation_m == pytest.approx((0.0, KINECT_DEPTH_OFFSET_LEFT_M, 0.0))
    assert depth_in_rgb.rotation_xyzw == pytest.approx((0.0, 0.0, 0.0, 1.0))


@pytest.mark.parametrize('camera_name, optical_frame', SENSOR_CAMERAS)
def test_optical_frames_match_mujoco_cameras(world, camera_name, optical_frame):
    world.set_twist(CRUISE_SPEED_MPS, 0.5)
    world.step(1.0)
    # The robot's full 3-D pose (MuJoCo quaternions are w, x, y, z).
    base = world.data.body(ROBOT_BODY)
    transforms = world.sensor_frames() + [FrameTransform(
        WORLD_FRAME, BASE_FOOTPRINT_FRAME, tuple(base.xpos), tuple(np.roll(base.xquat, -1)))]
    optical = chain_transforms(transforms, WORLD_FRAME, optical_frame)
    camera = world.data.camera(camera_name)
    # MuJoCo cameras look along -z with +y up; optical frames look along +z with +y down.
    assert optical.translation_m == pytest.approx(camera.xpos, abs=1e-9)
    assert optical.rotation_matrix() == pytest.approx(
        camera.xmat.reshape(3, 3) @ np.diag([1.0, -1.0, -1.0]), abs=1e-9)


@pytest.mark.parametrize('camera_name, optical_frame', SENSOR_CAMERAS)
@pytest.mark.parametrize('arc_m', SENSOR_ARCS_M)
def test_cameras_see_the_line_where_the_frames_project_it(sensor_view, rectangle_course,
                                                          camera_name, optical_frame, arc_m):
    world, images = sensor_view
    image = images[camera_name]
    x_m, y_m, _ = rectangle_course.point_at(arc_m)
    (column_px, row_px), _ = project_through_frames(world, optical_frame, [x_m, y_m, 0.0])
    assert has_paint(pixel_at(image, column_px, row_px), LINE)
    # Where the centre line crosses the nearest whole row: project a stretch of it.
    row = int(round(row_px))
    nearby_arcs_m = np.linspace(arc_m - CROSSING_SEARCH_M, arc_m + CROSSING_SEARCH_M,
                                CROSSING_SAMPLES)
    nearby_xyz_m = [(*rectangle_course.point_at(nearby_m)[:2], 0.0) for nearby_m in nearby_arcs_m]
    nearby_px, _ = project_through_frames(world, optical_frame, np.array(nearby_xyz_m))
    # Farther points lie higher in the image: rows fall as the arc grows.
    crossing_column_px = np.interp(row, nearby_px[::-1, 1], nearby_px[::-1, 0])
    assert line_centre_in_row(image, column_px, row) == pytest.approx(
        crossing_column_px, abs=LINE_CENTRE_TOLERANCE_PX)


def test_default_depth_range_keeps_the_floor_at_the_band_rows(opengl, course):
    world = FollowbotWorld(course, texture_size_px=SMALL_TEXTURE_PX)
    try:
        assert world.depth_range_m == (0.0, KINECT_MAX_DEPTH_M)
        assert np.all(np.isfinite(world.render_depth()[FOLLOWER_BAND_ROWS]))
    finally:
        world.close()


def test_depth_image_has_camera_shape_and_is_reused(depth_world):
    depth_m = depth_world.render_depth()
    width_px, height_px = depth_world.image_size_px
    assert depth_m.shape == (height_px, width_px)
    assert depth_m.dtype == np.float32
    assert depth_world.render_depth() is depth_m


@pytest.mark.parametrize('row_px', DEPTH_ROWS_PX)
def test_depth_of_the_floor_matches_the_geometry(depth_world, row_px):
    depth_m = depth_world.render_depth()
    assert depth_m[row_px, DEPTH_COLUMNS_PX] == pytest.approx(
        floor_depth_m(depth_world, row_px), abs=DEPTH_TOLERANCE_M)


def test_depth_is_nan_above_the_horizon(opengl, course):
    world = FollowbotWorld(course, texture_size_px=SMALL_TEXTURE_PX, camera_pitch_deg=0.0,
                           min_depth_m=0.0, max_depth_m=math.inf)
    try:
        depth_m = world.render_depth()
        _, _, _, cy_px = world.camera_intrinsics()
        assert np.all(np.isnan(depth_m[:math.ceil(cy_px)]))
        last_row = depth_m.shape[0] - 1
        assert depth_m[last_row, DEPTH_COLUMNS_PX] == pytest.approx(
            floor_depth_m(world, last_row), abs=DEPTH_TOLERANCE_M)
    finally:
        world.close()


def test_depth_nearer_than_a_minimum_range_is_nan(opengl, course):
    world = FollowbotWorld(course, texture_size_px=SMALL_TEXTURE_PX,
                           min_depth_m=KINECT_MIN_DEPTH_M)
    try:
        depth_m = world.render_depth()
        for row_px in DEPTH_ROWS_PX:
            expected_m = floor_depth_m(world, row_px)
            if expected_m < KINECT_MIN_DEPTH_M:
                assert np.all(np.isnan(depth_m[row_px])), f'row {row_px}'
            else:
                assert depth_m[row_px, DEPTH_COLUMNS_PX] == pytest.approx(
                    expected_m, abs=DEPTH_TOLERANCE_M)
    finally:
        world.close()


def test_depth_sees_an_obstacle_nearer_than_the_floor(opengl, rectangle_course,
                                                      obstacle_models_dir):
    world = FollowbotWorld(rectangle_course, texture_size_px=SMALL_TEXTURE_PX,
                           models_dir=obstacle_models_dir, min_depth_m=0.0)
    try:
        depth_m = world.render_depth().copy()
        face_x_m = OBSTACLE_CENTRE_M[0] - OBSTACLE_HALF_SIZE_M[0]
        for height_m, left_m in OBSTACLE_FACE_POINTS_M:
            point_m = [face_x_m, OBSTACLE_CENTRE_M[1] + left_m, height_m]
            (column_px, row_px), expected_m = project_through_frames(
                world, CAMERA_DEPTH_OPTICAL_FRAME, point_m)
            row, column = int(round(row_px)), int(round(column_px))
            assert 0 <= row < depth_m.shape[0] and 0 <= column < depth_m.shape[1]
            assert depth_m[row, column] == pytest.approx(expected_m, abs=DEPTH_TOLERANCE_M)
            assert depth_m[row, column] < floor_depth_m(world, row) - DEPTH_TOLERANCE_M
    finally:
        world.close()


def test_zero_noise_leaves_frames_untouched(opengl, course):
    world = noisy_world(course, stddev=0.0)
    try:
        frame = world.render_camera().copy()
        width_px, height_px = NOISE_IMAGE_SIZE_PX
        with mujoco.Renderer(world.model, height_px, width_px) as renderer:
            renderer.update_scene(world.data, camera=CAMERA_NAME)
            assert np.array_equal(frame, renderer.render())
    finally:
        world.close()


def test_noise_has_requested_spread_and_no_bias(noisy):
    width_px, height_px = NOISE_IMAGE_SIZE_PX
    with mujoco.Renderer(noisy.model, height_px, width_px) as renderer:
        renderer.update_scene(noisy.data, camera=CAMERA_NAME)
        clean = renderer.render().astype(int)
    unsaturated = (clean > NOISE_UNSATURATED_MARGIN) & (clean < 255 - NOISE_UNSATURATED_MARGIN)
    differences = np.concatenate([(noisy.render_camera().astype(int) - clean)[unsaturated]
                                  for _ in range(3)])
    assert np.std(differences) == pytest.approx(NOISE_STDDEV, abs=NOISE_STDDEV_TOLERANCE)
    assert abs(np.mean(differences)) < NOISE_STDDEV_TOLERANCE


def frames_over_time(world, count=3):
    """Return camera frames taken one physics step apart."""
    frames = []
    for _ in range(count):
        frames.append(world.render_camera().copy())
        world.step(world.timestep_s)
    return frames


def test_noise_changes_from_frame_to_frame(noisy):
    first, second = frames_over_time(noisy, 2)
    assert not np.array_equal(first, second)


def test_noise_of_an_instant_does_not_depend_on_frames_rendered_before(noisy):
    # A simulator renders only while someone subscribes; its runs must still repeat.
    first = noisy.render_camera().copy()
    for _ in range(3):
        noisy.render_camera()
    assert np.array_equal(noisy.render_camera(), first)


@pytest.mark.parametrize('seed, same', [(NOISE_SEED, True), (NOISE_SEED + 1, False)])
def test_noise_is_reproducible_from_its_seed(noisy, course, seed, same):
    other = noisy_world(course, seed=seed)
    try:
        frames_noisy = frames_over_time(noisy)
        frames_other = frames_over_time(other)
        assert all(np.array_equal(a, b) for a, b in zip(frames_noisy, frames_other)) == same
    finally:
        other.close()


def test_reset_repeats_the_noise(noisy):
    before = frames_over_time(noisy)
    noisy.reset()
    after = frames_over_time(noisy)
    assert all(np.array_equal(a, b) for a, b in zip(before, after))


def run_recording(world):
    """
    Drive a fixed sequence of commands, recording positions and camera frames.

    :return: (list of qpos copies, list of frame copies).
    """
    positions, frames = [], []
    for step in range(DETERMINISM_STEPS):
        world.set_twist(CRUISE_SPEED_MPS, (-1.0) ** step)
        world.step(DETERMINISM_STEP_S)
        positions.append(world.data.qpos.copy())
        frames.append(world.render_camera().copy())
    return positions, frames


def test_same_seed_and_commands_give_identical_runs(noisy, course):
    other = noisy_world(course)
    try:
        first_positions, first_frames = run_recording(noisy)
        other_positions, other_frames = run_recording(other)
        noisy.reset()
        again_positions, again_frames = run_recording(noisy)
        for positions, frames in ((other_positions, other_frames),
                                  (again_positions, again_frames)):
            assert all(np.array_equal(a, b) for a, b in zip(first_positions, positions))
            assert all(np.array_equal(a, b) for a, b in zip(first_frames, frames))
    finally:
        other.close()


@pytest.mark.parametrize('floor_size_m', FLOOR_SIZES_M)
def test_floor_takes_the_course_size(floor_size_m):
    world = FollowbotWorld(circle_course(floor_size_m), texture_size_px=SMALL_TEXTURE_PX)
    assert world.model.geom(FLOOR_GEOM).size[:2] == pytest.approx(
        (floor_size_m / 2.0, floor_size_m / 2.0))
    world.close()


@pytest.mark.parametrize('floor_size_m', FLOOR_SIZES_M)
def test_overview_shows_the_whole_floor(opengl, floor_size_m):
    course = circle_course(floor_size_m)
    world = FollowbotWorld(course, texture_size_px=FLOOR_TEST_TEXTURE_PX)
    try:
        image = world.render_overview(OVERVIEW_SIZE_PX)
        corner_m = FLOOR_CORNER_FRACTION * floor_size_m / 2.0
        corners_xy = [(x_m, y_m) for x_m in (-corner_m, corner_m) for y_m in (-corner_m, corner_m)]
        for corner_px in world.overview_pixels(np.array(corners_xy), OVERVIEW_SIZE_PX):
            assert has_paint(pixel_at(image, *corner_px), FLOOR)
        for fraction, left_m, paint in OVERVIEW_FLOOR_POINTS:
            point_xy = floor_point_beside_line(course, fraction * course.length_m, left_m)[:2]
            point_px = world.overview_pixels(point_xy[np.newaxis], OVERVIEW_SIZE_PX)[0]
            assert has_paint(pixel_at(image, *point_px), paint), f'{point_xy} is not {paint}'
    finally:
        world.close()


def test_reset_robot_keeps_the_clock_running(world, course):
    world.set_twist(CRUISE_SPEED_MPS, 0.5)
    world.step(1.0)
    wheel_angles_rad = world.wheel_angles()
    world.reset_robot()
    assert world.time_s == pytest.approx(1.0)
    assert world.robot_pose() == pytest.approx(course.start_pose())
    assert world.robot_twist() == pytest.approx((0.0, 0.0))
    assert world.wheel_speeds() == pytest.approx((0.0, 0.0))
    assert world.wheel_angles() == wheel_angles_rad


def test_reset_robot_stops_the_motors(world, course):
    world.set_twist(CRUISE_SPEED_MPS, 0.0)
    world.step(1.0)
    world.reset_robot()
    world.step(1.0)
    assert world.time_s == pytest.approx(2.0)
    assert world.robot_pose() == pytest.approx(course.start_pose(), abs=1e-4)


def test_reset_robot_to_a_pose_puts_it_there_at_rest(world, course):
    x_m, y_m, heading_rad = course.point_at(5.0)
    pose = (x_m + 0.03, y_m - 0.02, heading_rad + 0.1)
    world.set_twist(CRUISE_SPEED_MPS, 0.5)
    world.step(1.0)
    world.reset_robot(pose)
    assert world.robot_pose() == pytest.approx(pose)
    assert world.robot_twist() == pytest.approx((0.0, 0.0))
    world.step(0.5)
    assert world.robot_pose() == pytest.approx(pose, abs=1e-4)


def test_reset_after_reset_robot_restarts_the_clock(world):
    world.step(0.5)
    world.reset_robot()
    world.reset()
    assert world.time_s == 0.0
    assert world.wheel_angles() == (0.0, 0.0)


def test_viewer_needs_a_display(world, monkeypatch):
    monkeypatch.delenv('DISPLAY', raising=False)
    monkeypatch.delenv('WAYLAND_DISPLAY', raising=False)
    with pytest.raises(ViewerUnavailableError, match='DISPLAY'):
        world.open_viewer()
    assert world.sync_viewer() is False
