"""
Tests of the MuJoCo world: the model steps cleanly, drives like a Kobuki and renders the course.

Physics tests share one world per module and reset it before each test; rendering tests skip
where no OpenGL context can be made for ``mujoco.Renderer``.
"""

import math

from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.diff_drive import KOBUKI_MAX_LINEAR_SPEED_MPS
from followbot_sim.world import CAMERA_NAME
from followbot_sim.world import DEFAULT_HORIZONTAL_FOV_DEG
from followbot_sim.world import DEFAULT_IMAGE_HEIGHT_PX
from followbot_sim.world import DEFAULT_IMAGE_WIDTH_PX
from followbot_sim.world import focal_length_px
from followbot_sim.world import FollowbotWorld
from followbot_sim.world import ROBOT_BODY
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


@pytest.fixture(scope='module')
def opengl():
    """Skip the test unless a ``mujoco.Renderer`` can be made here."""
    try:
        renderer = mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 8, 8)
    except Exception as error:
        pytest.skip(f'mujoco.Renderer cannot be created (no OpenGL context?): {error}')
    renderer.close()


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
    x_m, y_m, heading_rad = course.point_at(arc_m)
    return np.array([x_m - left_m * math.sin(heading_rad),
                     y_m + left_m * math.cos(heading_rad), 0.0])


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
