"""Tests of the built-in courses: each builds, fits the floor and has its documented features."""

import math

from followbot_sim.course import BOOK_FLOOR_SIZE_M
from followbot_sim.course import BOOK_LINE_WIDTH_M
from followbot_sim.course import Course
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LapTracker
from followbot_sim.course import LIGHTING_EDGE_RAMP_M
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.course_library import Arc
from followbot_sim.course_library import COURSES
from followbot_sim.course_library import LIGHTING_ZONE_GAINS
from followbot_sim.course_library import LIGHTING_ZONE_RADIUS_M
from followbot_sim.course_library import Straight
from followbot_sim.course_library import turtle_loop_xy
from followbot_sim.course_library import with_lighting_zones
import numpy as np
import pytest

TEXTURE_SIZE_PX = 1024
COURSE_NAMES = sorted(COURSES)
# The floor the built-in courses were designed for.
FLOOR_EDGE_M = BOOK_FLOOR_SIZE_M / 2.0 - BOOK_LINE_WIDTH_M / 2.0
# Sampling for the geometric checks: a centimetre along the line.
ARC_STEP_M = 0.01
SAMPLE_PERIOD_S = 0.05


@pytest.fixture(scope='module')
def courses():
    return {name: make_course(name) for name in COURSE_NAMES}


@pytest.fixture(scope='module')
def textures(courses):
    return {name: course.draw_texture(TEXTURE_SIZE_PX) for name, course in courses.items()}


def texture_at(course, texture_rgb, x_m, y_m):
    """Return the texture pixel at a world position."""
    col, row = course.world_to_texture_px(x_m, y_m, texture_rgb.shape[0])
    return tuple(int(value) for value in texture_rgb[round(row), round(col)])


def headings_rad(course, arcs_m):
    """Return the unwrapped heading of the line at arc lengths, from chords 1 cm long."""
    behind_xy = np.array([course.point_at(arc_m - 0.005)[:2] for arc_m in arcs_m])
    ahead_xy = np.array([course.point_at(arc_m + 0.005)[:2] for arc_m in arcs_m])
    chord_xy = ahead_xy - behind_xy
    return np.unwrap(np.arctan2(chord_xy[:, 1], chord_xy[:, 0]))


def turn_over_rad(course, arcs_m, span_m):
    """Return the heading change over ``span_m`` of line centred at each arc length."""
    return (headings_rad(course, np.asarray(arcs_m) + span_m / 2.0)
            - headings_rad(course, np.asarray(arcs_m) - span_m / 2.0))


def radius_through_m(course, arc_m, half_span_m):
    """Return the radius of the circle through the line points at arc_m and half_span_m away."""
    points_xy = [np.array(course.point_at(arc_m + delta_m)[:2])
                 for delta_m in (-half_span_m, 0.0, half_span_m)]
    first, second = points_xy[1] - points_xy[0], points_xy[2] - points_xy[0]
    double_area_m2 = abs(first[0] * second[1] - first[1] * second[0])
    sides_m = [np.linalg.norm(first), np.linalg.norm(second),
               np.linalg.norm(points_xy[2] - points_xy[1])]
    return math.inf if double_area_m2 < 1e-12 else np.prod(sides_m) / (2.0 * double_area_m2)


def count_self_crossings(course):
    """Count the pairs of segments of the centre line (every 4th point) that properly cross."""
    points_xy = course.centre_line_xy[::4]
    starts, ends = points_xy, np.roll(points_xy, -1, axis=0)

    def orientation(a, b, c):
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))
    first_start, first_end = starts[:, np.newaxis], ends[:, np.newaxis]
    second_start, second_end = starts[np.newaxis, :], ends[np.newaxis, :]
    crossing = ((orientation(first_start, first_end, second_start)
                 * orientation(first_start, first_end, second_end) < 0)
                & (orientation(second_start, second_end, first_start)
                   * orientation(second_start, second_end, first_end) < 0))
    return int(np.count_nonzero(np.triu(crossing)))


def drive_centre_line(course, laps, offset_m=0.0, speed_m_s=0.5):
    """Feed a tracker points along the line (offset to the left), for some laps."""
    tracker = LapTracker(course)
    # A centimetre past the last lap mark, which summing the steps may miss by a rounding error.
    end_m = laps * course.length_m + 0.01
    steps = math.ceil(end_m / (speed_m_s * SAMPLE_PERIOD_S))
    for index, arc_m in enumerate(np.linspace(0.0, end_m, steps + 1)):
        x_m, y_m, _ = course.point_at(arc_m, offset_m)
        tracker.update(x_m, y_m, index * SAMPLE_PERIOD_S)
    return tracker


# --- every course --------------------------------------------------------------------------------

def test_the_library_has_the_documented_courses():
    assert set(COURSES) == {'book_loop', 'square_corners', 's_bends', 'dashed', 'figure_eight',
                            'distractor', 'hairpins', 'sharp_corners', 't_junction',
                            'line_end'}


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_builds_with_its_name_on_the_books_floor(courses, name):
    course = courses[name]
    assert isinstance(course, Course)
    assert course.name == name
    assert course.floor_size_m == BOOK_FLOOR_SIZE_M
    assert course.line_width_m == BOOK_LINE_WIDTH_M
    assert 15.0 < course.length_m < 40.0


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_stays_on_the_floor_with_a_margin(courses, name):
    assert np.abs(courses[name].centre_line_xy).max() <= FLOOR_EDGE_M - 0.5


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_starts_on_the_line_facing_along_it(courses, name):
    course = courses[name]
    x_m, y_m, yaw_rad = course.start_pose()
    assert course.nearest(x_m, y_m)[0] == pytest.approx(0.0, abs=1e-9)
    ahead_x_m, ahead_y_m, _ = course.point_at(0.05)
    tangent_rad = math.atan2(ahead_y_m - y_m, ahead_x_m - x_m)
    assert math.cos(yaw_rad - tangent_rad) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_starts_on_a_straight_or_gentle_part(courses, name):
    # Within a metre either side of the start the line bends with a radius of metres.
    course = courses[name]
    for half_span_m in (0.25, 0.5, 1.0):
        assert radius_through_m(course, 0.0, half_span_m) > 4.0


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_texture_is_yellow_at_the_start(courses, textures, name):
    x_m, y_m, _ = courses[name].start_pose()
    assert texture_at(courses[name], textures[name], x_m, y_m) == LINE_RGB


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_is_lapped_by_driving_its_centre_line(courses, name):
    tracker = drive_centre_line(courses[name], laps=1.1)
    assert tracker.laps_completed == 1
    assert tracker.arc_jumps == 0
    assert tracker.time_off_line_s == 0.0


@pytest.mark.parametrize('name', COURSE_NAMES)
def test_course_factories_build_the_same_course_every_time(courses, name):
    assert np.array_equal(COURSES[name]().centre_line_xy, courses[name].centre_line_xy)


# --- square_corners ------------------------------------------------------------------------------

def test_square_corners_has_eight_true_right_angle_corners_both_ways(courses):
    course = courses['square_corners']
    arcs_m = np.arange(0.0, course.length_m, ARC_STEP_M)
    # Over 6 cm of line a true corner turns the full 90 degrees; a bend of 1 m radius 3.4.
    turn_rad = turn_over_rad(course, arcs_m, 0.06)
    is_corner = np.abs(turn_rad) > math.radians(45.0)
    starts = np.flatnonzero(is_corner & ~np.roll(is_corner, 1))
    corner_turns_deg = [math.degrees(turn_rad[start:start + 10][
        np.argmax(np.abs(turn_rad[start:start + 10]))]) for start in starts]
    assert len(corner_turns_deg) == 8
    assert corner_turns_deg == pytest.approx(
        [90.0 if turn > 0 else -90.0 for turn in corner_turns_deg], abs=1.0)
    assert sum(turn > 0 for turn in corner_turns_deg) == 6
    assert sum(turn < 0 for turn in corner_turns_deg) == 2
    assert course.min_radius_of_curvature_m() < 0.1


def test_square_corners_measures_about_6_by_7_metres(courses):
    size_xy = np.ptp(courses['square_corners'].centre_line_xy, axis=0)
    assert size_xy == pytest.approx([6.0, 7.0], abs=0.5)


# --- s_bends -------------------------------------------------------------------------------------

def test_s_bends_hairpins_are_tight_but_drivable(courses):
    assert 0.35 <= courses['s_bends'].min_radius_of_curvature_m() <= 0.5


def test_s_bends_has_hairpins_turning_each_way(courses):
    course = courses['s_bends']
    arcs_m = np.arange(0.0, course.length_m, ARC_STEP_M)
    # A hairpin of radius 0.4 m turns 180 degrees in 1.26 m of line.
    turn_rad = turn_over_rad(course, arcs_m, 1.3)
    assert turn_rad.max() > math.radians(170.0)
    assert turn_rad.min() < -math.radians(170.0)


def test_s_bends_has_s_bends_turning_each_way_first(courses):
    course = courses['s_bends']
    arcs_m = np.arange(0.0, course.length_m, 0.05)
    # An S-bend: a turn of over 40 degrees in the 0.7 m before a point and the opposite turn
    # in the 0.7 m after it.
    turn_before_rad = turn_over_rad(course, arcs_m - 0.35, 0.7)
    turn_after_rad = turn_over_rad(course, arcs_m + 0.35, 0.7)
    limit_rad = math.radians(40.0)
    assert np.any((turn_before_rad > limit_rad) & (turn_after_rad < -limit_rad))
    assert np.any((turn_before_rad < -limit_rad) & (turn_after_rad > limit_rad))


def test_s_bends_does_not_cross_itself(courses):
    assert count_self_crossings(courses['s_bends']) == 0


# --- figure_eight --------------------------------------------------------------------------------

def test_figure_eight_crosses_itself_exactly_once(courses):
    assert count_self_crossings(courses['figure_eight']) == 1


def test_figure_eight_is_smooth_and_gentle(courses):
    assert courses['figure_eight'].min_radius_of_curvature_m() >= 1.0


def test_figure_eight_lobes_turn_opposite_ways(courses):
    course = courses['figure_eight']
    arcs_m = np.arange(0.0, course.length_m, 0.05)
    turn_rad = turn_over_rad(course, arcs_m, 0.1)
    assert turn_rad.max() > 0.0 > turn_rad.min()
    # One lobe left, one right: the heading ends where it started, not a full turn round.
    total_turn_rad = headings_rad(course, [course.length_m - 0.01]) - headings_rad(course, [0.0])
    assert abs(total_turn_rad[0]) < 0.1


@pytest.mark.parametrize('offset_m', [0.0, 0.05, -0.05])
def test_figure_eight_is_scored_through_its_crossing(courses, offset_m):
    course = courses['figure_eight']
    tracker = drive_centre_line(course, laps=2, offset_m=offset_m)
    assert tracker.laps_completed == 2
    assert tracker.arc_jumps == 0
    assert tracker.progress_m == pytest.approx(2.0 * course.length_m, abs=0.02)
    assert tracker.max_distance_from_line_m == pytest.approx(abs(offset_m), abs=1e-3)


# --- dashed --------------------------------------------------------------------------------------

def test_dashed_is_the_book_loop_painted_in_dashes(courses):
    dashed, book = courses['dashed'], courses['book_loop']
    assert np.array_equal(dashed.centre_line_xy, book.centre_line_xy)
    assert (dashed.dash_length_m, dashed.gap_length_m) == (0.30, 0.15)


def test_dashed_texture_has_gaps_at_the_expected_arc_lengths(courses, textures):
    course, texture_rgb = courses['dashed'], textures['dashed']
    period_m = course.dash_length_m + course.gap_length_m
    for start_m in np.arange(0.0, course.length_m - period_m, period_m):
        on_dash = course.point_at(start_m + course.dash_length_m / 2.0)
        in_gap = course.point_at(start_m + course.dash_length_m + course.gap_length_m / 2.0)
        assert texture_at(course, texture_rgb, *on_dash[:2]) == LINE_RGB
        assert texture_at(course, texture_rgb, *in_gap[:2]) == (FLOOR_GREY,) * 3


def test_dashed_gaps_are_scored_as_on_the_line(courses):
    course = courses['dashed']
    in_gap = course.point_at(course.dash_length_m + course.gap_length_m / 2.0)
    assert course.nearest(*in_gap[:2])[0] == pytest.approx(0.0, abs=1e-9)


# --- distractor ----------------------------------------------------------------------------------

def distractor_outline_xy(patch, points_per_side=20):
    """Return points around the edge of a distractor rectangle."""
    along_xy = np.array([math.cos(patch.yaw_rad), math.sin(patch.yaw_rad)])
    across_xy = np.array([-along_xy[1], along_xy[0]])
    fractions = np.linspace(-0.5, 0.5, points_per_side)
    outline = [side * 0.5 * patch.length_m * along_xy + fraction * patch.width_m * across_xy
               for side in (-1.0, 1.0) for fraction in fractions]
    outline += [fraction * patch.length_m * along_xy + side * 0.5 * patch.width_m * across_xy
                for side in (-1.0, 1.0) for fraction in fractions]
    return np.array(outline) + [patch.x_m, patch.y_m]


def test_distractor_is_the_book_loop_with_patches(courses):
    course = courses['distractor']
    assert np.array_equal(course.centre_line_xy, courses['book_loop'].centre_line_xy)
    assert len(course.distractors) >= 3


def test_distractor_patches_are_yellow_in_the_texture(courses, textures):
    course = courses['distractor']
    for patch in course.distractors:
        assert texture_at(course, textures['distractor'], patch.x_m, patch.y_m) == LINE_RGB


def test_distractor_patches_lie_beside_the_line_without_touching_it(courses):
    course = courses['distractor']
    for patch in course.distractors:
        assert 0.3 <= course.nearest(patch.x_m, patch.y_m)[0] <= 0.6
        edge_distances_m = [course.nearest(x_m, y_m)[0]
                            for x_m, y_m in distractor_outline_xy(patch)]
        # At least 10 cm of floor between the patch and the line's edge.
        assert min(edge_distances_m) > course.line_width_m / 2.0 + 0.1


def test_distractor_patches_sit_inside_bends_and_on_both_sides(courses):
    course = courses['distractor']
    offsets = [course.signed_offset(patch.x_m, patch.y_m) for patch in course.distractors]
    inside_bends = [offset_m > 0.0 and radius_through_m(course, arc_m, 0.5) < 2.0
                    for offset_m, arc_m in offsets]
    assert sum(inside_bends) >= 2
    assert any(offset_m < 0.0 for offset_m, _ in offsets)


def test_distractor_texture_differs_from_the_book_loop_only_at_the_patches(courses, textures):
    course = courses['distractor']
    changed_rows, changed_cols = np.nonzero(
        np.any(textures['distractor'] != textures['book_loop'], axis=2))
    patch_cols_rows = [course.world_to_texture_px(patch.x_m, patch.y_m, TEXTURE_SIZE_PX)
                       for patch in course.distractors]
    px_per_m = TEXTURE_SIZE_PX / BOOK_FLOOR_SIZE_M
    for row, col in zip(changed_rows, changed_cols):
        assert min(math.hypot(col - patch_col, row - patch_row)
                   for patch_col, patch_row in patch_cols_rows) < 0.4 * px_per_m


# --- lighting ------------------------------------------------------------------------------------

@pytest.mark.parametrize('name', COURSE_NAMES)
def test_lighting_zones_can_be_added_to_any_course(courses, name):
    course = courses[name]
    lit = with_lighting_zones(course)
    assert lit.name == f'{name}+lighting'
    assert [zone.gain for zone in lit.lighting_zones] == list(LIGHTING_ZONE_GAINS)
    for zone in lit.lighting_zones:
        assert course.nearest(zone.x_m, zone.y_m)[0] == pytest.approx(0.0, abs=1e-9)
    assert np.array_equal(lit.centre_line_xy, course.centre_line_xy)


def test_lighting_zones_brighten_and_dim_where_placed_and_nowhere_else(courses, textures):
    course = courses['book_loop']
    lit = with_lighting_zones(course)
    lit_rgb = lit.draw_texture(TEXTURE_SIZE_PX)
    plain_rgb = textures['book_loop']
    for zone in lit.lighting_zones:
        expected = tuple(min(255, round(value * zone.gain)) for value in LINE_RGB)
        assert texture_at(lit, lit_rgb, zone.x_m, zone.y_m) == expected
    changed_rows, changed_cols = np.nonzero(np.any(lit_rgb != plain_rgb, axis=2))
    zone_cols_rows = [lit.world_to_texture_px(zone.x_m, zone.y_m, TEXTURE_SIZE_PX)
                      for zone in lit.lighting_zones]
    px_per_m = TEXTURE_SIZE_PX / BOOK_FLOOR_SIZE_M
    reach_px = (LIGHTING_ZONE_RADIUS_M + LIGHTING_EDGE_RAMP_M / 2.0) * px_per_m + 1.0
    distances_px = np.min([np.hypot(changed_cols - col, changed_rows - row)
                           for col, row in zone_cols_rows], axis=0)
    assert distances_px.max() <= reach_px
    # The robot starts in the course's ordinary light.
    x_m, y_m, _ = lit.start_pose()
    assert texture_at(lit, lit_rgb, x_m, y_m) == LINE_RGB


def test_lighting_zones_add_to_those_a_course_has(courses):
    lit_twice = with_lighting_zones(with_lighting_zones(courses['s_bends']))
    assert len(lit_twice.lighting_zones) == 2 * len(LIGHTING_ZONE_GAINS)


# --- turtle paths --------------------------------------------------------------------------------

def test_turtle_square_with_rounded_corners_closes_and_measures_right():
    segments = [Straight(2.0), Arc(0.5, math.pi / 2.0)] * 4
    points_xy = turtle_loop_xy((0.0, 0.0, 0.0), segments)
    assert np.linalg.norm(points_xy[-1] - points_xy[0]) < 1e-9
    course = Course(points_xy)
    assert course.length_m == pytest.approx(8.0 + math.pi, abs=1e-3)
    assert np.max(points_xy, axis=0) == pytest.approx([2.5, 3.0], abs=1e-9)


def test_turtle_right_turns_bend_clockwise():
    points_xy = turtle_loop_xy((0.0, 0.0, 0.0), [Arc(1.0, -2.0 * math.pi)])
    assert np.min(points_xy[:, 1]) == pytest.approx(-2.0, abs=1e-4)
    assert np.max(points_xy[:, 1]) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize('segments, message', [
    ([Straight(2.0), Arc(0.5, math.pi / 2.0)], 'ends 2.'),
    ([], 'at least one segment'),
    ([(2.0, 0.0)], 'Straight or Arc'),
])
def test_turtle_path_rejects_paths_that_do_not_close(segments, message):
    with pytest.raises(ValueError, match=message):
        turtle_loop_xy((0.0, 0.0, 0.0), segments)


@pytest.mark.parametrize('make, message', [
    (lambda: Straight(0.0), 'length_m'),
    (lambda: Straight(math.inf), 'length_m'),
    (lambda: Arc(0.0, 1.0), 'radius_m'),
    (lambda: Arc(1.0, 0.0), 'angle_rad'),
])
def test_turtle_pieces_reject_invalid_sizes(make, message):
    with pytest.raises(ValueError, match=message):
        make()


# --- hairpins ------------------------------------------------------------------------------------

def test_hairpins_have_the_radius_of_issue_14(courses):
    assert courses['hairpins'].min_radius_of_curvature_m() == pytest.approx(0.15, abs=0.005)


def test_hairpins_turn_back_two_each_way(courses):
    course = courses['hairpins']
    arcs_m = np.arange(0.0, course.length_m, ARC_STEP_M)
    # A hairpin of radius 0.15 m turns 180 degrees in 0.47 m of line; the 0.3 m square turns
    # beside it turn away, so a 0.5 m span sees the hairpin alone.
    turn_rad = turn_over_rad(course, arcs_m, 0.5)
    is_hairpin = np.abs(turn_rad) > math.radians(170.0)
    starts = np.flatnonzero(is_hairpin & ~np.roll(is_hairpin, 1))
    signs = [np.sign(turn_rad[start]) for start in starts]
    assert sorted(signs) == [-1, -1, 1, 1]


# --- sharp_corners -------------------------------------------------------------------------------

def test_sharp_corners_turn_120_degrees_four_left_one_right(courses):
    course = courses['sharp_corners']
    arcs_m = np.arange(0.0, course.length_m, ARC_STEP_M)
    turn_rad = turn_over_rad(course, arcs_m, 0.06)
    is_corner = np.abs(turn_rad) > math.radians(60.0)
    starts = np.flatnonzero(is_corner & ~np.roll(is_corner, 1))
    corner_turns_deg = [math.degrees(turn_rad[start:start + 10][
        np.argmax(np.abs(turn_rad[start:start + 10]))]) for start in starts]
    assert sorted(corner_turns_deg) == pytest.approx([-120.0] + [120.0] * 4, abs=1.0)


# --- t_junction ----------------------------------------------------------------------------------

def test_t_junction_is_the_book_loop_with_stubs_square_to_it_and_touching_it(courses):
    course = courses['t_junction']
    assert np.array_equal(course.centre_line_xy, courses['book_loop'].centre_line_xy)
    assert len(course.distractors) == 3
    for stub in course.distractors:
        # Across the line (the stub's width runs along its own length from the line outwards).
        distance_m, arc_m = course.nearest(stub.x_m, stub.y_m)
        heading_rad = course.point_at(arc_m)[2]
        assert stub.length_m == pytest.approx(course.line_width_m)
        assert math.cos(stub.yaw_rad - heading_rad) == pytest.approx(1.0, abs=1e-6)
        assert distance_m == pytest.approx(stub.width_m / 2.0, abs=0.01)


def test_t_junction_stubs_join_the_painted_line(courses, textures):
    course, texture_rgb = courses['t_junction'], textures['t_junction']
    for stub in course.distractors:
        _, arc_m = course.nearest(stub.x_m, stub.y_m)
        x_m, y_m, _ = course.point_at(arc_m)
        # Every point from the line's centre to the stub's tip is painted.
        for share in np.linspace(0.0, 0.9, 10):
            assert texture_at(course, texture_rgb, x_m + 2.0 * share * (stub.x_m - x_m),
                              y_m + 2.0 * share * (stub.y_m - y_m)) == LINE_RGB


# --- line_end ------------------------------------------------------------------------------------

def test_line_end_paints_from_behind_the_start_to_its_end_then_bare_floor(courses, textures):
    course, texture_rgb = courses['line_end'], textures['line_end']
    begin_m, end_m = course.painted_interval_m
    assert (begin_m, end_m) == pytest.approx((-1.0, 1.5 + math.pi / 2.0 + 2.0))
    for arc_m in np.arange(begin_m + 0.05, end_m - 0.05, 0.1):
        assert texture_at(course, texture_rgb, *course.point_at(arc_m)[:2]) == LINE_RGB
    # Beyond the end, the floor straight ahead stays bare for more than the camera sees.
    x_m, y_m, heading_rad = course.point_at(end_m)
    for ahead_m in np.arange(0.05, 3.0, 0.05):
        assert texture_at(course, texture_rgb, x_m + ahead_m * math.cos(heading_rad),
                          y_m + ahead_m * math.sin(heading_rad)) == (FLOOR_GREY,) * 3
