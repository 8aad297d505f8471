"""Tests of tracing a course's centre line from an image of its floor."""

import collections
import math
import struct
import zlib

import cv2
from followbot_sim.course import BOOK_FLOOR_SIZE_M
from followbot_sim.course import book_loop
from followbot_sim.course import Course
from followbot_sim.course import FLOOR_GREY
from followbot_sim.course import LINE_RGB
from followbot_sim.course import world_to_texture_px
from followbot_sim.course_image import course_from_image
import numpy as np
import pytest

IMAGE_SIZE_PX = 1024
# cv2 paints a thickness-18 line about 19.5 px wide: 0.19 m on a 1024 px, 10 m floor.
LINE_THICKNESS_PX = 18
PAINTED_WIDTH_M = 0.19
# cv2 drawing coordinates carry this many fractional bits.
DRAW_SHIFT_BITS = 4
# The traced centre line must stay this close to the drawn one, and its length this close.
MAX_CENTRE_ERROR_M = 0.01
MAX_LENGTH_ERROR = 0.01
# Near a corner the line is one blob of paint: points this close to a vertex are not checked.
CORNER_EXCLUSION_M = PAINTED_WIDTH_M
# Spacing of the points that describe drawn curves.
CURVE_SPACING_M = 0.005
HAIRPIN_RADIUS_M = 0.4
DASH_M = 0.3
DASH_GAP_M = 0.25
JPEG_QUALITY = 75
# The start point is the centre-line point nearest the start pose, within pixel accuracy.
MAX_START_ERROR_M = 0.015
# Distance along the course at which the direction of travel is checked.
DIRECTION_CHECK_M = 0.5


def ellipse_xy(semi_x_m=3.0, semi_y_m=4.0):
    """Return a counter-clockwise ellipse centred on the floor, starting at its east end."""
    count = int(2.0 * math.pi * max(semi_x_m, semi_y_m) / CURVE_SPACING_M)
    angle_rad = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    return np.stack([semi_x_m * np.cos(angle_rad), semi_y_m * np.sin(angle_rad)], axis=1)


def l_shape_xy():
    """Return the corners of an L-shaped loop: five left turns and one right turn."""
    return np.array([(-3.0, -3.0), (3.0, -3.0), (3.0, 0.5), (0.2, 0.5), (0.2, 3.2), (-3.0, 3.2)])


def turtle_xy(start_xy, heading_rad, moves):
    """
    Walk a turtle and return the closed path it draws.

    :param moves: ``(length_m, radius_m)`` pairs: straight when radius is None, else an arc of
        that length turning left for a positive radius and right for a negative one.
    """
    points = [np.asarray(start_xy, dtype=float)]
    for length_m, radius_m in moves:
        steps = max(1, int(math.ceil(length_m / CURVE_SPACING_M)))
        turn_rad = 0.0 if radius_m is None else length_m / steps / radius_m
        # The chord of an arc step, taken along the heading halfway through the step.
        chord_m = length_m / steps if radius_m is None else 2.0 * radius_m * math.sin(turn_rad / 2)
        for _ in range(steps):
            heading_rad += turn_rad / 2.0
            points.append(points[-1] + chord_m * np.array([math.cos(heading_rad),
                                                           math.sin(heading_rad)]))
            heading_rad += turn_rad / 2.0
    assert np.linalg.norm(points[-1] - points[0]) < 1e-6
    return np.array(points[:-1])


def hairpins_xy():
    """Return a serpentine loop with three hairpins of 0.4 m radius, turning both ways."""
    hairpin_m = math.pi * HAIRPIN_RADIUS_M
    bend_m = math.pi / 2.0 * 0.6
    return turtle_xy((-2.4, -2.0), math.pi / 2.0, [
        (4.0, None), (hairpin_m, -HAIRPIN_RADIUS_M), (4.0, None),
        (hairpin_m, HAIRPIN_RADIUS_M), (4.0, None), (hairpin_m, -HAIRPIN_RADIUS_M),
        (4.6, None), (bend_m, -0.6), (1.2, None), (bend_m, -0.6), (0.6, None)])


def figure_eight_xy():
    """Return a figure-eight (lemniscate of Gerono) whose branches cross at 81 degrees."""
    count = 8000
    angle_rad = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    return np.stack([3.5 * np.sin(angle_rad), 3.0 * np.sin(angle_rad) * np.cos(angle_rad)], 1)


def floor_image(grey=FLOOR_GREY):
    """Return an empty floor image."""
    return np.full((IMAGE_SIZE_PX, IMAGE_SIZE_PX, 3), grey, dtype=np.uint8)


def to_draw_px(points_xy):
    """Convert world points to cv2's fixed-point drawing coordinates."""
    col, row = world_to_texture_px(points_xy[:, 0], points_xy[:, 1], IMAGE_SIZE_PX,
                                   BOOK_FLOOR_SIZE_M)
    return np.round(np.stack([col, row], axis=1) * (1 << DRAW_SHIFT_BITS)).astype(np.int32)


def draw_line(points_xy, grey=FLOOR_GREY, line_type=cv2.LINE_8, closed=True,
              thickness_px=LINE_THICKNESS_PX, image_rgb=None):
    """Paint a polyline in the book's yellow on a grey floor (or on ``image_rgb``), as RGB."""
    image_rgb = floor_image(grey) if image_rgb is None else image_rgb
    cv2.polylines(image_rgb, [to_draw_px(points_xy)], closed, LINE_RGB, thickness_px,
                  line_type, shift=DRAW_SHIFT_BITS)
    return image_rgb


def draw_dashes(points_xy, dash_m=DASH_M, gap_m=DASH_GAP_M):
    """
    Paint a closed polyline as dashes with square ends on a grey floor.

    Dashes are stretched a little so that a whole number of them fits the loop.
    """
    closed_xy = np.concatenate([points_xy, points_xy[:1]])
    arc_m = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed_xy, axis=0).T))])
    dash_count = round(arc_m[-1] / (dash_m + gap_m))
    dash_m = arc_m[-1] / dash_count - gap_m
    image_rgb = floor_image()
    for dash_start_m in np.arange(dash_count) * (dash_m + gap_m):
        dash_arc_m = np.linspace(dash_start_m, dash_start_m + dash_m,
                                 int(dash_m / CURVE_SPACING_M) + 2)
        dash_xy = np.stack([np.interp(dash_arc_m, arc_m, closed_xy[:, axis]) for axis in (0, 1)],
                           axis=1)
        tangent_xy = np.gradient(dash_xy, axis=0)
        normal_xy = np.stack([-tangent_xy[:, 1], tangent_xy[:, 0]], axis=1)
        normal_xy *= PAINTED_WIDTH_M / 2.0 / np.hypot(*normal_xy.T)[:, np.newaxis]
        outline_xy = np.concatenate([dash_xy + normal_xy, (dash_xy - normal_xy)[::-1]])
        cv2.fillPoly(image_rgb, [to_draw_px(outline_xy)], LINE_RGB, cv2.LINE_8,
                     shift=DRAW_SHIFT_BITS)
    return image_rgb


def jpeg_round_trip(image_rgb):
    """Compress and decompress an RGB image as a JPEG."""
    ok, encoded = cv2.imencode('.jpg', cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    assert ok
    return cv2.cvtColor(cv2.imdecode(encoded, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def lit(image_rgb, pools):
    """
    Light a floor image with round pools of light, bright or dim, with soft edges.

    :param pools: ``(x_m, y_m, radius_m, gain)`` of each pool; its light fades out over the
        outer half of its radius.
    """
    centres_m = (np.arange(IMAGE_SIZE_PX) + 0.5) * BOOK_FLOOR_SIZE_M / IMAGE_SIZE_PX
    x_m = centres_m[np.newaxis, :] - BOOK_FLOOR_SIZE_M / 2.0
    y_m = BOOK_FLOOR_SIZE_M / 2.0 - centres_m[:, np.newaxis]
    gain = np.ones((IMAGE_SIZE_PX, IMAGE_SIZE_PX))
    for pool_x_m, pool_y_m, radius_m, pool_gain in pools:
        inside = np.clip(2.0 - 2.0 * np.hypot(x_m - pool_x_m, y_m - pool_y_m) / radius_m, 0, 1)
        gain *= 1.0 + (pool_gain - 1.0) * inside
    return np.clip(np.round(image_rgb * gain[:, :, np.newaxis]), 0, 255).astype(np.uint8)


def book_loop_texture():
    """Return the default course's own anti-aliased floor texture."""
    return book_loop().draw_texture(IMAGE_SIZE_PX)


# A drawing: its true centre line, the line's sharp corners (none if None) and the floor image.
Case = collections.namedtuple('Case', ['centre_line_xy', 'corners_xy', 'draw'])
CASES = {
    'ellipse': Case(ellipse_xy, None, lambda: draw_line(ellipse_xy())),
    'book_loop_texture': Case(lambda: book_loop().centre_line_xy, None, book_loop_texture),
    'l_shape_corners': Case(l_shape_xy, l_shape_xy, lambda: draw_line(l_shape_xy())),
    'hairpins': Case(hairpins_xy, None, lambda: draw_line(hairpins_xy())),
    'dashed_ellipse': Case(ellipse_xy, None, lambda: draw_dashes(ellipse_xy())),
    'figure_eight': Case(figure_eight_xy, None, lambda: draw_line(figure_eight_xy())),
    'anti_aliased_dark_floor': Case(
        ellipse_xy, None, lambda: draw_line(ellipse_xy(), 40, cv2.LINE_AA)),
    'anti_aliased_light_floor': Case(
        l_shape_xy, l_shape_xy, lambda: draw_line(l_shape_xy(), 200, cv2.LINE_AA)),
    'jpeg_hairpins': Case(hairpins_xy, None, lambda: jpeg_round_trip(draw_line(hairpins_xy()))),
    # Hard-edged lines only a few pixels wide (3 and 4 cm here), as a paint program draws them.
    'hard_edged_3px': Case(ellipse_xy, None, lambda: draw_line(ellipse_xy(), thickness_px=3)),
    'hard_edged_4px': Case(ellipse_xy, None, lambda: draw_line(ellipse_xy(), thickness_px=4)),
    'pools_of_light': Case(ellipse_xy, None, lambda: lit(
        draw_line(ellipse_xy()), [(3.0, 0.0, 1.0, 0.4), (0.0, 4.0, 1.0, 1.7),
                                  (-3.0, 0.0, 1.0, 0.3)])),
}

_images = {}


def case_image(name):
    """Return the floor image of a case, drawn once per test session."""
    if name not in _images:
        _images[name] = CASES[name].draw()
    return _images[name]


def reference(name):
    """Return the drawn centre line of a case as a course."""
    return Course(CASES[name].centre_line_xy(), line_width_m=PAINTED_WIDTH_M)


def centre_errors_m(course, true_course, corners_xy=None):
    """Return each traced point's distance to the true centre line, away from any corners."""
    points_xy = course.centre_line_xy
    if corners_xy is not None:
        to_corner_m = np.min(np.hypot(*(points_xy[:, np.newaxis] - corners_xy).transpose(2, 0, 1)),
                             axis=1)
        points_xy = points_xy[to_corner_m > CORNER_EXCLUSION_M]
    return np.array([true_course.nearest(x_m, y_m)[0] for x_m, y_m in points_xy])


@pytest.mark.parametrize('name', list(CASES))
def test_traced_centre_line_follows_the_drawn_one(name):
    true_course = reference(name)
    course = course_from_image(case_image(name), BOOK_FLOOR_SIZE_M)
    corners = CASES[name].corners_xy
    errors_m = centre_errors_m(course, true_course, None if corners is None else corners())
    assert errors_m.max() <= MAX_CENTRE_ERROR_M
    assert course.length_m == pytest.approx(true_course.length_m, rel=MAX_LENGTH_ERROR)


@pytest.mark.parametrize('name', ['ellipse', 'l_shape_corners', 'figure_eight'])
def test_measured_line_width_matches_the_painted_one(name):
    course = course_from_image(case_image(name), BOOK_FLOOR_SIZE_M)
    assert course.line_width_m == pytest.approx(PAINTED_WIDTH_M, abs=0.01)


def test_given_line_width_is_kept():
    course = course_from_image(case_image('ellipse'), BOOK_FLOOR_SIZE_M, line_width_m=0.25)
    assert course.line_width_m == 0.25


@pytest.mark.parametrize('name, start_xy, yaw_rad', [
    ('ellipse', (3.2, 0.5), math.pi / 2.0),
    ('l_shape_corners', (-1.0, -2.8), 0.0),
    ('hairpins', (-1.5, 0.0), -math.pi / 2.0),
    ('figure_eight', (2.0, 1.3), 2.5),
    ('dashed_ellipse', (-2.9, -1.0), math.pi / 2.0),
])
@pytest.mark.parametrize('reverse', [False, True])
def test_course_starts_nearest_the_start_pose_and_runs_along_its_yaw(
        name, start_xy, yaw_rad, reverse):
    yaw_rad += math.pi if reverse else 0.0
    true_course = reference(name)
    course = course_from_image(case_image(name), BOOK_FLOOR_SIZE_M,
                               start_pose=(*start_xy, yaw_rad))
    start_x, start_y, _ = course.start_pose()
    _, true_start_arc_m = true_course.nearest(*start_xy)
    true_x, true_y, _ = true_course.point_at(true_start_arc_m)
    assert math.hypot(start_x - true_x, start_y - true_y) <= MAX_START_ERROR_M
    ahead_x, ahead_y, _ = course.point_at(DIRECTION_CHECK_M)
    travel_xy = np.array([ahead_x - start_x, ahead_y - start_y])
    assert np.dot(travel_xy, [math.cos(yaw_rad), math.sin(yaw_rad)]) > 0.0
    assert course.length_m == pytest.approx(true_course.length_m, rel=MAX_LENGTH_ERROR)


# The figure-eight's branches cross at the floor centre heading +-0.709 rad (or reversed).
@pytest.mark.parametrize('yaw_rad, heading_rad', [
    (0.6, 0.709), (-0.6, -0.709), (2.5, 2.433), (-2.5, -2.433)])
def test_start_at_a_crossing_takes_the_branch_closest_to_the_yaw(yaw_rad, heading_rad):
    course = course_from_image(case_image('figure_eight'), BOOK_FLOOR_SIZE_M,
                               start_pose=(0.0, 0.0, yaw_rad))
    start_x, start_y, _ = course.start_pose()
    ahead_x, ahead_y, _ = course.point_at(DIRECTION_CHECK_M / 5.0)
    assert (start_x, start_y) == pytest.approx((0.0, 0.0), abs=MAX_START_ERROR_M)
    traced_heading_rad = math.atan2(ahead_y - start_y, ahead_x - start_x)
    assert traced_heading_rad == pytest.approx(heading_rad, abs=0.05)


def test_without_start_pose_starts_nearest_the_floor_centre_counter_clockwise():
    course = course_from_image(case_image('hairpins'), BOOK_FLOOR_SIZE_M)
    start_x, start_y, heading_rad = course.start_pose()
    # The serpentine's last leg runs through the floor centre; counter-clockwise is northward.
    assert (start_x, start_y) == pytest.approx((0.0, 0.0), abs=MAX_START_ERROR_M)
    assert math.sin(heading_rad) == pytest.approx(1.0, abs=0.01)


def test_course_carries_the_image_as_its_floor():
    image_rgb = case_image('ellipse')
    course = course_from_image(image_rgb, BOOK_FLOOR_SIZE_M)
    assert np.array_equal(course.draw_texture(IMAGE_SIZE_PX), image_rgb)


def test_reads_an_rgba_png_file_like_the_books(tmp_path):
    image_rgb = case_image('hairpins')
    path = tmp_path / 'course.png'
    assert cv2.imwrite(str(path), cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGRA))
    from_file = course_from_image(path, BOOK_FLOOR_SIZE_M, name='from_file')
    from_array = course_from_image(image_rgb, BOOK_FLOOR_SIZE_M)
    assert from_file.name == 'from_file'
    assert np.array_equal(from_file.centre_line_xy, from_array.centre_line_xy)
    assert np.array_equal(from_file.draw_texture(IMAGE_SIZE_PX), image_rgb)


def c_shape_xy():
    """Return an open arc: three quarters of a circle."""
    angle_rad = np.linspace(0.0, 1.5 * math.pi, 2000)
    return np.stack([3.0 * np.cos(angle_rad), 3.0 * np.sin(angle_rad)], axis=1)


def triangle_xy():
    """Return a triangle whose corners turn by 117 and 127 degrees."""
    return np.array([(-3.0, -3.0), (3.0, -3.0), (0.0, 3.5)])


def ellipse_with_gap_image(gap_m=0.6):
    """Return an ellipse missing one stretch of line."""
    points_xy = ellipse_xy()
    keep = int(len(points_xy) * (1.0 - gap_m / Course(points_xy).length_m))
    return draw_line(points_xy[:keep], closed=False)


@pytest.mark.parametrize('image_rgb, match', [
    (floor_image(), 'no yellow'),
    (np.full((IMAGE_SIZE_PX, IMAGE_SIZE_PX, 3), (40, 90, 200), dtype=np.uint8), 'no yellow'),
    (draw_line(c_shape_xy(), closed=False), 'closed loop'),
    (ellipse_with_gap_image(), 'closed loop'),
    (draw_line(triangle_xy()), 'at most 100 degrees'),
    (floor_image()[:, :IMAGE_SIZE_PX // 2], 'square'),
    (floor_image()[:, :, 0], 'RGB uint8'),
], ids=['grey_floor', 'blue_floor', 'open_line', 'long_gap', 'too_sharp_corners', 'not_square',
        'not_rgb'])
def test_unusable_images_are_rejected(image_rgb, match):
    with pytest.raises(ValueError, match=match):
        course_from_image(image_rgb, BOOK_FLOOR_SIZE_M)


@pytest.mark.parametrize('start_pose, match', [
    ((0.0, 0.0, 0.0), 'within 0.5 m of the line'),
    ((3.0, 0.0), 'three finite numbers'),
    ((3.0, 0.0, math.nan), 'three finite numbers'),
])
def test_unusable_start_poses_are_rejected(start_pose, match):
    with pytest.raises(ValueError, match=match):
        course_from_image(case_image('ellipse'), BOOK_FLOOR_SIZE_M, start_pose=start_pose)


def test_missing_file_is_named(tmp_path):
    path = tmp_path / 'missing.png'
    with pytest.raises(FileNotFoundError, match='missing.png'):
        course_from_image(path, BOOK_FLOOR_SIZE_M)


def test_file_that_is_not_an_image_is_named(tmp_path):
    path = tmp_path / 'notes.png'
    path.write_text('not an image')
    with pytest.raises(ValueError, match='notes.png'):
        course_from_image(str(path), BOOK_FLOOR_SIZE_M)


def ellipse_with_branch_image(branch_end_xy):
    """Return the ellipse with a straight branch from its east end to ``branch_end_xy``."""
    return draw_line(np.array([(3.0, 0.0), branch_end_xy]), closed=False,
                     image_rgb=draw_line(ellipse_xy()))


def test_a_spur_sending_the_trace_round_again_is_refused_in_one_sentence():
    # A spur straight into the loop: the march runs down it and round the loop forever.
    with pytest.raises(ValueError, match='closed loop that does not fork'):
        course_from_image(ellipse_with_branch_image((1.0, 0.0)), BOOK_FLOOR_SIZE_M)


@pytest.mark.parametrize('start_pose', [(3.0, -0.5, math.pi / 2.0), (0.0, 4.0, math.pi)])
def test_a_y_junction_is_refused_rather_than_traced_as_one_loop(start_pose):
    # A branch leaving the loop at 30 degrees: the march passes the fork straight on.
    branch_end_xy = (3.0 - 2.0 * math.sin(math.radians(30.0)), 2.0 * math.cos(math.radians(30)))
    with pytest.raises(ValueError, match=r'the line branches: \d\.\d\d m of line around pixel'):
        course_from_image(ellipse_with_branch_image(branch_end_xy), BOOK_FLOOR_SIZE_M,
                          start_pose=start_pose)


def png_header_only(path, width_px, height_px):
    """Write the start of a PNG, signature and IHDR, claiming a size; no pixels follow."""
    header = struct.pack('>IIBBBBB', width_px, height_px, 8, 2, 0, 0, 0)
    path.write_bytes(b'\x89PNG\r\n\x1a\n' + struct.pack('>I', len(header)) + b'IHDR' + header
                     + struct.pack('>I', zlib.crc32(b'IHDR' + header)))
    return path


def test_an_oversized_png_is_refused_from_its_header_before_decoding(tmp_path):
    # 20000 x 20000 px would take minutes and gigabytes to decode and trace.
    path = png_header_only(tmp_path / 'huge.png', 20000, 20000)
    with pytest.raises(ValueError, match=r"huge.png' is 20000x20000 px; a course image may be "
                                         r'at most 4096x4096 px; scale it down\.'):
        course_from_image(path, BOOK_FLOOR_SIZE_M)


@pytest.mark.parametrize('suffix', ['.png', '.jpg'])
def test_an_image_just_over_the_limit_is_refused(tmp_path, suffix):
    path = tmp_path / f'floor{suffix}'
    cv2.imwrite(str(path), np.full((4097, 4097, 3), FLOOR_GREY, dtype=np.uint8))
    with pytest.raises(ValueError, match='is 4097x4097 px; a course image may be at most'):
        course_from_image(path, BOOK_FLOOR_SIZE_M)


def test_an_array_over_the_limit_is_refused():
    floor = np.broadcast_to(np.uint8(FLOOR_GREY), (4097, 4097, 3))
    with pytest.raises(ValueError, match='the image array is 4097x4097 px'):
        course_from_image(floor, BOOK_FLOOR_SIZE_M)
