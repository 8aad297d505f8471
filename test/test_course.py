"""Tests of the course geometry, its floor texture and the lap tracker."""

import json
import math

from followbot_sim.course import BOOK_FLOOR_SIZE_M
from followbot_sim.course import BOOK_LINE_WIDTH_M
from followbot_sim.course import book_loop
from followbot_sim.course import Course
from followbot_sim.course import COURSES
from followbot_sim.course import CURVATURE_BASELINE_M
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LapTracker
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.course import MAX_POINT_SPACING_M
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
