"""
Line-following course: centre-line geometry, floor texture and ground-truth lap scoring.

A pure NumPy (and OpenCV, for resizing floor images) module, no ROS and no MuJoCo, so that the
simulator, the scorer and the tests share one description of the course.

World frame: the floor is a square centred at the origin, x east, y north, metres. The floor
texture follows MuJoCo's convention for a 2-D texture stretched once over a plane
(``texrepeat="1 1"``): image row 0 is the north (+y) edge and column 0 the west (-x) edge.

Besides its continuous centre line, which the scoring always uses, a course can paint the line
as dashes, add yellow distractor patches beside it, bake pools of brighter or dimmer light into
the floor, or show a given image of the whole floor instead of painting a line. The built-in
courses live in :mod:`followbot_sim.course_library`; ``COURSES`` and ``book_loop`` can still be
imported from here.
"""

import bisect
import dataclasses
import functools
import math

import cv2
import numpy as np

BOOK_FLOOR_SIZE_M = 10.0
BOOK_LINE_WIDTH_M = 0.19
LINE_RGB = (255, 246, 0)
FLOOR_GREY = 116

# Dense enough that the polyline is within micrometres of a smooth curve of radius > 0.5 m.
MAX_POINT_SPACING_M = 0.01
# Lets a segment a rounding error longer than the spacing through without splitting it.
_SPACING_TOLERANCE = 1e-6
# Arc length either side of a vertex for estimating curvature: long enough to smooth the kinks
# of a subdivided polyline, short against the bends of a course.
CURVATURE_BASELINE_M = 0.1
# Consecutive points closer than this are one point (e.g. a repeated closing point).
_DUPLICATE_POINT_M = 1e-9
_MIN_LOOP_POINTS = 3

# Anti-aliasing: a pixel is painted in proportion to how much of a one-pixel box around its
# centre lies on the paint, so paint reaches half a pixel beyond its edge.
_ANTI_ALIAS_HALF_PX = 0.5
# The texture's line coverage is computed in runs of segments spanning about this many reaches
# (half line widths plus the anti-aliasing margin): fastest when measured at 1024-4096 px.
_DISTANCE_RUN_REACHES = 2.0
# A light pool's gain fades smoothly to none over this width, centred on its radius, as the
# edge of a real pool of light is soft.
LIGHTING_EDGE_RAMP_M = 0.25
_RGB_CHANNELS = 3
_MAX_CHANNEL_VALUE = 255

# Between two scorer updates the robot moves centimetres; a larger change of the nearest arc
# length means the nearest point hopped to another part of the course.
DEFAULT_MAX_ARC_STEP_M = 1.0

# Names defined in followbot_sim.course_library and still importable from this module.
_LIBRARY_NAMES = ('COURSES', 'book_loop')


def _require_finite(name, value):
    """
    Check that a value is a finite real number.

    :param name: name of the value, for the error message.
    :param value: the value.
    :return: the value as a float.
    :raises ValueError: if the value is not a finite real number.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value):
        raise ValueError(f'{name} must be a finite number, got {value!r}.')
    return float(value)


def _require_positive(name, value):
    """
    Check that a value is a positive finite real number.

    :param name: name of the value, for the error message.
    :param value: the value.
    :return: the value as a float.
    :raises ValueError: if the value is not a positive finite real number.
    """
    if _require_finite(name, value) <= 0.0:
        raise ValueError(f'{name} must be positive, got {value!r}.')
    return float(value)


@dataclasses.dataclass(frozen=True)
class Distractor:
    """
    A rectangle painted on the floor in the line's colour that is not part of the line.

    ``length_m`` runs along ``yaw_rad`` (counter-clockwise from east), ``width_m`` across it.
    """

    x_m: float
    y_m: float
    length_m: float
    width_m: float
    yaw_rad: float = 0.0

    def __post_init__(self):
        """Reject a rectangle that is not finite or has no area."""
        _require_finite('Distractor x_m', self.x_m)
        _require_finite('Distractor y_m', self.y_m)
        _require_positive('Distractor length_m', self.length_m)
        _require_positive('Distractor width_m', self.width_m)
        _require_finite('Distractor yaw_rad', self.yaw_rad)


@dataclasses.dataclass(frozen=True)
class LightingZone:
    """
    A pool of brighter (gain > 1) or dimmer (gain < 1) light baked into the floor texture.

    The gain multiplies the floor and line colours (saturating at 255) fully within
    ``radius_m - LIGHTING_EDGE_RAMP_M / 2`` of the centre and fades smoothly to none at
    ``radius_m + LIGHTING_EDGE_RAMP_M / 2``. Where pools overlap their gains multiply.
    """

    x_m: float
    y_m: float
    radius_m: float
    gain: float

    def __post_init__(self):
        """Reject a pool that is not finite, has no radius or a negative gain."""
        _require_finite('LightingZone x_m', self.x_m)
        _require_finite('LightingZone y_m', self.y_m)
        _require_positive('LightingZone radius_m', self.radius_m)
        if _require_finite('LightingZone gain', self.gain) < 0.0:
            raise ValueError(f'LightingZone gain must not be negative, got {self.gain!r}.')


def world_to_texture_px(x_m, y_m, size_px, floor_size_m=BOOK_FLOOR_SIZE_M):
    """
    Convert world coordinates to continuous floor-texture pixel coordinates.

    Pixel centres sit at integer coordinates (OpenCV's convention): pixel (col, row) covers
    x = (col + 0.5) / size * L - L / 2 and y = L / 2 - (row + 0.5) / size * L at its centre.

    :param x_m: east coordinate(s) in metres, scalar or array.
    :param y_m: north coordinate(s) in metres, scalar or array.
    :param size_px: side of the square texture in pixels.
    :param floor_size_m: side of the square floor in metres.
    :return: ``(col, row)`` as floats (or float arrays), column from the west edge and row from
        the north edge.
    """
    px_per_m = size_px / floor_size_m
    half_floor_m = floor_size_m / 2.0
    col = (np.asarray(x_m, dtype=float) + half_floor_m) * px_per_m - 0.5
    row = (half_floor_m - np.asarray(y_m, dtype=float)) * px_per_m - 0.5
    return col, row


def texture_px_to_world(col, row, size_px, floor_size_m=BOOK_FLOOR_SIZE_M):
    """
    Convert continuous floor-texture pixel coordinates to world coordinates.

    The inverse of :func:`world_to_texture_px`, with the same pixel-centre convention.

    :param col: column(s) from the west edge, scalar or array.
    :param row: row(s) from the north edge, scalar or array.
    :param size_px: side of the square texture in pixels.
    :param floor_size_m: side of the square floor in metres.
    :return: ``(x_m, y_m)`` as floats (or float arrays).
    """
    m_per_px = floor_size_m / size_px
    half_floor_m = floor_size_m / 2.0
    x_m = (np.asarray(col, dtype=float) + 0.5) * m_per_px - half_floor_m
    y_m = half_floor_m - (np.asarray(row, dtype=float) + 0.5) * m_per_px
    return x_m, y_m


def _wrap_to_half_length(delta_m, length_m):
    """
    Wrap a difference of arc lengths into (-length / 2, length / 2].

    :param delta_m: difference of two arc lengths in metres.
    :param length_m: loop length in metres.
    :return: the equivalent difference closest to zero.
    """
    half_m = length_m / 2.0
    return half_m - (half_m - delta_m) % length_m


def _as_loop_points(centre_line_xy):
    """
    Validate a closed loop's points and drop consecutive duplicates.

    :param centre_line_xy: (N, 2) points of the loop in metres, last point not repeated.
    :return: the distinct points as a float (M, 2) array.
    :raises ValueError: if the points are not a finite (N, 2) array of at least three distinct
        points.
    """
    try:
        points_xy = np.array(centre_line_xy, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f'centre_line_xy must be an (N, 2) array of numbers: {error}') from None
    if points_xy.ndim != 2 or points_xy.shape[1] != 2:
        raise ValueError(f'centre_line_xy must have shape (N, 2), got {points_xy.shape}.')
    if not np.all(np.isfinite(points_xy)):
        raise ValueError('centre_line_xy must contain only finite numbers.')
    step_m = np.linalg.norm(np.roll(points_xy, -1, axis=0) - points_xy, axis=1)
    points_xy = points_xy[step_m > _DUPLICATE_POINT_M]
    if len(points_xy) < _MIN_LOOP_POINTS:
        raise ValueError(
            f'centre_line_xy needs at least {_MIN_LOOP_POINTS} distinct points to make a loop, '
            f'got {len(points_xy)}.')
    return points_xy


def _subdivide_loop(points_xy, max_spacing_m):
    """
    Insert evenly spaced points into every segment longer than ``max_spacing_m``.

    :param points_xy: (N, 2) vertices of a closed polyline, last point not repeated.
    :param max_spacing_m: longest segment allowed in the result.
    :return: (M, 2) vertices, M >= N, the original vertices kept in order.
    """
    segment_xy = np.roll(points_xy, -1, axis=0) - points_xy
    segment_length_m = np.linalg.norm(segment_xy, axis=1)
    pieces = np.maximum(
        1, np.ceil(segment_length_m / max_spacing_m - _SPACING_TOLERANCE)).astype(int)
    segment_index = np.repeat(np.arange(len(points_xy)), pieces)
    first_piece = np.repeat(np.cumsum(pieces) - pieces, pieces)
    fraction = (np.arange(pieces.sum()) - first_piece) / pieces[segment_index]
    return points_xy[segment_index] + fraction[:, np.newaxis] * segment_xy[segment_index]


def _as_floor_image(floor_image_rgb):
    """
    Validate an image of the whole floor and keep a read-only copy.

    :param floor_image_rgb: an (H, W, 3) uint8 RGB image, or None.
    :return: a read-only copy, or None.
    :raises ValueError: if the image is not an (H, W, 3) uint8 array.
    """
    if floor_image_rgb is None:
        return None
    image_rgb = np.array(floor_image_rgb)
    if image_rgb.dtype != np.uint8 or image_rgb.ndim != 3 \
            or image_rgb.shape[2] != _RGB_CHANNELS or 0 in image_rgb.shape:
        raise ValueError(
            'floor_image_rgb must be a non-empty (H, W, 3) uint8 RGB image, got an array of '
            f'shape {image_rgb.shape} and type {image_rgb.dtype}.')
    image_rgb.setflags(write=False)
    return image_rgb


def _dash_intervals_m(dash_length_m, gap_length_m, length_m):
    """
    List the painted arc intervals of a dashed closed line.

    Dash k covers [k (d + g), k (d + g) + d), cut at the loop's length; a dash running into the
    end of the loop continues into the first one, so the two become one interval starting
    before 0.

    :param dash_length_m: length of a dash in metres.
    :param gap_length_m: length of a gap in metres.
    :param length_m: loop length in metres, at least one dash period.
    :return: ``(starts_m, ends_m)``, increasing arrays, ``starts_m[0] <= 0``.
    """
    period_m = dash_length_m + gap_length_m
    starts_m = np.arange(math.ceil(length_m / period_m)) * period_m
    ends_m = np.minimum(starts_m + dash_length_m, length_m)
    if len(starts_m) > 1 and ends_m[-1] >= length_m:
        starts_m[0] = starts_m[-1] - length_m
        starts_m, ends_m = starts_m[:-1], ends_m[:-1]
    return starts_m, ends_m


class Course:
    """
    A closed centre line painted on a square floor.

    Arc length runs along the polyline from its first point (the start) in the order the
    points were given, which is the direction of travel. The scoring geometry (nearest point,
    offsets, arc lengths) always uses the continuous centre line, however the line is painted.
    """

    def __init__(self, centre_line_xy, line_width_m=BOOK_LINE_WIDTH_M,
                 floor_size_m=BOOK_FLOOR_SIZE_M, name='custom', *, dash_length_m=None,
                 gap_length_m=None, distractors=(), lighting_zones=(), floor_image_rgb=None,
                 painted_interval_m=None):
        """
        Build a course from the points of its closed centre line.

        :param centre_line_xy: (N, 2) points in metres of a closed loop, last point not
            repeated (a repeated closing point is dropped); polylines coarser than
            ``MAX_POINT_SPACING_M`` are subdivided.
        :param line_width_m: width of the painted line in metres.
        :param floor_size_m: side of the square floor, centred at the origin, in metres.
        :param name: name of the course.
        :param dash_length_m: paint the line only on the arc intervals
            [k (d + g), k (d + g) + d) with this d in metres; None paints it solid.
        :param gap_length_m: the gap g between dashes in metres; given with ``dash_length_m``.
        :param distractors: :class:`Distractor` patches painted in the line's colour.
        :param lighting_zones: :class:`LightingZone` pools of light baked into the texture.
        :param floor_image_rgb: an (H, W, 3) uint8 RGB image of the whole floor, row 0 at the
            north edge, column 0 at the west edge, shown instead of painting the line (the
            centre line then only serves the scoring); None paints the line.
        :param painted_interval_m: ``(begin_m, end_m)``: paint the line only over these arc
            lengths in metres, ``begin_m`` negative to begin behind the start, so that it
            ends square at both and the rest of the loop is bare floor that only the scoring
            knows (a line that ends); None paints the whole loop.
        :raises ValueError: if the points are not a finite loop of at least three distinct
            points, a size is not positive, the line leaves the floor, the dash options are
            not both positive (or both None), a dash and a gap are longer than the loop,
            ``painted_interval_m`` is not a part of the loop holding the start, or the floor
            image is not an RGB uint8 image or comes with dashes or a painted interval.
        :raises TypeError: if a distractor or lighting zone is not of its class.
        """
        if not (math.isfinite(floor_size_m) and floor_size_m > 0.0):
            raise ValueError(f'floor_size_m must be positive and finite, got {floor_size_m}.')
        if not (math.isfinite(line_width_m) and 0.0 < line_width_m < floor_size_m):
            raise ValueError(
                f'line_width_m must be positive and narrower than the floor ({floor_size_m} m), '
                f'got {line_width_m}.')
        points_xy = _as_loop_points(centre_line_xy)
        limit_m = floor_size_m / 2.0 - line_width_m / 2.0
        farthest_m = float(np.max(np.abs(points_xy)))
        if farthest_m > limit_m:
            raise ValueError(
                f'the line must stay on the {floor_size_m} m floor: centre-line points need '
                f'|x| and |y| <= {limit_m:.3f} m, one is at {farthest_m:.3f} m.')

        self._name = str(name)
        self._line_width_m = float(line_width_m)
        self._floor_size_m = float(floor_size_m)
        self._points_xy = _subdivide_loop(points_xy, MAX_POINT_SPACING_M)
        self._points_xy.setflags(write=False)
        self._build_segment_table()
        self._set_paint_options(dash_length_m, gap_length_m, distractors, lighting_zones,
                                floor_image_rgb, painted_interval_m)

    def _build_segment_table(self):
        """
        Tabulate the segments for the nearest-point searches, twice over.

        Rows: start x, start y, delta x, delta y, inverse squared length, start arc length,
        length; columns: the segments, then the same segments again with their start arc
        lengths one loop further, so any arc window is one contiguous slice.
        """
        segment_count = len(self._points_xy)
        segment_xy = np.roll(self._points_xy, -1, axis=0) - self._points_xy
        segment_length_m = np.hypot(segment_xy[:, 0], segment_xy[:, 1])
        start_arc_m = np.concatenate(([0.0], np.cumsum(segment_length_m)[:-1]))
        self._length_m = float(np.sum(segment_length_m))
        one_loop = np.stack([self._points_xy[:, 0], self._points_xy[:, 1], segment_xy[:, 0],
                             segment_xy[:, 1], 1.0 / segment_length_m ** 2, start_arc_m,
                             segment_length_m])
        self._segment_table = np.concatenate((one_loop, one_loop), axis=1)
        self._segment_table[5, segment_count:] += self._length_m
        self._segment_table.setflags(write=False)
        # Views of the first loop, contiguous per row because nearest() is a hot path.
        self._all_segments = tuple(self._segment_table[:, :segment_count])
        (self._start_x, self._start_y, self._delta_x, self._delta_y, self._inverse_length_sq,
         self._segment_start_arc_m, self._segment_length_m) = self._all_segments
        self._doubled_start_arc_list = self._segment_table[5].tolist()
        self._segment_heading_rad = np.arctan2(self._delta_y, self._delta_x)

    def _set_paint_options(self, dash_length_m, gap_length_m, distractors, lighting_zones,
                           floor_image_rgb, painted_interval_m):
        """
        Validate and keep the options that change only how the floor is painted.

        :param dash_length_m: see :meth:`__init__`.
        :param gap_length_m: see :meth:`__init__`.
        :param distractors: see :meth:`__init__`.
        :param lighting_zones: see :meth:`__init__`.
        :param floor_image_rgb: see :meth:`__init__`.
        :param painted_interval_m: see :meth:`__init__`.
        :raises ValueError: as :meth:`__init__` says.
        :raises TypeError: as :meth:`__init__` says.
        """
        if (dash_length_m is None) != (gap_length_m is None):
            raise ValueError(
                'dash_length_m and gap_length_m must be given together for a dashed line or '
                f'both be None for a solid one, got {dash_length_m!r} and {gap_length_m!r}.')
        self._dash_length_m = self._gap_length_m = None
        if dash_length_m is not None:
            self._dash_length_m = _require_positive('dash_length_m', dash_length_m)
            self._gap_length_m = _require_positive('gap_length_m', gap_length_m)
            if self._dash_length_m + self._gap_length_m > self._length_m:
                raise ValueError(
                    f'a dash and a gap ({self._dash_length_m} m + {self._gap_length_m} m) must '
                    f'fit in the loop, which is {self._length_m:.3f} m long.')
            self._dash_starts_m, self._dash_ends_m = _dash_intervals_m(
                self._dash_length_m, self._gap_length_m, self._length_m)
        self._distractors = self._as_tuple_of('distractors', distractors, Distractor)
        self._lighting_zones = self._as_tuple_of('lighting_zones', lighting_zones, LightingZone)
        self._painted_interval_m = None
        if painted_interval_m is not None:
            self._painted_interval_m = self._as_painted_interval(painted_interval_m)
        self._floor_image_rgb = _as_floor_image(floor_image_rgb)
        if self._floor_image_rgb is not None and not (
                self._dash_length_m is None and self._painted_interval_m is None):
            raise ValueError(
                'a course with floor_image_rgb shows the line the image holds, so it cannot '
                'paint dashes or a line end; leave dash_length_m, gap_length_m and '
                'painted_interval_m None.')

    def _as_painted_interval(self, painted_interval_m):
        """
        Check the arc interval of a line that ends: it holds the start and not the whole loop.

        :param painted_interval_m: ``(begin_m, end_m)`` in metres.
        :return: the interval as a tuple of two floats.
        :raises ValueError: if it is not two finite numbers with
            ``-length < begin_m <= 0 < end_m < begin_m + length``.
        """
        try:
            begin_m, end_m = painted_interval_m
        except (TypeError, ValueError):
            raise ValueError('painted_interval_m must be two arc lengths (begin_m, end_m), '
                             f'got {painted_interval_m!r}.') from None
        begin_m = _require_finite('painted_interval_m begin', begin_m)
        end_m = _require_finite('painted_interval_m end', end_m)
        if not -self._length_m < begin_m <= 0.0 < end_m < begin_m + self._length_m:
            raise ValueError(
                f'painted_interval_m ({begin_m}, {end_m}) must hold the start (begin <= 0 < '
                f'end) and be shorter than the loop, which is {self._length_m:.3f} m long; '
                'None paints all of it.')
        return begin_m, end_m

    @staticmethod
    def _as_tuple_of(name, items, item_class):
        """
        Check that every item of a sequence is of a class.

        :param name: name of the sequence, for the error message.
        :param items: the sequence.
        :param item_class: the class every item must be.
        :return: the items as a tuple.
        :raises TypeError: if an item is of another class.
        """
        items = tuple(items)
        for item in items:
            if not isinstance(item, item_class):
                raise TypeError(f'{name} must hold only {item_class.__name__} objects, got '
                                f'{item!r}.')
        return items

    def __repr__(self):
        """Return a short description of the course."""
        return (f'Course(name={self._name!r}, length_m={self._length_m:.3f}, '
                f'points={len(self._points_xy)})')

    def replace(self, **changes):
        """
        Return a new course like this one with some constructor options changed.

        For example ``course.replace(lighting_zones=zones)`` lights a copy of a course and
        ``course.replace(dash_length_m=None, gap_length_m=None)`` paints its line solid.

        :param changes: constructor arguments by name (``centre_line_xy``, ``line_width_m``,
            ``floor_size_m``, ``name``, ``dash_length_m``, ``gap_length_m``, ``distractors``,
            ``lighting_zones``, ``floor_image_rgb``, ``painted_interval_m``).
        :return: the new course.
        :raises TypeError: if a name is not a constructor argument.
        :raises ValueError: if the new options are invalid, as for the constructor.
        """
        options = {
            'centre_line_xy': self._points_xy, 'line_width_m': self._line_width_m,
            'floor_size_m': self._floor_size_m, 'name': self._name,
            'dash_length_m': self._dash_length_m, 'gap_length_m': self._gap_length_m,
            'distractors': self._distractors, 'lighting_zones': self._lighting_zones,
            'floor_image_rgb': self._floor_image_rgb,
            'painted_interval_m': self._painted_interval_m,
        }
        unknown = sorted(set(changes) - set(options))
        if unknown:
            raise TypeError(f'Course.replace() got unknown options {", ".join(unknown)}; it '
                            f'accepts {", ".join(options)}.')
        options.update(changes)
        return Course(**options)

    @property
    def name(self):
        """Return the name of the course."""
        return self._name

    @property
    def length_m(self):
        """Return the length of the closed centre line in metres."""
        return self._length_m

    @property
    def line_width_m(self):
        """Return the width of the painted line in metres."""
        return self._line_width_m

    @property
    def floor_size_m(self):
        """Return the side of the square floor in metres."""
        return self._floor_size_m

    @property
    def centre_line_xy(self):
        """Return the dense (N, 2) read-only polyline of the centre line, not closed."""
        return self._points_xy

    @property
    def dash_length_m(self):
        """Return the length of a painted dash in metres, None for a solid line."""
        return self._dash_length_m

    @property
    def gap_length_m(self):
        """Return the length of a gap between dashes in metres, None for a solid line."""
        return self._gap_length_m

    @property
    def painted_interval_m(self):
        """Return the arc lengths ``(begin_m, end_m)`` of a line that ends, None for a loop."""
        return self._painted_interval_m

    @property
    def distractors(self):
        """Return the tuple of :class:`Distractor` patches painted beside the line."""
        return self._distractors

    @property
    def lighting_zones(self):
        """Return the tuple of :class:`LightingZone` pools baked into the texture."""
        return self._lighting_zones

    @property
    def floor_image_rgb(self):
        """Return the read-only image shown as the floor, None when the line is painted."""
        return self._floor_image_rgb

    def start_pose(self):
        """
        Return the pose at arc length 0, facing the direction of travel.

        :return: ``(x_m, y_m, yaw_rad)``.
        """
        return self.point_at(0.0)

    def point_at(self, arc_length_m, offset_m=0.0):
        """
        Return the point on the centre line at an arc length from the start, or beside it.

        :param arc_length_m: arc length in metres, taken modulo the course length.
        :param offset_m: distance from the centre line along its normal, positive to the left
            of the direction of travel (as :meth:`signed_offset` measures it), in metres.
        :return: ``(x_m, y_m, heading_rad)``, the heading along the direction of travel.
        """
        points_xy, heading_rad = self._points_at(np.array([arc_length_m], dtype=float))
        heading_rad = float(heading_rad[0])
        return (float(points_xy[0, 0]) - offset_m * math.sin(heading_rad),
                float(points_xy[0, 1]) + offset_m * math.cos(heading_rad), heading_rad)

    def _points_at(self, arc_length_m):
        """
        Interpolate points and headings of the centre line at arc lengths.

        :param arc_length_m: 1-D array of arc lengths in metres, taken modulo the length.
        :return: ``(points_xy, heading_rad)``: an (N, 2) array and an (N,) array.
        """
        arc_m = np.mod(arc_length_m, self._length_m)
        index = np.searchsorted(self._segment_start_arc_m, arc_m, side='right') - 1
        index = np.clip(index, 0, len(self._segment_length_m) - 1)
        fraction = (arc_m - self._segment_start_arc_m[index]) / self._segment_length_m[index]
        points_xy = np.stack([self._start_x[index] + fraction * self._delta_x[index],
                              self._start_y[index] + fraction * self._delta_y[index]], axis=1)
        return points_xy, self._segment_heading_rad[index]

    def _project(self, x_m, y_m, segments):
        """
        Find the nearest point of some segments of the centre line to a position.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :param segments: rows of a slice of the segment table (see
            :meth:`_build_segment_table`).
        :return: ``(distance_m, arc_length_m, cross)`` where ``cross`` is positive when the
            position is left of the nearest segment.
        """
        start_x, start_y, delta_x, delta_y, inverse_length_sq, start_arc_m, length_m = segments
        from_start_x = x_m - start_x
        from_start_y = y_m - start_y
        fraction = (from_start_x * delta_x + from_start_y * delta_y)
        fraction *= inverse_length_sq
        # Two in-place ufuncs cost less than np.clip on the short arrays of a window.
        np.maximum(fraction, 0.0, out=fraction)
        np.minimum(fraction, 1.0, out=fraction)
        offset_x = from_start_x - fraction * delta_x
        offset_y = from_start_y - fraction * delta_y
        distance_sq = offset_x * offset_x + offset_y * offset_y
        index = int(np.argmin(distance_sq))
        arc_m = (start_arc_m[index] + fraction[index] * length_m[index]) % self._length_m
        cross = delta_x[index] * from_start_y[index] - delta_y[index] * from_start_x[index]
        return math.sqrt(distance_sq[index]), float(arc_m), float(cross)

    def nearest(self, x_m, y_m):
        """
        Find the distance from a position to the centre line and where the nearest point is.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :return: ``(distance_m, arc_length_m)``: the exact distance to the polyline and the arc
            length of its nearest point, in [0, length).
        """
        distance_m, arc_m, _ = self._project(x_m, y_m, self._all_segments)
        return distance_m, arc_m

    def nearest_near(self, x_m, y_m, arc_hint_m, window_m):
        """
        Find the nearest point to a position among the centre line near an arc length.

        Searches only the part of the line within ``window_m`` of arc length either side of
        ``arc_hint_m`` (whole segments, so up to one segment more), which keeps following one
        branch where the line crosses itself or passes close by. Costs less than
        :meth:`nearest` for windows shorter than the loop.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :param arc_hint_m: arc length around which to search, in metres (any real number).
        :param window_m: half the arc length searched, in metres; a window reaching round the
            whole loop searches all of it.
        :return: ``(distance_m, arc_length_m)``: the distance to that part of the line and the
            arc length of its nearest point, in [0, length).
        :raises ValueError: if ``window_m`` is not positive.
        """
        if not window_m > 0.0:
            raise ValueError(f'window_m must be positive, got {window_m}.')
        segment_count = len(self._segment_length_m)
        if 2.0 * window_m >= self._length_m:
            return self.nearest(x_m, y_m)
        low_arc_m = (arc_hint_m - window_m) % self._length_m
        # bisect on a list: a tenth of the cost of np.searchsorted for one value.
        first = max(bisect.bisect_right(self._doubled_start_arc_list, low_arc_m) - 1, 0)
        stop = bisect.bisect_right(self._doubled_start_arc_list, low_arc_m + 2.0 * window_m,
                                   lo=first)
        stop = min(stop, first + segment_count)
        distance_m, arc_m, _ = self._project(x_m, y_m, tuple(self._segment_table[:, first:stop]))
        return distance_m, arc_m

    def signed_offset(self, x_m, y_m):
        """
        Find the signed offset of a position from the centre line.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :return: ``(offset_m, arc_length_m)``: the distance to the centre line, positive left of
            the direction of travel, and the arc length of the nearest point, in [0, length).
        """
        distance_m, arc_m, cross = self._project(x_m, y_m, self._all_segments)
        return math.copysign(distance_m, cross), arc_m

    def min_radius_of_curvature_m(self):
        """
        Estimate the tightest bend of the centre line.

        Fits a circle through the points ``CURVATURE_BASELINE_M`` behind and ahead of every
        vertex, which smooths the kinks of a subdivided coarse polyline; a right-angle corner reads
        as ``CURVATURE_BASELINE_M / sqrt(2)``.

        :return: the smallest radius of curvature in metres (``inf`` for no bend).
        """
        vertex_arc_m = self._segment_start_arc_m
        behind_xy, _ = self._points_at(vertex_arc_m - CURVATURE_BASELINE_M)
        ahead_xy, _ = self._points_at(vertex_arc_m + CURVATURE_BASELINE_M)
        to_vertex_xy = self._points_xy - behind_xy
        to_ahead_xy = ahead_xy - behind_xy
        product_of_sides_m3 = (np.linalg.norm(to_vertex_xy, axis=1)
                               * np.linalg.norm(ahead_xy - self._points_xy, axis=1)
                               * np.linalg.norm(to_ahead_xy, axis=1))
        double_area_m2 = np.abs(to_vertex_xy[:, 0] * to_ahead_xy[:, 1]
                                - to_vertex_xy[:, 1] * to_ahead_xy[:, 0])
        with np.errstate(divide='ignore'):
            # Circumradius of a triangle: abc / (4 area).
            radius_m = product_of_sides_m3 / (2.0 * double_area_m2)
        return float(np.min(radius_m))

    def dash_signed_distance_m(self, arc_length_m):
        """
        Measure how far arc lengths are inside the paint along the line.

        The paint is the dashes of a dashed line, cut to the painted interval of a line that
        ends.

        :param arc_length_m: arc length(s) in metres, taken modulo the course length.
        :return: the distance along the line to the nearest end of a dash (or of the painted
            interval), positive on paint and negative in a gap, as a float array shaped like the
            input; ``inf`` everywhere for a solid loop.
        """
        arc_m = np.mod(np.asarray(arc_length_m, dtype=float), self._length_m)
        if self._painted_interval_m is None:
            return self._dash_only_signed_distance_m(arc_m)
        begin_m, end_m = self._painted_interval_m
        # Arc from the beginning of the paint: paint on [0, painted), bare floor after it.
        from_begin_m = np.mod(arc_m - begin_m, self._length_m)
        painted_m = end_m - begin_m
        on_paint_m = np.minimum(from_begin_m, painted_m - from_begin_m)
        off_paint_m = np.minimum(from_begin_m - painted_m, self._length_m - from_begin_m)
        paint_m = np.where(from_begin_m < painted_m, on_paint_m, -off_paint_m)
        return np.minimum(paint_m, self._dash_only_signed_distance_m(arc_m))

    def _dash_only_signed_distance_m(self, arc_m):
        """
        Measure how far arc lengths are inside a painted dash, ignoring the painted interval.

        :param arc_m: array of arc lengths in [0, length) metres.
        :return: as :meth:`dash_signed_distance_m` for the dashes alone.
        """
        if self._dash_length_m is None:
            return np.full(arc_m.shape, np.inf)
        index = np.searchsorted(self._dash_starts_m, arc_m, side='right') - 1
        start_m = self._dash_starts_m[index]
        end_m = self._dash_ends_m[index]
        next_starts_m = np.append(self._dash_starts_m[1:], self._dash_starts_m[0] + self._length_m)
        on_dash_m = np.minimum(arc_m - start_m, end_m - arc_m)
        in_gap_m = np.minimum(arc_m - end_m, next_starts_m[index] - arc_m)
        return np.where(arc_m < end_m, on_dash_m, -in_gap_m)

    def world_to_texture_px(self, x_m, y_m, size_px):
        """
        Convert world coordinates to continuous pixel coordinates of this course's texture.

        :param x_m: east coordinate(s) in metres.
        :param y_m: north coordinate(s) in metres.
        :param size_px: side of the square texture in pixels.
        :return: ``(col, row)`` floats, pixel centres at integers, row 0 at the north edge.
        """
        return world_to_texture_px(x_m, y_m, size_px, self._floor_size_m)

    def draw_texture(self, size_px):
        """
        Draw the whole floor: the anti-aliased line on a grey background, or the floor image.

        Each pixel is painted by the share of a one-pixel box around its centre that lies
        within half the line width of the exact centre line (and, for a dashed line, within
        a dash along it), so the line's width and position hold to a small fraction of a pixel
        at any resolution. A course with ``floor_image_rgb`` shows that image resized instead
        (``cv2.INTER_AREA`` when shrinking, ``cv2.INTER_LINEAR`` otherwise). Distractors are
        then painted in the line's colour, anti-aliased alike, and the lighting zones scale
        every colour.

        :param size_px: side of the square image in pixels.
        :return: an RGB uint8 image of shape (size_px, size_px, 3), row 0 at the north edge,
            column 0 at the west edge.
        :raises ValueError: if ``size_px`` is not a positive integer.
        """
        if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) \
                or size_px < 1:
            raise ValueError(f'size_px must be a positive integer, got {size_px!r}.')
        size_px = int(size_px)
        if self._floor_image_rgb is None:
            image_rgb = np.full((size_px, size_px, _RGB_CHANNELS), FLOOR_GREY, dtype=np.uint8)
            coverage = self._line_coverage(size_px)
        else:
            image_rgb = _resized_image(self._floor_image_rgb, size_px)
            coverage = np.zeros((size_px, size_px), dtype=np.float32)
        for distractor in self._distractors:
            _add_rectangle_coverage(coverage, distractor, self._floor_size_m)
        _paint_line_colour(image_rgb, coverage)
        if self._lighting_zones:
            _apply_lighting(image_rgb, self._lighting_zones, self._floor_size_m)
        return image_rgb

    def _line_coverage(self, size_px):
        """
        Compute the share of each pixel that the painted line covers.

        :param size_px: side of the square texture in pixels.
        :return: a float32 (size_px, size_px) array of shares in [0, 1].
        """
        col, row = self.world_to_texture_px(
            self._points_xy[:, 0], self._points_xy[:, 1], size_px)
        px_per_m = size_px / self._floor_size_m
        half_width_px = self._line_width_m * px_per_m / 2.0
        reach_px = half_width_px + _ANTI_ALIAS_HALF_PX
        along_coverage = None
        if self._dash_length_m is not None or self._painted_interval_m is not None:
            along_coverage = functools.partial(self._dash_share, px_per_m=px_per_m)
        return _closed_polyline_coverage(
            np.stack([col, row], axis=1), size_px, reach_px, along_coverage)

    def _dash_share(self, segment_index, fraction, px_per_m):
        """
        Compute the share of pixels that the dashes (or the line that ends) cover along it.

        :param segment_index: integer array of the segments of the pixels' nearest points.
        :param fraction: float array of the nearest points' fractions along those segments.
        :param px_per_m: texture pixels per metre.
        :return: a float32 array of shares in [0, 1], shaped like the inputs.
        """
        arc_m = (self._segment_start_arc_m[segment_index]
                 + fraction * self._segment_length_m[segment_index])
        inside_px = self.dash_signed_distance_m(arc_m) * px_per_m
        return np.clip(inside_px + _ANTI_ALIAS_HALF_PX, 0.0, 1.0).astype(np.float32)


def _closed_polyline_coverage(points_px, size_px, reach_px, along_coverage=None):
    """
    Compute the share of each pixel that a closed polyline painted ``reach_px`` - 0.5 wide covers.

    Works through runs of consecutive segments, each against the pixels of its bounding box
    grown by ``reach_px``; within a run a pixel takes the exact distance to its nearest
    segment, and the share across the line is ``reach_px`` minus that distance, clipped to
    [0, 1]. Runs are combined by their largest share, so where the line crosses itself
    either branch paints.

    :param points_px: (N, 2) vertices as (col, row) pixel coordinates, pixel centres at
        integers, last vertex not repeated.
    :param size_px: side of the square image in pixels.
    :param reach_px: half the line width plus the anti-aliasing margin, in pixels.
    :param along_coverage: None for a solid line, or a function of integer arrays of segment
        indices and float arrays of fractions along those segments (each pixel's foot on the
        line of its nearest segment, the fraction unclamped) returning the share painted along
        the line there, as for dashes.
    :return: a float32 (size_px, size_px) array of shares in [0, 1].
    """
    starts_px = points_px.astype(np.float32)
    deltas_px = (np.roll(points_px, -1, axis=0) - points_px).astype(np.float32)
    length_sq_px2 = np.einsum('ij,ij->i', deltas_px, deltas_px)
    inverse_length_sq = 1.0 / length_sq_px2
    mean_segment_px = float(np.mean(np.sqrt(length_sq_px2)))
    run_segments = max(1, int(_DISTANCE_RUN_REACHES * reach_px / mean_segment_px))
    coverage = np.zeros((size_px, size_px), dtype=np.float32)
    for first in range(0, len(starts_px), run_segments):
        run = slice(first, first + run_segments)
        run_starts_px = starts_px[run]
        run_ends_px = run_starts_px + deltas_px[run]
        low_col, low_row = np.floor(
            np.minimum(run_starts_px.min(axis=0), run_ends_px.min(axis=0)) - reach_px)
        high_col, high_row = np.ceil(
            np.maximum(run_starts_px.max(axis=0), run_ends_px.max(axis=0)) + reach_px)
        col_begin, row_begin = max(int(low_col), 0), max(int(low_row), 0)
        col_end, row_end = min(int(high_col) + 1, size_px), min(int(high_row) + 1, size_px)
        if col_begin >= col_end or row_begin >= row_end:
            continue
        # Axes: (row, col, segment); the x and y parts are separable, so build them per axis.
        from_start_x = (np.arange(col_begin, col_end, dtype=np.float32)[:, np.newaxis]
                        - run_starts_px[:, 0])
        from_start_y = (np.arange(row_begin, row_end, dtype=np.float32)[:, np.newaxis]
                        - run_starts_px[:, 1])
        dot = (from_start_y[:, np.newaxis, :] * deltas_px[run, 1]
               + (from_start_x * deltas_px[run, 0])[np.newaxis])
        fraction = np.clip(dot * inverse_length_sq[run], 0.0, 1.0)
        # |p - a - f d|^2 = |p - a|^2 - f (2 (p - a).d - f |d|^2)
        run_distance_sq_px2 = ((from_start_y * from_start_y)[:, np.newaxis, :]
                               + (from_start_x * from_start_x)[np.newaxis]
                               - fraction * (2.0 * dot - fraction * length_sq_px2[run]))
        if along_coverage is None:
            nearest_distance_sq_px2 = run_distance_sq_px2.min(axis=2)
        else:
            nearest = run_distance_sq_px2.argmin(axis=2)[..., np.newaxis]
            nearest_distance_sq_px2 = np.take_along_axis(run_distance_sq_px2, nearest, 2)[..., 0]
            # Unclamped, so that pixels beyond the run's ends, which the neighbouring runs
            # paint too, are placed along the line there instead of at the run's end.
            nearest_fraction = (np.take_along_axis(dot, nearest, 2)[..., 0]
                                * inverse_length_sq[run][nearest[..., 0]])
        run_coverage = np.clip(
            reach_px - np.sqrt(np.maximum(nearest_distance_sq_px2, 0.0)), 0.0, 1.0)
        if along_coverage is not None:
            run_coverage *= along_coverage(first + nearest[..., 0], nearest_fraction)
        window = coverage[row_begin:row_end, col_begin:col_end]
        np.maximum(window, run_coverage, out=window)
    return coverage


def _pixel_centres_m(first_px, stop_px, size_px, floor_size_m):
    """
    Return the east coordinates of texture columns' centres (negated: north of rows' centres).

    :param first_px: first column (or row).
    :param stop_px: column (or row) after the last.
    :param size_px: side of the square texture in pixels.
    :param floor_size_m: side of the square floor in metres.
    :return: a float array of metres.
    """
    m_per_px = floor_size_m / size_px
    return (np.arange(first_px, stop_px) + 0.5) * m_per_px - floor_size_m / 2.0


def _pixel_box(x_m, y_m, half_x_m, half_y_m, size_px, floor_size_m):
    """
    Find the texture pixels whose centres may lie within a world-aligned box.

    :param x_m: east coordinate of the box centre in metres.
    :param y_m: north coordinate of the box centre in metres.
    :param half_x_m: half the box's east-west size in metres.
    :param half_y_m: half the box's north-south size in metres.
    :param size_px: side of the square texture in pixels.
    :param floor_size_m: side of the square floor in metres.
    :return: ``(row_begin, row_end, col_begin, col_end)``, clipped to the image (possibly
        empty).
    """
    col_low, row_low = world_to_texture_px(x_m - half_x_m, y_m + half_y_m, size_px,
                                           floor_size_m)
    col_high, row_high = world_to_texture_px(x_m + half_x_m, y_m - half_y_m, size_px,
                                             floor_size_m)
    col_begin = min(max(int(math.floor(col_low)), 0), size_px)
    row_begin = min(max(int(math.floor(row_low)), 0), size_px)
    col_end = max(min(int(math.ceil(col_high)) + 1, size_px), col_begin)
    row_end = max(min(int(math.ceil(row_high)) + 1, size_px), row_begin)
    return row_begin, row_end, col_begin, col_end


def _add_rectangle_coverage(coverage, distractor, floor_size_m):
    """
    Paint a distractor rectangle into a coverage map, anti-aliased like the line.

    :param coverage: float32 (size, size) shares of pixels painted, updated in place by
        taking the larger share.
    :param distractor: the :class:`Distractor`.
    :param floor_size_m: side of the square floor in metres.
    """
    size_px = coverage.shape[0]
    px_per_m = size_px / floor_size_m
    cos_yaw, sin_yaw = math.cos(distractor.yaw_rad), math.sin(distractor.yaw_rad)
    half_length_m, half_width_m = distractor.length_m / 2.0, distractor.width_m / 2.0
    margin_m = _ANTI_ALIAS_HALF_PX / px_per_m
    row_begin, row_end, col_begin, col_end = _pixel_box(
        distractor.x_m, distractor.y_m,
        half_length_m * abs(cos_yaw) + half_width_m * abs(sin_yaw) + margin_m,
        half_length_m * abs(sin_yaw) + half_width_m * abs(cos_yaw) + margin_m,
        size_px, floor_size_m)
    if row_begin == row_end or col_begin == col_end:
        return
    east_m = _pixel_centres_m(col_begin, col_end, size_px, floor_size_m) - distractor.x_m
    north_m = (-_pixel_centres_m(row_begin, row_end, size_px, floor_size_m)[:, np.newaxis]
               - distractor.y_m)
    along_m = cos_yaw * east_m + sin_yaw * north_m
    across_m = cos_yaw * north_m - sin_yaw * east_m
    # Signed distance to the rectangle's edge, negative inside.
    beyond_length_m = np.abs(along_m) - half_length_m
    beyond_width_m = np.abs(across_m) - half_width_m
    outside_m = np.hypot(np.maximum(beyond_length_m, 0.0), np.maximum(beyond_width_m, 0.0))
    signed_m = outside_m + np.minimum(np.maximum(beyond_length_m, beyond_width_m), 0.0)
    share = np.clip(_ANTI_ALIAS_HALF_PX - signed_m * px_per_m, 0.0, 1.0).astype(np.float32)
    window = coverage[row_begin:row_end, col_begin:col_end]
    np.maximum(window, share, out=window)


def _paint_line_colour(image_rgb, coverage):
    """
    Blend the line's colour into an image by a coverage map.

    :param image_rgb: uint8 (size, size, 3) image, painted in place.
    :param coverage: float32 (size, size) shares in [0, 1].
    """
    rows, cols = np.nonzero(coverage)
    share = coverage[rows, cols][:, np.newaxis]
    under_rgb = image_rgb[rows, cols].astype(np.float32)
    line_minus_under = np.array(LINE_RGB, dtype=np.float32) - under_rgb
    image_rgb[rows, cols] = np.round(under_rgb + share * line_minus_under)


def _apply_lighting(image_rgb, lighting_zones, floor_size_m):
    """
    Scale the colours of an image by the gains of pools of light.

    :param image_rgb: uint8 (size, size, 3) floor image, scaled in place, saturating at 255.
    :param lighting_zones: the :class:`LightingZone` pools.
    :param floor_size_m: side of the square floor in metres.
    """
    size_px = image_rgb.shape[0]
    half_ramp_m = LIGHTING_EDGE_RAMP_M / 2.0
    boxes = [_pixel_box(zone.x_m, zone.y_m, zone.radius_m + half_ramp_m,
                        zone.radius_m + half_ramp_m, size_px, floor_size_m)
             for zone in lighting_zones]
    row_begin, col_begin = min(box[0] for box in boxes), min(box[2] for box in boxes)
    row_end, col_end = max(box[1] for box in boxes), max(box[3] for box in boxes)
    if row_begin >= row_end or col_begin >= col_end:
        return
    gain = np.ones((row_end - row_begin, col_end - col_begin), dtype=np.float32)
    for zone, (zone_row_begin, zone_row_end, zone_col_begin, zone_col_end) in zip(
            lighting_zones, boxes):
        if zone_row_begin == zone_row_end or zone_col_begin == zone_col_end:
            continue
        east_m = _pixel_centres_m(zone_col_begin, zone_col_end, size_px, floor_size_m)
        north_m = -_pixel_centres_m(zone_row_begin, zone_row_end, size_px, floor_size_m)
        distance_m = np.hypot(east_m - zone.x_m, north_m[:, np.newaxis] - zone.y_m)
        ramp = np.clip((zone.radius_m + half_ramp_m - distance_m) / LIGHTING_EDGE_RAMP_M,
                       0.0, 1.0)
        weight = ramp * ramp * (3.0 - 2.0 * ramp)  # smoothstep: no kink at either end
        gain[zone_row_begin - row_begin:zone_row_end - row_begin,
             zone_col_begin - col_begin:zone_col_end - col_begin] *= (
            1.0 + weight * (zone.gain - 1.0)).astype(np.float32)
    region_rgb = image_rgb[row_begin:row_end, col_begin:col_end]
    scaled_rgb = np.rint(region_rgb * gain[..., np.newaxis])
    region_rgb[...] = np.minimum(scaled_rgb, _MAX_CHANNEL_VALUE)


def _resized_image(image_rgb, size_px):
    """
    Resize an RGB image to a square texture.

    :param image_rgb: (H, W, 3) uint8 image.
    :param size_px: side of the square result in pixels.
    :return: a new, writable (size_px, size_px, 3) uint8 image.
    """
    height_px, width_px = image_rgb.shape[:2]
    if (height_px, width_px) == (size_px, size_px):
        return image_rgb.copy()
    shrinking = size_px <= min(height_px, width_px)
    interpolation = cv2.INTER_AREA if shrinking else cv2.INTER_LINEAR
    return cv2.resize(np.ascontiguousarray(image_rgb), (size_px, size_px),
                      interpolation=interpolation)


def make_course(name):
    """
    Build a built-in course by name.

    :param name: a key of :data:`followbot_sim.course_library.COURSES`.
    :return: the course.
    :raises ValueError: if no course has that name.
    """
    # Imported here: the library builds its courses from this module.
    from followbot_sim.course_library import COURSES
    try:
        factory = COURSES[name]
    except (KeyError, TypeError):
        raise ValueError(
            f'unknown course {name!r}; known courses: {", ".join(sorted(COURSES))}.') from None
    return factory()


def __getattr__(name):
    """
    Return a name that moved to :mod:`followbot_sim.course_library` (``COURSES``, ``book_loop``).

    :param name: the attribute looked up.
    :return: the library's object of that name.
    :raises AttributeError: for any other name.
    """
    if name in _LIBRARY_NAMES:
        from followbot_sim import course_library
        return getattr(course_library, name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


class LapTracker:
    """
    Score a run against the course from the robot's true positions.

    Progress is the signed distance travelled along the centre line since the first update:
    it follows the robot's point on the line around the loop across the start, and driving
    backwards reduces it. Lap k completes when progress first reaches k course lengths, so
    reversing across a lap boundary and driving on does not count it twice.

    The robot's point on the line is followed continuously: each update searches the line
    within ``max_arc_step_m`` of arc length of the previous point, so where the line crosses
    itself or runs close by the tracker stays on the branch being driven. Only when the line
    elsewhere is nearer than that part by more than a line width (the robot cut across, or was
    moved) does the point hop there: that counts as an arc jump and adds no progress, so short
    cuts earn no laps.
    """

    def __init__(self, course, max_arc_step_m=DEFAULT_MAX_ARC_STEP_M):
        """
        Start a tracker with no updates.

        :param course: the course being driven.
        :param max_arc_step_m: largest motion along the line between updates, in metres: half
            the arc window searched around the previous point.
        :raises ValueError: if ``max_arc_step_m`` is not positive.
        """
        if not max_arc_step_m > 0.0:
            raise ValueError(f'max_arc_step_m must be positive, got {max_arc_step_m}.')
        self._course = course
        self._max_arc_step_m = float(max_arc_step_m)
        self._half_line_width_m = course.line_width_m / 2.0
        # Nearer by more than a line width: the robot is on another part of the line.
        self._jump_margin_m = course.line_width_m
        self.reset()

    def reset(self):
        """Forget all updates."""
        self._updates = 0
        self._start_time_s = 0.0
        self._time_s = 0.0
        self._distance_m = 0.0
        self._max_distance_m = 0.0
        self._sum_distance_sq_m2 = 0.0
        self._previous_arc_m = 0.0
        self._progress_m = 0.0
        self._laps_completed = 0
        self._lap_start_time_s = 0.0
        self._lap_times_s = []
        self._time_off_line_s = 0.0
        self._arc_jumps = 0

    def update(self, x_m, y_m, time_s):
        """
        Add the robot's true position at a time.

        The distance from the line is measured to the branch being followed, the one the
        robot's progress counts along.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :param time_s: time in seconds, not earlier than the previous update's.
        :raises ValueError: if a value is not finite or time runs backwards.
        """
        if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(time_s)):
            raise ValueError(f'position and time must be finite, got ({x_m}, {y_m}, {time_s}).')
        if self._updates == 0:
            distance_m, arc_m = self._course.nearest(x_m, y_m)
            self._start_time_s = time_s
            self._lap_start_time_s = time_s
        else:
            if time_s < self._time_s:
                raise ValueError(
                    f'time ran backwards from {self._time_s} s to {time_s} s; call reset() '
                    'to start a new run.')
            # The previous sample's state holds until this one.
            if self._distance_m > self._half_line_width_m:
                self._time_off_line_s += time_s - self._time_s
            distance_m, arc_m = self._course.nearest_near(
                x_m, y_m, self._previous_arc_m, self._max_arc_step_m)
            jumped = False
            # The global search can only be nearer by the margin when this part is that far.
            if distance_m > self._jump_margin_m:
                global_distance_m, global_arc_m = self._course.nearest(x_m, y_m)
                if distance_m - global_distance_m > self._jump_margin_m:
                    distance_m, arc_m, jumped = global_distance_m, global_arc_m, True
            if jumped:
                self._arc_jumps += 1
            else:
                self._advance(_wrap_to_half_length(arc_m - self._previous_arc_m,
                                                   self._course.length_m), time_s)
        self._updates += 1
        self._time_s = time_s
        self._previous_arc_m = arc_m
        self._distance_m = distance_m
        self._max_distance_m = max(self._max_distance_m, distance_m)
        self._sum_distance_sq_m2 += distance_m * distance_m

    def _advance(self, arc_step_m, time_s):
        """
        Add progress along the line and record the laps it completes.

        :param arc_step_m: progress since the previous update in metres.
        :param time_s: time of this update in seconds.
        """
        previous_progress_m = self._progress_m
        self._progress_m += arc_step_m
        length_m = self._course.length_m
        # Progress below the next lap mark before this step, so a crossing means arc_step_m > 0.
        while self._progress_m >= (self._laps_completed + 1) * length_m:
            lap_mark_m = (self._laps_completed + 1) * length_m
            fraction = (lap_mark_m - previous_progress_m) / arc_step_m
            crossing_time_s = self._time_s + fraction * (time_s - self._time_s)
            self._lap_times_s.append(crossing_time_s - self._lap_start_time_s)
            self._lap_start_time_s = crossing_time_s
            self._laps_completed += 1

    @property
    def course(self):
        """Return the course being scored."""
        return self._course

    @property
    def updates(self):
        """Return the count of updates since the start or the last reset."""
        return self._updates

    @property
    def time_s(self):
        """Return the time of the latest update in seconds."""
        return self._time_s

    @property
    def elapsed_s(self):
        """Return the time from the first update to the latest in seconds."""
        return self._time_s - self._start_time_s

    @property
    def distance_from_line_m(self):
        """Return the latest distance from the centre line in metres."""
        return self._distance_m

    @property
    def max_distance_from_line_m(self):
        """Return the largest distance from the centre line so far in metres."""
        return self._max_distance_m

    @property
    def rms_distance_from_line_m(self):
        """Return the RMS distance from the centre line over the updates in metres."""
        if self._updates == 0:
            return 0.0
        return math.sqrt(self._sum_distance_sq_m2 / self._updates)

    @property
    def progress_m(self):
        """Return the signed distance travelled along the line since the first update in metres."""
        return self._progress_m

    @property
    def laps_completed(self):
        """Return the count of full laps driven."""
        return self._laps_completed

    @property
    def lap_times_s(self):
        """Return the duration of each completed lap in seconds (a copy)."""
        return list(self._lap_times_s)

    @property
    def time_off_line_s(self):
        """Return the time spent farther than half the line width from the line in seconds."""
        return self._time_off_line_s

    @property
    def arc_jumps(self):
        """Return the count of updates whose point on the line hopped to another part."""
        return self._arc_jumps

    def summary(self):
        """
        Collect the figures of the run.

        :return: a JSON-serialisable dict of plain floats, ints, strings and lists.
        """
        return {
            'course': self._course.name,
            'course_length_m': float(self._course.length_m),
            'updates': int(self._updates),
            'time_s': float(self._time_s),
            'elapsed_s': float(self.elapsed_s),
            'distance_from_line_m': float(self._distance_m),
            'max_distance_from_line_m': float(self._max_distance_m),
            'rms_distance_from_line_m': float(self.rms_distance_from_line_m),
            'progress_m': float(self._progress_m),
            'laps_completed': int(self._laps_completed),
            'lap_times_s': [float(lap_s) for lap_s in self._lap_times_s],
            'time_off_line_s': float(self._time_off_line_s),
            'arc_jumps': int(self._arc_jumps),
        }
