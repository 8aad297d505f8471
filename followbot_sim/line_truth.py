"""
Ground truth of the line in the camera image: where the course's centre line is drawn, per frame.

The simulator knows the camera's pose and intrinsics, and the course's centre line: projecting
the centre line through the same pinhole (and the same lens distortion, when the camera model
adds one) that drew the frame tells where the line's centre lies at every image row, with no
detector involved. Occlusion is by nothing but the image bounds and the horizon (the floor
behind the camera): nothing stands on the line in the simulator's worlds.

A frame's truth is a :class:`LineTruth`: the visible pieces of the projected centre line as
``(column, row, width)`` polylines, and, for a set of rows, the stretches of each row the paint
covers, as a labeller marks a real frame (the shape
:func:`followbot_sim.perception_score.band_truth` scores a detection against). The paint is
projected as drawn, not from its centre: where the line crosses a row aslant the stretch is
longer than the tape is wide, and where a bend takes the tape out at the image's side the edge
of the paint still shows in rows its centre crosses outside the image. Pure numpy: no ROS, no
MuJoCo.
"""

import dataclasses

import numpy as np

# Floor points nearer the camera than this (along its optical axis) are clipped away: they are
# behind it, or so close that their projection is meaningless.
MIN_DEPTH_M = 1e-3
# A pixel's footprint: rows and columns from -0.5 to size - 0.5 lie on the image.
HALF_PIXEL = 0.5
# The paint is the union of a quadrilateral per painted segment of the centre line, mitred to
# its neighbours, and, where the line turns by more than this between segments, a polygon of
# JOIN_SIDES sides round the vertex (the round join the floor texture draws, where a mitre
# would reach out beyond it).
JOIN_MIN_TURN_RAD = 0.05
JOIN_SIDES = 8
# Stretches of one row less than this apart are one: the quadrilaterals of consecutive
# segments meet along their shared, mitred end, give or take rounding.
MERGE_GAP_PX = 1.0
# Polygons are crossed with the rows this many at a time (bounds the memory: polygons x
# JOIN_SIDES x rows floats).
POLYGON_CHUNK = 256


@dataclasses.dataclass(frozen=True)
class PinholeView:
    """
    A camera's pose in the world and its intrinsics, as the renderer used them for one frame.

    ``rotation`` holds the camera's optical-frame axes (x right, y down, z forward, as ROS's
    ``*_optical_frame``) as its columns, in world coordinates. Pixel centres sit at integer
    coordinates (the ROS convention): the principal point of a centred camera is
    ``((width - 1) / 2, (height - 1) / 2)``.
    """

    position_m: np.ndarray
    rotation: np.ndarray
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int

    def __post_init__(self):
        """Check the shapes and sizes, so a bad view fails here and not inside numpy."""
        if np.shape(self.position_m) != (3,) or np.shape(self.rotation) != (3, 3):
            raise ValueError('A PinholeView needs a 3-vector position and a 3x3 rotation, got '
                             f'shapes {np.shape(self.position_m)} and {np.shape(self.rotation)}.')
        if self.width_px <= 0 or self.height_px <= 0 or self.fx_px <= 0 or self.fy_px <= 0:
            raise ValueError('A PinholeView needs positive image size and focal lengths, got '
                             f'{self.width_px}x{self.height_px} px, fx={self.fx_px}, '
                             f'fy={self.fy_px}.')


@dataclasses.dataclass(frozen=True)
class LineTruth:
    """
    Where the line's centre is drawn in one frame.

    :ivar pieces: visible pieces of the centre line, each an (N, 3) array of points
        ``(column px, row px, line width px)`` in order along the line; a piece ends where the
        line leaves the image, passes the horizon or (dashed lines) enters a gap.
    :ivar rows_px: the rows sampled for :attr:`crossings`.
    :ivar crossings: for each sampled row, an (M, 2) array ``(middle column px, length px)``
        of the stretches of the row that the paint covers within the image, sorted by column;
        empty where the line is not seen.
    """

    pieces: tuple
    rows_px: np.ndarray
    crossings: tuple

    def polylines(self) -> list:
        """
        Return the pieces as lists of ``(x, y, width)`` tuples, as perception scoring takes them.

        :return: one list per piece.
        """
        return [[tuple(point) for point in piece.tolist()] for piece in self.pieces]

    @property
    def visible(self) -> bool:
        """Return whether any part of the line (its centre, or paint on a sampled row) shows."""
        return bool(self.pieces) or any(len(crossings) for crossings in self.crossings)


def sampled_rows(height_px: int, row_step_px: int) -> np.ndarray:
    """
    Return every ``row_step_px``-th row of an image, starting at row 0.

    :param height_px: image height in pixels.
    :param row_step_px: distance between sampled rows, a positive integer.
    :return: the rows, as floats.
    :raises ValueError: if the step is not a positive integer.
    """
    if int(row_step_px) != row_step_px or row_step_px < 1:
        raise ValueError(f'row_step_px must be a positive integer, got {row_step_px!r}.')
    return np.arange(0, height_px, int(row_step_px), dtype=float)


def _clip_segments_to_depth(starts, ends, min_depth_m):
    """
    Clip 3-D segments (camera coordinates) to the half-space z >= min_depth_m.

    :return: (starts, ends, kept mask) with the kept segments' clipped end points.
    """
    z0, z1 = starts[:, 2], ends[:, 2]
    kept = (z0 >= min_depth_m) | (z1 >= min_depth_m)
    with np.errstate(divide='ignore', invalid='ignore'):
        t = np.clip((min_depth_m - z0) / (z1 - z0), 0.0, 1.0)
    delta = ends - starts
    new_starts = np.where((z0 < min_depth_m)[:, None], starts + t[:, None] * delta, starts)
    new_ends = np.where((z1 < min_depth_m)[:, None], starts + t[:, None] * delta, ends)
    return new_starts, new_ends, kept


def _clip_segments_to_box(p0, p1, low, high):
    """
    Clip 2-D segments to an axis-aligned box (Liang-Barsky, all segments at once).

    :param p0: (S, 2) start points.
    :param p1: (S, 2) end points.
    :param low: (2,) lower corner.
    :param high: (2,) upper corner.
    :return: (t0, t1, kept): the kept part of each segment is p0 + t (p1 - p0), t in [t0, t1].
    """
    delta = p1 - p0
    t0 = np.zeros(len(p0))
    t1 = np.ones(len(p0))
    kept = np.ones(len(p0), dtype=bool)
    for axis in range(2):
        for sign, bound in ((-1.0, low[axis]), (1.0, high[axis])):
            p = sign * delta[:, axis]
            q = sign * (bound - p0[:, axis])
            parallel = p == 0.0
            kept &= ~(parallel & (q < 0.0))
            with np.errstate(divide='ignore', invalid='ignore'):
                r = q / p
            entering = ~parallel & (p < 0.0)
            leaving = ~parallel & (p > 0.0)
            t0 = np.where(entering, np.maximum(t0, r), t0)
            t1 = np.where(leaving, np.minimum(t1, r), t1)
    kept &= t0 <= t1
    return t0, t1, kept


def project_line(centre_line_xy, painted, line_width_m: float, view: PinholeView,
                 distort=None, closed: bool = True) -> list:
    """
    Project a floor polyline into the image and cut it into its visible pieces.

    Each segment is clipped in 3-D to the camera's front (the horizon), projected, distorted
    (if ``distort`` is given), then clipped to the image. A straight floor segment projects to
    a straight image segment through a pinhole, so the pieces are exact at the polyline's
    points; with distortion they are exact at the points and linear between them (the course's
    points lie 1 cm apart: far below a pixel of the curve's bend).

    :param centre_line_xy: (N, 2) floor points in metres (z = 0), in order.
    :param painted: (N,) booleans: whether the line is painted at each point (dashes); a
        segment is visible when both its ends are painted.
    :param line_width_m: the line's width on the floor, for the width in pixels.
    :param view: the camera.
    :param distort: None, or a function ``(x, y) -> (x, y)`` of normalised image coordinates
        (``x = X / Z``, ``y = Y / Z``) that the camera's lens applies.
    :param closed: whether the last point joins the first.
    :return: a list of (K, 3) arrays ``(column, row, width px)``, one per visible piece.
    """
    points = np.column_stack([np.asarray(centre_line_xy, dtype=float),
                              np.zeros(len(centre_line_xy))])
    camera_points = (points - np.asarray(view.position_m, dtype=float)) @ np.asarray(
        view.rotation, dtype=float)
    painted = np.asarray(painted, dtype=bool)
    next_index = np.arange(1, len(points) + 1)
    if closed:
        next_index[-1] = 0
    else:
        next_index = next_index[:-1]
    first_index = np.arange(len(next_index))
    starts, ends, kept = _clip_segments_to_depth(
        camera_points[first_index], camera_points[next_index], MIN_DEPTH_M)
    kept &= painted[first_index] & painted[next_index]

    def to_pixels(camera_xyz):
        normalised_x = camera_xyz[:, 0] / camera_xyz[:, 2]
        normalised_y = camera_xyz[:, 1] / camera_xyz[:, 2]
        if distort is not None:
            normalised_x, normalised_y = distort(normalised_x, normalised_y)
        width_px = line_width_m * view.fx_px / camera_xyz[:, 2]
        return np.column_stack([view.cx_px + view.fx_px * normalised_x,
                                view.cy_px + view.fy_px * normalised_y, width_px])

    with np.errstate(divide='ignore', invalid='ignore'):
        pixel_starts = to_pixels(np.where(kept[:, None], starts, 1.0))
        pixel_ends = to_pixels(np.where(kept[:, None], ends, 1.0))
    low = np.array([-HALF_PIXEL, -HALF_PIXEL])
    high = np.array([view.width_px - HALF_PIXEL, view.height_px - HALF_PIXEL])
    t0, t1, inside = _clip_segments_to_box(pixel_starts[:, :2], pixel_ends[:, :2], low, high)
    kept &= inside & np.all(np.isfinite(pixel_starts), axis=1) & np.all(
        np.isfinite(pixel_ends), axis=1)
    delta = pixel_ends - pixel_starts
    clipped_starts = pixel_starts + t0[:, None] * delta
    clipped_ends = pixel_starts + t1[:, None] * delta
    return _join_segments(clipped_starts, clipped_ends, kept, t0, t1, closed)


def _join_segments(starts, ends, kept, t0, t1, closed):
    """Join consecutive kept segments that were not cut at their joint into pieces."""
    pieces = []
    current = []
    count = len(kept)
    for index in range(count):
        if not kept[index]:
            if current:
                pieces.append(current)
            current = []
            continue
        if not current:
            current = [starts[index]]
        current.append(ends[index])
        if t1[index] < 1.0:
            pieces.append(current)
            current = []
        elif index + 1 < count and kept[index + 1] and t0[index + 1] > 0.0:
            pieces.append(current)
            current = []
    if current:
        pieces.append(current)
    pieces = [np.array(piece) for piece in pieces]
    # A closed loop seen whole or cut only at its first point: one piece, not two.
    if closed and len(pieces) > 1 and kept[0] and kept[-1] and t0[0] == 0.0 \
            and t1[-1] == 1.0:
        pieces[0] = np.vstack([pieces[-1], pieces[0][1:]])
        pieces.pop()
    return pieces


def _paint_polygons(centre_line_xy, painted, line_width_m: float) -> np.ndarray:
    """
    Return the paint of a closed line as convex floor polygons of JOIN_SIDES vertices.

    Each painted segment is a quadrilateral. Where the line turns gently its neighbours share
    their end across the line (a mitre), so the quadrilaterals neither overlap nor leave a
    wedge; where it turns by more than JOIN_MIN_TURN_RAD each ends square to itself and a
    polygon round the vertex fills the join. A quadrilateral repeats its last vertex to make up
    the count.

    :return: (P, JOIN_SIDES, 2) floor points in metres.
    """
    points = np.asarray(centre_line_xy, dtype=float)
    painted = np.asarray(painted, dtype=bool)
    following = np.roll(np.arange(len(points)), -1)
    previous = np.roll(np.arange(len(points)), 1)
    steps = points[following] - points
    lengths = np.hypot(*steps.T)
    directions = steps / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    half_width_m = line_width_m / 2.0
    # Per segment (from its point to the next): its own left side, half the width long.
    sides = half_width_m * np.column_stack([-directions[:, 1], directions[:, 0]])
    segment_painted = painted & painted[following] & (lengths > 0.0)
    turn_rad = np.abs(np.arctan2(
        directions[previous, 0] * directions[:, 1] - directions[previous, 1] * directions[:, 0],
        np.einsum('ij,ij->i', directions[previous], directions)))
    # Per point: the mitre, along the bisector and long enough to reach both segments' edges.
    between_painted = segment_painted & segment_painted[previous]
    mitred = between_painted & (turn_rad <= JOIN_MIN_TURN_RAD)
    with np.errstate(divide='ignore', invalid='ignore'):
        mitres = (sides + sides[previous]) / (1.0 + np.cos(turn_rad))[:, None]
    segments = np.flatnonzero(segment_painted)
    ends = following[segments]
    start_side = np.where(mitred[segments, None], mitres[segments], sides[segments])
    end_side = np.where(mitred[ends, None], mitres[ends], sides[segments])
    start, end = points[segments], points[ends]
    quadrilaterals = np.stack([start + start_side, end + end_side, end - end_side]
                              + [start - start_side] * (JOIN_SIDES - 3), axis=1)
    joins = np.flatnonzero(between_painted & ~mitred)
    angles = np.arange(JOIN_SIDES) * (2.0 * np.pi / JOIN_SIDES)
    corners = half_width_m * np.column_stack([np.cos(angles), np.sin(angles)])
    discs = points[joins][:, None, :] + corners[None, :, :]
    return np.concatenate([quadrilaterals, discs], axis=0)


def _row_spans(polygons_px, rows_px, chunk=POLYGON_CHUNK):
    """
    Cross convex image polygons with rows.

    :param polygons_px: (P, K, 2) vertices (column, row).
    :param rows_px: (R,) rows.
    :return: (row index, first column, last column) arrays, one entry per polygon and row it
        covers.
    """
    found = ([], [], [])
    for first in range(0, len(polygons_px), chunk):
        polygons = polygons_px[first:first + chunk]
        x0, y0 = polygons[:, :, 0:1], polygons[:, :, 1:2]
        following = np.roll(polygons, -1, axis=1)
        x1, y1 = following[:, :, 0:1], following[:, :, 1:2]
        low, high = np.minimum(y0, y1), np.maximum(y0, y1)
        # Half-open in row: a vertex lying on a row counts once.
        crossing = (low <= rows_px) & (rows_px < high)
        with np.errstate(divide='ignore', invalid='ignore'):
            columns = x0 + (rows_px - y0) * (x1 - x0) / (y1 - y0)
        first_px = np.where(crossing, columns, np.inf).min(axis=1)
        last_px = np.where(crossing, columns, -np.inf).max(axis=1)
        covered = np.nonzero(np.isfinite(first_px))
        found[0].append(covered[1])
        found[1].append(first_px[covered])
        found[2].append(last_px[covered])
    return tuple(np.concatenate(part) if part else np.empty(0) for part in found)


def paint_crossings(centre_line_xy, painted, line_width_m: float, view: PinholeView, rows_px,
                    distort=None) -> tuple:
    """
    Find the stretches of each row that the painted line covers in the image.

    The paint (see :func:`_paint_polygons`) is projected through the same pinhole, and lens
    distortion, that drew the frame; a polygon reaching behind the camera is left out (it lies
    at the far sides of the view, off the image).

    :param centre_line_xy: (N, 2) floor points of the closed centre line in metres.
    :param painted: (N,) booleans: whether the line is painted at each point.
    :param line_width_m: the line's width in metres.
    :param view: the camera.
    :param rows_px: the rows.
    :param distort: the lens's distortion of normalised coordinates, or None.
    :return: one (M, 2) array ``(middle column, length)`` per row, sorted by column, the
        stretches cut to the image's columns.
    """
    rows_px = np.asarray(rows_px, dtype=float)
    polygons = _paint_polygons(centre_line_xy, painted, line_width_m)
    floor = np.concatenate([polygons, np.zeros(polygons.shape[:2] + (1,))], axis=2)
    rotation = np.asarray(view.rotation, dtype=float)
    camera = (floor - np.asarray(view.position_m, dtype=float)) @ rotation
    ahead = np.all(camera[:, :, 2] >= MIN_DEPTH_M, axis=1)
    camera = camera[ahead]
    normalised_x = camera[:, :, 0] / camera[:, :, 2]
    normalised_y = camera[:, :, 1] / camera[:, :, 2]
    if distort is not None:
        normalised_x, normalised_y = distort(normalised_x, normalised_y)
    pixels = np.stack([view.cx_px + view.fx_px * normalised_x,
                       view.cy_px + view.fy_px * normalised_y], axis=2)
    right_px, bottom_px = view.width_px - HALF_PIXEL, view.height_px - HALF_PIXEL
    on_image = ((pixels[:, :, 0].max(axis=1) >= -HALF_PIXEL)
                & (pixels[:, :, 0].min(axis=1) <= right_px)
                & (pixels[:, :, 1].max(axis=1) >= -HALF_PIXEL)
                & (pixels[:, :, 1].min(axis=1) <= bottom_px))
    row_index, first_px, last_px = _row_spans(pixels[on_image], rows_px)
    first_px = np.maximum(first_px, -HALF_PIXEL)
    last_px = np.minimum(last_px, right_px)
    kept = first_px < last_px
    row_index, first_px, last_px = row_index[kept], first_px[kept], last_px[kept]
    # Merge overlapping stretches row by row, all rows at once: each row is shifted far
    # beyond the previous one, so a running maximum never carries over.
    order = np.lexsort((first_px, row_index))
    shift = row_index[order] * 4.0 * (view.width_px + MERGE_GAP_PX)
    starts, ends = first_px[order] + shift, last_px[order] + shift
    reach = np.maximum.accumulate(ends) if len(ends) else ends
    new = np.ones(len(starts), dtype=bool)
    new[1:] = starts[1:] > reach[:-1] + MERGE_GAP_PX
    heads = np.flatnonzero(new)
    merged_rows = row_index[order][heads]
    merged_first = starts[heads] - shift[heads]
    merged_last = (np.maximum.reduceat(ends, heads) if len(heads) else ends) - shift[heads]
    stretches = np.column_stack([(merged_first + merged_last) / 2.0, merged_last - merged_first])
    # Already in row order, and by column within a row.
    bounds = np.searchsorted(merged_rows, np.arange(1, len(rows_px)))
    return tuple(np.split(stretches, bounds))


def line_truth(centre_line_xy, painted, line_width_m: float, view: PinholeView, rows_px,
               distort=None) -> LineTruth:
    """
    Return the ground truth of a closed centre line in one frame.

    :param centre_line_xy: (N, 2) floor points of the closed centre line in metres.
    :param painted: (N,) booleans: whether the line is painted at each point.
    :param line_width_m: the line's width in metres.
    :param view: the camera as it rendered the frame.
    :param rows_px: the rows to report the paint's stretches at (see :func:`sampled_rows`).
    :param distort: the lens's distortion of normalised coordinates, or None for a pinhole.
    :return: the LineTruth.
    """
    pieces = project_line(centre_line_xy, painted, line_width_m, view, distort)
    rows_px = np.asarray(rows_px, dtype=float)
    return LineTruth(tuple(pieces), rows_px, paint_crossings(
        centre_line_xy, painted, line_width_m, view, rows_px, distort))
