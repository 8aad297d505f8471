"""Tests of the projection of image pixels onto the floor, against geometry and the simulator."""

import dataclasses
import math

from followbot.ground_projection import CameraGeometry
from followbot.line_detector import LineDetector
from followbot_sim.course import make_course
from followbot_sim.world import FollowbotWorld
from followbot_sim.world import RenderingUnavailableError
import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo

# The simulated Kinect: 640x480, 60 degrees across, 0.30 m up, 0.10 m ahead of the robot's
# centre, tilted down 30 degrees.
WIDTH_PX = 640
HEIGHT_PX = 480
FOCAL_PX = (WIDTH_PX / 2) / math.tan(math.radians(30.0))
CX_PX = (WIDTH_PX - 1) / 2
CY_PX = (HEIGHT_PX - 1) / 2
CAMERA_HEIGHT_M = 0.30
CAMERA_PITCH_RAD = math.radians(30.0)
CAMERA_FORWARD_M = 0.10
CAMERA = CameraGeometry(fx_px=FOCAL_PX, fy_px=FOCAL_PX, cx_px=CX_PX, cy_px=CY_PX,
                        height_m=CAMERA_HEIGHT_M, pitch_rad=CAMERA_PITCH_RAD,
                        forward_m=CAMERA_FORWARD_M)
# The pixel grid compared with the independent ray intersection: every 16th pixel.
GRID_STEP_PX = 16
# Floating-point agreement of two computations of the same floor point.
FLOOR_POINT_TOLERANCE_M = 1e-9
# The simulator renders the course's 0.19 m line; the band centroids lie on its centre line
# within this distance.
SIMULATED_LINE_TOLERANCE_M = 0.01
# The REP-103 robot axes of the optical frame's x (right), y (down) and z (ahead) on a level
# camera, as columns.
OPTICAL_TO_LEVEL_CAMERA = np.array([[0.0, 0.0, 1.0],
                                    [-1.0, 0.0, 0.0],
                                    [0.0, -1.0, 0.0]])


def with_fields(**changes):
    """Return the simulated camera's geometry with some fields changed (and validated)."""
    return dataclasses.replace(CAMERA, **changes)


def optical_to_robot_rotation(pitch_rad):
    """
    Return the rotation from a camera's optical frame to the robot's frame.

    :param pitch_rad: downward tilt of the camera from level.
    :return: a 3x3 matrix whose columns are the optical axes in the robot's frame.
    """
    # Tilting down is a positive rotation about the robot's y axis (left).
    cos_pitch, sin_pitch = math.cos(pitch_rad), math.sin(pitch_rad)
    pitch_down = np.array([[cos_pitch, 0.0, sin_pitch],
                           [0.0, 1.0, 0.0],
                           [-sin_pitch, 0.0, cos_pitch]])
    return pitch_down @ OPTICAL_TO_LEVEL_CAMERA


def intersect_rays_with_floor(camera, u_px, v_px):
    """
    Intersect pixel rays with the floor through a rotation matrix, independently of the module.

    :param camera: the CameraGeometry.
    :param u_px: pixel columns, a 1-D array.
    :param v_px: pixel rows, a 1-D array.
    :return: (x_m, y_m) arrays in the robot's frame, NaN where the ray does not go down.
    """
    inverse_k = np.linalg.inv(np.array([[camera.fx_px, 0.0, camera.cx_px],
                                        [0.0, camera.fy_px, camera.cy_px],
                                        [0.0, 0.0, 1.0]]))
    pixels = np.stack([u_px, v_px, np.ones_like(u_px)])
    rays = optical_to_robot_rotation(camera.pitch_rad) @ (inverse_k @ pixels)
    origin = np.array([[camera.forward_m], [0.0], [camera.height_m]])
    descending = rays[2] < 0.0
    distance = np.full(rays.shape[1], np.nan)
    distance[descending] = -camera.height_m / rays[2, descending]
    points = origin + distance * rays
    return points[0], points[1]


def floor_points_to_pixels(camera, x_m, y_m):
    """
    Project floor points in the robot's frame into the image with an ideal pinhole.

    :param camera: the CameraGeometry.
    :param x_m: forward coordinates, a 1-D array.
    :param y_m: leftward coordinates, a 1-D array.
    :return: (u_px, v_px) arrays.
    """
    offsets = np.stack([x_m - camera.forward_m, y_m, np.full_like(x_m, -camera.height_m)])
    in_optical = optical_to_robot_rotation(camera.pitch_rad).T @ offsets
    u_px = camera.cx_px + camera.fx_px * in_optical[0] / in_optical[2]
    v_px = camera.cy_px + camera.fy_px * in_optical[1] / in_optical[2]
    return u_px, v_px


def horizon_row_px(camera):
    """Return the image row of the horizon: rays through it run level."""
    return camera.cy_px - camera.fy_px * math.tan(camera.pitch_rad)


# Validation and construction.

@pytest.mark.parametrize('field, value, message_part', (
    ('fx_px', 0.0, 'fx_px must be finite and positive, got 0.0'),
    ('fx_px', -554.0, 'fx_px must be finite and positive'),
    ('fx_px', math.inf, 'fx_px must be finite and positive'),
    ('fy_px', math.nan, 'fy_px must be finite and positive'),
    ('height_m', 0.0, 'height_m must be finite and positive'),
    ('height_m', -0.3, 'height_m must be finite and positive'),
    ('cx_px', math.nan, 'cx_px must be finite'),
    ('cy_px', -math.inf, 'cy_px must be finite'),
    ('pitch_rad', math.inf, 'pitch_rad must be finite'),
    ('forward_m', math.nan, 'forward_m must be finite'),
))
def test_camera_geometry_rejects_geometry_that_cannot_project(field, value, message_part):
    with pytest.raises(ValueError, match=message_part):
        with_fields(**{field: value})


@pytest.mark.parametrize('changes', (
    {'pitch_rad': -0.2},
    {'pitch_rad': 0.0},
    {'forward_m': -0.05},
    {'cx_px': -10.0, 'cy_px': 2000.0},
))
def test_camera_geometry_accepts_any_finite_mounting(changes):
    camera = with_fields(**changes)
    for name, value in changes.items():
        assert getattr(camera, name) == value


def test_from_camera_matrix_reads_a_camera_infos_k():
    info = CameraInfo(k=[FOCAL_PX, 0.0, CX_PX, 0.0, FOCAL_PX + 1.0, CY_PX, 0.0, 0.0, 1.0])
    camera = CameraGeometry.from_camera_matrix(
        info.k, CAMERA_HEIGHT_M, CAMERA_PITCH_RAD, CAMERA_FORWARD_M)
    assert camera == with_fields(fy_px=FOCAL_PX + 1.0)
    assert all(isinstance(value, float) for value in (
        camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px))


def test_from_camera_matrix_puts_the_camera_at_the_robot_centre_by_default():
    camera = CameraGeometry.from_camera_matrix(
        (FOCAL_PX, 0, CX_PX, 0, FOCAL_PX, CY_PX, 0, 0, 1), CAMERA_HEIGHT_M, CAMERA_PITCH_RAD)
    assert camera.forward_m == 0.0
    assert camera == with_fields(forward_m=0.0)


@pytest.mark.parametrize('k, message_part', (
    ((FOCAL_PX, 0.0, CX_PX, 0.0, FOCAL_PX, CY_PX, 0.0, 0.0), 'K must have 9 elements, got 8'),
    (np.eye(3), 'K must have 9 elements, got 3'),
    ((), 'K must have 9 elements, got 0'),
    # An all-zero K: a CameraInfo from an uncalibrated camera.
    ((0.0,) * 9, 'fx_px must be finite and positive'),
))
def test_from_camera_matrix_rejects_a_k_that_is_not_a_pinhole(k, message_part):
    with pytest.raises(ValueError, match=message_part):
        CameraGeometry.from_camera_matrix(k, CAMERA_HEIGHT_M, CAMERA_PITCH_RAD)


# Where pixels land.

@pytest.mark.parametrize('pitch_deg', (10.0, 30.0, 45.0, 60.0, 89.0))
@pytest.mark.parametrize('height_m, forward_m', ((0.30, 0.10), (1.2, 0.0), (0.05, -0.2)))
def test_principal_point_lands_straight_ahead_at_height_over_tan_pitch(
        pitch_deg, height_m, forward_m):
    camera = with_fields(pitch_rad=math.radians(pitch_deg), height_m=height_m,
                         forward_m=forward_m)
    x_m, y_m = camera.pixels_to_floor(CX_PX, CY_PX)
    assert x_m == pytest.approx(forward_m + height_m / math.tan(math.radians(pitch_deg)))
    assert y_m == pytest.approx(0.0, abs=1e-12)


def test_camera_looking_straight_down_sees_the_floor_under_it():
    camera = with_fields(pitch_rad=math.pi / 2)
    x_m, y_m = camera.pixels_to_floor(CX_PX, CY_PX)
    assert x_m == pytest.approx(CAMERA_FORWARD_M)
    assert y_m == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize('column_offset_px', (1.0, 40.0, 300.0))
@pytest.mark.parametrize('row_px', (CY_PX, 300.0, HEIGHT_PX - 1.0))
def test_pixels_right_of_centre_land_right_and_mirror_ones_left(column_offset_px, row_px):
    (right_x_m, left_x_m), (right_y_m, left_y_m) = CAMERA.pixels_to_floor(
        [CX_PX + column_offset_px, CX_PX - column_offset_px], [row_px, row_px])
    assert right_y_m < 0.0 < left_y_m
    assert left_y_m == pytest.approx(-right_y_m)
    assert left_x_m == pytest.approx(right_x_m)


def test_lower_rows_land_nearer():
    rows_px = np.arange(HEIGHT_PX)
    x_m, y_m = CAMERA.pixels_to_floor(np.full(HEIGHT_PX, CX_PX), rows_px)
    assert np.all(np.isfinite(x_m))
    assert np.all(np.diff(x_m) < 0.0)
    assert np.all(x_m > CAMERA_FORWARD_M)
    np.testing.assert_allclose(y_m, 0.0, atol=1e-12)


def test_rows_at_or_above_the_horizon_see_no_floor():
    camera = with_fields(pitch_rad=math.radians(10.0))
    horizon_px = horizon_row_px(camera)
    rows_px = np.array([horizon_px - 200.0, horizon_px - 1.0, horizon_px - 1e-6,
                        horizon_px + 1.0])
    columns_px = np.array([0.0, CX_PX, 500.0, CX_PX])
    x_m, y_m = camera.pixels_to_floor(columns_px, rows_px)
    assert np.all(np.isnan(x_m[:3])) and np.all(np.isnan(y_m[:3]))
    # A row just below the horizon sees the floor, far away.
    assert x_m[3] > 10.0
    assert y_m[3] == pytest.approx(0.0, abs=1e-9)


def test_level_camera_has_its_horizon_on_the_principal_row():
    camera = with_fields(pitch_rad=0.0)
    assert horizon_row_px(camera) == CY_PX
    x_m, y_m = camera.pixels_to_floor([CX_PX, CX_PX, 100.0, CX_PX], [CY_PX, CY_PX - 1.0,
                                                                     CY_PX, CY_PX + 1.0])
    assert np.all(np.isnan(x_m[:3])) and np.all(np.isnan(y_m[:3]))
    # One row below the principal row, the ray falls by 1/fy per metre ahead.
    assert x_m[3] == pytest.approx(CAMERA_FORWARD_M + CAMERA_HEIGHT_M * FOCAL_PX)
    assert y_m[3] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize('camera', (
    CAMERA,
    with_fields(pitch_rad=math.radians(5.0)),
    with_fields(pitch_rad=math.radians(75.0), forward_m=-0.1, height_m=1.0),
    with_fields(fx_px=400.0, fy_px=420.0, cx_px=300.0, cy_px=260.0),
    with_fields(pitch_rad=math.radians(-5.0)),
), ids=('simulated_kinect', 'nearly_level', 'steep_high', 'non_square_pixels', 'looking_up'))
def test_grid_of_pixels_matches_an_independent_ray_intersection(camera):
    columns_px, rows_px = np.meshgrid(np.arange(0, WIDTH_PX, GRID_STEP_PX, dtype=float),
                                      np.arange(0, HEIGHT_PX, GRID_STEP_PX, dtype=float))
    x_m, y_m = camera.pixels_to_floor(columns_px, rows_px)
    expected_x_m, expected_y_m = intersect_rays_with_floor(
        camera, columns_px.ravel(), rows_px.ravel())
    assert x_m.shape == y_m.shape == columns_px.shape
    np.testing.assert_array_equal(np.isnan(x_m.ravel()), np.isnan(expected_x_m))
    np.testing.assert_array_equal(np.isnan(y_m), np.isnan(x_m))
    np.testing.assert_allclose(x_m.ravel(), expected_x_m, rtol=1e-9,
                               atol=FLOOR_POINT_TOLERANCE_M)
    np.testing.assert_allclose(y_m.ravel(), expected_y_m, rtol=1e-9,
                               atol=FLOOR_POINT_TOLERANCE_M)


def test_floor_points_seen_by_a_pinhole_come_back_where_they_were():
    ahead_m, left_m = np.meshgrid(np.linspace(0.4, 3.0, 14), np.linspace(-0.8, 0.8, 9))
    ahead_m, left_m = ahead_m.ravel(), left_m.ravel()
    u_px, v_px = floor_points_to_pixels(CAMERA, ahead_m, left_m)
    x_m, y_m = CAMERA.pixels_to_floor(u_px, v_px)
    np.testing.assert_allclose(x_m, ahead_m, atol=FLOOR_POINT_TOLERANCE_M)
    np.testing.assert_allclose(y_m, left_m, atol=FLOOR_POINT_TOLERANCE_M)


def test_a_higher_camera_sees_the_same_pixels_proportionally_farther():
    columns_px = np.array([0.0, CX_PX, 500.0, 639.0])
    rows_px = np.array([479.0, 300.0, CY_PX, 200.0])
    x_m, y_m = CAMERA.pixels_to_floor(columns_px, rows_px)
    higher_x_m, higher_y_m = with_fields(height_m=2 * CAMERA_HEIGHT_M).pixels_to_floor(
        columns_px, rows_px)
    np.testing.assert_allclose(higher_x_m - CAMERA_FORWARD_M, 2 * (x_m - CAMERA_FORWARD_M))
    np.testing.assert_allclose(higher_y_m, 2 * y_m)


def test_mounting_forward_shifts_points_forward_only():
    columns_px, rows_px = [0.0, CX_PX, 639.0], [479.0, 300.0, 250.0]
    x_m, y_m = CAMERA.pixels_to_floor(columns_px, rows_px)
    shifted_x_m, shifted_y_m = with_fields(forward_m=CAMERA_FORWARD_M + 0.25).pixels_to_floor(
        columns_px, rows_px)
    np.testing.assert_allclose(shifted_x_m, x_m + 0.25)
    np.testing.assert_array_equal(shifted_y_m, y_m)


def test_scalars_give_scalars_and_lists_give_arrays():
    x_m, y_m = CAMERA.pixels_to_floor(CX_PX, 400.0)
    assert np.ndim(x_m) == np.ndim(y_m) == 0
    x_m, y_m = CAMERA.pixels_to_floor([1.0, 2.0, 3.0], [400.0, 410.0, 420.0])
    assert x_m.shape == y_m.shape == (3,)
    x_m, y_m = CAMERA.pixels_to_floor([], [])
    assert x_m.shape == y_m.shape == (0,)


@pytest.mark.parametrize('camera', (
    CAMERA,
    with_fields(pitch_rad=math.radians(75.0), forward_m=-0.1, height_m=1.0),
    # A phone held above the floor, its top rows looking back past the vertical.
    with_fields(pitch_rad=math.radians(80.0), cy_px=-94.0, height_m=1.1),
), ids=('simulated_kinect', 'steep_high', 'past_the_vertical'))
def test_a_line_across_the_view_spans_the_rows_between_its_two_edges(camera):
    width_m = 0.05
    rows_px = np.arange(0.0, HEIGHT_PX, GRID_STEP_PX)
    ahead_m, _ = camera.pixels_to_floor(np.full_like(rows_px, CX_PX), rows_px)
    edges_m = np.concatenate([ahead_m - width_m / 2.0, ahead_m + width_m / 2.0])
    _, edge_rows_px = floor_points_to_pixels(camera, edges_m, np.zeros_like(edges_m))
    near_px, far_px = np.split(edge_rows_px, 2)
    np.testing.assert_allclose(camera.across_line_rows_px(rows_px, width_m),
                               near_px - far_px, rtol=1e-9)


# Against the simulator.

def test_band_centroids_in_the_simulated_camera_land_on_the_course_centre_line():
    course = make_course('book_loop')
    world = FollowbotWorld(course)
    try:
        image_rgb = world.render_camera()
    except RenderingUnavailableError as error:
        world.close()
        pytest.skip(f'MuJoCo cannot render here: {error}')
    try:
        fx_px, fy_px, cx_px, cy_px = world.camera_intrinsics()
        camera = CameraGeometry(fx_px=fx_px, fy_px=fy_px, cx_px=cx_px, cy_px=cy_px,
                                height_m=CAMERA_HEIGHT_M,
                                pitch_rad=math.radians(world.camera_pitch_deg),
                                forward_m=CAMERA_FORWARD_M)
        assert world.camera_pitch_deg == pytest.approx(30.0)
        detection = LineDetector().detect(image_rgb, 'rgb8')
        robot_x_m, robot_y_m, robot_yaw_rad = course.start_pose()
        assert world.robot_pose() == pytest.approx((robot_x_m, robot_y_m, robot_yaw_rad))
    finally:
        world.close()

    assert detection.confidence == 1.0
    ahead_m, left_m = camera.pixels_to_floor(
        [band.centroid_x_px for band in detection.bands],
        [band.centroid_y_px for band in detection.bands])
    # Nearest band nearest: the bands see the floor ever farther ahead.
    assert np.all(np.diff(ahead_m) > 0.0)
    cos_yaw, sin_yaw = math.cos(robot_yaw_rad), math.sin(robot_yaw_rad)
    for forward_m, leftward_m in zip(ahead_m, left_m):
        world_x_m = robot_x_m + cos_yaw * forward_m - sin_yaw * leftward_m
        world_y_m = robot_y_m + sin_yaw * forward_m + cos_yaw * leftward_m
        distance_m, _ = course.nearest(world_x_m, world_y_m)
        assert distance_m < SIMULATED_LINE_TOLERANCE_M
