"""
Line-following course: centre-line geometry, floor texture and ground-truth lap scoring.

A pure NumPy module (no ROS, no MuJoCo) so that the simulator, the scorer and the tests share
one description of the course.

World frame: the floor is a square centred at the origin, x east, y north, metres. The floor
texture follows MuJoCo's convention for a 2-D texture stretched once over a plane
(``texrepeat="1 1"``): image row 0 is the north (+y) edge and column 0 the west (-x) edge.
"""

import math

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
# centre lies on the line, so paint reaches half a pixel beyond the line's edge.
_ANTI_ALIAS_HALF_PX = 0.5
# The texture's distance field is computed in runs of segments spanning about this many reaches
# (half line widths plus the anti-aliasing margin): fastest when measured at 1024-4096 px.
_DISTANCE_RUN_REACHES = 2.0

# book_loop: an egg whose long axis runs north-south, narrow end north, tilted a little, with a
# third-harmonic wobble so that its sides bend with different radii, like the book's course.
# x(t) = a cos t (1 - taper sin t) + c3 cos 3t + s3 sin 3t, y(t) = b sin t, then rotated.
_BOOK_LOOP_SEMI_AXIS_X_M = 2.45
_BOOK_LOOP_SEMI_AXIS_Y_M = 4.25
_BOOK_LOOP_EGG_TAPER = 0.10
_BOOK_LOOP_WOBBLE_COS3_M = 0.03
_BOOK_LOOP_WOBBLE_SIN3_M = 0.04
_BOOK_LOOP_TILT_RAD = math.radians(-7.0)
# Parameter samples used to measure the curve before resampling it evenly by arc length.
_BOOK_LOOP_MEASURE_SAMPLES = 1 << 16

# Between two scorer updates the robot moves centimetres; a larger change of the nearest arc
# length means the nearest point hopped to another part of the course.
DEFAULT_MAX_ARC_STEP_M = 1.0


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


class Course:
    """
    A closed centre line painted on a square floor.

    Arc length runs along the polyline from its first point (the start) in the order the
    points were given, which is the direction of travel.
    """

    def __init__(self, centre_line_xy, line_width_m=BOOK_LINE_WIDTH_M,
                 floor_size_m=BOOK_FLOOR_SIZE_M, name='custom'):
        """
        Build a course from the points of its closed centre line.

        :param centre_line_xy: (N, 2) points in metres of a closed loop, last point not
            repeated (a repeated closing point is dropped); polylines coarser than
            ``MAX_POINT_SPACING_M`` are subdivided.
        :param line_width_m: width of the painted line in metres.
        :param floor_size_m: side of the square floor, centred at the origin, in metres.
        :param name: name of the course.
        :raises ValueError: if the points are not a finite loop of at least three distinct
            points, a size is not positive, or the line leaves the floor.
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

        # Per-segment arrays, kept separate and contiguous because nearest() is a hot path.
        segment_xy = np.roll(self._points_xy, -1, axis=0) - self._points_xy
        self._start_x = np.ascontiguousarray(self._points_xy[:, 0])
        self._start_y = np.ascontiguousarray(self._points_xy[:, 1])
        self._delta_x = np.ascontiguousarray(segment_xy[:, 0])
        self._delta_y = np.ascontiguousarray(segment_xy[:, 1])
        self._segment_length_m = np.hypot(self._delta_x, self._delta_y)
        self._inverse_length_sq = 1.0 / self._segment_length_m ** 2
        self._segment_heading_rad = np.arctan2(self._delta_y, self._delta_x)
        self._segment_start_arc_m = np.concatenate(([0.0], np.cumsum(self._segment_length_m)[:-1]))
        self._length_m = float(np.sum(self._segment_length_m))

    def __repr__(self):
        """Return a short description of the course."""
        return (f'Course(name={self._name!r}, length_m={self._length_m:.3f}, '
                f'points={len(self._points_xy)})')

    @property
    def name(self):
        """Name of the course."""
        return self._name

    @property
    def length_m(self):
        """Length of the closed centre line in metres."""
        return self._length_m

    @property
    def line_width_m(self):
        """Width of the painted line in metres."""
        return self._line_width_m

    @property
    def floor_size_m(self):
        """Side of the square floor in metres."""
        return self._floor_size_m

    @property
    def centre_line_xy(self):
        """Dense (N, 2) read-only polyline of the centre line, last point not repeated."""
        return self._points_xy

    def start_pose(self):
        """
        Return the pose at arc length 0, facing the direction of travel.

        :return: ``(x_m, y_m, yaw_rad)``.
        """
        return self.point_at(0.0)

    def point_at(self, arc_length_m):
        """
        Return the point on the centre line at an arc length from the start.

        :param arc_length_m: arc length in metres, taken modulo the course length.
        :return: ``(x_m, y_m, heading_rad)``, the heading along the direction of travel.
        """
        points_xy, heading_rad = self._points_at(np.array([arc_length_m], dtype=float))
        return float(points_xy[0, 0]), float(points_xy[0, 1]), float(heading_rad[0])

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

    def _project(self, x_m, y_m):
        """
        Find the nearest point of the centre line to a position.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :return: ``(distance_m, arc_length_m, cross)`` where ``cross`` is positive when the
            position is left of the nearest segment.
        """
        from_start_x = x_m - self._start_x
        from_start_y = y_m - self._start_y
        fraction = (from_start_x * self._delta_x + from_start_y * self._delta_y)
        fraction *= self._inverse_length_sq
        np.clip(fraction, 0.0, 1.0, out=fraction)
        offset_x = from_start_x - fraction * self._delta_x
        offset_y = from_start_y - fraction * self._delta_y
        distance_sq = offset_x * offset_x + offset_y * offset_y
        index = int(np.argmin(distance_sq))
        arc_m = (self._segment_start_arc_m[index]
                 + fraction[index] * self._segment_length_m[index]) % self._length_m
        cross = (self._delta_x[index] * from_start_y[index]
                 - self._delta_y[index] * from_start_x[index])
        return math.sqrt(distance_sq[index]), float(arc_m), float(cross)

    def nearest(self, x_m, y_m):
        """
        Find the distance from a position to the centre line and where the nearest point is.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :return: ``(distance_m, arc_length_m)``: the exact distance to the polyline and the arc
            length of its nearest point, in [0, length).
        """
        distance_m, arc_m, _ = self._project(x_m, y_m)
        return distance_m, arc_m

    def signed_offset(self, x_m, y_m):
        """
        Find the signed offset of a position from the centre line.

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :return: ``(offset_m, arc_length_m)``: the distance to the centre line, positive left of
            the direction of travel, and the arc length of the nearest point, in [0, length).
        """
        distance_m, arc_m, cross = self._project(x_m, y_m)
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
        Draw the whole floor: the anti-aliased line on a grey background.

        Each pixel is painted by the share of a one-pixel box around its centre that lies
        within half the line width of the exact centre line, so the line's width and position
        hold to a small fraction of a pixel at any resolution.

        :param size_px: side of the square image in pixels.
        :return: an RGB uint8 image of shape (size_px, size_px, 3), row 0 at the north edge,
            column 0 at the west edge.
        :raises ValueError: if ``size_px`` is not a positive integer.
        """
        if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) \
                or size_px < 1:
            raise ValueError(f'size_px must be a positive integer, got {size_px!r}.')
        size_px = int(size_px)
        col, row = self.world_to_texture_px(
            self._points_xy[:, 0], self._points_xy[:, 1], size_px)
        half_width_px = self._line_width_m * size_px / self._floor_size_m / 2.0
        reach_px = half_width_px + _ANTI_ALIAS_HALF_PX
        distance_px = _closed_polyline_distance_px(
            np.stack([col, row], axis=1), size_px, reach_px)
        image_rgb = np.full((size_px, size_px, 3), FLOOR_GREY, dtype=np.uint8)
        rows, cols = np.nonzero(distance_px < reach_px)
        coverage = np.clip(reach_px - distance_px[rows, cols], 0.0, 1.0)[:, np.newaxis]
        line_minus_floor = np.array(LINE_RGB, dtype=np.float32) - FLOOR_GREY
        image_rgb[rows, cols] = np.round(FLOOR_GREY + coverage * line_minus_floor)
        return image_rgb


def _closed_polyline_distance_px(points_px, size_px, reach_px):
    """
    Compute each pixel centre's distance to a closed polyline, exactly near the line.

    Works through runs of consecutive segments, each against the pixels of its bounding box
    grown by ``reach_px``, so every pixel within ``reach_px`` of the line gets its exact
    distance while the rest of the image costs nothing.

    :param points_px: (N, 2) vertices as (col, row) pixel coordinates, pixel centres at
        integers, last vertex not repeated.
    :param size_px: side of the square image in pixels.
    :param reach_px: distance within which the result must be exact.
    :return: a float32 (size_px, size_px) array: the distance in pixels where it is below
        ``reach_px``, some value at least ``reach_px`` (possibly ``inf``) elsewhere.
    """
    starts_px = points_px.astype(np.float32)
    deltas_px = (np.roll(points_px, -1, axis=0) - points_px).astype(np.float32)
    length_sq_px2 = np.einsum('ij,ij->i', deltas_px, deltas_px)
    inverse_length_sq = 1.0 / length_sq_px2
    mean_segment_px = float(np.mean(np.sqrt(length_sq_px2)))
    run_segments = max(1, int(_DISTANCE_RUN_REACHES * reach_px / mean_segment_px))
    distance_sq_px2 = np.full((size_px, size_px), np.inf, dtype=np.float32)
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
        window = distance_sq_px2[row_begin:row_end, col_begin:col_end]
        np.minimum(window, run_distance_sq_px2.min(axis=2), out=window)
    return np.sqrt(np.maximum(distance_sq_px2, 0.0))


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
    # Measure the curve densely, then place points evenly along its arc length so the
    # polyline is uniform however fast the parameter runs.
    parameter_rad = np.linspace(0.0, 2.0 * math.pi, _BOOK_LOOP_MEASURE_SAMPLES + 1)
    dense_xy = _book_loop_curve(parameter_rad)
    dense_arc_m = np.concatenate(
        ([0.0], np.cumsum(np.linalg.norm(np.diff(dense_xy, axis=0), axis=1))))
    point_count = math.ceil(dense_arc_m[-1] / MAX_POINT_SPACING_M)
    even_arc_m = np.arange(point_count) * (dense_arc_m[-1] / point_count)
    points_xy = _book_loop_curve(np.interp(even_arc_m, dense_arc_m, parameter_rad))
    bbox_centre_xy = (dense_xy.min(axis=0) + dense_xy.max(axis=0)) / 2.0
    return Course(points_xy - bbox_centre_xy, name='book_loop')


COURSES = {'book_loop': book_loop}


def make_course(name):
    """
    Build a registered course by name.

    :param name: a key of ``COURSES``.
    :return: the course.
    :raises ValueError: if no course has that name.
    """
    try:
        factory = COURSES[name]
    except (KeyError, TypeError):
        raise ValueError(
            f'unknown course {name!r}; known courses: {", ".join(sorted(COURSES))}.') from None
    return factory()


class LapTracker:
    """
    Score a run against the course from the robot's true positions.

    Progress is the signed distance travelled along the centre line since the first update:
    it follows the nearest point around the loop across the start, and driving backwards
    reduces it. Lap k completes when progress first reaches k course lengths, so reversing
    across a lap boundary and driving on does not count it twice. A hop of the nearest point
    larger than ``max_arc_step_m`` between updates (the robot passing where two parts of the
    course are close, or cutting across) adds no progress, so short cuts earn no laps.
    """

    def __init__(self, course, max_arc_step_m=DEFAULT_MAX_ARC_STEP_M):
        """
        Start a tracker with no updates.

        :param course: the course being driven.
        :param max_arc_step_m: largest change of the nearest arc length between updates that
            counts as motion along the line, in metres.
        :raises ValueError: if ``max_arc_step_m`` is not positive.
        """
        if not max_arc_step_m > 0.0:
            raise ValueError(f'max_arc_step_m must be positive, got {max_arc_step_m}.')
        self._course = course
        self._max_arc_step_m = float(max_arc_step_m)
        self._half_line_width_m = course.line_width_m / 2.0
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

        :param x_m: east coordinate in metres.
        :param y_m: north coordinate in metres.
        :param time_s: time in seconds, not earlier than the previous update's.
        :raises ValueError: if a value is not finite or time runs backwards.
        """
        if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(time_s)):
            raise ValueError(f'position and time must be finite, got ({x_m}, {y_m}, {time_s}).')
        distance_m, arc_m = self._course.nearest(x_m, y_m)
        if self._updates == 0:
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
            arc_step_m = _wrap_to_half_length(arc_m - self._previous_arc_m,
                                              self._course.length_m)
            if abs(arc_step_m) > self._max_arc_step_m:
                self._arc_jumps += 1
            else:
                self._advance(arc_step_m, time_s)
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
        """Course being scored."""
        return self._course

    @property
    def updates(self):
        """Count of updates since the start or the last reset."""
        return self._updates

    @property
    def time_s(self):
        """Time of the latest update in seconds."""
        return self._time_s

    @property
    def elapsed_s(self):
        """Time from the first update to the latest in seconds."""
        return self._time_s - self._start_time_s

    @property
    def distance_from_line_m(self):
        """Latest distance from the centre line in metres."""
        return self._distance_m

    @property
    def max_distance_from_line_m(self):
        """Largest distance from the centre line so far in metres."""
        return self._max_distance_m

    @property
    def rms_distance_from_line_m(self):
        """Root mean square of the distance from the centre line over the updates in metres."""
        if self._updates == 0:
            return 0.0
        return math.sqrt(self._sum_distance_sq_m2 / self._updates)

    @property
    def progress_m(self):
        """Signed distance travelled along the centre line since the first update in metres."""
        return self._progress_m

    @property
    def laps_completed(self):
        """Count of full laps driven."""
        return self._laps_completed

    @property
    def lap_times_s(self):
        """Duration of each completed lap in seconds (a copy)."""
        return list(self._lap_times_s)

    @property
    def time_off_line_s(self):
        """Time spent farther than half the line width from the centre line in seconds."""
        return self._time_off_line_s

    @property
    def arc_jumps(self):
        """Count of updates whose nearest point hopped too far to count as progress."""
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
