"""Tests of the course geometry, its floor texture and the lap tracker."""

import json
import math

from followbot_sim import course_library
from followbot_sim.course import BOOK_FLOOR_SIZE_M
from followbot_sim.course import BOOK_LINE_WIDTH_M
from followbot_sim.course import book_loop
from followbot_sim.course import Course
from followbot_sim.course import COURSES
from followbot_sim.course import CURVATURE_BASELINE_M
from followbot_sim.course import Distractor
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LapTracker
from followbot_sim.course import LIGHTING_EDGE_RAMP_M
from followbot_sim.course import LightingZone
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.course import MAX_POINT_SPACING_M
from followbot_sim.course import texture_px_to_world
from followbot_sim.course import world_to_texture_px
import numpy as np
import pytest

CIRCLE_RADIUS_M = 2.0
# About 9 mm chords, so the polygon stays within 20 micrometres of the circle.
CIRCLE_POINTS = 1440
TEXTURE_SIZE_PX = 1024
# Blue separates the two paints best (yellow 0, grey 116): below halfway is mostly line.
LINE_BLUE_THRESHOLD = FLOOR_GREY // 2
SAMPLE_PERIOD_S = 0.05
DRIVE_SPEED_M_S = 0.5


@pytest.fixture(scope='module')
def book():
    return book_loop()


def circle_course(radius_m=CIRCLE_RADIUS_M, centre_xy=(0.0, 0.0), points=CIRCLE_POINTS):
    """Build a counter-clockwise circle course starting at angle 0."""
    angle_rad = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    centre_line_xy = np.stack([radius_m * np.cos(angle_rad), radius_m * np.sin(angle_rad)], 1)
    return Course(centre_line_xy + np.asarray(centre_xy), name='circle')


def rectangle_course(half_width_m, half_height_m):
    """Build a counter-clockwise rectangle course starting at the middle of its east side."""
    return Course([(half_width_m, 0.0), (half_width_m, half_height_m),
                   (-half_width_m, half_height_m), (-half_width_m, -half_height_m),
                   (half_width_m, -half_height_m)])


def drive_circle(tracker, angles_rad, radius_m=CIRCLE_RADIUS_M, start_time_s=0.0):
    """
    Feed the tracker positions on a circle at the given angles, one sample period apart.

    :return: the time of the last sample.
    """
    time_s = start_time_s
    for index, angle_rad in enumerate(angles_rad):
        time_s = start_time_s + index * SAMPLE_PERIOD_S
        tracker.update(radius_m * math.cos(angle_rad), radius_m * math.sin(angle_rad), time_s)
    return time_s


def constant_speed_angles(start_rad, end_rad, radius_m=CIRCLE_RADIUS_M,
                          speed_m_s=DRIVE_SPEED_M_S):
    """Return the angles of a drive from start to end at constant speed, both ends included."""
    step_rad = speed_m_s * SAMPLE_PERIOD_S / radius_m
    count = int(abs(end_rad - start_rad) / step_rad)
    angles_rad = start_rad + math.copysign(step_rad, end_rad - start_rad) * np.arange(count + 1)
    return list(angles_rad) + [end_rad]


def segments_cross(first_start, first_end, second_start, second_end):
    """Tell, for arrays of segments, which pairs properly cross each other."""
    def orientation(a, b, c):
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))
    return ((orientation(first_start, first_end, second_start)
             * orientation(first_start, first_end, second_end) < 0)
            & (orientation(second_start, second_end, first_start)
               * orientation(second_start, second_end, first_end) < 0))


def angle_difference_rad(first_rad, second_rad):
    return (first_rad - second_rad + math.pi) % (2.0 * math.pi) - math.pi


def is_line_px(pixel_rgb):
    return pixel_rgb[2] < LINE_BLUE_THRESHOLD


# --- book_loop ---------------------------------------------------------------------------------

def test_book_loop_length_is_the_books(book):
    assert 20.5 <= book.length_m <= 21.5


def test_book_loop_bounding_box_is_the_books(book):
    size_xy = np.ptp(book.centre_line_xy, axis=0)
    assert size_xy[0] == pytest.approx(5.1, abs=0.5)
    assert size_xy[1] == pytest.approx(8.5, abs=0.5)


def test_book_loop_lies_on_the_floor_with_its_full_width(book):
    limit_m = BOOK_FLOOR_SIZE_M / 2.0 - BOOK_LINE_WIDTH_M / 2.0
    assert np.all(np.abs(book.centre_line_xy) <= limit_m)


def test_book_loop_has_the_books_dimensions(book):
    assert book.name == 'book_loop'
    assert book.line_width_m == BOOK_LINE_WIDTH_M
    assert book.floor_size_m == BOOK_FLOOR_SIZE_M


def test_book_loop_does_not_cross_itself(book):
    # Every 4th point is within a millimetre of the curve and keeps the check small.
    points_xy = book.centre_line_xy[::4]
    starts = points_xy
    ends = np.roll(points_xy, -1, axis=0)
    crossings = segments_cross(starts[:, np.newaxis], ends[:, np.newaxis],
                               starts[np.newaxis, :], ends[np.newaxis, :])
    assert not crossings.any()


def test_book_loop_bends_gently_enough_for_a_turtlebot(book):
    # A follower looking ~0.45 m ahead cuts a bend of radius R by about
    # R - sqrt(R^2 - 0.45^2): below 0.095 m (half the line) only for R above ~1 m.
    assert book.min_radius_of_curvature_m() >= 1.0


def test_book_loop_points_are_dense(book):
    spacing_m = np.linalg.norm(np.roll(book.centre_line_xy, -1, axis=0) - book.centre_line_xy,
                               axis=1)
    assert spacing_m.max() <= MAX_POINT_SPACING_M + 1e-9


def test_book_loop_start_pose_is_on_the_line_facing_along_it(book):
    x_m, y_m, yaw_rad = book.start_pose()
    distance_m, arc_m = book.nearest(x_m, y_m)
    assert distance_m == pytest.approx(0.0, abs=1e-9)
    assert min(arc_m, book.length_m - arc_m) == pytest.approx(0.0, abs=1e-6)
    ahead_x_m, ahead_y_m, _ = book.point_at(0.1)
    tangent_rad = math.atan2(ahead_y_m - y_m, ahead_x_m - x_m)
    assert angle_difference_rad(yaw_rad, tangent_rad) == pytest.approx(0.0, abs=0.02)


def test_book_loop_start_is_on_a_gentle_part(book):
    # The circle through the start and points 0.5 m either side has a radius of metres.
    previous_xy = np.array(book.point_at(-0.5)[:2])
    start_xy = np.array(book.point_at(0.0)[:2])
    next_xy = np.array(book.point_at(0.5)[:2])
    sides_m = [np.linalg.norm(start_xy - previous_xy), np.linalg.norm(next_xy - start_xy),
               np.linalg.norm(next_xy - previous_xy)]
    first, second = start_xy - previous_xy, next_xy - previous_xy
    double_area_m2 = abs(first[0] * second[1] - first[1] * second[0])
    assert np.prod(sides_m) / (2.0 * double_area_m2) > 3.0


def test_book_loop_runs_counter_clockwise(book):
    x_m, y_m = book.centre_line_xy[:, 0], book.centre_line_xy[:, 1]
    signed_area_m2 = 0.5 * np.sum(x_m * np.roll(y_m, -1) - np.roll(x_m, -1) * y_m)
    assert signed_area_m2 > 0.0


# --- registry ----------------------------------------------------------------------------------

def test_make_course_builds_book_loop():
    assert make_course('book_loop').name == 'book_loop'
    assert 'book_loop' in COURSES


@pytest.mark.parametrize('name', ['no_such_course', '', None])
def test_make_course_rejects_unknown_names_listing_known_ones(name):
    with pytest.raises(ValueError, match='book_loop'):
        make_course(name)


# --- construction and validation ---------------------------------------------------------------

@pytest.mark.parametrize('kwargs, message', [
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0)]}, 'at least 3'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (0.0, 0.0)]}, 'at least 3'),
    ({'centre_line_xy': [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)]}, 'shape'),
    ({'centre_line_xy': [0.0, 1.0, 2.0]}, 'shape'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, math.nan), (1.0, 1.0)]}, 'finite'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, math.inf), (1.0, 1.0)]}, 'finite'),
    ({'centre_line_xy': [('a', 0.0), (1.0, 0.0), (1.0, 1.0)]}, 'numbers'),
    ({'centre_line_xy': [(0.0, 0.0), (5.5, 0.0), (1.0, 1.0)]}, 'floor'),
    ({'centre_line_xy': [(0.0, 0.0), (4.95, 0.0), (1.0, 1.0)]}, 'floor'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 'line_width_m': 0.0},
     'line_width_m'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 'line_width_m': -0.1},
     'line_width_m'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 'line_width_m': math.nan},
     'line_width_m'),
    ({'centre_line_xy': [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 'floor_size_m': 0.0},
     'floor_size_m'),
])
def test_course_rejects_invalid_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Course(**kwargs)


def test_course_accepts_a_line_touching_the_floor_edge_with_its_edge():
    edge_m = BOOK_FLOOR_SIZE_M / 2.0 - BOOK_LINE_WIDTH_M / 2.0
    course = Course([(0.0, 0.0), (edge_m, 0.0), (edge_m, edge_m)])
    assert course.length_m == pytest.approx(edge_m * (2.0 + math.sqrt(2.0)))


def test_coarse_course_is_subdivided_keeping_its_corners_and_length():
    course = rectangle_course(1.0, 0.5)
    points_xy = course.centre_line_xy
    spacing_m = np.linalg.norm(np.roll(points_xy, -1, axis=0) - points_xy, axis=1)
    assert spacing_m.max() <= MAX_POINT_SPACING_M + 1e-12
    assert course.length_m == pytest.approx(6.0)
    for corner_xy in [(1.0, 0.5), (-1.0, 0.5), (-1.0, -0.5), (1.0, -0.5)]:
        assert np.min(np.linalg.norm(points_xy - corner_xy, axis=1)) < 1e-12
    assert tuple(points_xy[0]) == (1.0, 0.0)


def test_repeated_closing_point_is_dropped():
    open_loop = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0)]
    assert Course(open_loop + [open_loop[0]]).length_m == pytest.approx(
        Course(open_loop).length_m)


def test_centre_line_is_read_only(book):
    with pytest.raises(ValueError):
        book.centre_line_xy[0, 0] = 0.0


# --- point_at ----------------------------------------------------------------------------------

@pytest.mark.parametrize('arc_m, expected', [
    (0.0, (1.0, 0.0, math.pi / 2.0)),
    (0.25, (1.0, 0.25, math.pi / 2.0)),
    (1.5, (0.0, 0.5, math.pi)),
    (6.0, (1.0, 0.0, math.pi / 2.0)),
    (-0.25, (1.0, -0.25, math.pi / 2.0)),
    (6.25, (1.0, 0.25, math.pi / 2.0)),
    (4.0, (-0.5, -0.5, 0.0)),
])
def test_point_at_walks_the_rectangle_and_wraps(arc_m, expected):
    x_m, y_m, heading_rad = rectangle_course(1.0, 0.5).point_at(arc_m)
    assert (x_m, y_m) == pytest.approx(expected[:2], abs=1e-9)
    assert angle_difference_rad(heading_rad, expected[2]) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize('offset_m', [0.05, -0.1])
def test_point_at_an_offset_is_that_far_beside_the_line(offset_m):
    # Going north up the rectangle's east side, left is west.
    course = rectangle_course(1.0, 0.5)
    x_m, y_m, heading_rad = course.point_at(0.25, offset_m)
    assert (x_m, y_m) == pytest.approx((1.0 - offset_m, 0.25), abs=1e-9)
    assert angle_difference_rad(heading_rad, math.pi / 2.0) == pytest.approx(0.0, abs=1e-9)
    assert course.signed_offset(x_m, y_m) == pytest.approx((offset_m, 0.25), abs=1e-9)


# --- nearest and signed_offset -----------------------------------------------------------------

@pytest.mark.parametrize('arc_m', [0.0, 0.123, 3.3, 7.77, 12.5, 20.0])
def test_points_on_the_line_are_at_distance_zero(book, arc_m):
    x_m, y_m, _ = book.point_at(arc_m)
    distance_m, nearest_arc_m = book.nearest(x_m, y_m)
    assert distance_m == pytest.approx(0.0, abs=1e-9)
    assert nearest_arc_m == pytest.approx(arc_m, abs=1e-6)


@pytest.mark.parametrize('arc_m', [0.5, 4.0, 9.1, 14.2, 19.9])
@pytest.mark.parametrize('offset_m', [-0.3, -0.05, 0.02, 0.25])
def test_point_offset_along_the_normal_is_that_far(book, arc_m, offset_m):
    # Take the normal from the smooth curve through neighbours, not from one short segment.
    before_xy = np.array(book.point_at(arc_m - 0.05)[:2])
    after_xy = np.array(book.point_at(arc_m + 0.05)[:2])
    tangent_xy = (after_xy - before_xy) / np.linalg.norm(after_xy - before_xy)
    left_normal_xy = np.array([-tangent_xy[1], tangent_xy[0]])
    x_m, y_m = np.array(book.point_at(arc_m)[:2]) + offset_m * left_normal_xy
    distance_m, nearest_arc_m = book.nearest(x_m, y_m)
    signed_m, signed_arc_m = book.signed_offset(x_m, y_m)
    assert distance_m == pytest.approx(abs(offset_m), abs=1e-3)
    assert nearest_arc_m == pytest.approx(arc_m, abs=5e-3)
    assert signed_m == pytest.approx(offset_m, abs=1e-3)
    assert signed_arc_m == nearest_arc_m


def test_circle_distance_and_arc_length_match_the_analytic_circle():
    course = circle_course()
    rng = np.random.default_rng(seed=12)
    radius_m = rng.uniform(0.5, 4.5, size=200)
    angle_rad = rng.uniform(-math.pi, math.pi, size=200)
    for point_radius_m, point_angle_rad in zip(radius_m, angle_rad):
        x_m = point_radius_m * math.cos(point_angle_rad)
        y_m = point_radius_m * math.sin(point_angle_rad)
        distance_m, arc_m = course.nearest(x_m, y_m)
        signed_m, _ = course.signed_offset(x_m, y_m)
        assert 0.0 <= arc_m < course.length_m
        assert distance_m == pytest.approx(abs(point_radius_m - CIRCLE_RADIUS_M), abs=1e-3)
        # Counter-clockwise travel: inside the circle is on the left.
        assert signed_m == pytest.approx(CIRCLE_RADIUS_M - point_radius_m, abs=1e-3)
        expected_arc_m = CIRCLE_RADIUS_M * (point_angle_rad % (2.0 * math.pi))
        arc_error_m = (arc_m - expected_arc_m + course.length_m / 2.0) % course.length_m
        # Off the line, projecting onto a chord instead of the arc shifts the foot by up to
        # the distance times half the chord angle.
        arc_tolerance_m = 1e-4 + distance_m * math.pi / CIRCLE_POINTS
        assert arc_error_m - course.length_m / 2.0 == pytest.approx(0.0, abs=arc_tolerance_m)


def test_circle_length_and_radius_of_curvature():
    course = circle_course()
    assert course.length_m == pytest.approx(2.0 * math.pi * CIRCLE_RADIUS_M, rel=1e-4)
    assert course.min_radius_of_curvature_m() == pytest.approx(CIRCLE_RADIUS_M, rel=1e-2)


def test_radius_of_curvature_of_a_right_angle_is_under_the_baseline():
    radius_m = rectangle_course(1.0, 0.5).min_radius_of_curvature_m()
    assert radius_m == pytest.approx(CURVATURE_BASELINE_M / math.sqrt(2.0), rel=1e-6)


def test_nearest_returns_plain_floats(book):
    distance_m, arc_m = book.nearest(0.3, -0.7)
    assert type(distance_m) is float and type(arc_m) is float


# --- texture -----------------------------------------------------------------------------------

@pytest.mark.parametrize('x_m, y_m, expected_col_row', [
    (-4.95, 4.95, (0.0, 0.0)),
    (4.95, -4.95, (99.0, 99.0)),
    (4.95, 4.95, (99.0, 0.0)),
    (0.0, 0.0, (49.5, 49.5)),
    (-5.0, 5.0, (-0.5, -0.5)),
])
def test_world_to_texture_px_follows_mujoco_plane_convention(x_m, y_m, expected_col_row):
    assert world_to_texture_px(x_m, y_m, 100) == pytest.approx(expected_col_row)


@pytest.mark.parametrize('x_m, y_m', [(-4.95, 4.95), (0.0, 0.0), (3.21, -1.7), (-5.0, 5.0)])
def test_texture_px_to_world_inverts_world_to_texture_px(x_m, y_m):
    col, row = world_to_texture_px(x_m, y_m, 100, 12.0)
    assert texture_px_to_world(col, row, 100, 12.0) == pytest.approx((x_m, y_m))


def test_course_world_to_texture_px_uses_its_floor_size():
    course = Course([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], floor_size_m=20.0)
    assert course.world_to_texture_px(-9.9, 9.9, 100) == pytest.approx((0.0, 0.0))


def test_texture_is_an_rgb_image_of_the_floor(book):
    texture_rgb = book.draw_texture(TEXTURE_SIZE_PX)
    assert texture_rgb.shape == (TEXTURE_SIZE_PX, TEXTURE_SIZE_PX, 3)
    assert texture_rgb.dtype == np.uint8
    assert tuple(texture_rgb[0, 0]) == (FLOOR_GREY,) * 3


def test_texture_is_yellow_at_the_start_and_grey_half_a_metre_off(book):
    texture_rgb = book.draw_texture(TEXTURE_SIZE_PX)
    x_m, y_m, yaw_rad = book.start_pose()
    col, row = book.world_to_texture_px(x_m, y_m, TEXTURE_SIZE_PX)
    assert tuple(texture_rgb[round(row), round(col)]) == LINE_RGB
    for side in (1.0, -1.0):
        off_x_m = x_m - side * 0.5 * math.sin(yaw_rad)
        off_y_m = y_m + side * 0.5 * math.cos(yaw_rad)
        col, row = book.world_to_texture_px(off_x_m, off_y_m, TEXTURE_SIZE_PX)
        assert tuple(texture_rgb[round(row), round(col)]) == (FLOOR_GREY,) * 3


@pytest.mark.parametrize('size_px', [256, 512, 1024, 2048])
def test_texture_line_width_matches_the_course(size_px):
    # The east side of this rectangle runs north, so an image row crosses it squarely.
    course = rectangle_course(2.0, 3.0)
    texture_rgb = course.draw_texture(size_px)
    _, row = course.world_to_texture_px(2.0, 0.0, size_px)
    middle_row_rgb = texture_rgb[round(row)]
    east_half_rgb = middle_row_rgb[size_px // 2:]
    line_px = int(np.count_nonzero(east_half_rgb[:, 2] < LINE_BLUE_THRESHOLD))
    assert line_px == pytest.approx(BOOK_LINE_WIDTH_M * size_px / BOOK_FLOOR_SIZE_M, abs=2.0)


@pytest.mark.parametrize('size_px', [256, 1024])
@pytest.mark.parametrize('east_side_x_m', [2.0, 2.003, 2.005, 2.0075])
def test_texture_line_holds_width_and_position_to_a_fraction_of_a_pixel(size_px,
                                                                        east_side_x_m):
    # Steps of 0.3, 0.5 and 0.75 px at 1024 px: the paint must follow sub-pixel moves.
    course = rectangle_course(east_side_x_m, 3.0)
    texture_rgb = course.draw_texture(size_px)
    col, row = course.world_to_texture_px(east_side_x_m, 0.0, size_px)
    east_half_blue = texture_rgb[round(row), size_px // 2:, 2].astype(float)
    coverage = (FLOOR_GREY - east_half_blue) / FLOOR_GREY
    painted_cols = size_px // 2 + np.arange(len(coverage))
    width_px = BOOK_LINE_WIDTH_M * size_px / BOOK_FLOOR_SIZE_M
    assert coverage.sum() == pytest.approx(width_px, abs=0.05)
    assert np.sum(coverage * painted_cols) / coverage.sum() == pytest.approx(col, abs=0.05)


def test_texture_puts_north_east_at_the_top_right():
    course = Course([(1.5, 1.5), (3.5, 1.5), (3.5, 3.5), (1.5, 3.5)])
    texture_rgb = course.draw_texture(TEXTURE_SIZE_PX)
    half_px = TEXTURE_SIZE_PX // 2
    is_line = texture_rgb[:, :, 2] < LINE_BLUE_THRESHOLD
    assert is_line[:half_px, half_px:].any()
    assert not is_line[half_px:, :].any()
    assert not is_line[:, :half_px].any()


def test_texture_is_anti_aliased(book):
    texture_rgb = book.draw_texture(TEXTURE_SIZE_PX)
    blue = texture_rgb[:, :, 2]
    assert np.any((blue > 0) & (blue < FLOOR_GREY))


@pytest.mark.parametrize('size_px', [0, -5, 10.5, True])
def test_texture_rejects_bad_sizes(book, size_px):
    with pytest.raises(ValueError, match='size_px'):
        book.draw_texture(size_px)


# --- LapTracker --------------------------------------------------------------------------------

@pytest.mark.parametrize('start_rad', [0.0, 1.0, -0.3, math.pi])
def test_driving_a_circle_counts_laps_and_lap_times(start_rad):
    course = circle_course()
    tracker = LapTracker(course)
    end_time_s = drive_circle(
        tracker, constant_speed_angles(start_rad, start_rad + 2.5 * 2.0 * math.pi))
    lap_time_s = course.length_m / DRIVE_SPEED_M_S
    assert tracker.laps_completed == 2
    assert tracker.lap_times_s == pytest.approx([lap_time_s, lap_time_s], abs=1e-2)
    assert tracker.progress_m == pytest.approx(2.5 * course.length_m, abs=1e-2)
    assert tracker.time_s == end_time_s
    assert tracker.arc_jumps == 0


def test_progress_just_short_of_a_lap_is_no_lap():
    course = circle_course()
    tracker = LapTracker(course)
    drive_circle(tracker, constant_speed_angles(0.0, 2.0 * math.pi - 0.01))
    assert tracker.laps_completed == 0
    assert tracker.lap_times_s == []


def test_driving_backwards_reduces_progress_and_completes_no_lap():
    course = circle_course()
    tracker = LapTracker(course)
    drive_circle(tracker, constant_speed_angles(0.5, 0.5 - 1.5 * 2.0 * math.pi))
    assert tracker.progress_m == pytest.approx(-1.5 * course.length_m, abs=1e-2)
    assert tracker.laps_completed == 0


def test_backing_across_the_start_and_driving_on_does_not_count_twice():
    course = circle_course()
    tracker = LapTracker(course)
    # Forward a little, back across the start, then forward to just short of a full lap.
    angles_rad = (constant_speed_angles(0.5, 1.0) + constant_speed_angles(1.0, -0.5)
                  + constant_speed_angles(-0.5, 0.5 + 2.0 * math.pi - 0.05))
    end_time_s = drive_circle(tracker, angles_rad)
    assert tracker.laps_completed == 0
    drive_circle(tracker, constant_speed_angles(0.5 - 0.05, 0.5 + 0.1),
                 start_time_s=end_time_s + SAMPLE_PERIOD_S)
    assert tracker.laps_completed == 1


def test_reversing_over_a_completed_lap_mark_does_not_count_it_again():
    course = circle_course()
    tracker = LapTracker(course)
    two_pi = 2.0 * math.pi
    angles_rad = (constant_speed_angles(0.0, two_pi + 0.5) + constant_speed_angles(two_pi + 0.5,
                                                                                   two_pi - 0.5)
                  + constant_speed_angles(two_pi - 0.5, two_pi + 1.0))
    drive_circle(tracker, angles_rad)
    assert tracker.laps_completed == 1
    assert len(tracker.lap_times_s) == 1


def test_a_hop_to_another_part_of_the_course_adds_no_progress():
    course = circle_course()
    tracker = LapTracker(course)
    end_time_s = drive_circle(tracker, constant_speed_angles(0.0, 0.5))
    progress_m = tracker.progress_m
    drive_circle(tracker, [0.5 + math.pi], start_time_s=end_time_s + SAMPLE_PERIOD_S)
    assert tracker.arc_jumps == 1
    assert tracker.progress_m == progress_m


@pytest.mark.parametrize('offset_m, off_line', [
    (0.05, False), (-0.05, False), (0.09, False), (0.15, True), (-0.3, True),
])
def test_distance_statistics_on_an_offset_path(offset_m, off_line):
    course = circle_course()
    tracker = LapTracker(course)
    end_time_s = drive_circle(tracker, constant_speed_angles(0.0, 3.0),
                              radius_m=CIRCLE_RADIUS_M + offset_m)
    assert tracker.distance_from_line_m == pytest.approx(abs(offset_m), abs=1e-3)
    assert tracker.max_distance_from_line_m == pytest.approx(abs(offset_m), abs=1e-3)
    assert tracker.rms_distance_from_line_m == pytest.approx(abs(offset_m), abs=1e-3)
    expected_off_line_s = end_time_s if off_line else 0.0
    assert tracker.time_off_line_s == pytest.approx(expected_off_line_s, abs=1e-9)


def test_time_off_line_counts_only_the_time_off_the_line():
    course = circle_course()
    tracker = LapTracker(course)
    on_line_end_s = drive_circle(tracker, constant_speed_angles(0.0, 1.0))
    off_line_start_s = on_line_end_s + SAMPLE_PERIOD_S
    off_line_end_s = drive_circle(tracker, constant_speed_angles(1.0, 2.0),
                                  radius_m=CIRCLE_RADIUS_M + 0.2, start_time_s=off_line_start_s)
    assert tracker.time_off_line_s == pytest.approx(off_line_end_s - off_line_start_s,
                                                    abs=SAMPLE_PERIOD_S + 1e-9)
    assert tracker.max_distance_from_line_m == pytest.approx(0.2, abs=1e-3)


def test_summary_is_json_serialisable_and_complete():
    course = circle_course()
    tracker = LapTracker(course)
    drive_circle(tracker, constant_speed_angles(0.0, 2.0 * math.pi + 0.5))
    summary = json.loads(json.dumps(tracker.summary(), allow_nan=False))
    assert summary['laps_completed'] == 1
    assert summary['course'] == 'circle'
    for key in ['distance_from_line_m', 'max_distance_from_line_m', 'rms_distance_from_line_m',
                'progress_m', 'lap_times_s', 'time_s', 'time_off_line_s']:
        assert key in summary


def test_summary_before_any_update_is_all_zero():
    summary = LapTracker(circle_course()).summary()
    json.dumps(summary, allow_nan=False)
    assert summary['updates'] == 0
    assert summary['laps_completed'] == 0
    assert summary['rms_distance_from_line_m'] == 0.0


def test_reset_forgets_the_run():
    course = circle_course()
    tracker = LapTracker(course)
    drive_circle(tracker, constant_speed_angles(0.0, 2.0 * math.pi + 0.5))
    tracker.reset()
    assert tracker.summary() == LapTracker(course).summary()
    drive_circle(tracker, constant_speed_angles(1.0, 1.5), start_time_s=0.0)
    assert tracker.laps_completed == 0
    assert tracker.elapsed_s == pytest.approx(tracker.time_s)


@pytest.mark.parametrize('x_m, y_m, time_s, message', [
    (2.0, 0.0, 0.5, 'backwards'),
    (math.nan, 0.0, 2.0, 'finite'),
    (2.0, 0.0, math.inf, 'finite'),
])
def test_update_rejects_bad_samples(x_m, y_m, time_s, message):
    tracker = LapTracker(circle_course())
    tracker.update(2.0, 0.0, 1.0)
    with pytest.raises(ValueError, match=message):
        tracker.update(x_m, y_m, time_s)


def test_tracker_rejects_a_non_positive_arc_step():
    with pytest.raises(ValueError, match='max_arc_step_m'):
        LapTracker(circle_course(), max_arc_step_m=0.0)


def test_tracker_follows_book_loop_at_the_books_speed(book):
    tracker = LapTracker(book)
    speed_m_s = 0.2
    time_s = 0.0
    while time_s <= 1.2 * book.length_m / speed_m_s:
        x_m, y_m, _ = book.point_at(speed_m_s * time_s)
        tracker.update(x_m, y_m, time_s)
        time_s += SAMPLE_PERIOD_S
    assert tracker.laps_completed == 1
    assert tracker.lap_times_s[0] == pytest.approx(book.length_m / speed_m_s, abs=1e-3)
    assert tracker.max_distance_from_line_m == pytest.approx(0.0, abs=1e-9)


# --- the library's names, still importable from here ----------------------------------------

def test_courses_and_book_loop_are_the_librarys():
    assert COURSES is course_library.COURSES
    assert book_loop is course_library.book_loop


def test_unknown_module_attributes_still_raise_attribute_error():
    import followbot_sim.course as course_module
    with pytest.raises(AttributeError, match='no_such_name'):
        course_module.no_such_name


# --- nearest_near --------------------------------------------------------------------------------

def brute_force_nearest_in_window(course, x_m, y_m, arc_hint_m, window_m):
    """Return the distance to points sampled every millimetre of a window of arc length."""
    arcs_m = np.arange(arc_hint_m - window_m, arc_hint_m + window_m + 1e-4, 1e-3)
    points_xy = np.array([course.point_at(arc_m)[:2] for arc_m in arcs_m])
    distances_m = np.hypot(points_xy[:, 0] - x_m, points_xy[:, 1] - y_m)
    return float(distances_m.min()), float(arcs_m[np.argmin(distances_m)] % course.length_m)


@pytest.mark.parametrize('x_m, y_m, arc_hint_m, window_m', [
    (2.2, 0.5, 1.0, 0.5),  # near the hint: the same as the global nearest point
    (2.0, 0.0, 2.0 * math.pi, 1.0),  # the position is half a loop away from the window
    (1.9, -0.1, 0.2, 0.6),  # the window wraps round the start
    (1.9, -0.1, 12.3, 0.6),  # a hint beyond one loop wraps too
    (0.5, 0.5, -3.0, 0.8),  # negative hint
])
def test_nearest_near_finds_the_nearest_point_within_the_arc_window(x_m, y_m, arc_hint_m,
                                                                    window_m):
    course = circle_course()
    distance_m, arc_m = course.nearest_near(x_m, y_m, arc_hint_m, window_m)
    expected_distance_m, expected_arc_m = brute_force_nearest_in_window(
        course, x_m, y_m, arc_hint_m, window_m)
    assert 0.0 <= arc_m < course.length_m
    # Whole segments are searched, so the result may be up to one segment beyond the window.
    assert distance_m <= expected_distance_m + 1e-6
    assert distance_m == pytest.approx(expected_distance_m, abs=MAX_POINT_SPACING_M)
    arc_error_m = (arc_m - expected_arc_m + course.length_m / 2.0) % course.length_m
    assert arc_error_m - course.length_m / 2.0 == pytest.approx(0.0, abs=2 * MAX_POINT_SPACING_M)


def test_nearest_near_with_a_window_round_the_loop_is_the_global_nearest(book):
    assert book.nearest_near(0.3, -0.7, 4.0, book.length_m) == book.nearest(0.3, -0.7)


def test_nearest_near_rejects_a_non_positive_window(book):
    with pytest.raises(ValueError, match='window_m'):
        book.nearest_near(0.0, 0.0, 1.0, 0.0)


# --- painting options: dashes, distractors, lighting, floor images ---------------------------

def straight_sided_course(**options):
    """Build a 4 m x 6 m rectangle whose east side runs north from its start at (2, 0)."""
    return Course([(2.0, 0.0), (2.0, 3.0), (-2.0, 3.0), (-2.0, -3.0), (2.0, -3.0)],
                  name='rectangle', **options)


def texture_at(course, texture_rgb, x_m, y_m):
    """Return the texture pixel at a world position."""
    col, row = course.world_to_texture_px(x_m, y_m, texture_rgb.shape[0])
    return tuple(int(value) for value in texture_rgb[round(row), round(col)])


def test_a_plain_course_has_no_painting_options(book):
    assert book.dash_length_m is None and book.gap_length_m is None
    assert book.distractors == () and book.lighting_zones == ()
    assert book.floor_image_rgb is None


@pytest.mark.parametrize('options, error, message', [
    ({'dash_length_m': 0.3}, ValueError, 'together'),
    ({'gap_length_m': 0.3}, ValueError, 'together'),
    ({'dash_length_m': 0.0, 'gap_length_m': 0.1}, ValueError, 'dash_length_m must be positive'),
    ({'dash_length_m': 0.3, 'gap_length_m': -0.1}, ValueError, 'gap_length_m must be positive'),
    ({'dash_length_m': math.nan, 'gap_length_m': 0.1}, ValueError, 'finite'),
    ({'dash_length_m': 15.0, 'gap_length_m': 6.0}, ValueError, 'fit in the loop'),
    ({'distractors': [(0.0, 0.0, 0.1, 0.1, 0.0)]}, TypeError, 'Distractor'),
    ({'lighting_zones': [Distractor(0.0, 0.0, 0.1, 0.1)]}, TypeError, 'LightingZone'),
    ({'floor_image_rgb': np.zeros((8, 8, 3), dtype=np.float32)}, ValueError, 'uint8'),
    ({'floor_image_rgb': np.zeros((8, 8), dtype=np.uint8)}, ValueError, r'\(H, W, 3\)'),
    ({'floor_image_rgb': np.zeros((0, 8, 3), dtype=np.uint8)}, ValueError, 'non-empty'),
    ({'floor_image_rgb': np.zeros((8, 8, 3), dtype=np.uint8), 'dash_length_m': 0.3,
      'gap_length_m': 0.1}, ValueError, 'cannot paint dashes'),
])
def test_course_rejects_invalid_painting_options(options, error, message):
    with pytest.raises(error, match=message):
        straight_sided_course(**options)


@pytest.mark.parametrize('make, message', [
    (lambda: Distractor(0.0, 0.0, 0.0, 0.1), 'length_m must be positive'),
    (lambda: Distractor(0.0, 0.0, 0.1, -0.1), 'width_m must be positive'),
    (lambda: Distractor(math.inf, 0.0, 0.1, 0.1), 'x_m must be a finite number'),
    (lambda: Distractor(0.0, 0.0, 0.1, 0.1, 'north'), 'yaw_rad must be a finite number'),
    (lambda: LightingZone(0.0, 0.0, 0.0, 1.5), 'radius_m must be positive'),
    (lambda: LightingZone(0.0, 0.0, 1.0, -0.5), 'gain must not be negative'),
    (lambda: LightingZone(0.0, math.nan, 1.0, 1.5), 'y_m must be a finite number'),
])
def test_distractors_and_lighting_zones_reject_invalid_values(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_replace_changes_only_the_options_given(book):
    zone = LightingZone(0.0, 0.0, 1.0, 1.5)
    lit = book.replace(lighting_zones=[zone], name='lit')
    assert lit.name == 'lit' and lit.lighting_zones == (zone,)
    assert np.array_equal(lit.centre_line_xy, book.centre_line_xy)
    assert lit.length_m == book.length_m and lit.line_width_m == book.line_width_m
    assert book.lighting_zones == () and book.name == 'book_loop'


def test_replace_can_make_a_dashed_line_solid_again():
    dashed = straight_sided_course(dash_length_m=0.3, gap_length_m=0.2)
    solid = dashed.replace(dash_length_m=None, gap_length_m=None)
    assert solid.dash_length_m is None
    assert np.array_equal(solid.draw_texture(256), straight_sided_course().draw_texture(256))


def test_replace_rejects_unknown_options(book):
    with pytest.raises(TypeError, match='lighting_zones'):
        book.replace(lighting=True)


@pytest.mark.parametrize('arc_m, expected_m', [
    (0.0, 0.0), (0.1, 0.1), (0.2, 0.1), (0.3, 0.0), (0.35, -0.05), (0.45, -0.05),
    (0.5, 0.0), (0.65, 0.15), (19.75, 0.05), (-0.25, 0.05), (20.0, 0.0), (20.1, 0.1),
])
def test_dash_signed_distance_is_positive_on_dashes_and_negative_in_gaps(arc_m, expected_m):
    # 0.3 m dashes every 0.5 m on a 20 m loop: the last dash, from 19.5 m, runs into the first.
    course = straight_sided_course(dash_length_m=0.3, gap_length_m=0.2)
    assert course.length_m == pytest.approx(20.0)
    assert course.dash_signed_distance_m(arc_m) == pytest.approx(expected_m, abs=1e-9)


def test_dash_signed_distance_of_a_solid_line_is_infinite(book):
    assert np.all(np.isinf(book.dash_signed_distance_m([0.0, 3.0])))


@pytest.mark.parametrize('dash_length_m, gap_length_m', [(0.3, 0.15), (0.5, 0.5), (0.2, 0.35)])
def test_dashed_texture_has_dashes_and_gaps_at_their_arc_lengths(dash_length_m, gap_length_m):
    course = book_loop().replace(dash_length_m=dash_length_m, gap_length_m=gap_length_m)
    texture_rgb = course.draw_texture(TEXTURE_SIZE_PX)
    period_m = dash_length_m + gap_length_m
    for start_m in np.arange(0.0, course.length_m - period_m, period_m):
        dash_x_m, dash_y_m, _ = course.point_at(start_m + dash_length_m / 2.0)
        gap_x_m, gap_y_m, _ = course.point_at(start_m + dash_length_m + gap_length_m / 2.0)
        assert texture_at(course, texture_rgb, dash_x_m, dash_y_m) == LINE_RGB
        assert texture_at(course, texture_rgb, gap_x_m, gap_y_m) == (FLOOR_GREY,) * 3


def test_dashes_keep_the_line_width_and_have_square_ends():
    size_px = 1000  # 100 px per metre
    course = straight_sided_course(dash_length_m=0.3, gap_length_m=0.2)
    texture_rgb = course.draw_texture(size_px)
    is_line = texture_rgb[:, :, 2] < LINE_BLUE_THRESHOLD
    # The east side runs north from the start (2, 0): dashes cover y in [0, 0.3), [0.5, 0.8).
    col, _ = course.world_to_texture_px(2.0, 0.0, size_px)
    rows_across_dash = [round(course.world_to_texture_px(2.0, y_m, size_px)[1])
                        for y_m in (0.05, 0.15, 0.25, 0.55, 0.75)]
    for row in rows_across_dash:
        assert np.count_nonzero(is_line[row, round(col) - 20:round(col) + 20]) == \
            pytest.approx(BOOK_LINE_WIDTH_M * 100, abs=2)
    _, row_03 = course.world_to_texture_px(2.0, 0.3, size_px)
    _, row_05 = course.world_to_texture_px(2.0, 0.5, size_px)
    # Every pixel across the line stops at the same row: a square end, not a rounded one.
    for offset_px in range(-8, 9):
        ends_col = is_line[:, round(col) + offset_px]
        assert not ends_col[round(row_05) + 2:round(row_03) - 1].any()
        assert ends_col[round(row_03) + 1:round(row_03) + 5].all()


def test_dashed_line_is_scored_against_the_continuous_centre_line():
    course = book_loop().replace(dash_length_m=0.3, gap_length_m=0.15)
    gap_x_m, gap_y_m, _ = course.point_at(0.375)
    assert course.nearest(gap_x_m, gap_y_m)[0] == pytest.approx(0.0, abs=1e-9)
    tracker = LapTracker(course)
    for index, arc_m in enumerate(np.arange(0.0, course.length_m + 0.5, 0.02)):
        tracker.update(*course.point_at(arc_m)[:2], index * SAMPLE_PERIOD_S)
    assert tracker.laps_completed == 1
    assert tracker.time_off_line_s == 0.0
    assert tracker.max_distance_from_line_m == pytest.approx(0.0, abs=1e-9)


def test_distractors_are_painted_in_the_line_colour_and_leave_the_line_alone():
    patch = Distractor(0.0, 1.0, 0.6, 0.2, math.radians(30.0))
    course = straight_sided_course(distractors=[patch])
    texture_rgb = course.draw_texture(TEXTURE_SIZE_PX)
    plain_rgb = straight_sided_course().draw_texture(TEXTURE_SIZE_PX)
    assert texture_at(course, texture_rgb, 0.0, 1.0) == LINE_RGB
    along_x_m, along_y_m = math.cos(patch.yaw_rad), math.sin(patch.yaw_rad)
    for distance_m, expected_rgb in [(0.25, LINE_RGB), (0.35, (FLOOR_GREY,) * 3)]:
        x_m, y_m = patch.x_m + distance_m * along_x_m, patch.y_m + distance_m * along_y_m
        assert texture_at(course, texture_rgb, x_m, y_m) == expected_rgb
    # Across the patch: 0.1 m either side of its axis is its edge.
    for distance_m, expected_rgb in [(0.07, LINE_RGB), (0.13, (FLOOR_GREY,) * 3)]:
        x_m, y_m = patch.x_m - distance_m * along_y_m, patch.y_m + distance_m * along_x_m
        assert texture_at(course, texture_rgb, x_m, y_m) == expected_rgb
    changed = np.any(texture_rgb != plain_rgb, axis=2)
    rows, cols = np.nonzero(changed)
    assert len(rows) == pytest.approx(0.6 * 0.2 * (TEXTURE_SIZE_PX / 10.0) ** 2, rel=0.1)


def test_distractor_area_holds_at_any_angle():
    areas_px = []
    for yaw_deg in (0.0, 17.0, 45.0, 90.0):
        course = straight_sided_course(
            distractors=[Distractor(0.0, 0.0, 0.5, 0.25, math.radians(yaw_deg))])
        blue = course.draw_texture(TEXTURE_SIZE_PX)[:, :, 2].astype(float)
        middle = slice(TEXTURE_SIZE_PX // 2 - 60, TEXTURE_SIZE_PX // 2 + 60)
        areas_px.append(np.sum(FLOOR_GREY - blue[middle, middle]) / FLOOR_GREY)
    expected_px = 0.5 * 0.25 * (TEXTURE_SIZE_PX / 10.0) ** 2
    assert areas_px == pytest.approx([expected_px] * 4, rel=0.01)


def test_a_distractor_off_the_floor_edge_is_clipped():
    course = straight_sided_course(distractors=[Distractor(4.95, -4.95, 0.5, 0.5)])
    texture_rgb = course.draw_texture(256)
    assert tuple(texture_rgb[-1, -1]) == LINE_RGB


@pytest.mark.parametrize('gain', [1.7, 0.4])
def test_lighting_zone_scales_floor_and_line_inside_and_nothing_outside(gain):
    # A pool of light centred on the east side of the rectangle, at (2, 1).
    zone = LightingZone(2.0, 1.0, 0.8, gain)
    course = straight_sided_course(lighting_zones=[zone])
    texture_rgb = course.draw_texture(TEXTURE_SIZE_PX)
    plain_rgb = straight_sided_course().draw_texture(TEXTURE_SIZE_PX)
    scaled_floor = min(255, round(FLOOR_GREY * gain))
    scaled_line = tuple(min(255, round(value * gain)) for value in LINE_RGB)
    assert texture_at(course, texture_rgb, 2.0, 1.0) == scaled_line
    assert texture_at(course, texture_rgb, 1.5, 1.0) == (scaled_floor,) * 3
    inner_m = zone.radius_m - LIGHTING_EDGE_RAMP_M / 2.0
    assert texture_at(course, texture_rgb, 2.0 - inner_m + 0.02, 1.0) == (scaled_floor,) * 3
    # Untouched beyond the soft edge, and nowhere else.
    outer_m = zone.radius_m + LIGHTING_EDGE_RAMP_M / 2.0
    col, row = course.world_to_texture_px(zone.x_m, zone.y_m, TEXTURE_SIZE_PX)
    rows, cols = np.nonzero(np.any(texture_rgb != plain_rgb, axis=2))
    distance_m = np.hypot(rows - row, cols - col) * 10.0 / TEXTURE_SIZE_PX
    assert distance_m.max() < outer_m + 0.01
    assert len(rows) > 0.9 * math.pi * (inner_m * TEXTURE_SIZE_PX / 10.0) ** 2


def test_lighting_changes_gradually_across_the_soft_edge():
    zone = LightingZone(0.0, 0.0, 1.0, 1.7)
    texture_rgb = straight_sided_course(lighting_zones=[zone]).draw_texture(1000)
    # A row through the centre, west to east: floor grey rising to the full gain and back.
    grey = texture_rgb[500, 350:650, 0].astype(int)
    assert grey.min() == FLOOR_GREY and grey.max() == round(FLOOR_GREY * 1.7)
    steps = np.abs(np.diff(grey))
    # 81 grey levels over the 0.25 m (25 px) ramp: no jump bigger than a few levels.
    assert steps.max() <= 6
    assert np.count_nonzero((grey > FLOOR_GREY) & (grey < grey.max())) >= 2 * 20


def test_overlapping_lighting_zones_multiply():
    zones = [LightingZone(0.0, 0.0, 1.0, 2.0), LightingZone(0.0, 0.0, 1.0, 0.5)]
    texture_rgb = straight_sided_course(lighting_zones=zones).draw_texture(256)
    assert tuple(texture_rgb[128, 128]) == (FLOOR_GREY,) * 3


def block_image(blocks_rgb, block_px):
    """Build an image of uniform square blocks, one per entry of a (rows, cols, 3) array."""
    return np.repeat(np.repeat(np.asarray(blocks_rgb, dtype=np.uint8), block_px, axis=0),
                     block_px, axis=1)


FLOOR_BLOCKS_RGB = [[(200, 10, 10), (10, 200, 10)], [(10, 10, 200), (250, 250, 250)]]


def test_floor_image_round_trips_through_draw_texture_at_its_size():
    image_rgb = np.random.default_rng(3).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    course = straight_sided_course(floor_image_rgb=image_rgb)
    texture_rgb = course.draw_texture(64)
    assert np.array_equal(texture_rgb, image_rgb)
    texture_rgb[0, 0] = 0  # the texture is a copy: the course keeps its image
    assert np.array_equal(course.floor_image_rgb, image_rgb)


@pytest.mark.parametrize('size_px', [32, 64, 200])
def test_floor_image_is_resized_keeping_north_up_and_its_colours(size_px):
    image_rgb = block_image(FLOOR_BLOCKS_RGB, 64)
    course = straight_sided_course(floor_image_rgb=image_rgb)
    texture_rgb = course.draw_texture(size_px)
    assert texture_rgb.shape == (size_px, size_px, 3)
    quarter_px = size_px // 4
    for row_block in range(2):
        for col_block in range(2):
            row = quarter_px + row_block * 2 * quarter_px
            col = quarter_px + col_block * 2 * quarter_px
            assert tuple(texture_rgb[row, col]) == FLOOR_BLOCKS_RGB[row_block][col_block]


def test_floor_image_is_shrunk_by_area_averaging():
    # A one-pixel checkerboard averages to a flat grey when halved, as INTER_AREA does.
    checker = (np.indices((64, 64)).sum(axis=0) % 2 * 200).astype(np.uint8)
    image_rgb = np.repeat(checker[:, :, np.newaxis], 3, axis=2)
    texture_rgb = straight_sided_course(floor_image_rgb=image_rgb).draw_texture(32)
    assert np.all(texture_rgb == 100)


def test_floor_image_course_does_not_paint_its_centre_line_but_adds_the_rest():
    image_rgb = np.full((100, 100, 3), 30, dtype=np.uint8)
    course = straight_sided_course(floor_image_rgb=image_rgb,
                                   distractors=[Distractor(0.0, 0.0, 1.0, 1.0)],
                                   lighting_zones=[LightingZone(-3.0, -3.0, 1.0, 2.0)])
    texture_rgb = course.draw_texture(200)
    assert texture_at(course, texture_rgb, 2.0, 1.0) == (30, 30, 30)  # on the centre line
    assert texture_at(course, texture_rgb, 0.0, 0.0) == LINE_RGB
    assert texture_at(course, texture_rgb, -3.0, -3.0) == (60, 60, 60)
    assert course.nearest(2.0, 1.0)[0] == pytest.approx(0.0)


def test_floor_image_is_read_only():
    course = straight_sided_course(floor_image_rgb=np.zeros((4, 4, 3), dtype=np.uint8))
    with pytest.raises(ValueError):
        course.floor_image_rgb[0, 0, 0] = 1


def test_plain_texture_is_unchanged_by_empty_options(book):
    assert np.array_equal(book.replace(distractors=(), lighting_zones=()).draw_texture(512),
                          book.draw_texture(512))


# --- LapTracker on lines that cross or pass close by ------------------------------------------

def lemniscate_course():
    """Build a figure-eight (lemniscate) course that crosses itself at the origin."""
    parameter_rad = np.linspace(0.0, 2.0 * math.pi, 4000, endpoint=False) + 0.3
    scale = 3.0 / (1.0 + np.sin(parameter_rad) ** 2)
    return Course(np.stack([scale * np.cos(parameter_rad),
                            scale * np.sin(parameter_rad) * np.cos(parameter_rad)], axis=1),
                  name='lemniscate')


def offset_point(course, arc_m, offset_m):
    """Return the point ``offset_m`` left of the centre line at an arc length."""
    before_xy = np.array(course.point_at(arc_m - 0.05)[:2])
    after_xy = np.array(course.point_at(arc_m + 0.05)[:2])
    tangent_xy = (after_xy - before_xy) / np.linalg.norm(after_xy - before_xy)
    x_m, y_m, _ = course.point_at(arc_m)
    return x_m - offset_m * tangent_xy[1], y_m + offset_m * tangent_xy[0]


@pytest.mark.parametrize('offset_m', [0.0, 0.04, -0.06])
def test_tracker_follows_a_self_crossing_line_through_the_crossing(offset_m):
    course = lemniscate_course()
    tracker = LapTracker(course)
    # A centimetre past the second lap mark, which summing the steps may miss by a rounding.
    end_m = 2.0 * course.length_m + 0.01
    arcs_m = np.linspace(0.0, end_m, math.ceil(end_m / (DRIVE_SPEED_M_S * SAMPLE_PERIOD_S)) + 1)
    hops_of_the_global_nearest = 0
    for index, arc_m in enumerate(arcs_m):
        x_m, y_m = offset_point(course, arc_m, offset_m)
        _, global_arc_m = course.nearest(x_m, y_m)
        if abs((global_arc_m - arc_m + course.length_m / 2.0) % course.length_m
               - course.length_m / 2.0) > 1.0:
            hops_of_the_global_nearest += 1
        tracker.update(x_m, y_m, index * SAMPLE_PERIOD_S)
    assert tracker.laps_completed == 2
    assert tracker.arc_jumps == 0
    assert tracker.progress_m == pytest.approx(end_m, abs=1e-2)
    assert tracker.max_distance_from_line_m == pytest.approx(abs(offset_m), abs=2e-3)
    if offset_m != 0.0:
        # The globally nearest point does hop to the other branch near the crossing.
        assert hops_of_the_global_nearest > 0


def test_a_short_cut_across_the_book_loop_earns_no_lap(book):
    tracker = LapTracker(book)
    time_s = 0.0
    step_m = DRIVE_SPEED_M_S * SAMPLE_PERIOD_S

    def drive(points_xy):
        nonlocal time_s
        for x_m, y_m in points_xy:
            tracker.update(x_m, y_m, time_s)
            time_s += SAMPLE_PERIOD_S

    # Along the east side, straight across to the west side, then on round to the start.
    drive(book.point_at(arc_m)[:2] for arc_m in np.arange(0.0, 2.0, step_m))
    east_xy = np.array(book.point_at(2.0)[:2])
    west_xy = np.array(book.point_at(9.8)[:2])
    across_m = np.linalg.norm(west_xy - east_xy)
    drive(east_xy + fraction * (west_xy - east_xy)
          for fraction in np.arange(0.0, 1.0, step_m / across_m))
    drive(book.point_at(arc_m)[:2] for arc_m in np.arange(9.8, book.length_m + 0.5, step_m))
    assert tracker.laps_completed == 0
    assert tracker.arc_jumps == 1
    # What was driven along the line, plus a little where the cut left it at an angle.
    driven_along_line_m = 2.0 + book.length_m + 0.5 - 9.8
    assert driven_along_line_m <= tracker.progress_m < driven_along_line_m + across_m / 2.0


# A line that ends: paint over an arc interval only.

@pytest.mark.parametrize('arc_m, expected_m', [
    (0.0, 1.0), (2.5, 1.0), (3.0, 0.5), (3.5, 0.0), (4.0, -0.5), (10.0, -6.5),
    (19.5, 0.5), (19.0, 0.0), (18.5, -0.5), (-0.5, 0.5),
])
def test_painted_interval_signed_distance_is_positive_on_paint_and_negative_beyond(
        arc_m, expected_m):
    # 20 m loop painted from 1 m behind the start to 3.5 m after it.
    course = straight_sided_course(painted_interval_m=(-1.0, 3.5))
    assert course.dash_signed_distance_m(arc_m) == pytest.approx(expected_m, abs=1e-9)


def test_painted_interval_texture_ends_square_and_leaves_the_rest_bare():
    size_px = 1000  # 100 px per metre
    course = straight_sided_course(painted_interval_m=(-1.0, 2.5))
    texture_rgb = course.draw_texture(size_px)
    # The east side runs north from (2, 0): paint up to y = 2.5, bare beyond and elsewhere.
    for y_m in (-0.9, 0.0, 1.0, 2.45):
        assert texture_at(course, texture_rgb, 2.0, y_m) == LINE_RGB
    for x_m, y_m in ((2.0, 2.55), (2.0, 2.9), (0.0, 3.0), (-2.0, 0.0), (2.0, -1.1)):
        assert texture_at(course, texture_rgb, x_m, y_m) == (FLOOR_GREY,) * 3


def test_painted_interval_is_kept_by_replace_and_scored_on_the_whole_loop():
    course = straight_sided_course(painted_interval_m=(-1.0, 2.5))
    assert course.replace(name='other').painted_interval_m == (-1.0, 2.5)
    assert course.replace(painted_interval_m=None).painted_interval_m is None
    # The bare part of the loop is still the centre line the scoring measures against.
    assert course.nearest(-2.0, 0.0)[0] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize('painted_interval_m, message', [
    ((0.5, 2.0), 'hold the start'),
    ((-1.0, 0.0), 'hold the start'),
    ((-1.0, 19.5), 'shorter than the loop'),
    ((-1.0, math.nan), 'finite'),
    (3.0, 'two arc lengths'),
    ((1.0, 2.0, 3.0), 'two arc lengths'),
])
def test_painted_interval_rejects_intervals_that_are_not_part_of_the_loop_at_the_start(
        painted_interval_m, message):
    with pytest.raises(ValueError, match=message):
        straight_sided_course(painted_interval_m=painted_interval_m)
