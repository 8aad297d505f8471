"""
The piece of line a user shows in a camera frame, and the tape's width measured on it.

Around a pixel on the line (in a window) or in a box around a piece of it, each pixel's colour
is placed between the floor's colour (the median of the pixels around the window or box) and
the line's (the median around the pixel, or of the box's pixels least like the floor), in CIE
Lab, where distances follow what the eye sees. Pixels nearer the line's colour that touch the
pixel shown (or form the box's largest such patch) are the piece; those nearer the floor's
colour are the floor. No colour preset takes part: the piece is what :mod:`followbot.calibration`
judges its proposals against.

With the camera's intrinsics and mounting, the piece's edges are put on the floor and the
tape's width is measured across the line's direction (:func:`measure_line_width_m`).
"""

from typing import NamedTuple

import cv2
import numpy as np

# The window searched around a pixel on the line: this share of the image's smaller side on
# each side of it, at least MIN_WINDOW_HALF_PX; doubled (up to WINDOW_DOUBLINGS times) while
# the line fills more than FULL_WINDOW_SHARE of it (a near, wide line).
WINDOW_HALF_SHARE = 0.08
MIN_WINDOW_HALF_PX = 12
WINDOW_DOUBLINGS = 3
FULL_WINDOW_SHARE = 0.5
# The line's colour is the median of this many pixels' square around the pixel shown.
SEED_SIZE_PX = 5
# Thickness of the ring around a box whose median colour is the floor's.
RING_PX = 4
# In a box, the line's colour is the median of this share of its pixels least like the floor.
SEED_SHARE = 0.1
# Between the floor's colour (0) and the line's (1), a pixel at or above this is the line's;
# for the colour statistics only the pixels at or above CORE_LEVEL (not the blurred edge).
LINE_LEVEL = 0.5
CORE_LEVEL = 0.65
# The line must differ from its floor by at least this CIE Lab distance (a just visible
# difference is about 2; tape on a floor, tens).
MIN_LAB_CONTRAST = 12.0
# Fewest pixels of a piece of line worth measuring.
MIN_PIECE_PX = 12
# Width measurement: the line's direction at a row joins the crossings this many rows
# before and after; at least MIN_WIDTH_CROSSINGS rows must be measured.
DIRECTION_REACH_PX = 3
MIN_WIDTH_CROSSINGS = 5
# A line fewer pixels across than this is widened noticeably by a camera's blur.
MIN_SHARP_ACROSS_PX = 8.0


class CalibrationError(ValueError):
    """The frame, the piece of line shown or the camera cannot give a configuration."""


class LineSample(NamedTuple):
    """
    A piece of the line shown by the user, and the floor around it.

    ``piece`` and ``floor`` are (H, W) bool images; ``core`` is the piece without its blurred
    edge, whose colours describe the line; ``seed_px`` (x, y) a pixel of the piece.
    """

    piece: np.ndarray
    core: np.ndarray
    floor: np.ndarray
    seed_px: tuple


def check_point(point, size):
    """
    Check that a pixel lies inside an image.

    :param point: (x, y).
    :param size: (width, height) of the image.
    :raises CalibrationError: if it lies outside.
    """
    x_px, y_px = point
    width, height = size
    if not (0 <= x_px < width and 0 <= y_px < height):
        raise CalibrationError(
            f'The point ({x_px}, {y_px}) lies outside the {width}x{height} frame.')


def check_region(region, size):
    """
    Check that a box lies inside an image and holds pixels.

    :param region: (x, y, width, height) of the box.
    :param size: (width, height) of the image.
    :raises CalibrationError: if it is empty or reaches outside the image.
    """
    x_px, y_px, box_width, box_height = region
    width, height = size
    if box_width < 1 or box_height < 1:
        raise CalibrationError(
            f'The region {box_width}x{box_height} is empty: give a width and height of at '
            'least 1.')
    if x_px < 0 or y_px < 0 or x_px + box_width > width or y_px + box_height > height:
        raise CalibrationError(
            f'The region {x_px},{y_px},{box_width},{box_height} reaches outside the '
            f'{width}x{height} frame.')


def _lab(image_bgr):
    """Return an image's CIE Lab colours as float32 (L 0-100, a and b about -128..127)."""
    return cv2.cvtColor(image_bgr.astype(np.float32) / 255.0, cv2.COLOR_BGR2LAB)


def _ring(lab, box, thickness):
    """Return the colours of the ring of pixels just outside a box (inside the image)."""
    x0, y0, x1, y1 = box
    height, width = lab.shape[:2]
    outer = (max(x0 - thickness, 0), max(y0 - thickness, 0), min(x1 + thickness, width),
             min(y1 + thickness, height))
    around = np.zeros((height, width), bool)
    around[outer[1]:outer[3], outer[0]:outer[2]] = True
    around[y0:y1, x0:x1] = False
    if not around.any():
        # The box is the whole image: its own outermost pixels stand for the floor.
        around[y0:y1, x0:x1] = True
        around[y0 + thickness:y1 - thickness, x0 + thickness:x1 - thickness] = False
    return lab[around]


def _levels(lab_pixels, floor_lab, line_lab):
    """Return where colours lie between the floor's (0) and the line's (1) colour."""
    axis = line_lab - floor_lab
    return (lab_pixels - floor_lab) @ axis / float(axis @ axis)


def _sample(image_bgr, box, floor_lab, line_lab, seed_px):
    """
    Split a box of the image into the piece of line, its core and the floor.

    :param seed_px: a pixel of the piece, or None for the box's largest patch of line.
    :return: the LineSample; its ``piece`` is None when the box has no line pixel.
    """
    if float(np.linalg.norm(line_lab - floor_lab)) < MIN_LAB_CONTRAST:
        where = f'at ({seed_px[0]}, {seed_px[1]})' if seed_px else 'in the region'
        raise CalibrationError(
            f'The colour {where} hardly differs from the floor around it (CIE Lab distance '
            f'{np.linalg.norm(line_lab - floor_lab):.1f}, at least {MIN_LAB_CONTRAST:g} '
            'needed): show a piece of the line.')
    x0, y0, x1, y1 = box
    lab = _lab(image_bgr[y0:y1, x0:x1])
    levels = _levels(lab.reshape(-1, 3), floor_lab, line_lab).reshape(lab.shape[:2])
    line = (levels >= LINE_LEVEL).astype(np.uint8)
    count, labels = cv2.connectedComponents(line, connectivity=8)
    if count < 2:
        return None
    if seed_px is None:
        sizes = np.bincount(labels.reshape(-1), minlength=count)[1:]
        chosen = 1 + int(np.argmax(sizes))
        rows, columns = np.nonzero(labels == chosen)
        middle = len(rows) // 2
        seed_px = (x0 + int(columns[middle]), y0 + int(rows[middle]))
    else:
        chosen = _component_nearest(labels, (seed_px[0] - x0, seed_px[1] - y0))
    height, width = image_bgr.shape[:2]
    piece = np.zeros((height, width), bool)
    core = np.zeros((height, width), bool)
    floor = np.zeros((height, width), bool)
    piece[y0:y1, x0:x1] = labels == chosen
    core[y0:y1, x0:x1] = (labels == chosen) & (levels >= CORE_LEVEL)
    floor[y0:y1, x0:x1] = levels < LINE_LEVEL
    return LineSample(piece, core, floor, seed_px)


def _component_nearest(labels, point):
    """Return the label of the connected patch at a pixel, or of the patch nearest to it."""
    x_px, y_px = point
    if labels[y_px, x_px]:
        return int(labels[y_px, x_px])
    rows, columns = np.nonzero(labels)
    nearest = int(np.argmin((columns - x_px) ** 2 + (rows - y_px) ** 2))
    return int(labels[rows[nearest], columns[nearest]])


def sample_at_point(image_bgr, point):
    """
    Find the piece of line around a pixel on it.

    :param image_bgr: the (H, W, 3) uint8 frame.
    :param point: (x, y) of a pixel on the line.
    :return: the LineSample.
    :raises CalibrationError: if the pixel is outside the frame or does not stand out from
        the floor around it.
    """
    height, width = image_bgr.shape[:2]
    check_point(point, (width, height))
    x_px, y_px = int(point[0]), int(point[1])
    half_px = max(MIN_WINDOW_HALF_PX, int(WINDOW_HALF_SHARE * min(width, height)))
    reach = SEED_SIZE_PX // 2
    seed = image_bgr[max(y_px - reach, 0):y_px + reach + 1, max(x_px - reach, 0):x_px + reach + 1]
    line_lab = np.median(_lab(seed).reshape(-1, 3), axis=0)
    lab = _lab(image_bgr)
    for doubling in range(WINDOW_DOUBLINGS + 1):
        last = doubling == WINDOW_DOUBLINGS
        box = (max(x_px - half_px, 0), max(y_px - half_px, 0), min(x_px + half_px + 1, width),
               min(y_px + half_px + 1, height))
        half_px *= 2
        floor_lab = np.median(_ring(lab, box, RING_PX), axis=0)
        if not last and float(np.linalg.norm(line_lab - floor_lab)) < MIN_LAB_CONTRAST:
            continue  # The line fills the window: its floor lies farther out.
        sample = _sample(image_bgr, box, floor_lab, line_lab, (x_px, y_px))
        window_px = (box[2] - box[0]) * (box[3] - box[1])
        if last or sample is None or int(sample.piece.sum()) <= FULL_WINDOW_SHARE * window_px:
            break
    return _checked(sample, f'at ({x_px}, {y_px})')


def sample_in_region(image_bgr, region):
    """
    Find the piece of line in a box around it.

    :param image_bgr: the (H, W, 3) uint8 frame.
    :param region: (x, y, width, height) of a box holding a piece of the line and some floor.
    :return: the LineSample.
    :raises CalibrationError: if the box reaches outside the frame or holds nothing that
        stands out from the floor around it.
    """
    height, width = image_bgr.shape[:2]
    check_region(region, (width, height))
    x_px, y_px, box_width, box_height = (int(value) for value in region)
    box = (x_px, y_px, x_px + box_width, y_px + box_height)
    lab = _lab(image_bgr)
    floor_lab = np.median(_ring(lab, box, RING_PX), axis=0)
    inside = lab[box[1]:box[3], box[0]:box[2]].reshape(-1, 3)
    distance = np.linalg.norm(inside - floor_lab, axis=1)
    least_alike = distance >= np.quantile(distance, 1.0 - SEED_SHARE)
    line_lab = np.median(inside[least_alike], axis=0)
    sample = _sample(image_bgr, box, floor_lab, line_lab, None)
    return _checked(sample, f'in the region {x_px},{y_px},{box_width},{box_height}')


def _checked(sample, where):
    """Return a sample large enough to describe the line, or raise."""
    if sample is None or int(sample.core.sum()) < MIN_PIECE_PX:
        raise CalibrationError(
            f'Too few pixels of a line {where} ({MIN_PIECE_PX} needed): show a piece of the '
            'line where it is wider.')
    return sample


class Width(NamedTuple):
    """The tape's width on the floor, and how many pixels across it was measured on."""

    metres: float
    across_px: float


def measure_line_width_m(sample, geometry):
    """
    Measure the tape's width on the floor from the piece of line.

    The piece is cut across by image rows (or columns, for a piece lying more across the
    image than along it). Where a row crosses it once, the crossing's two edges are put on
    the floor; the line's direction there joins the floor points of the crossings
    DIRECTION_REACH_PX rows before and after. The width is the crossing's extent across that
    direction; the median over all rows is taken (a curve, blur and noise move single rows).

    :param sample: the LineSample.
    :param geometry: the camera's CameraGeometry.
    :return: the Width: in metres, and in pixels across the line in the image (blur widens a
        line only a few pixels across).
    :raises CalibrationError: if the piece is not on the floor (above the horizon) or too
        small to measure.
    """
    rows, columns = np.nonzero(sample.piece)
    along_rows = np.ptp(rows) >= np.ptp(columns)
    mask = sample.piece if along_rows else sample.piece.T
    crossings = {}
    for index in np.flatnonzero(mask.any(axis=1)):
        edges = np.flatnonzero(np.diff(np.concatenate(([0], mask[index].view(np.int8), [0]))))
        if len(edges) == 2:
            crossings[int(index)] = (edges[0] - 0.5, edges[1] - 0.5)
    widths, across_px = [], []
    for index, (first, last) in crossings.items():
        before = crossings.get(index - DIRECTION_REACH_PX)
        after = crossings.get(index + DIRECTION_REACH_PX)
        if before is None or after is None:
            continue
        ends = [(first, index), (last, index), (sum(before) / 2.0, index - DIRECTION_REACH_PX),
                (sum(after) / 2.0, index + DIRECTION_REACH_PX)]
        if not along_rows:
            ends = [(row, column) for column, row in ends]
        x_m, y_m = geometry.pixels_to_floor([end[0] for end in ends], [end[1] for end in ends])
        points = np.stack((x_m, y_m), axis=1)
        if not np.isfinite(points).all():
            continue
        direction = points[3] - points[2]
        length = float(np.hypot(*direction))
        if length > 0.0:
            widths.append(_across(points[1] - points[0], direction))
            across_px.append(_across((last - first, 0.0), (
                (sum(after) - sum(before)) / 2.0, 2.0 * DIRECTION_REACH_PX)))
    if len(widths) < MIN_WIDTH_CROSSINGS:
        seen = np.isfinite(geometry.pixels_to_floor(columns.astype(float),
                                                    rows.astype(float))[0])
        if not seen.any():
            raise CalibrationError(
                "The line shown lies above the floor's horizon for this camera: check "
                '--camera-pitch-deg and the camera info.')
        raise CalibrationError(
            'The piece of line shown is too small or too ragged to measure its width: show '
            'it where it is wider.')
    return Width(float(np.median(widths)), float(np.median(across_px)))


def _across(chord, direction):
    """Return the extent of a chord across a direction (the cross product over its length)."""
    return abs(chord[0] * direction[1] - chord[1] * direction[0]) / float(np.hypot(*direction))
