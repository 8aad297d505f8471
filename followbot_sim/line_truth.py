"""
Ground truth of the line in the camera image: where the course's centre line is drawn, per frame.

The simulator knows the camera's pose and intrinsics, and the course's centre line: projecting
the centre line through the same pinhole (and the same lens distortion, when the camera model
adds one) that drew the frame tells where the line's centre lies at every image row, with no
detector involved. Occlusion is by nothing but the image bounds and the horizon (the floor
behind the camera): nothing stands on the line in the simulator's worlds.

A frame's truth is a :class:`LineTruth`: the visible pieces of the projected centre line as
``(column, row, width)`` polylines (the shape :func:`followbot_sim.perception_score.band_truth`
scores a detection against), and, for a set of rows, the columns where the line crosses them.
Pure numpy: no ROS, no MuJoCo.
"""

import dataclasses

import numpy as np

# Floor points nearer the camera than this (along its optical axis) are clipped away: they are
# behind it, or so close that their projection is meaningless.
MIN_DEPTH_M = 1e-3
# A pixel's footprint: rows and columns from -0.5 to size - 0.5 lie on the image.
HALF_PIXEL = 0.5


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
    :ivar crossings: for each sampled row, an (M, 2) array of ``(column px, width px)`` where a
        visible piece crosses the row, sorted by column; empty where the line is not seen.
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
        """Return whether any part of the line is in the image."""
        return bool(self.pieces)


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


def row_crossings(pieces, rows_px) -> tuple:
    """
    Find where the pieces cross each row.

    :param pieces: (K, 3) arrays ``(column, row, width)`` from :func:`project_line`.
    :param rows_px: the rows.
    :return: one (M, 2) array ``(column, width)`` per row, sorted by column.
    """
    rows_px = np.asarray(rows_px, dtype=float)
    if not pieces:
        return tuple(np.empty((0, 2)) for _ in rows_px)
    starts = np.vstack([piece[:-1] for piece in pieces])
    ends = np.vstack([piece[1:] for piece in pieces])
    last_of_piece = np.zeros(len(starts), dtype=bool)
    last_of_piece[np.cumsum([len(piece) - 1 for piece in pieces]) - 1] = True
    v0, v1 = starts[:, 1:2], ends[:, 1:2]
    low, high = np.minimum(v0, v1), np.maximum(v0, v1)
    # Half-open in row, so a joint lying exactly on a row counts once; a piece's last
    # segment is closed, so its end point counts too.
    spans = (low <= rows_px) & ((rows_px < high) | (last_of_piece[:, None] & (rows_px == high)))
    rise = np.where(v1 == v0, 1.0, v1 - v0)
    t = np.where(v1 == v0, 0.5, (rows_px - v0) / rise)
    columns = starts[:, 0:1] + t * (ends[:, 0:1] - starts[:, 0:1])
    widths = starts[:, 2:3] + t * (ends[:, 2:3] - starts[:, 2:3])
    crossings = []
    for row_index in range(len(rows_px)):
        mask = spans[:, row_index]
        found = np.column_stack([columns[mask, row_index], widths[mask, row_index]])
        crossings.append(found[np.argsort(found[:, 0])])
    return tuple(crossings)


def line_truth(centre_line_xy, painted, line_width_m: float, view: PinholeView, rows_px,
               distort=None) -> LineTruth:
    """
    Return the ground truth of a closed centre line in one frame.

    :param centre_line_xy: (N, 2) floor points of the closed centre line in metres.
    :param painted: (N,) booleans: whether the line is painted at each point.
    :param line_width_m: the line's width in metres.
    :param view: the camera as it rendered the frame.
    :param rows_px: the rows to report crossings at (see :func:`sampled_rows`).
    :param distort: the lens's distortion of normalised coordinates, or None for a pinhole.
    :return: the LineTruth.
    """
    pieces = project_line(centre_line_xy, painted, line_width_m, view, distort)
    rows_px = np.asarray(rows_px, dtype=float)
    return LineTruth(tuple(pieces), rows_px, row_crossings(pieces, rows_px))
