"""
The built-in courses, and tools to build courses from curves and turtle paths.

Every built-in course fits the book's 10 m x 10 m floor with its 0.19 m line and starts (arc
length 0) on a straight or gently curved part, the direction of travel following the point
order. ``COURSES`` maps their names to functions building them;
:func:`followbot_sim.course.make_course` builds one by name and :func:`with_lighting_zones`
adds pools of bright and dim light along any course.
"""

import dataclasses
import math

from followbot_sim.course import Course
from followbot_sim.course import Distractor
from followbot_sim.course import LightingZone
from followbot_sim.course import MAX_POINT_SPACING_M
import numpy as np

# A turtle path closes when its end is this near its start (an exact drawing closes within
# micrometres; hand-measured lengths and angles may not).
TURTLE_CLOSURE_TOLERANCE_M = 0.05
# Samples of a parametric curve's parameter used to measure it before resampling it evenly.
_CURVE_MEASURE_SAMPLES = 1 << 16

# book_loop: an egg whose long axis runs north-south, narrow end north, tilted a little, with a
# third-harmonic wobble so that its sides bend with different radii, like the book's course.
# x(t) = a cos t (1 - taper sin t) + c3 cos 3t + s3 sin 3t, y(t) = b sin t, then rotated.
_BOOK_LOOP_SEMI_AXIS_X_M = 2.45
_BOOK_LOOP_SEMI_AXIS_Y_M = 4.25
_BOOK_LOOP_EGG_TAPER = 0.10
_BOOK_LOOP_WOBBLE_COS3_M = 0.03
_BOOK_LOOP_WOBBLE_SIN3_M = 0.04
_BOOK_LOOP_TILT_RAD = math.radians(-7.0)

# square_corners: a U-shaped polygon 6 m x 7 m with a 2 m x 3 m notch from the north, so its
# eight true right-angle corners turn left six times and right twice (counter-clockwise); the
# start is on the east side, 2.5 m from the corners either side.
_SQUARE_CORNERS_VERTICES_XY = (
    (3.0, -1.0), (3.0, 3.5), (1.0, 3.5), (1.0, 0.5), (-1.0, 0.5), (-1.0, 3.5), (-3.0, 3.5),
    (-3.0, -3.5), (3.0, -3.5))

# s_bends: straights, S-bends and hairpins. An S-bend turns by the angle of a 3-4-5 triangle
# and back, so on radius R it runs 1.6 R ahead and shifts 0.8 R sideways: round numbers that
# let the straights below close the loop exactly.
_S_BEND_RADIUS_M = 0.75
_S_BEND_ANGLE_RAD = math.atan2(4.0, 3.0)
# A Kobuki turns in place, so a hairpin far tighter than the ~1 m bends of the book loop is
# drivable; its legs run 0.8 m apart.
_HAIRPIN_RADIUS_M = 0.4
_S_BENDS_CORNER_RADIUS_M = 1.0
# The start, on the southern straight heading east, and the loop from there.
_S_BENDS_START_POSE = (-1.4, -3.5, 0.0)

# figure_eight: a lemniscate of Bernoulli, (x^2 + y^2)^2 = a^2 (x^2 - y^2), which crosses itself
# at right angles in its middle; its tightest bends, at the tips, have radius a / 3.
_LEMNISCATE_HALF_WIDTH_M = 4.0
# Start on the nearly straight stretch ~0.85 m after the crossing, where the bend radius is ~6 m.
_FIGURE_EIGHT_START_AFTER_CROSSING_RAD = 0.3

# dashed: 0.30 m dashes and 0.15 m gaps. The camera (0.30 m up, tilted 30 degrees down,
# 46.8 degrees vertical field of view) sees the floor from ~0.3 m to ~2.7 m ahead of the robot
# centre, so at least two dashes are always in view and a gap is a sixteenth of what it sees;
# a gap is also shorter than the robot (0.35 m) and takes 0.75 s at the book's 0.2 m/s.
_DASH_LENGTH_M = 0.30
_GAP_LENGTH_M = 0.15

# distractor: yellow patches beside the book loop, as (arc length of the nearest line point,
# offset of the patch centre to the left of the line, length along the line, width across it,
# angle from the line's direction), metres and degrees. The loop runs counter-clockwise, so
# left is the inside; arcs 5.6 m and 16.2 m are the tight north and south bends.
_BOOK_LOOP_DISTRACTORS = (
    (2.5, -0.45, 0.40, 0.10, 0.0),  # a stripe outside the start straight
    (5.6, 0.40, 0.25, 0.25, 45.0),  # a square inside the tight north bend
    (9.0, 0.50, 0.50, 0.12, 30.0),  # an angled stripe inside the west side
    (13.0, -0.35, 0.30, 0.08, 0.0),  # a short parallel stripe outside
    (16.2, 0.45, 0.35, 0.15, 90.0),  # a stripe pointing at the line inside the south bend
)

# hairpins: a rounded rectangle whose long sides each grow two fingers, one pointing out of the
# loop and one into it, so the robot drives right and left hairpins of 0.15 m centre-line radius
# (issue 14 saw a follower lose the line at ~0.14 m hairpins on public tracks). A finger's legs
# run 0.30 m apart, so the 0.19 m lines leave an 0.11 m gap between them.
_HAIRPIN_TIGHT_RADIUS_M = 0.15
_FINGER_LEG_M = 1.0
_FINGER_CORNER_RADIUS_M = 0.3
_HAIRPINS_CORNER_RADIUS_M = 0.5
_HAIRPINS_SIDE_STRAIGHT_M = 1.0
_HAIRPINS_END_STRAIGHT_M = 3.0

# sharp_corners: a pentagon whose five straight sides meet at corners turning 120 degrees (a
# 60-degree angle between the sides), four left and one right; side lengths a, b, c, d, e with
# b + d = c + e = a close it, since unit vectors 120 degrees apart sum to zero. The start is in
# the middle of the first (south) side, heading east.
_SHARP_CORNERS_TURN_RAD = math.radians(120.0)
_SHARP_CORNERS_SIDES_M = (8.0, 5.0, 2.0, 3.0, 6.0)
_SHARP_CORNERS_TURNS = (+1, +1, -1, +1, +1)

# t_junction: the book loop with stubs of line branching off square to it, a T the follower must
# drive straight through; as (arc length, +1 left / -1 right). Each stub is painted like the line,
# 0.19 m wide, from the centre line out to 0.5 m from it, on the gentle parts of the loop.
_T_JUNCTION_STUBS = ((2.5, +1), (9.5, -1), (13.0, +1))
_STUB_LENGTH_M = 0.5

# line_end: a rounded rectangle whose line is painted only from 1 m behind the start (in the
# middle of its east side) up that side, round the north-east corner and 2 m along the north
# side, where the line stops; the rest of the loop is bare floor (the scoring's centre line).
# The floor ahead of the end stays bare for more than the ~2.7 m the camera sees.
_LINE_END_SIDES_M = (3.0, 4.0)
_LINE_END_CORNER_RADIUS_M = 1.0
_LINE_END_PAINTED_BEHIND_START_M = 1.0
_LINE_END_PAINTED_ALONG_NORTH_SIDE_M = 2.0

# with_lighting_zones: pools of bright and dim light alternating along the line, centred on it
# at these fractions of its length (none reaches the start), each covering ~1.6 m of line.
LIGHTING_ZONE_FRACTIONS = (0.125, 0.375, 0.625, 0.875)
LIGHTING_ZONE_GAINS = (1.7, 0.4, 1.7, 0.4)
LIGHTING_ZONE_RADIUS_M = 0.8


@dataclasses.dataclass(frozen=True)
class Straight:
    """A straight piece of a turtle path."""

    length_m: float

    def __post_init__(self):
        """Reject a length that is not positive and finite."""
        if not (math.isfinite(self.length_m) and self.length_m > 0.0):
            raise ValueError(f'a straight needs a positive finite length_m, got {self.length_m}.')


@dataclasses.dataclass(frozen=True)
class Arc:
    """A circular piece of a turtle path, turning left for a positive angle."""

    radius_m: float
    angle_rad: float

    def __post_init__(self):
        """Reject a radius that is not positive or an angle that is zero or not finite."""
        if not (math.isfinite(self.radius_m) and self.radius_m > 0.0):
            raise ValueError(f'an arc needs a positive finite radius_m, got {self.radius_m}.')
        if not (math.isfinite(self.angle_rad) and self.angle_rad != 0.0):
            raise ValueError(f'an arc needs a non-zero finite angle_rad, got {self.angle_rad}.')


def turtle_loop_xy(start_pose, segments, closure_tolerance_m=TURTLE_CLOSURE_TOLERANCE_M):
    """
    Trace a closed loop of straights and arcs from a start pose.

    :param start_pose: ``(x_m, y_m, yaw_rad)`` where the path starts, yaw counter-clockwise
        from east.
    :param segments: :class:`Straight` and :class:`Arc` pieces in driving order.
    :param closure_tolerance_m: how near its start the path must end.
    :return: (N, 2) points in metres, arcs sampled at most ``MAX_POINT_SPACING_M`` apart, the
        start first; the path's end is the last point unless it is the start itself.
    :raises ValueError: if there are no segments, one is of another kind, or the path ends
        farther than ``closure_tolerance_m`` from its start.
    """
    x_m, y_m, yaw_rad = (float(value) for value in start_pose)
    points_xy = [np.array([[x_m, y_m]])]
    if not segments:
        raise ValueError('a turtle path needs at least one segment.')
    for segment in segments:
        if isinstance(segment, Straight):
            x_m += segment.length_m * math.cos(yaw_rad)
            y_m += segment.length_m * math.sin(yaw_rad)
            points_xy.append(np.array([[x_m, y_m]]))
        elif isinstance(segment, Arc):
            turn = math.copysign(1.0, segment.angle_rad)
            centre_x_m = x_m - turn * segment.radius_m * math.sin(yaw_rad)
            centre_y_m = y_m + turn * segment.radius_m * math.cos(yaw_rad)
            steps = math.ceil(segment.radius_m * abs(segment.angle_rad) / MAX_POINT_SPACING_M)
            heading_rad = yaw_rad + segment.angle_rad * np.arange(1, steps + 1) / steps
            arc_xy = np.stack([centre_x_m + turn * segment.radius_m * np.sin(heading_rad),
                               centre_y_m - turn * segment.radius_m * np.cos(heading_rad)], 1)
            points_xy.append(arc_xy)
            x_m, y_m = arc_xy[-1]
            yaw_rad += segment.angle_rad
        else:
            raise ValueError(f'turtle path segments must be Straight or Arc, got {segment!r}.')
    points_xy = np.concatenate(points_xy)
    miss_m = float(np.hypot(*(points_xy[-1] - points_xy[0])))
    if miss_m > closure_tolerance_m:
        raise ValueError(
            f'the turtle path ends {miss_m:.3f} m from its start; a closed loop must end '
            f'within {closure_tolerance_m} m of it.')
    return points_xy


def _evenly_spaced_closed_curve(curve):
    """
    Sample a closed parametric curve at points evenly spaced by arc length, centred.

    :param curve: a function of parameter values in [0, 2 pi] returning (N, 2) points in
        metres, closed (equal at 0 and 2 pi); the start is the point at parameter 0.
    :return: (M, 2) points at most ``MAX_POINT_SPACING_M`` apart, last point not repeated,
        shifted so that the curve's bounding box is centred on the origin.
    """
    # Measure the curve densely, then place points evenly along its arc length so the
    # polyline is uniform however fast the parameter runs.
    parameter_rad = np.linspace(0.0, 2.0 * math.pi, _CURVE_MEASURE_SAMPLES + 1)
    dense_xy = curve(parameter_rad)
    dense_arc_m = np.concatenate(
        ([0.0], np.cumsum(np.linalg.norm(np.diff(dense_xy, axis=0), axis=1))))
    point_count = math.ceil(dense_arc_m[-1] / MAX_POINT_SPACING_M)
    even_arc_m = np.arange(point_count) * (dense_arc_m[-1] / point_count)
    points_xy = curve(np.interp(even_arc_m, dense_arc_m, parameter_rad))
    bbox_centre_xy = (dense_xy.min(axis=0) + dense_xy.max(axis=0)) / 2.0
    return points_xy - bbox_centre_xy


def _book_loop_curve(parameter_rad):
    """
    Evaluate the book_loop egg curve, before centring, at parameter values.

    :param parameter_rad: curve parameter(s) in [0, 2 pi); 0 is the start on the east side and
        increasing values run counter-clockwise.
    :return: (N, 2) points in metres.
    """
    t = np.asarray(parameter_rad, dtype=float)
    x_m = (_BOOK_LOOP_SEMI_AXIS_X_M * np.cos(t) * (1.0 - _BOOK_LOOP_EGG_TAPER * np.sin(t))
           + _BOOK_LOOP_WOBBLE_COS3_M * np.cos(3.0 * t)
           + _BOOK_LOOP_WOBBLE_SIN3_M * np.sin(3.0 * t))
    y_m = _BOOK_LOOP_SEMI_AXIS_Y_M * np.sin(t)
    cos_tilt, sin_tilt = math.cos(_BOOK_LOOP_TILT_RAD), math.sin(_BOOK_LOOP_TILT_RAD)
    return np.stack([cos_tilt * x_m - sin_tilt * y_m, sin_tilt * x_m + cos_tilt * y_m], axis=1)


def book_loop():
    """
    Build the default course, an irregular egg-shaped loop like the book's Gazebo world.

    About 5.1 m x 8.5 m and 21.4 m long, centred on the 10 m floor, narrow end to the north
    where the tightest bend has a ~1.04 m radius; the robot starts on the gentle east side
    heading north (counter-clockwise).

    :return: the course, named 'book_loop'.
    """
    return Course(_evenly_spaced_closed_curve(_book_loop_curve), name='book_loop')


def square_corners():
    """
    Build a U-shaped loop of straight lines meeting at eight true right-angle corners.

    6 m x 7 m and 32 m long, run counter-clockwise from the middle of its east side: six
    corners turn left and the two at the bottom of the northern notch turn right.

    :return: the course, named 'square_corners'.
    """
    return Course(_SQUARE_CORNERS_VERTICES_XY, name='square_corners')


def _s_bend(turn):
    """
    Return the two arcs of an S-bend.

    :param turn: +1 to turn left first (shifting left), -1 to turn right first.
    :return: a list of two :class:`Arc` pieces.
    """
    return [Arc(_S_BEND_RADIUS_M, turn * _S_BEND_ANGLE_RAD),
            Arc(_S_BEND_RADIUS_M, -turn * _S_BEND_ANGLE_RAD)]


def _s_bends_segments():
    """
    Return the turtle path of the s_bends course from its start.

    :return: a list of :class:`Straight` and :class:`Arc` pieces.
    """
    corner = Arc(_S_BENDS_CORNER_RADIUS_M, math.pi / 2.0)
    return [
        Straight(1.2), *_s_bend(+1), Straight(1.0), corner,  # south side, S-bend to the left
        Straight(1.0), *_s_bend(-1), Straight(1.7), corner,  # east side, S-bend to the right
        Straight(3.6), corner,  # north side
        Straight(3.5), Arc(_HAIRPIN_RADIUS_M, -math.pi),  # down, right hairpin
        Straight(4.1), Arc(_HAIRPIN_RADIUS_M, math.pi),  # up, left hairpin
        Straight(5.1), corner, Straight(1.2),  # down the west side, back to the start
    ]


def s_bends():
    """
    Build a loop of S-bends (radius 0.75 m) and hairpins (radius 0.4 m) turning both ways.

    About 7.2 m x 6.5 m and 34 m long: S-bends left and right on the south and east sides,
    1 m corners, then a right and a left hairpin on the west side, whose legs run 0.8 m apart.
    The start is on the southern straight heading east.

    :return: the course, named 's_bends'.
    """
    points_xy = turtle_loop_xy(_S_BENDS_START_POSE, _s_bends_segments())
    return Course(points_xy, name='s_bends')


def _figure_eight_curve(parameter_rad):
    """
    Evaluate the figure_eight lemniscate from its start.

    :param parameter_rad: curve parameter(s) in [0, 2 pi]; the line crosses itself at
        parameter pi - the start offset and 2 pi - the start offset.
    :return: (N, 2) points in metres.
    """
    # The lemniscate's own parameter is pi / 2 at the crossing.
    t = (np.asarray(parameter_rad, dtype=float) + math.pi / 2.0
         + _FIGURE_EIGHT_START_AFTER_CROSSING_RAD)
    scale = _LEMNISCATE_HALF_WIDTH_M / (1.0 + np.sin(t) ** 2)
    return np.stack([scale * np.cos(t), scale * np.sin(t) * np.cos(t)], axis=1)


def figure_eight():
    """
    Build a smooth figure-eight loop that crosses itself once, at right angles.

    A lemniscate 8 m x 2.8 m and 21 m long whose tightest bends, at its tips, have a 1.33 m
    radius; one lobe is driven counter-clockwise and the other clockwise. The start is
    ~0.85 m after the crossing, heading away from it.

    :return: the course, named 'figure_eight'.
    """
    return Course(_evenly_spaced_closed_curve(_figure_eight_curve), name='figure_eight')


def dashed():
    """
    Build the book loop painted as a dashed line, 0.30 m dashes and 0.15 m gaps.

    The centre line, and so the scoring, is the book loop's; the start is the start of a dash.

    :return: the course, named 'dashed'.
    """
    return book_loop().replace(name='dashed', dash_length_m=_DASH_LENGTH_M,
                               gap_length_m=_GAP_LENGTH_M)


def _centred(points_xy):
    """
    Shift points so that their bounding box is centred on the origin.

    :param points_xy: (N, 2) points in metres.
    :return: the shifted (N, 2) points.
    """
    points_xy = np.asarray(points_xy, dtype=float)
    return points_xy - (points_xy.min(axis=0) + points_xy.max(axis=0)) / 2.0


def _finger(turn):
    """
    Return the turtle pieces of a finger: a square turn off the side, a hairpin and back.

    :param turn: -1 to turn right off the side first (a left hairpin), +1 to turn left first.
    :return: a list of :class:`Straight` and :class:`Arc` pieces that leave the heading as it
        was, 2 x (corner radius + hairpin radius) further along the side.
    """
    corner = Arc(_FINGER_CORNER_RADIUS_M, turn * math.pi / 2.0)
    return [corner, Straight(_FINGER_LEG_M), Arc(_HAIRPIN_TIGHT_RADIUS_M, -turn * math.pi),
            Straight(_FINGER_LEG_M), corner]


def hairpins():
    """
    Build a loop with four hairpins of 0.15 m centre-line radius, two left and two right.

    A rounded rectangle (0.5 m corners) run counter-clockwise, each long side carrying a finger
    out of the loop (a left hairpin) and one into it (a right hairpin); a finger's legs are
    1 m long and 0.30 m apart, joined to the side by 0.3 m quarter turns. About 5.8 m x 6.9 m
    and 27 m long; the start is in the middle of the east side, heading north.

    :return: the course, named 'hairpins'.
    """
    corner = Arc(_HAIRPINS_CORNER_RADIUS_M, math.pi / 2.0)
    side = Straight(_HAIRPINS_SIDE_STRAIGHT_M)
    long_side = [side, *_finger(-1), side, *_finger(+1), side]
    half_end = Straight(_HAIRPINS_END_STRAIGHT_M / 2.0)
    segments = [half_end, corner, *long_side, corner, Straight(_HAIRPINS_END_STRAIGHT_M),
                corner, *long_side, corner, half_end]
    points_xy = turtle_loop_xy((0.0, 0.0, math.pi / 2.0), segments)
    return Course(_centred(points_xy), name='hairpins')


def sharp_corners():
    """
    Build a pentagon whose corners each turn 120 degrees: four left, one right.

    Every corner leaves a 60-degree angle between the sides (sharper than the ~95-degree
    turns issue 14 saw a follower fail at); 8 m x 5.2 m and 24 m long, run counter-clockwise
    from the middle of its south side.

    :return: the course, named 'sharp_corners'.
    """
    vertices_xy = [(0.0, 0.0)]
    heading_rad = 0.0
    for side_m, turn in zip(_SHARP_CORNERS_SIDES_M, _SHARP_CORNERS_TURNS):
        x_m, y_m = vertices_xy[-1]
        vertices_xy.append((x_m + side_m * math.cos(heading_rad),
                            y_m + side_m * math.sin(heading_rad)))
        heading_rad += turn * _SHARP_CORNERS_TURN_RAD
    # The last side ends where the first began; start halfway along the first.
    closing_vertex = vertices_xy.pop()
    if math.hypot(*closing_vertex) > TURTLE_CLOSURE_TOLERANCE_M:
        raise ValueError(f'the sharp_corners sides do not close: they end at {closing_vertex}.')
    start_xy = ((vertices_xy[0][0] + vertices_xy[1][0]) / 2.0, vertices_xy[0][1])
    return Course(_centred([start_xy, *vertices_xy[1:], vertices_xy[0]]), name='sharp_corners')


def t_junction():
    """
    Build the book loop with three T-junctions: stubs of line square to it, to be ignored.

    Each stub is as wide as the line and reaches 0.5 m from the centre line, two to the left
    (inside) and one to the right; the follower must drive straight past them on the loop.

    :return: the course, named 't_junction'.
    """
    course = book_loop()
    stubs = tuple(
        distractor_beside(course, arc_m, side * _STUB_LENGTH_M / 2.0, course.line_width_m,
                          _STUB_LENGTH_M)
        for arc_m, side in _T_JUNCTION_STUBS)
    return course.replace(name='t_junction', distractors=stubs)


def line_end():
    """
    Build a line that ends: 6.1 m of a rounded rectangle's line, then bare floor.

    The painted line begins 1 m behind the start, runs 2.5 m north past it, round a 1 m corner
    to the west and 2 m on, where it stops square, 5.07 m after the start; the follower must
    stop there. The rest of the 6 m x 5 m loop is the scoring's centre line only.

    :return: the course, named 'line_end'.
    """
    side_ns_m, side_ew_m = _LINE_END_SIDES_M
    corner = Arc(_LINE_END_CORNER_RADIUS_M, math.pi / 2.0)
    half_side = Straight(side_ns_m / 2.0)
    segments = [half_side, corner, Straight(side_ew_m), corner, Straight(side_ns_m),
                corner, Straight(side_ew_m), corner, half_side]
    points_xy = turtle_loop_xy((0.0, 0.0, math.pi / 2.0), segments)
    end_m = (side_ns_m / 2.0 + _LINE_END_CORNER_RADIUS_M * math.pi / 2.0
             + _LINE_END_PAINTED_ALONG_NORTH_SIDE_M)
    return Course(_centred(points_xy), name='line_end',
                  painted_interval_m=(-_LINE_END_PAINTED_BEHIND_START_M, end_m))


def distractor_beside(course, arc_length_m, offset_m, length_m, width_m, yaw_rad=0.0):
    """
    Place a distractor patch beside a course's line.

    :param course: the course.
    :param arc_length_m: arc length of the line point the patch is beside, in metres.
    :param offset_m: distance of the patch centre from that point, along the normal to the
        line, positive to the left of the direction of travel, in metres.
    :param length_m: length of the patch along the line's direction there, in metres.
    :param width_m: width of the patch across it, in metres.
    :param yaw_rad: angle of the patch from the line's direction, counter-clockwise.
    :return: the :class:`Distractor`.
    """
    x_m, y_m, heading_rad = course.point_at(arc_length_m, offset_m)
    return Distractor(x_m, y_m, length_m, width_m, heading_rad + yaw_rad)


def distractor():
    """
    Build the book loop with yellow patches beside the line, some inside its tight bends.

    Five rectangles 0.35-0.5 m from the centre line, none touching the line: parallel
    stripes, an angled stripe, a square and a stripe pointing at the line.

    :return: the course, named 'distractor'.
    """
    course = book_loop()
    patches = tuple(
        distractor_beside(course, arc_m, offset_m, length_m, width_m, math.radians(yaw_deg))
        for arc_m, offset_m, length_m, width_m, yaw_deg in _BOOK_LOOP_DISTRACTORS)
    return course.replace(name='distractor', distractors=patches)


def with_lighting_zones(course):
    """
    Add the standard pools of bright and dim light along a course's line.

    Four pools of radius ``LIGHTING_ZONE_RADIUS_M`` centred on the line at the fractions
    ``LIGHTING_ZONE_FRACTIONS`` of its length, gains ``LIGHTING_ZONE_GAINS`` (bright, dim,
    bright, dim), added to any the course has.

    :param course: the course.
    :return: a new course named '<name>+lighting'.
    """
    zones = tuple(
        LightingZone(*course.point_at(fraction * course.length_m)[:2],
                     LIGHTING_ZONE_RADIUS_M, gain)
        for fraction, gain in zip(LIGHTING_ZONE_FRACTIONS, LIGHTING_ZONE_GAINS))
    return course.replace(name=f'{course.name}+lighting',
                          lighting_zones=course.lighting_zones + zones)


COURSES = {
    'book_loop': book_loop,
    'square_corners': square_corners,
    's_bends': s_bends,
    'dashed': dashed,
    'figure_eight': figure_eight,
    'distractor': distractor,
    'hairpins': hairpins,
    'sharp_corners': sharp_corners,
    't_junction': t_junction,
    'line_end': line_end,
}
