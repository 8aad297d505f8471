"""
Tests of the line's ground truth in the camera image.

The projection is exact on known geometry, and the truth of a rendered frame lies on the line
MuJoCo drew.
"""

import math

from followbot_sim.course import Course
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LINE_RGB
from followbot_sim.course import make_course
from followbot_sim.line_truth import line_truth
from followbot_sim.line_truth import PinholeView
from followbot_sim.line_truth import sampled_rows
from followbot_sim.world import FollowbotWorld
import numpy as np
import pytest

FOCAL_PX = 100.0
SIZE_PX = 201
HEIGHT_M = 1.0
# A camera 1 m above the floor looking straight down, image x = world x, image y = -world y.
DOWN_ROTATION = np.array([[1.0, 0.0, 0.0],
                          [0.0, -1.0, 0.0],
                          [0.0, 0.0, -1.0]])
# The drawn line is found in rows where it lies wholly inside the image, this far from an edge.
EDGE_MARGIN_PX = 2.0
# Truth and drawing agree to this (the brief's 1 px).
MAX_ERROR_PX = 1.0
# A row's drawn line needs this much yellow (summed weights) to be measured.
MIN_LINE_WEIGHT = 3.0
# A row's coverage-weighted centre is the centre line's crossing only where the line runs
# steeply through the row (across it, a bend's yellow spreads sideways): the check takes rows
# where the crossing moves at most this many columns per row.
MAX_CHECKED_SLOPE_PX = 0.5
# Poses the robot is put in for the rendered check: (arc length m, sideways m, yaw offset rad).
POSES = [(0.0, 0.0, 0.0), (3.0, 0.08, 0.3), (7.5, -0.1, -0.4), (12.0, 0.0, 0.6)]


def down_view():
    """Return a 201x201 camera 1 m above the origin looking straight down."""
    centre_px = (SIZE_PX - 1) / 2.0
    return PinholeView(np.array([0.0, 0.0, HEIGHT_M]), DOWN_ROTATION, FOCAL_PX, FOCAL_PX,
                       centre_px, centre_px, SIZE_PX, SIZE_PX)


def square_loop(half_m):
    """Return a closed square centre line, corners at +-half_m, points 1 cm apart."""
    return loop_through([[half_m, -half_m], [half_m, half_m], [-half_m, half_m],
                         [-half_m, -half_m]])


def loop_through(corners):
    """Return a closed centre line through the corners, points 1 cm apart."""
    corners = np.asarray(corners, dtype=float)
    points = []
    for start, end in zip(corners, np.roll(corners, -1, axis=0)):
        count = int(round(np.hypot(*(end - start)) / 0.01))
        points += [start + fraction * (end - start) for fraction in np.arange(count) / count]
    return np.array(points)


def test_straight_down_view_puts_a_line_at_its_metric_column():
    points = square_loop(0.5)
    truth = line_truth(points, np.ones(len(points), bool), 0.1, down_view(),
                       sampled_rows(SIZE_PX, 10))
    centre_px = (SIZE_PX - 1) / 2.0
    # Row of the image centre: the square's two vertical sides at x = -0.5 and +0.5 m.
    middle = list(truth.rows_px).index(100.0)
    columns = truth.crossings[middle][:, 0]
    np.testing.assert_allclose(columns, [centre_px - 50.0, centre_px + 50.0], atol=1e-9)
    # The line is 0.1 m wide at 1 m: 10 px.
    np.testing.assert_allclose(truth.crossings[middle][:, 1], 10.0)


def test_a_line_crossing_rows_aslant_covers_more_of_each_row():
    # A diamond: its sides cross the rows at 45 degrees, so the 10 px tape covers 10 sqrt(2).
    points = loop_through([[0.5, 0.0], [0.0, 0.5], [-0.5, 0.0], [0.0, -0.5]])
    truth = line_truth(points, np.ones(len(points), bool), 0.1, down_view(),
                       sampled_rows(SIZE_PX, 5))
    row = list(truth.rows_px).index(75.0)
    np.testing.assert_allclose(truth.crossings[row], [[75.0, 10.0 * math.sqrt(2.0)],
                                                      [125.0, 10.0 * math.sqrt(2.0)]],
                               atol=1e-6)


def test_paint_at_the_side_is_true_though_the_centre_is_outside():
    # Sides at +-1.02 m: centres 2 px beyond the image's sides, the paint 5 px either side.
    points = square_loop(1.02)
    truth = line_truth(points, np.ones(len(points), bool), 0.1, down_view(),
                       sampled_rows(SIZE_PX, 10))
    row = list(truth.rows_px).index(100.0)
    # Only what lies on the image counts: from column -0.5 to 3, and from 197 to 200.5.
    np.testing.assert_allclose(truth.crossings[row], [[1.25, 3.5], [198.75, 3.5]], atol=1e-6)
    assert truth.visible and not truth.pieces


def test_line_outside_the_image_is_not_visible():
    points = square_loop(2.0)
    truth = line_truth(points, np.ones(len(points), bool), 0.1, down_view(),
                       sampled_rows(SIZE_PX, 5))
    assert not truth.visible
    assert all(len(crossings) == 0 for crossings in truth.crossings)


def test_floor_behind_the_camera_is_cut_at_the_horizon():
    # A level camera 0.3 m up looking along +x: the floor behind it must not appear.
    rotation = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    view = PinholeView(np.array([0.0, 0.0, 0.3]), rotation, FOCAL_PX, FOCAL_PX, 100.0,
                       100.0, SIZE_PX, SIZE_PX)
    points = square_loop(1.0)
    truth = line_truth(points, np.ones(len(points), bool), 0.1, view, sampled_rows(SIZE_PX, 1))
    rows = np.concatenate([piece[:, 1] for piece in truth.pieces])
    # Every visible point lies below the horizon (row 100) and within the image.
    assert rows.min() > 100.0
    assert rows.max() <= SIZE_PX - 0.5
    # Ahead lies the far side (x = +1 m, 0.3 m down at 1 m: row 130, spanning the width); its
    # paint, 0.95 to 1.05 m away, covers rows 128.6 to 131.6 from side to side. The sides
    # y = +-1 m enter the image only from 1 m on, at its corners: nearer rows see nothing, as
    # the back side (x = -1 m) is behind the camera.
    painted_rows = [row for row, crossings in zip(truth.rows_px, truth.crossings)
                    if len(crossings)]
    assert painted_rows == [129.0, 130.0, 131.0]
    middle = list(truth.rows_px).index(130.0)
    np.testing.assert_allclose(truth.crossings[middle], [[100.0, SIZE_PX]], atol=1e-6)


def test_gaps_of_a_dashed_line_are_not_visible():
    points = square_loop(0.5)
    painted = (np.arange(len(points)) // 10) % 2 == 0
    truth = line_truth(points, painted, 0.1, down_view(), sampled_rows(SIZE_PX, 1))
    solid = line_truth(points, np.ones(len(points), bool), 0.1, down_view(),
                       sampled_rows(SIZE_PX, 1))
    assert len(truth.pieces) > 10 * len(solid.pieces)
    crossed = sum(len(crossings) for crossings in truth.crossings)
    assert 0 < crossed < sum(len(crossings) for crossings in solid.crossings)


def test_sampled_rows_refuses_a_zero_step():
    with pytest.raises(ValueError, match='row_step_px'):
        sampled_rows(480, 0)


def test_bad_view_is_refused_with_a_sentence():
    with pytest.raises(ValueError, match='3x3 rotation'):
        PinholeView(np.zeros(3), np.eye(2), 1.0, 1.0, 0.0, 0.0, 8, 8)


def drawn_line_centre_px(image_row):
    """
    Return the centre column of the yellow line in one rendered row, by its coverage.

    Each pixel's share of line is read from its blue channel, which the line (blue 0) lowers
    from the floor's grey: the coverage-weighted mean column is the drawn centre.
    """
    coverage = np.clip((FLOOR_GREY - image_row[:, 2].astype(float)) / (FLOOR_GREY - LINE_RGB[2]),
                       0.0, 1.0)
    weight = coverage.sum()
    if weight < MIN_LINE_WEIGHT:
        return math.nan
    return float((coverage * np.arange(len(coverage))).sum() / weight)


@pytest.mark.parametrize('course_name', ['book_loop', 's_bends', 'figure_eight'])
def test_truth_lies_on_the_rendered_line(opengl, course_name):
    course = make_course(course_name)
    world = FollowbotWorld(course)
    try:
        checked = 0
        for arc_m, sideways_m, yaw_offset_rad in POSES:
            x_m, y_m, heading_rad = course.point_at(arc_m, sideways_m)
            world.reset_robot((x_m, y_m, heading_rad + yaw_offset_rad))
            image = world.render_camera()
            truth = world.line_truth(row_step_px=1)
            width_px = world.image_size_px[0]
            for row, crossings, next_crossings in zip(truth.rows_px, truth.crossings,
                                                      truth.crossings[1:]):
                if len(crossings) != 1 or len(next_crossings) != 1:
                    continue
                column_px, line_width_px = crossings[0]
                slope_px = abs(next_crossings[0][0] - column_px)
                margin_px = EDGE_MARGIN_PX + line_width_px / 2
                inside = margin_px <= column_px <= width_px - 1 - margin_px
                if slope_px > MAX_CHECKED_SLOPE_PX or not inside:
                    continue
                drawn_px = drawn_line_centre_px(image[int(row)])
                assert abs(drawn_px - column_px) <= MAX_ERROR_PX, (
                    f'{course_name} pose {arc_m} m row {row}: truth {column_px:.2f} px, '
                    f'drawn {drawn_px:.2f} px')
                checked += 1
        assert checked >= 50 * len(POSES)
    finally:
        world.close()


def test_a_line_that_is_not_painted_has_no_truth_in_the_frame(opengl):
    course = Course(square_loop(1.0), line_width_m=0.05, floor_size_m=4.0)
    world = FollowbotWorld(course, texture_size_px=512)
    try:
        # Put the robot outside the square, looking away from it.
        world.reset_robot((1.5, 0.0, 0.0))
        assert not world.line_truth(8).visible
    finally:
        world.close()
