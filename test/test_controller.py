"""
Tests of the line-following controller: its config, its two steering laws, its states over time.

Frames come 50 ms apart, as from the simulated camera. Detections are built band by band, as the
detector makes them; floor points are built on rays and circles from the robot, where the answer
is known by geometry. Where a test is about a steering law, not about the acceleration limits,
it uses limits so high that one frame reaches any command.
"""

from collections import namedtuple
import dataclasses
from dataclasses import fields
import math

from conftest import PACKAGE_DIR
from followbot.controller import arc_pose
from followbot.controller import compose_poses
from followbot.controller import ControllerConfig
from followbot.controller import estimate_path
from followbot.controller import line_ends_in_view
from followbot.controller import LineFollowingController
from followbot.controller import LOST_LINE_BEHAVIOURS
from followbot.controller import MAX_TIME_STEP_S
from followbot.controller import PathEstimate
from followbot.controller import pursuit_curvature
from followbot.controller import relative_pose
from followbot.controller import RememberedRoute
from followbot.controller import STEERING_LAWS
from followbot.controller import VelocityCommand
from followbot.line_detector import BandDetection
from followbot.line_detector import Detection
import numpy as np
import pytest
import yaml

BOOK_PARAMETERS_FILE = PACKAGE_DIR / 'config' / 'book_follower.yaml'
IMAGE_WIDTH_PX = 640
IMAGE_HEIGHT_PX = 480
# The detector's default number of bands, and where they lie in a 640x480 image.
BAND_COUNT = 6
NEAREST_BAND_CENTRE_PX = 456
BAND_SPACING_PX = 60
BAND_HEIGHT_PX = 12
LINE_AREA_PX = 300
# The simulated camera's 20 Hz.
FRAME_PERIOD_S = 0.05
# Distances ahead at which the bands see the floor, nearest first (the default camera's ~0.34 m
# to ~0.87 m).
BAND_DISTANCES_M = (0.35, 0.45, 0.55, 0.65, 0.75, 0.85)
# Accelerations so high that one frame reaches any command: the steering law's own command shows.
UNLIMITED_ACCELERATIONS = {
    'max_linear_acceleration_mps2': 1e6, 'max_angular_acceleration_radps2': 1e6}
# Enough frames for any default acceleration limit to reach its target.
SETTLING_FRAMES = 60
# What one frame did: the command returned and the controller's state after it.
Frame = namedtuple('Frame', 'command state')
STATES = ('waiting', 'acquiring', 'tracking', 'coasting', 'lost', 'line end')
LEFT = 1
RIGHT = -1
# Rounding allowed where a bound is reached exactly.
TOLERANCE = 1e-9
# Speed planning stated here, not taken from the defaults, which may still be tuned.
SPEED_PLANNING = {
    'linear_speed_mps': 0.7, 'max_lateral_acceleration_mps2': 0.6, 'bearing_gain_radps': 2.0,
    'max_angular_speed_radps': 3.0, 'look_ahead_m': 0.5, 'confidence_for_full_speed': 0.5}


# Detections and floor points.

def band(index, centroid_x_px=None):
    """
    Return what band ``index`` (0 nearest) saw: the line at a column, or nothing when None.

    :param index: the band's place, nearest first.
    :param centroid_x_px: the column of the line's stripe in the band, or None.
    :return: the BandDetection.
    """
    centre_px = NEAREST_BAND_CENTRE_PX - index * BAND_SPACING_PX
    top_px = centre_px - BAND_HEIGHT_PX // 2
    found = centroid_x_px is not None
    return BandDetection(
        found=found, centroid_x_px=centroid_x_px if found else math.nan,
        centroid_y_px=float(centre_px) if found else math.nan,
        area_px=LINE_AREA_PX if found else 0, top_px=top_px, bottom_px=top_px + BAND_HEIGHT_PX)


def seen(error=0.0, seen_count=BAND_COUNT):
    """
    Return a Detection whose nearest ``seen_count`` bands saw the line at a normalised error.

    :param error: the line's offset from the image centre, -1 (left edge) to 1 (right edge).
    :param seen_count: how many bands, nearest first, saw it; the others saw nothing.
    :return: the Detection, as sure as the share of the bands that saw the line.
    """
    centroid_x_px = IMAGE_WIDTH_PX / 2 * (1.0 + error)
    return Detection(
        bands=tuple(band(index, centroid_x_px if index < seen_count else None)
                    for index in range(BAND_COUNT)),
        image_width_px=IMAGE_WIDTH_PX, image_height_px=IMAGE_HEIGHT_PX,
        confidence=seen_count / BAND_COUNT)


def nothing_seen():
    """Return the Detection of a camera frame in which no band saw the line."""
    return seen(seen_count=0)


def ray_points(bearing_rad, distances_m=BAND_DISTANCES_M):
    """
    Return floor points on a straight line from the robot, in a direction.

    :param bearing_rad: the direction from the robot's heading, positive to the left.
    :param distances_m: the points' distances from the robot, nearest first.
    :return: an (n, 2) array of (x forward, y left) points.
    """
    distances_m = np.asarray(distances_m, dtype=float)
    return np.stack((distances_m * math.cos(bearing_rad),
                     distances_m * math.sin(bearing_rad)), axis=1)


def circle_bearing_rad(radius_m, side, distance_m):
    """
    Return the direction of the point at a distance on the robot's circle of a radius.

    The circle leaves the robot straight ahead, bending to ``side``; a chord of length d of a
    circle of radius R makes the angle asin(d / 2R) with the tangent at its start.

    :param radius_m: the circle's radius.
    :param side: LEFT or RIGHT.
    :param distance_m: the point's distance from the robot, at most the diameter.
    :return: the direction from the robot's heading, positive to the left.
    """
    return side * math.asin(distance_m / (2.0 * radius_m))


def circle_points(radius_m, side, distances_m=BAND_DISTANCES_M):
    """
    Return floor points on a circle that leaves the robot straight ahead, bending to a side.

    :param radius_m: the circle's radius.
    :param side: LEFT or RIGHT.
    :param distances_m: the points' distances from the robot, nearest first.
    :return: an (n, 2) array of (x forward, y left) points.
    """
    return np.array([ray_points(circle_bearing_rad(radius_m, side, distance_m), (distance_m,))[0]
                     for distance_m in distances_m])


STRAIGHT_AHEAD_M = ray_points(0.0)


# Driving a controller.

def unlimited_config(**fields_to_set):
    """Return a ControllerConfig with unlimited accelerations and the given fields."""
    return ControllerConfig(**{**UNLIMITED_ACCELERATIONS, **fields_to_set})


def drive(controller, detection, floor_xy_m=None, frame_count=1, start_s=0.0):
    """
    Give a controller the same frame ``frame_count`` times, one frame period apart.

    :param controller: the LineFollowingController.
    :param detection: the Detection of every frame.
    :param floor_xy_m: the floor points of every frame, or None.
    :param frame_count: how many frames.
    :param start_s: the first frame's time.
    :return: a list of Frame, the command and the state after each frame.
    """
    frames = []
    for index in range(frame_count):
        command = controller.update(detection, start_s + index * FRAME_PERIOD_S, floor_xy_m)
        frames.append(Frame(command, controller.state))
    return frames


def law_command(floor_xy_m=STRAIGHT_AHEAD_M, detection=None, **fields_to_set):
    """
    Return the command of a fresh controller that has trusted a frame, without acceleration limits.

    :param floor_xy_m: the floor points of the frame.
    :param detection: the Detection of the frame; all bands see the line when None.
    :param fields_to_set: ControllerConfig fields other than the accelerations.
    :return: the VelocityCommand the steering law gives for the frame.
    """
    config = unlimited_config(**fields_to_set)
    controller = LineFollowingController(config)
    detection = seen() if detection is None else detection
    # One frame more than it takes to trust: the first frame has no time step to accelerate in.
    return drive(controller, detection, floor_xy_m, config.frames_to_trust + 1)[-1].command


def tracking_controller(config, detection=None, floor_xy_m=STRAIGHT_AHEAD_M):
    """
    Return a controller that has followed a line long enough to settle, and its last frame time.

    :param config: the ControllerConfig.
    :param detection: the Detection of every frame; all bands see the line when None.
    :param floor_xy_m: the floor points of every frame.
    :return: (controller, time of its last frame in seconds).
    """
    controller = LineFollowingController(config)
    detection = seen() if detection is None else detection
    drive(controller, detection, floor_xy_m, SETTLING_FRAMES)
    assert controller.state == 'tracking'
    return controller, (SETTLING_FRAMES - 1) * FRAME_PERIOD_S


def book_config():
    """Return the ControllerConfig of config/book_follower.yaml, the book's follower."""
    with open(BOOK_PARAMETERS_FILE, encoding='utf-8') as parameters_file:
        parameters = yaml.safe_load(parameters_file)['/**/follower']['ros__parameters']
    names = {field.name for field in fields(ControllerConfig)}
    return ControllerConfig(**{name: value for name, value in parameters.items()
                               if name in names})


# ControllerConfig validation.

# Every number of the config (frames_to_trust, a count, is checked apart).
NUMBER_FIELDS = tuple(field.name for field in fields(ControllerConfig)
                      if isinstance(getattr(ControllerConfig(), field.name), float))
# Numbers that cannot be zero: a divisor, and limits at which the robot could never move.
POSITIVE_FIELDS = ('confidence_for_full_speed', 'max_lateral_acceleration_mps2',
                   'max_linear_acceleration_mps2', 'max_angular_acceleration_radps2')


def test_every_number_of_the_config_is_checked():
    assert set(NUMBER_FIELDS) == {field.name for field in fields(ControllerConfig)} - {
        'steering_law', 'lost_line_behaviour', 'frames_to_trust', 'stop_at_line_end'}
    assert set(POSITIVE_FIELDS) <= set(NUMBER_FIELDS)


def test_default_config_is_valid_and_uses_the_path_law():
    config = ControllerConfig()
    assert config.steering_law == 'path'
    assert config.lost_line_behaviour in LOST_LINE_BEHAVIOURS
    assert config.min_linear_speed_mps <= config.linear_speed_mps
    assert config.frames_to_trust >= 1


@pytest.mark.parametrize('name', NUMBER_FIELDS)
@pytest.mark.parametrize('value', (-0.5, -1e-9, math.nan, math.inf, -math.inf))
def test_config_rejects_negative_and_non_finite_numbers(name, value):
    with pytest.raises(ValueError, match=rf'^{name} must be finite and at least'):
        ControllerConfig(**{name: value})


@pytest.mark.parametrize('name', NUMBER_FIELDS)
@pytest.mark.parametrize('value', (True, False, '0.5', None, [0.5]))
def test_config_rejects_numbers_of_the_wrong_type(name, value):
    with pytest.raises(TypeError, match=rf'^{name} must be a number, got'):
        ControllerConfig(**{name: value})


@pytest.mark.parametrize('name', POSITIVE_FIELDS)
@pytest.mark.parametrize('value', (0, 0.0))
def test_config_rejects_zero_where_it_cannot_work(name, value):
    with pytest.raises(ValueError, match=rf'^{name} must be finite and at least'):
        ControllerConfig(**{name: value})


@pytest.mark.parametrize('name', sorted(set(NUMBER_FIELDS) - set(POSITIVE_FIELDS)))
def test_config_accepts_zero_elsewhere(name):
    # A zero speed needs a zero minimum speed too.
    config = ControllerConfig(**{'min_linear_speed_mps': 0.0, name: 0})
    assert getattr(config, name) == 0


def test_config_accepts_integers_for_numbers():
    config = ControllerConfig(linear_speed_mps=1, max_angular_speed_radps=2, line_memory_s=0)
    assert (config.linear_speed_mps, config.max_angular_speed_radps) == (1, 2)


@pytest.mark.parametrize('value', (0, -1, -100))
def test_config_rejects_frames_to_trust_below_one(value):
    with pytest.raises(ValueError, match=r'^frames_to_trust must be at least 1, got'):
        ControllerConfig(frames_to_trust=value)


@pytest.mark.parametrize('value', (2.0, True, '2', None, math.nan))
def test_config_rejects_frames_to_trust_that_is_not_an_integer(value):
    with pytest.raises(TypeError, match=r'^frames_to_trust must be an integer, got'):
        ControllerConfig(frames_to_trust=value)


@pytest.mark.parametrize('name, value, allowed', (
    ('steering_law', 'pure_pursuit', 'path, proportional'),
    ('steering_law', 'PATH', 'path, proportional'),
    ('steering_law', '', 'path, proportional'),
    ('steering_law', None, 'path, proportional'),
    ('lost_line_behaviour', 'spin', 'search, stop'),
    ('lost_line_behaviour', 'STOP', 'search, stop'),
    ('lost_line_behaviour', 'search ', 'search, stop'),
))
def test_config_rejects_unknown_laws_and_behaviours(name, value, allowed):
    with pytest.raises(ValueError, match=rf'^{name} must be one of {allowed}, got'):
        ControllerConfig(**{name: value})


@pytest.mark.parametrize('name', STEERING_LAWS)
def test_config_accepts_every_steering_law(name):
    assert ControllerConfig(steering_law=name).steering_law == name


@pytest.mark.parametrize('min_linear_speed_mps, linear_speed_mps', (
    (0.3, 0.2), (0.05, 0.0), (1.0, 0.999)))
def test_config_rejects_a_minimum_speed_above_the_speed(min_linear_speed_mps, linear_speed_mps):
    with pytest.raises(ValueError, match=r'^min_linear_speed_mps .* must not exceed'):
        ControllerConfig(min_linear_speed_mps=min_linear_speed_mps,
                         linear_speed_mps=linear_speed_mps)


def test_config_accepts_a_minimum_speed_equal_to_the_speed():
    assert ControllerConfig(min_linear_speed_mps=0.3, linear_speed_mps=0.3).linear_speed_mps == 0.3


# pursuit_curvature and estimate_path.

@pytest.mark.parametrize('radius_m', (0.3, 1.0, 3.0, 10.0))
@pytest.mark.parametrize('side', (LEFT, RIGHT))
@pytest.mark.parametrize('distance_m', (0.1, 0.5, 0.6))
def test_pursuit_curvature_of_a_point_ahead_on_a_circle_is_the_circles(radius_m, side,
                                                                       distance_m):
    x_m, y_m = circle_points(radius_m, side, (distance_m,))[0]
    assert pursuit_curvature(x_m, y_m) == pytest.approx(side / radius_m)


@pytest.mark.parametrize('x_m', (0.1, 0.5, 3.0))
def test_pursuit_curvature_straight_ahead_is_zero(x_m):
    assert pursuit_curvature(x_m, 0.0) == 0.0


def test_pursuit_curvature_takes_arrays():
    points = np.concatenate((circle_points(1.0, LEFT), circle_points(0.5, RIGHT)))
    curvatures = pursuit_curvature(points[:, 0], points[:, 1])
    assert curvatures == pytest.approx([1.0] * BAND_COUNT + [-2.0] * BAND_COUNT)


@pytest.mark.parametrize('bearing_rad', (0.0, 0.3, -0.3, 1.2, -1.2))
@pytest.mark.parametrize('look_ahead_m, nearer_m, farther_m', (
    (0.5, 0.4, 0.6),
    (0.5, 0.45, 0.9),
    (0.8, 0.2, 1.0),
))
def test_look_ahead_point_lies_between_the_points_at_the_distance(bearing_rad, look_ahead_m,
                                                                  nearer_m, farther_m):
    points = ray_points(bearing_rad, (0.1, nearer_m, farther_m, farther_m + 0.5))
    estimate = estimate_path(points, look_ahead_m)
    assert (estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx(
        tuple(ray_points(bearing_rad, (look_ahead_m,))[0]))
    assert estimate.bearing_rad == pytest.approx(bearing_rad)


def test_look_ahead_point_is_at_the_distance_on_a_segment_across_the_view():
    # The line crosses about 0.4 m ahead, running to the left (a sharp corner).
    estimate = estimate_path([(0.4, 0.0), (0.45, 0.4)], 0.5)
    assert math.hypot(estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx(0.5)


def test_look_ahead_point_is_where_the_polyline_first_reaches_the_distance():
    # Out to 0.6 m, then back towards the robot: the first crossing, 0.5 m straight ahead.
    points = [(0.3, 0.0), (0.6, 0.0), (0.35, 0.3)]
    estimate = estimate_path(points, 0.5)
    assert (estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx((0.5, 0.0))


@pytest.mark.parametrize('points', (
    [(0.6, 0.1)],
    [(0.6, 0.1), (0.8, 0.2)],
    [(0.6, -0.1), (0.7, 0.0), (0.9, 0.2)],
))
def test_look_ahead_point_is_the_nearest_point_when_all_are_farther(points):
    estimate = estimate_path(points, 0.5)
    assert (estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx(points[0])


@pytest.mark.parametrize('points', (
    [(0.3, 0.1)],
    [(0.2, 0.1), (0.3, 0.2)],
    [(0.2, -0.1), (0.3, 0.0), (0.4, -0.2)],
))
def test_look_ahead_point_is_the_farthest_point_when_all_are_nearer(points):
    estimate = estimate_path(points, 0.5)
    assert (estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx(points[-1])


def test_look_ahead_point_at_a_points_distance_is_that_point():
    estimate = estimate_path([(0.3, 0.0), (0.35, 0.2), (0.3, 0.4), (0.2, 0.6)], 0.5)
    assert (estimate.look_ahead_x_m, estimate.look_ahead_y_m) == pytest.approx((0.3, 0.4))


@pytest.mark.parametrize('offset_m', (0.0, 0.1, -0.2))
@pytest.mark.parametrize('slope', (0.0, 0.5, -0.5, 2.0, -3.0))
def test_heading_is_the_direction_of_the_points_line(offset_m, slope):
    x_m = np.array(BAND_DISTANCES_M)
    points = np.stack((x_m, offset_m + slope * x_m), axis=1)
    assert estimate_path(points, 0.5).heading_rad == pytest.approx(math.atan(slope))


def test_heading_of_a_line_across_the_view_is_a_right_angle():
    estimate = estimate_path([(0.4, 0.0), (0.4, 0.3)], 0.5)
    assert abs(estimate.heading_rad) == pytest.approx(math.pi / 2)


@pytest.mark.parametrize('points, sharpest_per_m', (
    # 2y / (x^2 + y^2) per point: 0, -1.379, 0.276.
    ([(0.4, 0.0), (0.5, -0.2), (0.6, 0.05)], -0.4 / 0.29),
    ([(0.4, 0.0), (0.5, 0.2), (0.6, -0.05)], 0.4 / 0.29),
    ([(0.5, 0.0), (0.9, 0.0)], 0.0),
    ([(0.5, 0.1)], 0.2 / 0.26),
))
def test_sharpest_curvature_is_the_largest_arc_curvature_with_its_sign(points, sharpest_per_m):
    assert estimate_path(points, 0.5).sharpest_curvature_per_m == pytest.approx(sharpest_per_m)


@pytest.mark.parametrize('radius_m', (0.5, 1.0, 4.0))
@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_path_along_a_circle_is_the_circle(radius_m, side):
    estimate = estimate_path(circle_points(radius_m, side), 0.5)
    assert estimate.sharpest_curvature_per_m == pytest.approx(side / radius_m)
    # Linear interpolation between two points of the circle falls just inside it.
    assert estimate.pursuit_curvature_per_m == pytest.approx(side / radius_m, rel=0.02)
    assert estimate.bearing_rad == pytest.approx(
        circle_bearing_rad(radius_m, side, 0.5), abs=0.01)


def test_path_estimate_bearing_and_pursuit_curvature():
    estimate = PathEstimate(look_ahead_x_m=0.3, look_ahead_y_m=-0.4, heading_rad=0.0,
                            sharpest_curvature_per_m=0.0)
    assert estimate.bearing_rad == pytest.approx(math.atan2(-0.4, 0.3))
    assert estimate.pursuit_curvature_per_m == pytest.approx(2.0 * -0.4 / 0.25)


# The proportional law.

@pytest.mark.parametrize('centroid_x_px', (320.0, 420.0, 220.0, 640.0, 0.0, 100.0, 333.3))
def test_book_config_steers_with_the_books_law(centroid_x_px):
    controller = LineFollowingController(book_config())
    error = (centroid_x_px - IMAGE_WIDTH_PX / 2) / (IMAGE_WIDTH_PX / 2)
    command = drive(controller, seen(error), frame_count=2)[-1].command
    # The book: angular = -(cx - w/2) / 100 rad/s at 0.2 m/s.
    assert command.angular_radps == pytest.approx(-(centroid_x_px - IMAGE_WIDTH_PX / 2) / 100)
    assert command.linear_mps == pytest.approx(0.2)


def test_book_config_is_the_proportional_law_at_the_books_gain():
    config = book_config()
    assert config.steering_law == 'proportional'
    assert (config.linear_speed_mps, config.angular_gain_radps) == (0.2, 3.2)
    assert config.frames_to_trust == 1


@pytest.mark.parametrize('error, angular_radps', (
    (0.0, 0.0),
    (0.1, -0.32),
    (-0.1, 0.32),
    (0.4, -1.28),
    # Clamped at max_angular_speed_radps, 1.5 rad/s here.
    (0.5, -1.5),
    (-0.5, 1.5),
    (1.0, -1.5),
    (-1.0, 1.5),
))
def test_proportional_law_is_clamped_at_the_angular_speed_limit(error, angular_radps):
    command = law_command(None, seen(error), steering_law='proportional', linear_speed_mps=0.2,
                          angular_gain_radps=3.2, max_angular_speed_radps=1.5)
    assert command == VelocityCommand(pytest.approx(0.2), pytest.approx(angular_radps))


@pytest.mark.parametrize('error', (-1.0, -0.3, 0.0, 0.3, 1.0))
@pytest.mark.parametrize('seen_count', (1, 3, BAND_COUNT))
def test_proportional_law_drives_at_a_constant_speed(error, seen_count):
    command = law_command(None, seen(error, seen_count), steering_law='proportional',
                          linear_speed_mps=0.3)
    assert command.linear_mps == pytest.approx(0.3)


@pytest.mark.parametrize('error', (0.05, 0.3, 0.9))
def test_proportional_law_turns_towards_the_line(error):
    # REP-103: positive yaw rate is counter-clockwise, a left turn. A line right of the image
    # centre needs a right turn.
    assert law_command(None, seen(error), steering_law='proportional').angular_radps < 0.0
    assert law_command(None, seen(-error), steering_law='proportional').angular_radps > 0.0


def test_proportional_law_steers_on_the_nearest_band_that_saw_the_line():
    bands = (band(0), band(1, 480.0), band(2, 160.0)) + tuple(
        band(index) for index in range(3, BAND_COUNT))
    detection = Detection(bands, IMAGE_WIDTH_PX, IMAGE_HEIGHT_PX, confidence=2 / BAND_COUNT)
    command = law_command(None, detection, steering_law='proportional',
                          angular_gain_radps=3.2, max_angular_speed_radps=10.0)
    assert command.angular_radps == pytest.approx(-3.2 * 0.5)


def test_proportional_law_needs_no_floor_points_and_makes_no_path_estimate():
    controller = LineFollowingController(unlimited_config(steering_law='proportional'))
    drive(controller, seen(0.2), None, 3)
    assert controller.state == 'tracking'
    assert controller.last_command.linear_mps > 0.0
    assert controller.path_estimate is None


# The path law.

def test_path_law_drives_straight_at_full_speed_on_a_straight_line():
    config = unlimited_config()
    command = law_command(STRAIGHT_AHEAD_M)
    assert command == VelocityCommand(pytest.approx(config.linear_speed_mps), 0.0)


@pytest.mark.parametrize('side', (LEFT, RIGHT))
@pytest.mark.parametrize('floor_xy_m', (
    'circle 4 m', 'circle 1 m', 'circle 0.5 m', 'ray 0.05 rad', 'ray 0.5 rad', 'ray 1.2 rad',
    'one point'))
def test_path_law_turns_towards_the_side_of_the_line(side, floor_xy_m):
    points = {
        'circle 4 m': circle_points(4.0, side),
        'circle 1 m': circle_points(1.0, side),
        'circle 0.5 m': circle_points(0.5, side),
        'ray 0.05 rad': ray_points(side * 0.05),
        'ray 0.5 rad': ray_points(side * 0.5),
        'ray 1.2 rad': ray_points(side * 1.2),
        'one point': [(0.5, side * 0.1)],
    }[floor_xy_m]
    command = law_command(points, seen(seen_count=len(points)))
    # REP-103: a line to the left (positive y) needs a left turn, a positive yaw rate.
    assert math.copysign(1.0, command.angular_radps) == side
    assert command.angular_radps != 0.0
    assert command.linear_mps > 0.0


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_path_law_steers_along_a_steady_bend_without_offset(side):
    # Pure pursuit: on a circle the yaw rate over the speed is the circle's curvature.
    command = law_command(circle_points(2.0, side), **SPEED_PLANNING)
    assert command.angular_radps / command.linear_mps == pytest.approx(side / 2.0, rel=0.02)


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_path_law_slows_for_sharper_bends(side):
    config = unlimited_config(**SPEED_PLANNING)
    radii_m = (math.inf, 8.0, 2.0, 1.0, 0.8, 0.6)
    speeds_mps = []
    for radius_m in radii_m:
        points = STRAIGHT_AHEAD_M if math.isinf(radius_m) else circle_points(radius_m, side)
        command = law_command(points, **SPEED_PLANNING)
        speeds_mps.append(command.linear_mps)
        # The lateral acceleration bound: v * w = v^2 / R.
        assert abs(command.linear_mps * command.angular_radps) <= (
            config.max_lateral_acceleration_mps2 + TOLERANCE)
    assert speeds_mps == sorted(speeds_mps, reverse=True)
    assert speeds_mps[-1] < speeds_mps[0]
    assert speeds_mps[-1] >= config.min_linear_speed_mps


def test_path_law_slows_before_a_bend_not_in_it():
    # Straight up to 0.55 m, past the look-ahead point, then a sharp bend to the left.
    points = [(0.35, 0.0), (0.45, 0.0), (0.55, 0.0), (0.6, 0.35)]
    straight = law_command(STRAIGHT_AHEAD_M[:4], seen(seen_count=4), **SPEED_PLANNING)
    before_bend = law_command(points, seen(seen_count=4), **SPEED_PLANNING)
    assert before_bend.angular_radps == pytest.approx(0.0)
    assert before_bend.linear_mps < straight.linear_mps


@pytest.mark.parametrize('seen_count, full_speed', (
    (6, True), (5, True), (4, True), (3, True), (2, False), (1, False)))
def test_path_law_drives_slower_when_fewer_bands_see_the_line(seen_count, full_speed):
    # With confidence_for_full_speed 0.5, three of six bands are enough for full speed.
    config = unlimited_config(**SPEED_PLANNING)
    speeds_mps = [
        law_command(STRAIGHT_AHEAD_M[:count], seen(seen_count=count), **SPEED_PLANNING).linear_mps
        for count in (seen_count, seen_count - 1)]
    if full_speed:
        assert speeds_mps[0] == pytest.approx(config.linear_speed_mps)
    else:
        assert speeds_mps[0] < config.linear_speed_mps
        # And fewer still is slower still, down to not moving at all with no band.
        assert speeds_mps[1] < speeds_mps[0]


@pytest.mark.parametrize('bearing_rad', (0.6, -0.6, 0.9, -0.9, 1.3, -1.3))
@pytest.mark.parametrize('seen_count', (1, 3, BAND_COUNT))
def test_path_law_turns_to_a_point_far_to_the_side_at_least_at_bearing_gain(bearing_rad,
                                                                            seen_count):
    points = ray_points(bearing_rad, BAND_DISTANCES_M[:seen_count])
    command = law_command(points, seen(seen_count=seen_count), bearing_gain_radps=2.0,
                          max_angular_speed_radps=10.0)
    estimate_bearing_rad = estimate_path(points, unlimited_config().look_ahead_m).bearing_rad
    assert estimate_bearing_rad == pytest.approx(bearing_rad)
    assert math.copysign(1.0, command.angular_radps) == math.copysign(1.0, bearing_rad)
    assert abs(command.angular_radps) >= 2.0 * abs(bearing_rad) - TOLERANCE


def test_path_law_keeps_the_lateral_acceleration_bound_when_turning_to_a_point_to_the_side():
    config = unlimited_config(**SPEED_PLANNING)
    # Every band sees the line (full confidence), 45 degrees and more to the left: a corner.
    command = law_command([(0.3, 0.3), (0.35, 0.4)], **SPEED_PLANNING)
    assert abs(command.linear_mps * command.angular_radps) <= (
        config.max_lateral_acceleration_mps2 + TOLERANCE)


@pytest.mark.parametrize('floor_xy_m', (STRAIGHT_AHEAD_M, circle_points(0.45, LEFT)))
def test_path_law_never_exceeds_the_angular_speed_limit(floor_xy_m):
    command = law_command(floor_xy_m, max_angular_speed_radps=0.4)
    assert abs(command.angular_radps) <= 0.4


def test_path_law_treats_missing_floor_points_as_no_line():
    controller = LineFollowingController(unlimited_config(frames_to_trust=1))
    for frame in drive(controller, seen(), None, 5):
        assert frame.command.linear_mps == 0.0
        assert frame.state == 'lost'
    assert controller.path_estimate is None


def test_path_law_coasts_when_floor_points_go_missing_while_tracking():
    controller, time_s = tracking_controller(unlimited_config(line_memory_s=0.3))
    last_command = controller.last_command
    assert controller.update(seen(), time_s + FRAME_PERIOD_S, None) == last_command
    assert controller.state == 'coasting'


def test_path_law_treats_an_empty_floor_array_as_no_line():
    controller = LineFollowingController(unlimited_config(frames_to_trust=1))
    frame = drive(controller, seen(), np.empty((0, 2)), 2)[-1]
    assert frame.command.linear_mps == 0.0
    assert frame.state != 'tracking'


def test_path_law_keeps_the_path_estimate_of_the_last_frame():
    # Told to stop when the line is lost, it coasts on the last command, not along the line.
    config = unlimited_config(frames_to_trust=1, lost_line_behaviour='stop')
    controller = LineFollowingController(config)
    points = circle_points(1.0, RIGHT)
    drive(controller, seen(), points, 2)
    assert controller.path_estimate == estimate_path(points, config.look_ahead_m)
    drive(controller, nothing_seen(), None, 1, start_s=0.1)
    assert controller.path_estimate == estimate_path(points, config.look_ahead_m)


# Acceleration limits.

@pytest.mark.parametrize('steering_law', STEERING_LAWS)
def test_speed_rises_by_at_most_the_linear_acceleration_limit_per_frame(steering_law):
    config = ControllerConfig(steering_law=steering_law, frames_to_trust=1,
                              linear_speed_mps=0.5, max_linear_acceleration_mps2=0.8)
    controller = LineFollowingController(config)
    # Uneven frame times: the step follows the time between frames.
    times_s = np.cumsum([0.0, 0.05, 0.02, 0.1, 0.05, 0.15, 0.05, 0.05, 0.2, 0.1, 0.1])
    speed_mps = 0.0
    previous_s = times_s[0]
    for time_s in times_s:
        command = controller.update(seen(), time_s, STRAIGHT_AHEAD_M)
        speed_mps = min(config.linear_speed_mps,
                        speed_mps + config.max_linear_acceleration_mps2 * (time_s - previous_s))
        previous_s = time_s
        assert command.linear_mps == pytest.approx(speed_mps)
    assert speed_mps == config.linear_speed_mps


def test_yaw_rate_rises_by_at_most_the_angular_acceleration_limit_per_frame():
    config = ControllerConfig(
        steering_law='proportional', frames_to_trust=1, angular_gain_radps=3.2,
        max_angular_speed_radps=10.0, max_angular_acceleration_radps2=4.0)
    controller = LineFollowingController(config)
    frames = drive(controller, seen(-1.0), frame_count=20)
    expected_radps = [min(3.2, 4.0 * FRAME_PERIOD_S * index) for index in range(20)]
    assert [frame.command.angular_radps for frame in frames] == pytest.approx(expected_radps)


def test_yaw_rate_falls_by_at_most_the_angular_acceleration_limit_per_frame():
    config = ControllerConfig(
        steering_law='proportional', frames_to_trust=1, angular_gain_radps=3.2,
        max_angular_speed_radps=10.0, max_angular_acceleration_radps2=4.0)
    controller, time_s = tracking_controller(config, seen(-1.0))
    frames = drive(controller, seen(1.0), frame_count=40, start_s=time_s + FRAME_PERIOD_S)
    expected_radps = [max(-3.2, 3.2 - 4.0 * FRAME_PERIOD_S * index) for index in range(1, 41)]
    assert [frame.command.angular_radps for frame in frames] == pytest.approx(expected_radps)


@pytest.mark.parametrize('steering_law', STEERING_LAWS)
def test_first_frame_starts_from_rest(steering_law):
    controller = LineFollowingController(
        ControllerConfig(steering_law=steering_law, frames_to_trust=1))
    command = controller.update(seen(0.5), 12.0, circle_points(1.0, RIGHT))
    assert command == VelocityCommand(0.0, 0.0)
    assert controller.state == 'tracking'


@pytest.mark.parametrize('pause_s', (MAX_TIME_STEP_S, 1.0, 60.0))
def test_a_long_pause_between_frames_counts_as_the_longest_time_step(pause_s):
    config = ControllerConfig(linear_speed_mps=0.7, max_linear_acceleration_mps2=1.0,
                              max_angular_acceleration_radps2=2.0, max_angular_speed_radps=3.0,
                              steering_law='proportional', angular_gain_radps=3.2)
    controller = LineFollowingController(config)
    controller.update(seen(-1.0), 0.0)
    command = controller.update(seen(-1.0), pause_s)
    assert command.linear_mps == pytest.approx(1.0 * MAX_TIME_STEP_S)
    assert command.angular_radps == pytest.approx(2.0 * MAX_TIME_STEP_S)


def test_a_frame_older_than_the_last_does_not_accelerate():
    controller = LineFollowingController(ControllerConfig(frames_to_trust=1))
    drive(controller, seen(), STRAIGHT_AHEAD_M, 3, start_s=5.0)
    before = controller.last_command
    assert controller.update(seen(), 1.0, STRAIGHT_AHEAD_M) == before


# Hysteresis: trusting the line.

def test_starts_waiting_at_rest():
    controller = LineFollowingController()
    assert controller.state == 'waiting'
    assert controller.last_command == VelocityCommand(0.0, 0.0)
    assert controller.path_estimate is None


@pytest.mark.parametrize('lost_line_behaviour', LOST_LINE_BEHAVIOURS)
def test_keeps_waiting_and_still_while_no_image_can_be_used(lost_line_behaviour):
    controller = LineFollowingController(
        unlimited_config(lost_line_behaviour=lost_line_behaviour))
    for frame in drive(controller, Detection.nothing_seen(), None, 5):
        assert frame == Frame(VelocityCommand(0.0, 0.0), 'waiting')


@pytest.mark.parametrize('frames_to_trust', (1, 2, 3, 5))
@pytest.mark.parametrize('steering_law', STEERING_LAWS)
def test_drives_only_after_frames_to_trust_frames_in_a_row(frames_to_trust, steering_law):
    controller = LineFollowingController(
        unlimited_config(frames_to_trust=frames_to_trust, steering_law=steering_law))
    # A frame without the line first, so that the line's frames have a time step to move in.
    controller.update(nothing_seen(), 0.0)
    frames = drive(controller, seen(), STRAIGHT_AHEAD_M, frames_to_trust - 1,
                   start_s=FRAME_PERIOD_S)
    for frame in frames:
        assert frame.command.linear_mps == 0.0
        assert frame.state == 'acquiring'
    command = controller.update(seen(), frames_to_trust * FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert command.linear_mps > 0.0
    assert controller.state == 'tracking'


@pytest.mark.parametrize('steering_law', STEERING_LAWS)
def test_a_single_sighting_between_misses_never_drives(steering_law):
    controller = LineFollowingController(
        unlimited_config(frames_to_trust=2, steering_law=steering_law))
    for index in range(20):
        sighting = index % 2 == 0
        command = controller.update(seen() if sighting else nothing_seen(),
                                    index * FRAME_PERIOD_S,
                                    STRAIGHT_AHEAD_M if sighting else None)
        assert command.linear_mps == 0.0
        assert controller.state == ('acquiring' if sighting else 'lost')


def test_a_miss_starts_the_count_of_sightings_again():
    controller = LineFollowingController(unlimited_config(frames_to_trust=3))
    frames = (True, True, False, True, True)
    for index, sighting in enumerate(frames):
        command = controller.update(seen() if sighting else nothing_seen(),
                                    index * FRAME_PERIOD_S,
                                    STRAIGHT_AHEAD_M if sighting else None)
        assert command.linear_mps == 0.0
    controller.update(seen(), len(frames) * FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert controller.state == 'tracking'


def test_a_frame_without_the_line_before_any_sighting_is_lost():
    controller = LineFollowingController()
    controller.update(nothing_seen(), 0.0)
    assert controller.state == 'lost'


def test_states_are_reported_by_name_through_a_whole_run():
    # The line seen ending 0.85 m ahead is driven to, 0.035 m a frame, until 0.8 m short of
    # it: two frames.
    controller = LineFollowingController(unlimited_config(
        frames_to_trust=2, line_memory_s=0.12, line_end_stop_short_m=0.8))
    frames = (
        ('waiting', Detection.nothing_seen()), ('acquiring', seen()), ('tracking', seen()),
        ('coasting', nothing_seen()), ('coasting', nothing_seen()), ('tracking', seen()),
        ('coasting', nothing_seen()), ('coasting', nothing_seen()), ('lost', nothing_seen()),
        ('acquiring', seen()), ('lost', nothing_seen()), ('acquiring', seen()),
        ('tracking', seen()), ('tracking', seen(seen_count=2)), ('coasting', nothing_seen()),
        ('coasting', nothing_seen()), ('line end', nothing_seen()), ('line end', nothing_seen()),
        ('acquiring', seen()), ('tracking', seen()))
    states = []
    for index, (_, detection) in enumerate(frames):
        controller.update(detection, index * FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
        states.append(controller.state)
    assert states == [state for state, _ in frames]
    assert set(states) == set(STATES)


# Line memory and the lost line.

@pytest.mark.parametrize('steering_law, detection, floor_xy_m, lost_line_behaviour', (
    # Searching, the path law drives on along a line seen running on out of view (below).
    ('path', seen(), circle_points(1.0, LEFT), 'stop'),
    ('path', seen(), circle_points(0.6, RIGHT), 'stop'),
    ('proportional', seen(0.3), None, 'search'),
    ('proportional', seen(0.3), None, 'stop'),
))
def test_a_gap_shorter_than_the_line_memory_is_coasted_on_the_last_command(
        steering_law, detection, floor_xy_m, lost_line_behaviour):
    config = ControllerConfig(steering_law=steering_law, line_memory_s=0.3,
                              lost_line_behaviour=lost_line_behaviour)
    controller, time_s = tracking_controller(config, detection, floor_xy_m)
    last_command = controller.last_command
    assert last_command.linear_mps > 0.0
    # Misses up to 0.25 s after the last sighting, within the 0.3 s memory.
    for frame in drive(controller, nothing_seen(), None, 5, start_s=time_s + FRAME_PERIOD_S):
        assert frame == Frame(last_command, 'coasting')


@pytest.mark.parametrize('steering_law, detection, floor_xy_m', (
    ('path', seen(), circle_points(1.0, LEFT)),
    ('proportional', seen(0.3), None),
))
def test_a_gap_longer_than_the_line_memory_loses_the_line(steering_law, detection, floor_xy_m):
    config = ControllerConfig(steering_law=steering_law, line_memory_s=0.3,
                              lost_line_behaviour='stop')
    controller, time_s = tracking_controller(config, detection, floor_xy_m)
    frames = drive(controller, nothing_seen(), None, 10, start_s=time_s + FRAME_PERIOD_S)
    # 0.3 s of memory: misses 0.05 s to 0.25 s after the last sighting coast, from 0.35 s on
    # the line is lost.
    assert all(frame.command.linear_mps > 0.0 for frame in frames[:5])
    assert all(frame.state == 'coasting' for frame in frames[:5])
    assert all(frame.command.linear_mps == 0.0 for frame in frames[6:])
    assert all(frame.state == 'lost' for frame in frames[6:])


def test_a_zero_line_memory_loses_the_line_at_the_first_miss():
    controller, time_s = tracking_controller(ControllerConfig(line_memory_s=0.0,
                                                              lost_line_behaviour='stop'))
    assert controller.update(nothing_seen(), time_s + FRAME_PERIOD_S).linear_mps == 0.0
    assert controller.state == 'lost'


def test_frame_times_going_back_do_not_stretch_the_line_memory():
    config = ControllerConfig(line_memory_s=0.3)
    controller, time_s = tracking_controller(config)
    # The clock starts again from zero; one second of frames without the line follows.
    frames = drive(controller, nothing_seen(), None, 20, start_s=0.0)
    assert frames[-1].command.linear_mps == 0.0
    assert frames[-1].state == 'lost'


def test_the_line_found_while_coasting_is_trusted_at_once():
    config = unlimited_config(frames_to_trust=5, line_memory_s=0.3)
    controller, time_s = tracking_controller(config)
    controller.update(nothing_seen(), time_s + FRAME_PERIOD_S)
    assert controller.state == 'coasting'
    command = controller.update(seen(), time_s + 2 * FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert controller.state == 'tracking'
    assert command.linear_mps == pytest.approx(config.linear_speed_mps)


def test_the_line_found_after_it_was_lost_must_be_trusted_again():
    config = unlimited_config(frames_to_trust=2, line_memory_s=0.0, lost_line_behaviour='stop')
    controller, time_s = tracking_controller(config)
    controller.update(nothing_seen(), time_s + FRAME_PERIOD_S)
    command = controller.update(seen(), time_s + 2 * FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert controller.state == 'acquiring'
    assert command.linear_mps == 0.0


@pytest.mark.parametrize('steering_law, detection, floor_xy_m, side', (
    ('path', seen(), circle_points(1.0, LEFT), LEFT),
    ('path', seen(), circle_points(1.0, RIGHT), RIGHT),
    ('path', seen(seen_count=2), ray_points(0.8, (0.4, 0.5)), LEFT),
    ('path', seen(seen_count=2), ray_points(-0.8, (0.4, 0.5)), RIGHT),
    # The book's law: a line right of the image centre is steered to on the right.
    ('proportional', seen(0.4), None, RIGHT),
    ('proportional', seen(-0.05), None, LEFT),
))
def test_search_turns_in_place_towards_the_side_of_the_last_steering(
        steering_law, detection, floor_xy_m, side):
    # Two near bands and bare floor beyond also read as a line's end: search regardless.
    config = unlimited_config(steering_law=steering_law, line_memory_s=0.0,
                              lost_line_behaviour='search', search_angular_speed_radps=1.25,
                              stop_at_line_end=False)
    controller, time_s = tracking_controller(config, detection, floor_xy_m)
    # A line seen running on out of view (the path law's circles) is driven along first.
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + FRAME_PERIOD_S)
    searching = frames[coasting_frames(frames):]
    assert len(searching) >= 5
    for frame in searching:
        assert frame == Frame(VelocityCommand(0.0, pytest.approx(side * 1.25)), 'lost')


def test_search_remembers_the_side_through_straight_steering():
    config = unlimited_config(line_memory_s=0.0)
    controller, time_s = tracking_controller(config, floor_xy_m=circle_points(1.0, RIGHT))
    drive(controller, seen(), STRAIGHT_AHEAD_M, 5, start_s=time_s + FRAME_PERIOD_S)
    assert controller.last_command.angular_radps == 0.0
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + 6 * FRAME_PERIOD_S)
    # On along the straight line it saw, then the search.
    assert all(frame.command.angular_radps == pytest.approx(0.0, abs=TOLERANCE)
               for frame in frames[:coasting_frames(frames)])
    assert frames[-1] == Frame(
        VelocityCommand(0.0, pytest.approx(-config.search_angular_speed_radps)), 'lost')


@pytest.mark.parametrize('steering_law', STEERING_LAWS)
def test_search_turns_left_when_the_line_was_never_steered_to_a_side(steering_law):
    config = unlimited_config(steering_law=steering_law)
    controller = LineFollowingController(config)
    frame = drive(controller, nothing_seen(), None, 2)[-1]
    assert frame == Frame(
        VelocityCommand(0.0, pytest.approx(config.search_angular_speed_radps)), 'lost')


def test_search_keeps_its_direction_while_the_line_is_being_trusted_again():
    config = unlimited_config(frames_to_trust=3, line_memory_s=0.0)
    controller, time_s = tracking_controller(config, floor_xy_m=circle_points(1.0, RIGHT))
    misses = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + FRAME_PERIOD_S)
    assert misses[-1].state == 'lost'
    time_s += (SETTLING_FRAMES + 1) * FRAME_PERIOD_S
    frames = drive(controller, seen(), STRAIGHT_AHEAD_M, 2, start_s=time_s)
    for frame in frames:
        assert frame == Frame(
            VelocityCommand(0.0, pytest.approx(-config.search_angular_speed_radps)), 'acquiring')


@pytest.mark.parametrize('floor_xy_m', (STRAIGHT_AHEAD_M, circle_points(0.8, LEFT)))
def test_stop_behaviour_stops_when_the_line_is_lost(floor_xy_m):
    config = unlimited_config(line_memory_s=0.0, lost_line_behaviour='stop')
    controller, time_s = tracking_controller(config, floor_xy_m=floor_xy_m)
    for frame in drive(controller, nothing_seen(), None, 5, start_s=time_s + FRAME_PERIOD_S):
        assert frame == Frame(VelocityCommand(0.0, 0.0), 'lost')


def test_stop_is_not_delayed_by_the_linear_acceleration_limit():
    config = ControllerConfig(line_memory_s=0.0, lost_line_behaviour='stop',
                              max_linear_acceleration_mps2=0.5,
                              max_angular_acceleration_radps2=2.0)
    controller, time_s = tracking_controller(config, floor_xy_m=circle_points(0.8, LEFT))
    turning_radps = controller.last_command.angular_radps
    assert turning_radps > 2.0 * FRAME_PERIOD_S
    commands = [frame.command for frame in drive(controller, nothing_seen(), None,
                                                 SETTLING_FRAMES, start_s=time_s + FRAME_PERIOD_S)]
    # Forward speed drops to zero at once; the turn slows within the angular limit.
    assert all(command.linear_mps == 0.0 for command in commands)
    assert commands[0].angular_radps == pytest.approx(turning_radps - 2.0 * FRAME_PERIOD_S)
    assert commands[-1] == VelocityCommand(0.0, 0.0)


@pytest.mark.parametrize('steering_law', STEERING_LAWS)
@pytest.mark.parametrize('lost_line_behaviour', LOST_LINE_BEHAVIOURS)
def test_never_drives_forward_while_the_line_is_lost(steering_law, lost_line_behaviour):
    config = ControllerConfig(steering_law=steering_law, lost_line_behaviour=lost_line_behaviour,
                              line_memory_s=0.18)
    controller = LineFollowingController(config)
    time_s = 0.0
    sightings = ((seen(0.5), circle_points(0.8, RIGHT)), (seen(-0.5), circle_points(0.8, LEFT)),
                 (seen(), STRAIGHT_AHEAD_M), (seen(0.1, 2), ray_points(-0.1, (0.4, 0.5))))
    along_the_line = steering_law == 'path' and lost_line_behaviour == 'search'
    for detection, floor_xy_m in sightings:
        drive(controller, detection, floor_xy_m, 20, start_s=time_s)
        time_s += 20 * FRAME_PERIOD_S
        frames = drive(controller, nothing_seen(), None, 40, start_s=time_s)
        time_s += 40 * FRAME_PERIOD_S
        # Coasting through the 0.18 s memory, then lost; or, where the line was seen ending,
        # on to its end and stopped there; or, searching, on along the line seen running on
        # out of view, then lost. Never forward again.
        coasting = coasting_frames(frames)
        ends = line_ends_in_view(detection)
        if ends or along_the_line:
            assert coasting_distance_m(frames) <= (
                polyline_length_m(floor_xy_m) - config.line_end_stop_short_m)
            assert {frame.state for frame in frames[coasting:]} == {
                'line end' if ends else 'lost'}
        else:
            assert coasting == 3
            assert {frame.state for frame in frames[coasting:]} == {'lost'}
        assert all(frame.command.linear_mps == 0.0 for frame in frames[coasting:])


# reset() and the config setter.

def test_reset_forgets_everything_seen_and_commanded():
    config = unlimited_config(line_memory_s=0.0)
    controller, time_s = tracking_controller(config, floor_xy_m=circle_points(1.0, RIGHT))
    controller.reset()
    assert controller.state == 'waiting'
    assert controller.last_command == VelocityCommand(0.0, 0.0)
    assert controller.path_estimate is None
    # The side last steered to is forgotten: the search turns left by convention.
    drive(controller, nothing_seen(), None, 2, start_s=time_s + FRAME_PERIOD_S)
    assert controller.last_command.angular_radps == pytest.approx(
        config.search_angular_speed_radps)


def test_reset_starts_again_from_rest_and_distrust():
    config = ControllerConfig(frames_to_trust=2)
    controller, time_s = tracking_controller(config)
    controller.reset()
    command = controller.update(seen(), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert command == VelocityCommand(0.0, 0.0)
    assert controller.state == 'acquiring'


def test_config_setter_uses_the_new_config_and_keeps_what_was_seen():
    controller, time_s = tracking_controller(unlimited_config(linear_speed_mps=0.6))
    new_config = unlimited_config(linear_speed_mps=0.3, frames_to_trust=10)
    controller.config = new_config
    assert controller.config is new_config
    command = controller.update(seen(), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert controller.state == 'tracking'
    assert command.linear_mps == pytest.approx(0.3)


def test_config_setter_keeps_the_acceleration_limits_going():
    controller, time_s = tracking_controller(ControllerConfig(linear_speed_mps=0.6))
    controller.config = ControllerConfig(linear_speed_mps=0.3, max_linear_acceleration_mps2=1.0)
    command = controller.update(seen(), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M)
    assert command.linear_mps == pytest.approx(0.6 - 1.0 * FRAME_PERIOD_S)


def test_controller_keeps_its_config():
    config = ControllerConfig(linear_speed_mps=0.1)
    assert LineFollowingController(config).config is config


def test_stop_command_is_zero():
    assert LineFollowingController.stop_command() == VelocityCommand(0.0, 0.0)


# A line that ends.

def test_a_line_running_out_of_the_top_of_the_view_does_not_end_in_view():
    assert not line_ends_in_view(seen())


def test_a_line_seen_only_in_near_bands_with_bare_floor_beyond_ends_in_view():
    assert line_ends_in_view(seen(seen_count=2))


def test_a_line_with_line_coloured_pixels_beyond_does_not_end_in_view():
    # The far bands hold paint the detector did not take for the line (a corner's other leg).
    near = seen(seen_count=2)
    bands = near.bands[:2] + tuple(band._replace(area_px=LINE_AREA_PX) for band in near.bands[2:])
    assert not line_ends_in_view(Detection(bands, IMAGE_WIDTH_PX, IMAGE_HEIGHT_PX,
                                           near.confidence))


def test_no_line_does_not_end_in_view():
    assert not line_ends_in_view(nothing_seen())


def points_turning_away(side, near_offset_m=0.0):
    """
    Return floor points of a line straight ahead whose farthest band sees it aside.

    This is how the bands see a corner sharper than the camera's view ahead: the leg the robot
    drives along in the near bands, the leg it turns onto crossing the farthest band.

    :param side: LEFT or RIGHT, where the farthest point lies.
    :param near_offset_m: how far left the nearer points lie.
    :return: an (n, 2) array of (x forward, y left) points.
    """
    points = STRAIGHT_AHEAD_M + (0.0, near_offset_m)
    points[-1, 1] = side * 1.5 * ControllerConfig().turn_side_offset_m
    return points


def coasting_frames(frames):
    """Return how many frames, from the first, the controller coasted."""
    return next((index for index, frame in enumerate(frames) if frame.state != 'coasting'),
                len(frames))


def polyline_length_m(floor_xy_m):
    """Return the length of the line from the robot through floor points, nearest first."""
    points = np.vstack(((0.0, 0.0), floor_xy_m))
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


def coasting_distance_m(frames):
    """Return how far the commands of the first frames, while coasting, drove the robot."""
    return sum(frame.command.linear_mps for frame in frames[:coasting_frames(frames)]) * (
        FRAME_PERIOD_S)


def approach_the_end(controller, time_s):
    """Show a controller the end of a straight line coming into view, then no line."""
    for seen_count in range(BAND_COUNT - 1, 0, -1):
        time_s += FRAME_PERIOD_S
        controller.update(seen(seen_count=seen_count), time_s,
                          STRAIGHT_AHEAD_M[:seen_count])
    return drive(controller, nothing_seen(), None, SETTLING_FRAMES + 100,
                 start_s=time_s + FRAME_PERIOD_S)


@pytest.mark.parametrize('steering_law, approach_points, corner_search_angle_deg', [
    ('path', STRAIGHT_AHEAD_M, ControllerConfig().corner_search_angle_deg),
    ('proportional', circle_points(0.8, RIGHT), ControllerConfig().corner_search_angle_deg),
    # A bend just before the end, with the look round corners switched off.
    ('path', circle_points(0.8, RIGHT), 0.0)])
def test_stops_without_turning_at_a_line_it_saw_end(
        steering_law, approach_points, corner_search_angle_deg):
    config = ControllerConfig(steering_law=steering_law, line_memory_s=0.1,
                              corner_search_angle_deg=corner_search_angle_deg)
    controller, time_s = tracking_controller(config, seen(0.2), approach_points)
    # The end comes into view: fewer and fewer bands see the line, bare floor beyond.
    for seen_count in range(BAND_COUNT - 1, 0, -1):
        time_s += FRAME_PERIOD_S
        controller.update(seen(seen_count=seen_count), time_s,
                          STRAIGHT_AHEAD_M[:seen_count])
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + FRAME_PERIOD_S)
    # It coasts (path law: on to the end it saw 0.35 m ahead, less the distance it stops
    # short; proportional: through the line memory), then stands still at the end.
    coasting = coasting_frames(frames)
    if steering_law == 'path':
        assert coasting_distance_m(frames) == pytest.approx(
            BAND_DISTANCES_M[0] - config.line_end_stop_short_m,
            abs=config.linear_speed_mps * FRAME_PERIOD_S)
    else:
        assert coasting == 2
    assert all(frame == Frame(VelocityCommand(0.0, 0.0), 'line end')
               for frame in frames[coasting:])


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_looks_round_a_sharp_corner_then_turns_back_and_stops_at_the_line_end(side):
    config = ControllerConfig(line_memory_s=0.1)
    controller, time_s = tracking_controller(config, seen(), points_turning_away(side))
    frames = approach_the_end(controller, time_s)
    looking = [frame for frame in frames[coasting_frames(frames):]
               if frame.command != VelocityCommand(0.0, 0.0)]
    assert all(frame.state == 'line end' and frame.command.linear_mps == 0.0
               for frame in looking)
    # In place, toward the side the line turned away to, about as far as told; then back to
    # face where the line ended, and still.
    toward = next(index for index, frame in enumerate(looking)
                  if frame.command.angular_radps * side < 0.0)
    turned_rad = sum(frame.command.angular_radps for frame in looking[:toward]) * (
        side * FRAME_PERIOD_S)
    # Give or take a frame or two at the search speed and the slowing down to turn back.
    speed_radps = config.corner_search_angular_speed_radps
    assert turned_rad == pytest.approx(
        math.radians(config.corner_search_angle_deg),
        abs=speed_radps * (2 * FRAME_PERIOD_S
                           + speed_radps / config.max_angular_acceleration_radps2))
    assert all(frame.command.angular_radps * side < 0.0 for frame in looking[toward:])
    net_rad = sum(frame.command.angular_radps for frame in looking) * FRAME_PERIOD_S
    assert net_rad == pytest.approx(0.0, abs=0.05)
    assert frames[-1] == Frame(VelocityCommand(0.0, 0.0), 'line end')


def test_stops_at_once_at_a_line_end_when_told_not_to_search():
    config = ControllerConfig(line_memory_s=0.1, lost_line_behaviour='stop')
    controller, time_s = tracking_controller(config, seen(), points_turning_away(LEFT))
    frames = approach_the_end(controller, time_s)
    assert all(frame == Frame(VelocityCommand(0.0, 0.0), 'line end')
               for frame in frames[coasting_frames(frames):])


def test_a_turn_seen_long_before_the_end_is_not_looked_round():
    config = ControllerConfig(line_memory_s=0.1)
    controller, time_s = tracking_controller(config, seen(), points_turning_away(LEFT))
    later_s = time_s + config.turn_side_memory_s + 1.0
    drive(controller, seen(), STRAIGHT_AHEAD_M, SETTLING_FRAMES, start_s=later_s)
    frames = approach_the_end(controller, later_s + SETTLING_FRAMES * FRAME_PERIOD_S)
    assert all(frame == Frame(VelocityCommand(0.0, 0.0), 'line end')
               for frame in frames[coasting_frames(frames):])


def test_searches_toward_the_side_the_line_turned_away_to():
    # Steering right onto the near points, while the farthest band sees the line turn left:
    # a lost line is searched for on the left, not back along the way the robot came.
    config = unlimited_config(line_memory_s=0.0)
    controller, time_s = tracking_controller(config, seen(),
                                             points_turning_away(LEFT, near_offset_m=-0.05))
    assert controller.last_command.angular_radps < 0.0
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + FRAME_PERIOD_S)
    assert frames[-1] == Frame(VelocityCommand(0.0, config.search_angular_speed_radps), 'lost')


def test_searches_at_a_line_end_when_told_not_to_stop_there():
    config = ControllerConfig(line_memory_s=0.0, stop_at_line_end=False)
    controller, time_s = tracking_controller(config, seen(-0.2), circle_points(0.8, LEFT))
    controller.update(seen(seen_count=1), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M[:1])
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + 2 * FRAME_PERIOD_S)
    assert frames[-1] == Frame(VelocityCommand(0.0, config.search_angular_speed_radps), 'lost')


def test_follows_the_line_again_when_it_comes_back_after_a_line_end():
    config = unlimited_config(line_memory_s=0.0)
    controller, time_s = tracking_controller(config)
    controller.update(seen(seen_count=1), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M[:1])
    drive(controller, nothing_seen(), None, SETTLING_FRAMES, start_s=time_s + 2 * FRAME_PERIOD_S)
    assert controller.state == 'line end'
    frames = drive(controller, seen(), STRAIGHT_AHEAD_M, 3, start_s=time_s + 4.0)
    assert [frame.state for frame in frames] == ['acquiring', 'tracking', 'tracking']
    assert frames[-1].command.linear_mps > 0.0


def test_stop_at_line_end_must_be_a_boolean():
    with pytest.raises(TypeError, match='stop_at_line_end'):
        ControllerConfig(stop_at_line_end=1)


# The route to a line end seen ahead: dead reckoning of the robot's own commands.

def test_a_remembered_point_ahead_comes_nearer_as_the_robot_drives_straight_on():
    route = RememberedRoute()
    route.remember([(1.0, 0.2)])
    route.advance(VelocityCommand(0.5, 0.0), 1.2)
    np.testing.assert_allclose(route.ahead(0.0), [(0.4, 0.2)], atol=1e-12)


@pytest.mark.parametrize('steps', (1, 7))
def test_driving_a_quarter_circle_brings_the_robot_to_its_end_facing_left(steps):
    # A quarter circle of 0.5 m radius to the left ends 0.5 m ahead and 0.5 m left, heading
    # left: the point 1 m further left is then 1 m straight ahead.
    route = RememberedRoute()
    route.remember([(0.5, 0.5), (0.5, 1.5)])
    for _ in range(steps):
        route.advance(VelocityCommand(0.5 * 1.0, 1.0), (math.pi / 2.0) / steps)
    np.testing.assert_allclose(route.ahead(1e-9), [(1.0, 0.0)], atol=1e-12)


def test_points_reached_or_left_behind_are_dropped_and_the_end_reached_forgets_all():
    route = RememberedRoute()
    route.remember([(0.2, 0.0), (0.4, 0.0), (0.6, 0.1)])
    route.advance(VelocityCommand(1.0, 0.0), 0.35)
    np.testing.assert_allclose(route.ahead(0.1), [(0.25, 0.1)], atol=1e-12)
    # Backing up does not bring the dropped points back.
    route.advance(VelocityCommand(-1.0, 0.0), 0.35)
    np.testing.assert_allclose(route.ahead(0.1), [(0.6, 0.1)], atol=1e-12)
    route.advance(VelocityCommand(1.0, 0.0), 0.6)
    assert len(route.ahead(0.1)) == 0
    route.advance(VelocityCommand(-1.0, 0.0), 0.6)
    assert len(route.ahead(0.1)) == 0


def test_a_measured_move_takes_the_place_of_the_commanded_one():
    # Odometry, in a frame of its own, says the robot went 0.3 m and turned a quarter left
    # while the command said 0.5 m straight on: the route is where odometry says.
    route = RememberedRoute()
    route.remember([(1.0, 1.0)])
    start = (2.0, -3.0, 0.5)
    route.advance(VelocityCommand(0.5, 0.0), 0.0, start)
    route.advance(VelocityCommand(0.5, 0.0), 1.0,
                  compose_poses(start, (0.3, 0.0, math.pi / 2.0)))
    np.testing.assert_allclose(route.ahead(0.0), [(1.0, -0.7)], atol=1e-12)


def test_a_step_without_a_measured_pose_is_driven_by_the_command_and_not_counted_twice():
    route = RememberedRoute()
    route.remember([(2.0, 0.0)])
    route.advance(VelocityCommand(1.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    route.advance(VelocityCommand(1.0, 0.0), 0.5, (0.25, 0.0, 0.0))
    # Odometry missing for a step: the command's 0.5 m.
    route.advance(VelocityCommand(1.0, 0.0), 0.5, None)
    # Back, its first pose is only the new reference, not a move from the last one: that
    # step is the command's 0.5 m too.
    route.advance(VelocityCommand(1.0, 0.0), 0.5, (10.0, 10.0, 1.0))
    np.testing.assert_allclose(route.ahead(0.0), [(0.75, 0.0)], atol=1e-12)


def test_a_line_along_the_path_just_driven_is_on_the_trail():
    route = RememberedRoute()
    for _ in range(50):
        route.advance(VelocityCommand(0.5, 0.0), 0.05)
    # 1.25 m straight on, then turned round in place: the way back lies ahead.
    route.advance(VelocityCommand(0.0, math.pi), 1.0)
    way_back = [(0.35, 0.0), (0.6, 0.02), (0.85, -0.03)]
    assert route.on_trail(way_back, 2.0, 0.1)
    # A line beside it, as a hairpin's other leg 0.3 m away, is not.
    assert not route.on_trail([(x_m, 0.3) for x_m, _ in way_back], 2.0, 0.1)
    # Nor is the path driven longer ago than counts, nor anything when told so.
    assert not route.on_trail([(1.1, 0.0), (1.2, 0.0)], 0.5, 0.1)
    assert not route.on_trail(way_back, 2.0, 0.0)


@pytest.mark.parametrize('jump', ((1e6, 0.0, 0.0), (0.0, 0.0, 3.0), (math.nan, 0.0, 0.0)))
def test_an_odometry_jump_is_driven_by_the_command_and_only_resets_the_reference(jump):
    # A reset odometry or a glitch moves the pose further in a frame than any base goes.
    route = RememberedRoute()
    route.remember([(2.0, 0.0)])
    route.advance(VelocityCommand(1.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    route.advance(VelocityCommand(1.0, 0.0), 0.05, jump)
    np.testing.assert_allclose(route.ahead(0.0), [(1.95, 0.0)], atol=1e-12)
    # Measured moves from the new reference count again.
    route.advance(VelocityCommand(1.0, 0.0), 0.05, compose_poses(jump, (0.01, 0.0, 0.0)))
    if math.isfinite(jump[0]):
        np.testing.assert_allclose(route.ahead(0.0), [(1.94, 0.0)], atol=1e-9)


def test_poses_compose_with_their_relative_moves_and_arcs():
    start = (1.0, 2.0, 3.0)
    end = arc_pose(start, 0.4, -1.3, 0.7)
    np.testing.assert_allclose(compose_poses(start, relative_pose(start, end)), end,
                               atol=1e-12)
    # Driving an arc back for the same time returns to the start.
    np.testing.assert_allclose(arc_pose(end, 0.4, -1.3, -0.7), start, atol=1e-12)


def place_after(commands):
    """
    Return where commands, each held for a frame, take the robot, in its frame at the start.

    Integrated in small steps, independently of the controller's exact arcs.

    :param commands: the VelocityCommands, in order.
    :return: (x forward, y left) in metres.
    """
    x_m, y_m, yaw_rad = 0.0, 0.0, 0.0
    step_s = FRAME_PERIOD_S / 100
    for command in commands:
        for _ in range(100):
            x_m += command.linear_mps * math.cos(yaw_rad) * step_s
            y_m += command.linear_mps * math.sin(yaw_rad) * step_s
            yaw_rad += command.angular_radps * step_s
    return x_m, y_m


def assert_driven_to_short_of(end_m, sighting, frames, config):
    """
    Assert that a sighting's command and the coasting after it took the robot near a point.

    Where the commands took the robot from the sighting (each held for a frame) must be the
    distance it stops short of the point, give or take a frame's travel.

    :param end_m: the (x forward, y left) point in the robot's frame at the sighting.
    :param sighting: the command answering the sighting.
    :param frames: the frames after it, coasting first.
    :param config: the ControllerConfig.
    """
    commands = [sighting] + [frame.command for frame in frames[:coasting_frames(frames)]]
    assert math.dist(place_after(commands), end_m) == pytest.approx(
        config.line_end_stop_short_m, abs=config.linear_speed_mps * FRAME_PERIOD_S)


def hairpin_half_points(side, radius_m=0.15, start_m=0.35):
    """Return floor points of a line straight ahead turning back on a small circle, to its top."""
    angles_rad = np.linspace(0.0, math.pi / 2.0, 4)
    return np.stack((start_m + radius_m * np.sin(angles_rad),
                     side * radius_m * (1.0 - np.cos(angles_rad))), axis=1)


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_drives_round_a_hairpin_it_saw_end_to_its_top_then_looks_round_it(side):
    # The turn of a hairpin leaves the view at its bottom edge: the last frame that saw the
    # line showed it from 0.35 m ahead, turning to a side and ending at the hairpin's top.
    config = ControllerConfig()
    points = hairpin_half_points(side)
    controller, time_s = tracking_controller(config, seen(), STRAIGHT_AHEAD_M)
    sighting = controller.update(seen(seen_count=len(points)), time_s + FRAME_PERIOD_S, points)
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + 2 * FRAME_PERIOD_S)
    coasting = coasting_frames(frames)
    # Turning toward the hairpin's side all the way there.
    assert coasting > 5
    assert all(frame.command.linear_mps > 0.0 and frame.command.angular_radps * side > 0.0
               for frame in frames[1:coasting])
    assert_driven_to_short_of(points[-1], sighting, frames, config)
    # Then in place toward that side, looking for the way back.
    assert all(frame.state == 'line end' and frame.command.linear_mps == 0.0
               for frame in frames[coasting:])
    assert any(frame.command.angular_radps * side > 0.0 for frame in frames[coasting:])


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_a_line_that_vanished_where_it_ran_on_out_of_view_is_driven_along_then_searched(side):
    # Glare or worn paint hides the whole line at once: it was seen running on out of the top
    # of the view, on a bend, so it is where it was seen. Searching, the robot drives on along
    # it, well past the line memory, to the farthest point it saw, and searches there.
    config = ControllerConfig(line_memory_s=0.3)
    points = circle_points(1.0, side)
    controller, time_s = tracking_controller(config, seen(), points)
    sighting = controller.last_command
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + FRAME_PERIOD_S)
    coasting = coasting_frames(frames)
    assert coasting > 2 * round(config.line_memory_s / FRAME_PERIOD_S)
    assert all(frame.command.linear_mps > 0.0 and frame.command.angular_radps * side > 0.0
               for frame in frames[:coasting])
    assert_driven_to_short_of(points[-1], sighting, frames, config)
    # Then the search, toward the side the line bent to.
    assert all(frame.state == 'lost' and frame.command.linear_mps == 0.0
               for frame in frames[coasting:])
    assert frames[-1].command.angular_radps == pytest.approx(
        side * config.search_angular_speed_radps)


def test_a_route_is_forgotten_when_time_goes_back():
    config = ControllerConfig()
    controller, time_s = tracking_controller(config, seen(), STRAIGHT_AHEAD_M)
    controller.update(seen(seen_count=2), time_s + FRAME_PERIOD_S, STRAIGHT_AHEAD_M[:2])
    # A restarted simulation or a looped bag: what was seen is not where the robot now is.
    frames = drive(controller, nothing_seen(), None, 3, start_s=0.0)
    assert all(frame.command.linear_mps == 0.0 for frame in frames)


@pytest.mark.parametrize('with_odometry', (True, False))
def test_a_base_that_lags_its_commands_is_driven_to_a_line_end_by_odometry(with_odometry):
    # A real base answers its commands late: here it goes half as fast as told. By the
    # commands the robot would think itself at the line's end halfway there; by odometry (in
    # a frame of its own) it drives on until it is there.
    config = ControllerConfig()
    controller, time_s = tracking_controller(config, seen(), STRAIGHT_AHEAD_M)
    start = pose = (5.0, -2.0, 1.0)
    command = controller.update(seen(seen_count=2), time_s + FRAME_PERIOD_S,
                                STRAIGHT_AHEAD_M[:2], pose)
    for index in range(SETTLING_FRAMES):
        pose = arc_pose(pose, 0.5 * command.linear_mps, 0.5 * command.angular_radps,
                        FRAME_PERIOD_S)
        command = controller.update(nothing_seen(), time_s + (index + 2) * FRAME_PERIOD_S,
                                    None, pose if with_odometry else None)
        if controller.state != 'coasting':
            break
    travelled_m = relative_pose(start, pose)[0]
    end_m = STRAIGHT_AHEAD_M[1][0] - config.line_end_stop_short_m
    if with_odometry:
        assert travelled_m == pytest.approx(end_m, abs=config.linear_speed_mps * FRAME_PERIOD_S)
    else:
        assert travelled_m < 0.7 * end_m


@pytest.mark.parametrize('trail_tolerance_m, followed', ((0.1, False), (0.0, True)))
def test_a_lost_line_found_again_along_the_way_it_came_is_not_followed_back(
        trail_tolerance_m, followed):
    # Lost after following a straight line (driven on along it, then searching), the robot has
    # turned round: the line now seen straight ahead is the one it drove along.
    config = ControllerConfig(trail_tolerance_m=trail_tolerance_m)
    controller, time_s = tracking_controller(config, seen(), STRAIGHT_AHEAD_M)
    # Each command is driven until the next frame: the last is not driven yet.
    turned_rad = -math.pi
    while turned_rad < 0.0:
        time_s += FRAME_PERIOD_S
        command = controller.update(nothing_seen(), time_s, None)
        assert command.linear_mps > 0.0 or controller.state == 'lost'
        turned_rad += command.angular_radps * FRAME_PERIOD_S
    start_s = time_s + FRAME_PERIOD_S
    # Seen for long enough to be trusted (the robot turning on meanwhile: not for long).
    way_back = np.array([(0.35, 0.0), (0.5, 0.0), (0.65, 0.0)])
    frames = drive(controller, seen(seen_count=3), way_back, config.frames_to_trust + 1,
                   start_s=start_s)
    assert (frames[-1].state == 'tracking') == followed
    if not followed:
        assert frames[-1].state == 'lost' and frames[-1].command.linear_mps == 0.0


def test_the_proportional_law_coasts_on_its_last_command_at_a_line_end():
    # It has no floor points, so no route: the line memory, then the stop.
    config = ControllerConfig(steering_law='proportional', line_memory_s=0.12)
    controller, time_s = tracking_controller(config, seen(0.2), None)
    controller.update(seen(0.2, seen_count=1), time_s + FRAME_PERIOD_S)
    frames = drive(controller, nothing_seen(), None, 10, start_s=time_s + 2 * FRAME_PERIOD_S)
    assert coasting_frames(frames) == 2
    assert {frame.state for frame in frames[2:]} == {'line end'}


@pytest.mark.parametrize('side', (LEFT, RIGHT))
def test_a_line_leaving_the_view_at_its_side_is_not_driven_to_but_looked_round(side):
    # A square corner seen from before it: the nearest band sees the new leg at the image's
    # edge and nothing beyond. Where it leaves the view is not where it ends: the robot coasts
    # on its last command (the turn it was making), then turns in place toward it.
    config = ControllerConfig(line_memory_s=0.12)
    controller, time_s = tracking_controller(config, seen(), points_turning_away(side))
    leaving = seen(-side * 0.95, seen_count=1)
    leaving = dataclasses.replace(leaving, bands=(
        leaving.bands[0]._replace(at_side=True), *leaving.bands[1:]))
    controller.update(leaving, time_s + FRAME_PERIOD_S, ray_points(side * 0.4, (0.4,)))
    frames = drive(controller, nothing_seen(), None, SETTLING_FRAMES,
                   start_s=time_s + 2 * FRAME_PERIOD_S)
    assert coasting_frames(frames) == 2
    assert all(frame.command == frames[0].command for frame in frames[:2])
    assert {frame.state for frame in frames[2:]} == {'line end'}
    assert all(frame.command.linear_mps == 0.0 for frame in frames[2:])
    assert any(frame.command.angular_radps * side > 0.0 for frame in frames[2:])
