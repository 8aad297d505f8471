"""
Courses from an image: trace the centre line of a yellow line painted on a grey floor.

The image is the whole square floor, row 0 at the north edge and column 0 at the west edge (the
convention of ``Course.draw_texture``). Tracing happens in pixel coordinates (column, row); the
result is converted to the world frame (metres, floor centred at the origin, x east, y north).

The line is found by colour: a pixel's share of line paint is its HSV chroma (saturation times
value, i.e. ``max - min`` of R, G, B) over the chroma of solid line paint, counted only where the
hue is yellow. Blending yellow with grey of any level keeps the hue and scales the chroma
linearly, so anti-aliased edges weigh in proportion to the paint they carry and a grey floor
weighs nothing. Each cross-section of the line measures its paint against its own solid paint,
so a line in a pool of dim light keeps its width.

The centre line is traced by marching along the painted ribbon in ~1.5 cm steps: predict a step
ahead along the current heading, re-centre on the paint across the perpendicular cross-section
(limited to one line width either side, so a crossing branch cannot pull the trace), and take
the heading from the last half line width of points. Where the cross-section is wider than a
line (a corner or a crossing) or thinner (a dash's end) the march goes straight on; where the
paint ends ahead it looks for the continuation, first around a corner (smallest turn first, up
to ``MAX_TURN_RAD``), then across a gap (up to ``MAX_GAP_M``). The trace closes where it comes
back to where it started.

The clean stretches of the march are then smoothed and the passages between them rebuilt: a
sharp corner as the intersection of the two stretches' lines, anything else (a crossing, a gap)
as a cubic fitted to the centre line on both sides. Finally every stretch point is re-centred
across the tangent of that loop and the loop is rebuilt once more.
"""

import collections
import math
import pathlib
import struct

import cv2
from followbot_sim.course import Course
from followbot_sim.course import texture_px_to_world
from followbot_sim.course import world_to_texture_px
import numpy as np

# Largest course image side read, checked in the file's header before decoding: 4096 px is
# 2.4 mm a pixel on the book's 10 m floor (finer than any camera sees it), ~50 MB decoded and a
# trace of seconds. A 20000 px image would take minutes and gigabytes.
MAX_IMAGE_SIDE_PX = 4096
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
JPEG_SIGNATURE = b'\xff\xd8'
# JPEG start-of-frame markers (baseline, progressive, ...): they carry the image size. The
# others of 0xC0-0xCF are DHT (C4), JPG (C8) and DAC (CC).
JPEG_START_OF_FRAME = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers without a length field: TEM, RST0-7.
JPEG_STANDALONE_MARKERS = frozenset([0x01, *range(0xD0, 0xD8)])

# Yellow in OpenCV's 0-179 hue scale (60 degrees); the book's RGB(255, 246, 0) has hue 29.
YELLOW_HUE = 30
# Accepts orange-yellow to lime-yellow (+-24 degrees), and the hue shifts of lossy compression.
YELLOW_HUE_TOLERANCE = 12
# Chroma (0-255) below which a pixel is floor: grey of any level has ~0, JPEG noise stays below.
MIN_LINE_CHROMA = 40
# Percentile of the yellow pixels' chroma taken as typical solid paint: most of a line is solid,
# its anti-aliased edges are below.
SOLID_PAINT_PERCENTILE = 90
# Across a cross-section, paint is measured against the solid paint of that section, so a line
# lit dimly keeps its width; that paint must be at least this share of the typical one (a line
# lit at 30%), else the section holds no line.
MIN_SECTION_PAINT = 0.3
# A sample with at least this share of its section's solid paint is on the line.
LINE_PIXEL_COVERAGE = 0.5
# A passage whose straight chord has at least this share of typical paint everywhere runs over
# paint (a corner), not across a gap.
MIN_PASSAGE_PAINT = MIN_SECTION_PAINT * LINE_PIXEL_COVERAGE

# Paint farther than this many line widths from the traced centre line belongs to no part of the
# loop (an L corner's outer pixel lies 0.71 widths from its vertex): a branch, refused.
MAX_OFF_LOOP_WIDTHS = 1.0
# Sub-pixel precision of the loop drawn for that test (cv2's fixed-point drawing).
BRANCH_DRAW_SHIFT_BITS = 4
# The start pose must be this close to a line pixel.
MAX_START_DISTANCE_M = 0.5
# Centre-line points this much farther from the start pose than the nearest tie with it (where
# branches cross); among them, directions whose cosines with the start yaw differ by less than
# this tie too, and the nearer wins.
START_TIE_M = 0.01
START_ALIGNMENT_TIE = 0.05
# Marching step along the line: small against bends of ~0.4 m radius, large enough to be quick.
STEP_M = 0.015
# The step is at most this share of the line width, so thin lines are sampled finely enough.
MAX_STEP_WIDTHS = 0.25
# Smallest step in pixels: finer than this only repeats the same pixels.
MIN_STEP_PX = 0.5
# Spacing of the samples across a cross-section: fine enough for a sub-pixel centroid.
SECTION_SAMPLE_PX = 0.5
# Half length of a cross-section in line widths: a crossing branch or a corner's other arm
# within it makes the paint reach the section's end.
SECTION_HALF_WIDTHS = 1.0
# Paint within this many pixels outside a section's line-pixel run belongs to its soft edges
# (anti-aliasing plus bilinear sampling).
EDGE_FUZZ_PX = 2.0
# A section reaches at least this far past a line's soft edges, so that on a line only a few
# pixels wide (hard-edged 3-4 px) the edges do not touch the section's ends as a crossing would.
MIN_SECTION_MARGIN_PX = 1.0
# A cross-section of a clean stretch of line holds between these shares of a line width.
FULL_SECTION_WIDTHS = 0.75
MAX_SECTION_WIDTHS = 1.5
# Below this share of a line width a cross-section is no paint at all; between it and the full
# width it is thin (a dash's rounded end, whose centroid depends on the heading): passed straight.
MIN_SECTION_WIDTHS = 0.3
# A cross-section may be re-centred by at most this share of a line width from its prediction.
MAX_RECENTRE_WIDTHS = 0.5
# The heading is the direction from the point this many line widths back along the trace.
HEADING_BASELINE_WIDTHS = 0.5
# Where the line ends ahead, its continuation around a corner is probed this many line widths
# from the last clean point, turning in these steps up to the largest turn.
TURN_PROBE_WIDTHS = 1.25
TURN_STEP_RAD = math.radians(5.0)
MAX_TURN_RAD = math.radians(100.0)
# Within this many line widths of travel the heading may turn by at most the angle whose cosine
# this is (135 degrees): more is the march turning back along the line, past a corner sharper
# than the largest turn. A 0.4 m hairpin turns ~55 degrees in that distance.
REVERSAL_WINDOW_WIDTHS = 2.0
REVERSAL_HEADING_COS = math.cos(math.radians(135.0))
# Longest gap in the paint to jump across (dashed lines have gaps up to ~0.25 m). The far side
# is probed from the last clean point, from half a line width to the gap plus half a line width
# ahead (clean points sit up to ~0.2 widths inside a dash's rounded end), in quarter widths,
# turning up to the largest turn as the line may bend on across the gap.
MAX_GAP_M = 0.3
MAX_GAP_TURN_RAD = math.radians(45.0)
GAP_PROBE_START_WIDTHS = 0.5
GAP_PROBE_END_WIDTHS = 0.5
GAP_PROBE_STEP_WIDTHS = 0.25
# A corner, a crossing or a dash's rounded end is passed straight for at most this many widths.
MAX_JUNCTION_WIDTHS = 3.0
# Before the trace may close it must have been this many line widths away from its seed; it
# closes where it comes back within half a line width, heading within 45 degrees of the seed's.
CLOSE_AWAY_WIDTHS = 2.0
CLOSE_LATERAL_WIDTHS = 0.5
CLOSE_MIN_HEADING_COS = math.cos(math.radians(45.0))
# The trace gives up after this many times the length the painted area allows (area / width);
# dashed lines are at least a third paint.
MAX_TRACE_LENGTH_FACTOR = 3.0
# Seeds tried where the nearest line pixel sits in a corner or crossing.
MAX_SEED_ATTEMPTS = 10
SEED_ANGLE_STEP_RAD = math.radians(5.0)
# Each stretch's end heading is fitted (quadratic in arc length) over this many line widths.
END_FIT_WIDTHS = 1.0
# A quadratic through fewer points than this would follow their noise: fit a line instead.
QUADRATIC_FIT_MIN_POINTS = 4
# A passage over paint turning more than this is a sharp corner rebuilt as a vertex.
CORNER_MIN_TURN_RAD = math.radians(30.0)
# The vertex of a corner lies within this many line widths of both stretches' ends.
MAX_CORNER_ARM_WIDTHS = 3.0
# Other passages are bridged by a cubic fitted over this many line widths either side.
BRIDGE_CONTEXT_WIDTHS = 1.0
BRIDGE_FIT_DEGREE = 3
# A clean stretch shorter than this many line widths is too short to trust its direction.
MIN_STRETCH_WIDTHS = 0.5
# Samples of the straight chord across a passage: all painted over a corner, not over a gap.
BRIDGE_PAINT_SAMPLES = 16
# The re-centring pass keeps cross-sections at least this share of the typical one: a dash's
# rounded ends, whose centroids depend on the heading, are left to the passages.
RECENTRE_MIN_WIDTH_SHARE = 0.9
# Moving average over +-this many line widths along clean stretches: removes pixel noise, shifts
# a 0.4 m bend by < 1 mm.
SMOOTHING_HALF_WIDTHS = 0.25

_SECTION_CLEAN = 'clean'
_SECTION_THIN = 'thin'
_SECTION_WIDE = 'wide'
_SECTION_NONE = 'none'
_Section = collections.namedtuple('_Section', ['status', 'centre_px', 'width_px'])


def course_from_image(image, floor_size_m, start_pose=None, name='image', line_width_m=None):
    """
    Build a course from an image of the floor with a yellow line painted on it.

    The course starts at the centre-line point nearest ``start_pose`` and runs in the direction
    closest to its yaw (where branches cross there, along the branch closest to the yaw).
    Without a start pose it starts at the centre-line point nearest the floor centre and runs
    counter-clockwise (positive enclosed area; for a figure-eight, the direction in which its
    larger lobe runs counter-clockwise). Corners of up to ``MAX_TURN_RAD`` become sharp
    vertices, crossings are passed straight through and gaps of up to ``MAX_GAP_M`` bridged.

    :param image: path of a PNG or JPEG file (alpha is dropped), or an RGB uint8 array of shape
        (N, N, 3); row 0 is the north edge, column 0 the west edge.
    :param floor_size_m: side of the square floor the image covers, in metres.
    :param start_pose: ``(x_m, y_m, yaw_rad)`` near the line, or None.
    :param name: name of the course.
    :param line_width_m: width of the line in metres; measured from the image when None.
    :return: the course, carrying the image as its floor.
    :raises FileNotFoundError: if ``image`` is a path to no file.
    :raises ValueError: if the image cannot be read, is not square or larger than
        ``MAX_IMAGE_SIDE_PX`` a side (checked in a file's header before decoding), holds no
        yellow line or a line that forks, the start pose is farther than
        ``MAX_START_DISTANCE_M`` from the line, or the line does not close into a loop.
    """
    if not (math.isfinite(floor_size_m) and floor_size_m > 0.0):
        raise ValueError(f'floor_size_m must be positive and finite, got {floor_size_m}.')
    image_rgb = _read_rgb(image)
    size_px = image_rgb.shape[0]
    px_per_m = size_px / floor_size_m
    coverage = _line_coverage(image_rgb)
    line_pixels = coverage > 0.0
    line_rows, line_cols = np.nonzero(line_pixels)
    if len(line_rows) == 0:
        raise ValueError(
            'the image holds no yellow line pixels; check that the line is painted in a '
            'saturated yellow (hue about 60 degrees) on a grey floor.')
    width_px, ridge_pixels = _line_ridge(line_pixels)

    if start_pose is None:
        start_xy, forward_xy = np.zeros(2), None
    else:
        x_m, y_m, yaw_rad = _checked_pose(start_pose)
        start_xy = np.array([x_m, y_m])
        forward_xy = np.array([math.cos(yaw_rad), math.sin(yaw_rad)])
    target_px = np.array(world_to_texture_px(*start_xy, size_px, floor_size_m))
    if start_pose is not None:
        line_px = np.stack([line_cols, line_rows], axis=1)
        nearest_m = np.min(np.hypot(*(line_px - target_px).T)) / px_per_m
        if nearest_m > MAX_START_DISTANCE_M:
            raise ValueError(
                f'the start pose ({x_m:.3f}, {y_m:.3f}) m is {nearest_m:.2f} m from the nearest '
                f'line pixel; put it within {MAX_START_DISTANCE_M} m of the line.')

    ridge_rows, ridge_cols = np.nonzero(ridge_pixels)
    ridge_px = np.stack([ridge_cols, ridge_rows], axis=1).astype(float)
    tracer = _Tracer(coverage, width_px, px_per_m)
    seed_px, seed_heading = tracer.find_seed(
        ridge_px[np.argsort(np.hypot(*(ridge_px - target_px).T))])
    runs, closed_by_run = tracer.trace(seed_px, seed_heading,
                                       np.count_nonzero(line_pixels) / width_px)
    loop_px = tracer.join_runs(runs, closed_by_run)
    _check_no_branches(line_pixels, loop_px, tracer.line_width_px(), px_per_m)
    loop_xy = np.stack(texture_px_to_world(loop_px[:, 0], loop_px[:, 1], size_px,
                                           floor_size_m), axis=1)
    measured_width_m = tracer.line_width_px() / px_per_m
    course_width_m = measured_width_m if line_width_m is None else float(line_width_m)

    ordered_xy = _loop_from_start(loop_xy, start_xy, forward_xy)
    return Course(ordered_xy, line_width_m=course_width_m, floor_size_m=floor_size_m,
                  name=name, floor_image_rgb=image_rgb)


def _check_no_branches(line_pixels, loop_px, width_px, px_per_m):
    """
    Refuse paint that the traced loop does not run along: a Y-junction's other branch, a spur.

    The march passes junctions straight on, so it closes a loop along one branch and never
    sees the others; a robot on such a track would choose a branch the course does not score.

    :param line_pixels: boolean mask of the line pixels.
    :param loop_px: (N, 2) points of the traced closed centre line as (column, row).
    :param width_px: the line width in pixels.
    :param px_per_m: image pixels per metre of floor.
    :raises ValueError: if a patch of paint at least a line width square lies farther than
        ``MAX_OFF_LOOP_WIDTHS`` line widths from the loop.
    """
    shift = 1 << BRANCH_DRAW_SHIFT_BITS
    near_loop = np.zeros(line_pixels.shape, dtype=np.uint8)
    reach_px = MAX_OFF_LOOP_WIDTHS * width_px
    cv2.polylines(near_loop, [np.round(loop_px * shift).astype(np.int32)], True, 1,
                  2 * int(math.ceil(reach_px)) + 1, cv2.LINE_8, shift=BRANCH_DRAW_SHIFT_BITS)
    off_loop = (line_pixels & (near_loop == 0)).astype(np.uint8)
    count, _, stats, centroids = cv2.connectedComponentsWithStats(off_loop, connectivity=8)
    min_area_px = max(width_px * width_px, 1.0)
    patches = [index for index in range(1, count)
               if stats[index, cv2.CC_STAT_AREA] >= min_area_px]
    if patches:
        largest = max(patches, key=lambda index: stats[index, cv2.CC_STAT_AREA])
        column, row = centroids[largest]
        branch_m = stats[largest, cv2.CC_STAT_AREA] / width_px / px_per_m
        raise ValueError(
            f'the line branches: {branch_m:.2f} m of line around pixel (column {column:.0f}, '
            f'row {row:.0f}) is off the loop '
            'traced (a Y-junction, a spur or a second line); a course must be one closed '
            'loop, which may cross itself but not fork.')


def _checked_pose(pose):
    """
    Check a start pose.

    :param pose: ``(x_m, y_m, yaw_rad)``.
    :return: the pose as three floats.
    :raises ValueError: if it is not three finite numbers.
    """
    try:
        values = tuple(float(value) for value in pose)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 3 or not all(math.isfinite(value) for value in values):
        raise ValueError(f'start_pose must be three finite numbers (x_m, y_m, yaw_rad), got '
                         f'{pose!r}.')
    return values


def _read_rgb(image):
    """
    Read or check the floor image.

    :param image: a path (str or ``pathlib.Path``) or an RGB uint8 (N, N, 3) array.
    :return: the RGB uint8 image, C-contiguous.
    :raises FileNotFoundError: if the path names no file.
    :raises ValueError: if the file is not an image, the array is not RGB uint8, or the image
        is not square.
    """
    if isinstance(image, (str, pathlib.Path)):
        path = pathlib.Path(image)
        if not path.is_file():
            raise FileNotFoundError(f'no course image file at {str(path)!r}.')
        _check_image_size(image_header_size(path), repr(str(path)))
        # IMREAD_COLOR drops alpha, expands grey and reduces 16-bit images to 8 bits.
        image_bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image_bgr is None:
            raise ValueError(
                f'cannot read {str(path)!r} as an image; give a PNG or JPEG file.')
        image_rgb = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGB)
        source = repr(str(path))
    else:
        image_rgb = np.asarray(image)
        if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
            raise ValueError(
                'a course image array must be RGB uint8 of shape (N, N, 3), got '
                f'{image_rgb.dtype} of shape {image_rgb.shape}.')
        source = 'the image array'
        _check_image_size(image_rgb.shape[1::-1], source)
        image_rgb = np.ascontiguousarray(image_rgb)
    height_px, width_px = image_rgb.shape[:2]
    if height_px != width_px:
        raise ValueError(
            f'{source} is {width_px}x{height_px} px; a course image must be square because '
            'it covers the whole square floor.')
    return image_rgb


def image_header_size(path):
    """
    Read a PNG's or JPEG's size from its header, without decoding the image.

    :param path: the file's path.
    :return: ``(width_px, height_px)``.
    :raises ValueError: if the file is neither a PNG nor a JPEG, or its header is cut short.
    """
    unreadable = ValueError(f'cannot read {str(path)!r} as an image; give a PNG or JPEG file.')
    with open(path, 'rb') as image_file:
        start = image_file.read(len(PNG_SIGNATURE))
        if start == PNG_SIGNATURE:
            # The first chunk is IHDR: length, type, then width and height, big-endian.
            header = image_file.read(16)
            if len(header) < 16 or header[4:8] != b'IHDR':
                raise unreadable
            return struct.unpack('>II', header[8:16])
        if not start.startswith(JPEG_SIGNATURE):
            raise unreadable
        image_file.seek(len(JPEG_SIGNATURE))
        while True:
            marker = image_file.read(2)
            if len(marker) < 2 or marker[0] != 0xFF:
                raise unreadable
            if marker[1] == 0xFF:
                # Fill bytes before a marker.
                image_file.seek(-1, 1)
                continue
            if marker[1] in JPEG_STANDALONE_MARKERS:
                continue
            length_bytes = image_file.read(2)
            if len(length_bytes) < 2:
                raise unreadable
            (length,) = struct.unpack('>H', length_bytes)
            if marker[1] in JPEG_START_OF_FRAME:
                # Precision (1 byte), then height and width.
                frame = image_file.read(5)
                if len(frame) < 5:
                    raise unreadable
                height_px, width_px = struct.unpack('>HH', frame[1:5])
                return width_px, height_px
            if length < 2:
                raise unreadable
            image_file.seek(length - 2, 1)


def _check_image_size(size_px, source):
    """
    Refuse an image too large to trace in reasonable time and memory.

    :param size_px: ``(width_px, height_px)``.
    :param source: how to name the image in the message.
    :raises ValueError: if a side exceeds ``MAX_IMAGE_SIDE_PX`` or is zero.
    """
    width_px, height_px = size_px
    if not (0 < width_px <= MAX_IMAGE_SIDE_PX and 0 < height_px <= MAX_IMAGE_SIDE_PX):
        raise ValueError(
            f'{source} is {width_px}x{height_px} px; a course image may be at most '
            f'{MAX_IMAGE_SIDE_PX}x{MAX_IMAGE_SIDE_PX} px; scale it down.')


def _line_coverage(image_rgb):
    """
    Estimate each pixel's share of yellow line paint, relative to typical solid paint.

    :param image_rgb: RGB uint8 image.
    :return: float32 array of the image's shape, 0 for floor, 1 for typical solid line paint
        (less where the line is lit dimly).
    """
    hsv = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2HSV)
    # Saturation times value is max - min, the chroma, linear in the share of paint.
    chroma = hsv[:, :, 1].astype(np.float32) * hsv[:, :, 2] / 255.0
    hue_offset = np.abs(hsv[:, :, 0].astype(np.int16) - YELLOW_HUE)
    yellow = (hue_offset <= YELLOW_HUE_TOLERANCE) & (chroma >= MIN_LINE_CHROMA)
    if not np.any(yellow):
        return np.zeros(chroma.shape, dtype=np.float32)
    typical_paint = np.percentile(chroma[yellow], SOLID_PAINT_PERCENTILE)
    coverage = np.where(yellow, chroma / typical_paint, np.float32(0.0))
    return np.minimum(coverage, 1.0, out=coverage)


def _line_ridge(line_pixels):
    """
    Find the ridge of the line pixels' distance transform and estimate the line width from it.

    :param line_pixels: boolean mask of the line pixels, not empty.
    :return: ``(width_px, ridge_pixels)``: the typical line width in pixels and a boolean mask
        of the pixels farthest from the floor across the line (its middle).
    """
    mask = line_pixels.astype(np.uint8)
    distance_px = cv2.distanceTransform(mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    ridge = (distance_px >= cv2.dilate(distance_px, np.ones((3, 3), np.uint8))) & line_pixels
    # A band of w pixels has its middle pixel (w + 1) / 2 from the nearest floor pixel.
    return max(2.0 * float(np.median(distance_px[ridge])) - 1.0, 1.0), ridge


def _unit(vector):
    """
    Scale a 2-D vector to unit length.

    :param vector: a non-zero 2-D vector.
    :return: the unit vector.
    """
    return vector / math.hypot(vector[0], vector[1])


def _turned(heading, angle_rad):
    """
    Rotate a 2-D direction.

    :param heading: 2-D direction.
    :param angle_rad: angle to rotate by (positive from the first axis toward the second).
    :return: the rotated direction.
    """
    cos_angle, sin_angle = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([cos_angle * heading[0] - sin_angle * heading[1],
                     sin_angle * heading[0] + cos_angle * heading[1]])


def _moving_average(points, half_window, cyclic):
    """
    Smooth a polyline with a centred moving average.

    :param points: (N, 2) points.
    :param half_window: points either side in the average.
    :param cyclic: whether the polyline is a closed loop; an open one keeps its end points, the
        window shrinking symmetrically toward them.
    :return: (N, 2) smoothed points.
    """
    count = len(points)
    if half_window < 1 or count < 3:
        return points
    if cyclic:
        half_window = min(half_window, (count - 1) // 2)
        padded = np.concatenate([points[-half_window:], points, points[:half_window]])
        sums = np.concatenate([np.zeros((1, 2)), np.cumsum(padded, axis=0)])
        return (sums[2 * half_window + 1:] - sums[:count]) / (2 * half_window + 1)
    index = np.arange(count)
    reach = np.minimum(np.minimum(index, count - 1 - index), half_window)
    sums = np.concatenate([np.zeros((1, 2)), np.cumsum(points, axis=0)])
    totals = sums[index + reach + 1] - sums[index - reach]
    return totals / (2 * reach + 1)[:, np.newaxis]


def _end_tangent(points):
    """
    Estimate the tangent at the last point of a stretch of centre line.

    Fits x and y as quadratics of arc length (a line for few points) and differentiates at the
    end, so a bend does not make the tangent lag.

    :param points: (N, 2) points in order of travel, N >= 2.
    :return: the unit tangent at the last point, pointing onward.
    """
    arc_px = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    arc_px -= arc_px[-1]
    degree = 2 if len(points) >= QUADRATIC_FIT_MIN_POINTS else 1
    slope = [np.polyfit(arc_px, points[:, axis], degree)[-2] for axis in (0, 1)]
    return _unit(np.array(slope))


def _fit_across(before, after, step_px):
    """
    Bridge a passage with a cubic fitted to the centre line on both sides of it.

    :param before: (N, 2) points leading up to the passage, its start last.
    :param after: (M, 2) points leading away from the passage, its end first.
    :param step_px: spacing of the bridging points.
    :return: (K, 2) points strictly inside the passage, joining its ends exactly.
    """
    start, end = before[-1], after[0]
    chord_px = math.hypot(*(end - start))
    count = int(math.ceil(chord_px / step_px))
    if count < 2:
        return np.empty((0, 2))
    # Parameter: distance along the points, straight across the passage.
    before_u = -np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(before[::-1], axis=0).T))])
    after_u = chord_px + np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(after, axis=0).T))])
    u = np.concatenate([before_u[::-1], after_u])
    points = np.concatenate([before, after])
    degree = min(BRIDGE_FIT_DEGREE, len(points) - 1)
    coefficients = [np.polyfit(u, points[:, axis], degree) for axis in (0, 1)]

    def curve(values):
        return np.stack([np.polyval(coefficient, values) for coefficient in coefficients], 1)

    fraction = np.arange(1, count)[:, np.newaxis] / count
    start_miss, end_miss = start - curve([0.0])[0], end - curve([chord_px])[0]
    return (curve(fraction[:, 0] * chord_px) + (1.0 - fraction) * start_miss
            + fraction * end_miss)


def _loop_from_start(loop_xy, start_xy, forward_xy):
    """
    Reorder a closed centre line to start at its point nearest a position.

    Where branches cross, every point within ``START_TIE_M`` of the nearest counts as nearest,
    and the branch running closest to the direction of travel is taken.

    :param loop_xy: (N, 2) points of the closed centre line in metres, last not repeated.
    :param start_xy: the position in metres.
    :param forward_xy: unit direction of travel to follow as closely as possible, or None for
        counter-clockwise (positive signed area) from the single nearest point.
    :return: (M, 2) points in metres, the first the nearest point, in the chosen direction.
    """
    segment_xy = np.roll(loop_xy, -1, axis=0) - loop_xy
    length_m = np.hypot(*segment_xy.T)
    fraction = np.clip(np.einsum('ij,ij->i', start_xy - loop_xy, segment_xy) / length_m ** 2,
                       0.0, 1.0)
    foot_xy = loop_xy + fraction[:, np.newaxis] * segment_xy
    distance_m = np.hypot(*(foot_xy - start_xy).T)
    if forward_xy is None:
        index = int(np.argmin(distance_m))
        after_xy = np.roll(loop_xy, -1, axis=0)
        backward = np.sum(loop_xy[:, 0] * after_xy[:, 1] - after_xy[:, 0] * loop_xy[:, 1]) < 0.0
    else:
        alignment = segment_xy @ forward_xy / length_m
        nearest = distance_m <= np.min(distance_m) + START_TIE_M
        best_alignment = np.max(np.abs(alignment[nearest]))
        candidates = nearest & (np.abs(alignment) >= best_alignment - START_ALIGNMENT_TIE)
        index = int(np.argmin(np.where(candidates, distance_m, np.inf)))
        backward = alignment[index] < 0.0
    onward_xy = np.concatenate([loop_xy[index + 1:], loop_xy[:index + 1]])
    if backward:
        onward_xy = onward_xy[::-1]
    return np.concatenate([foot_xy[index:index + 1], onward_xy])


class _Tracer:
    """March along a painted line in a coverage image and rebuild its centre line."""

    def __init__(self, coverage, width_px, px_per_m):
        """
        Prepare to trace.

        :param coverage: float32 image of each pixel's share of typical line paint.
        :param width_px: typical line width in pixels.
        :param px_per_m: image pixels per metre of floor.
        """
        # A zero border lets samples off the image read as floor without bounds checks.
        self._coverage = np.pad(coverage, 2)
        self._width_px = width_px
        self._px_per_m = px_per_m
        self._step_px = max(min(STEP_M * px_per_m, MAX_STEP_WIDTHS * width_px), MIN_STEP_PX)
        # A thin line's soft edges are as wide as a thick one's: the section reaches past them.
        half_px = max(SECTION_HALF_WIDTHS * width_px,
                      width_px / 2.0 + EDGE_FUZZ_PX + MIN_SECTION_MARGIN_PX)
        sample_count = int(math.ceil(half_px / SECTION_SAMPLE_PX))
        self._offsets_px = np.arange(-sample_count, sample_count + 1) * SECTION_SAMPLE_PX
        self._fuzz_samples = int(round(EDGE_FUZZ_PX / SECTION_SAMPLE_PX))
        self._heading_back = max(1, int(round(HEADING_BASELINE_WIDTHS * width_px
                                              / self._step_px)))
        self._max_uncertain_px = MAX_JUNCTION_WIDTHS * width_px
        turn_steps_rad = np.arange(1, int(round(MAX_TURN_RAD / TURN_STEP_RAD)) + 1) * TURN_STEP_RAD
        # Straight on first, then left and right alternately, smallest turn first.
        turns_rad = np.concatenate([[0.0], np.stack([turn_steps_rad, -turn_steps_rad], 1).ravel()])
        corner_probes = [(TURN_PROBE_WIDTHS * width_px, turn_rad) for turn_rad in turns_rad]
        gap_distances_px = np.arange(
            GAP_PROBE_START_WIDTHS * width_px,
            MAX_GAP_M * px_per_m + GAP_PROBE_END_WIDTHS * width_px,
            GAP_PROBE_STEP_WIDTHS * width_px)
        gap_turns_rad = turns_rad[np.abs(turns_rad) <= MAX_GAP_TURN_RAD + 1e-9]
        self._probes = corner_probes + [(distance_px, turn_rad) for distance_px in gap_distances_px
                                        for turn_rad in gap_turns_rad]
        self._section_widths_px = []
        self._recentred_widths_px = []

    def _sample(self, points):
        """
        Read the coverage at points by bilinear interpolation.

        :param points: (N, 2) points as (column, row).
        :return: (N,) coverage values, 0 off the image.
        """
        limit = np.array(self._coverage.shape[::-1]) - 2
        shifted = np.clip(points + 2.0, 0.0, limit)
        corner = np.floor(shifted).astype(int)
        fraction = shifted - corner
        col, row = corner[:, 0], corner[:, 1]
        fc, fr = fraction[:, 0], fraction[:, 1]
        image = self._coverage
        return ((image[row, col] * (1.0 - fc) + image[row, col + 1] * fc) * (1.0 - fr)
                + (image[row + 1, col] * (1.0 - fc) + image[row + 1, col + 1] * fc) * fr)

    def section(self, point, heading):
        """
        Measure the line across a heading through a point.

        The paint is measured against the solid paint within ``MAX_RECENTRE_WIDTHS`` of the
        point, so a dimly lit line keeps its width.

        :param point: the predicted centre-line point as (column, row).
        :param heading: unit direction of the line there.
        :return: a ``_Section``: clean with the paint's centroid and width when one line's
            width of paint is near the point, thin when there is less, wide when the paint
            reaches the section's ends or is too wide (a corner or crossing), none when there
            is no or hardly any paint near the point.
        """
        normal = np.array([-heading[1], heading[0]])
        weights = self._sample(point + self._offsets_px[:, np.newaxis] * normal)
        middle = len(weights) // 2
        max_recentre_samples = int(MAX_RECENTRE_WIDTHS * self._width_px / SECTION_SAMPLE_PX)
        solid_paint = np.max(weights[middle - max_recentre_samples:
                                     middle + max_recentre_samples + 1])
        if solid_paint < MIN_SECTION_PAINT:
            return _Section(_SECTION_NONE, None, 0.0)
        weights = np.minimum(weights / solid_paint, 1.0)
        painted = weights >= LINE_PIXEL_COVERAGE
        painted_index = np.flatnonzero(painted)
        # The painted sample nearest the prediction, within the re-centring limit.
        nearest = painted_index[np.argmin(np.abs(painted_index - middle))]
        unpainted = np.flatnonzero(~painted)
        first = unpainted[unpainted < nearest].max(initial=-1) + 1
        last = unpainted[unpainted > nearest].min(initial=len(weights)) - 1
        low = first - self._fuzz_samples
        high = last + self._fuzz_samples
        if low < 0 or high >= len(weights) or np.any(painted[low:first]) \
                or np.any(painted[last + 1:high + 1]):
            return _Section(_SECTION_WIDE, None, 0.0)
        run_weights = weights[low:high + 1]
        width_px = float(np.sum(run_weights)) * SECTION_SAMPLE_PX
        if width_px > MAX_SECTION_WIDTHS * self._width_px:
            return _Section(_SECTION_WIDE, None, width_px)
        if width_px < MIN_SECTION_WIDTHS * self._width_px:
            return _Section(_SECTION_NONE, None, width_px)
        offset_px = float(np.dot(run_weights, self._offsets_px[low:high + 1])) / np.sum(
            run_weights)
        status = _SECTION_CLEAN if width_px >= FULL_SECTION_WIDTHS * self._width_px \
            else _SECTION_THIN
        return _Section(status, point + offset_px * normal, width_px)

    def find_seed(self, candidates_px):
        """
        Find a clean point of the line to start tracing from, and the line's direction there.

        :param candidates_px: (N, 2) pixels in the middle of the line as (column, row), best
            first.
        :return: ``(point, heading)``: a centre-line point and a unit tangent.
        :raises ValueError: if no candidate lies on a clean stretch of line.
        """
        tried_px = []
        for candidate in candidates_px:
            if any(math.hypot(*(candidate - tried)) < self._width_px / 2.0
                   for tried in tried_px):
                continue
            tried_px.append(candidate)
            seed = self._seed_at(candidate)
            if seed is not None:
                return seed
            if len(tried_px) >= MAX_SEED_ATTEMPTS:
                break
        raise ValueError(
            'no clean stretch of line (one line width wide, no corner or crossing) was found '
            'near the start; check that the line is a single ribbon of even width.')

    def _seed_at(self, candidate):
        """
        Find the centre line and its direction near a line pixel.

        :param candidate: a line pixel as (column, row).
        :return: ``(point, heading)``, or None if the line is not clean there.
        """
        best = None
        for angle_rad in np.arange(0.0, math.pi, SEED_ANGLE_STEP_RAD):
            heading = np.array([math.cos(angle_rad), math.sin(angle_rad)])
            section = self.section(candidate, heading)
            if section.status == _SECTION_CLEAN and (best is None
                                                     or section.width_px < best[0].width_px):
                best = (section, heading)
        if best is None:
            return None
        (section, heading) = best
        reach_px = HEADING_BASELINE_WIDTHS * self._width_px
        ahead = self.section(section.centre_px + reach_px * heading, heading)
        behind = self.section(section.centre_px - reach_px * heading, heading)
        if ahead.status != _SECTION_CLEAN or behind.status != _SECTION_CLEAN:
            return None
        heading = _unit(ahead.centre_px - behind.centre_px)
        centred = self.section(section.centre_px, heading)
        if centred.status != _SECTION_CLEAN:
            return None
        return centred.centre_px, heading

    def _continuation(self, point, heading):
        """
        Look for the line's continuation where it ends ahead.

        First around a corner: one probe distance ahead, smallest turn first, up to
        ``MAX_TURN_RAD``. Then across a gap: nearest first, turning up to ``MAX_GAP_TURN_RAD``
        (the line bends on across the gap), up to ``MAX_GAP_M`` of floor between the ends.

        :param point: last clean centre-line point.
        :param heading: direction of travel there.
        :return: a clean centre-line point of the continuation, or None.
        """
        for distance_px, turn_rad in self._probes:
            direction = _turned(heading, turn_rad)
            section = self.section(point + distance_px * direction, direction)
            if section.status == _SECTION_CLEAN:
                return section.centre_px
        return None

    def trace(self, seed, seed_heading, painted_length_px):
        """
        March around the line from a seed until back at the seed.

        :param seed: clean centre-line point to start at.
        :param seed_heading: unit direction to march in.
        :param painted_length_px: painted area over line width, the line's length if unbroken.
        :return: ``(runs, closed_by_run)``: the clean stretches in order of travel, each a list
            of points, the first starting at the seed, and whether the last stretch runs into the
            seed without a passage between.
        :raises ValueError: if the line ends, or the march goes on too long to be one loop.
        """
        runs = [[seed]]
        point, heading, clean_heading = seed, seed_heading, seed_heading
        uncertain_px = 0.0
        travelled_px = 0.0
        left_seed = False
        max_travel_px = MAX_TRACE_LENGTH_FACTOR * painted_length_px
        recent_headings = collections.deque(
            maxlen=max(2, int(round(REVERSAL_WINDOW_WIDTHS * self._width_px / self._step_px))))
        while True:
            predicted = point + self._step_px * heading
            section = self.section(predicted, heading)
            last_clean = runs[-1][-1]
            # Whether this step adds a point, and whether that point starts a new stretch.
            appended = section.status != _SECTION_WIDE and section.status != _SECTION_THIN
            new_run = section.status == _SECTION_NONE or uncertain_px > 0.0
            if section.status == _SECTION_CLEAN:
                if new_run:
                    runs.append([])
                run = runs[-1]
                run.append(section.centre_px)
                self._section_widths_px.append(section.width_px)
                if len(run) > 1:
                    heading = _unit(run[-1] - run[max(0, len(run) - 1 - self._heading_back)])
                clean_heading = heading
                point = section.centre_px
                uncertain_px = 0.0
            elif section.status == _SECTION_NONE:
                found = self._continuation(last_clean, clean_heading)
                if found is None:
                    raise ValueError(self._open_line_message(last_clean))
                runs.append([found])
                heading = clean_heading = _unit(found - last_clean)
                point = found
                uncertain_px = 0.0
            else:
                # Through a corner, a crossing or a dash's rounded end: straight on.
                point = predicted
                uncertain_px += self._step_px
                if uncertain_px > self._max_uncertain_px:
                    raise ValueError(self._open_line_message(last_clean))
            travelled_px += self._step_px
            recent_headings.append(heading)
            if float(np.dot(heading, recent_headings[0])) < REVERSAL_HEADING_COS:
                raise ValueError(
                    f'the trace turned back on itself near pixel (column {last_clean[0]:.0f}, '
                    f'row {last_clean[1]:.0f}); check that the corners of the line turn by at '
                    f'most {math.degrees(MAX_TURN_RAD):.0f} degrees and that no gap lies on a '
                    'tight bend.')
            if travelled_px > max_travel_px:
                raise ValueError(
                    f'the trace ran {travelled_px / self._px_per_m:.1f} m without returning to '
                    'its start; check that the line is one closed loop that does not fork (a '
                    'Y-junction or a spur sends the trace round again).')
            from_seed = point - seed
            along_px = float(np.dot(from_seed, seed_heading))
            lateral_px = abs(float(seed_heading[0] * from_seed[1]
                                   - seed_heading[1] * from_seed[0]))
            if math.hypot(*from_seed) > CLOSE_AWAY_WIDTHS * self._width_px:
                left_seed = True
            elif (left_seed and along_px >= 0.0
                  and lateral_px < CLOSE_LATERAL_WIDTHS * self._width_px
                  and float(np.dot(heading, seed_heading)) > CLOSE_MIN_HEADING_COS):
                # Drop the point past the seed, and a stretch it alone made.
                if appended:
                    runs[-1].pop()
                    if not runs[-1]:
                        runs.pop()
                return runs, appended and not new_run

    def _open_line_message(self, end_px):
        """
        Describe where the line ends.

        :param end_px: last clean centre-line point as (column, row).
        :return: the error message.
        """
        return (f'the line ends near pixel (column {end_px[0]:.0f}, row {end_px[1]:.0f}) with '
                f'no continuation around a corner of up to {math.degrees(MAX_TURN_RAD):.0f} '
                f'degrees or across a gap of up to {MAX_GAP_M} m; check that the line is one '
                'closed loop.')

    def median_section_width_px(self):
        """
        Return the median width of the clean cross-sections met while marching.

        :return: the width in pixels.
        """
        return float(np.median(self._section_widths_px))

    def line_width_px(self):
        """
        Return the line width measured across the rebuilt centre line.

        The median of the full-width cross-sections of the re-centring pass (those of the march
        when there were none), which leaves out a dash's rounded ends.

        :return: the width in pixels.
        """
        return float(np.median(self._recentred_widths_px or self._section_widths_px))

    def join_runs(self, runs, closed_by_run):
        """
        Rebuild the closed centre line from the clean stretches met while marching.

        The stretches are smoothed and the passages between them rebuilt. Then every stretch
        point is re-centred across the tangent of that first loop, which the march only knew
        from the points behind it, and the loop is rebuilt again.

        :param runs: clean stretches in order around the loop, each a list of points.
        :param closed_by_run: whether the last stretch runs straight into the first.
        :return: (N, 2) points of the closed centre line as (column, row).
        """
        if closed_by_run and len(runs) > 1:
            runs = [runs[-1] + runs[0]] + runs[1:-1]
        cyclic = closed_by_run and len(runs) == 1
        stretches = [np.array(run) for run in runs]
        loop, owners = self._assemble(stretches, cyclic)
        recentred = self._recentre(loop, owners)
        if recentred:
            loop, _ = self._assemble(recentred, cyclic and len(recentred) == 1)
        return loop

    def _assemble(self, stretches, cyclic):
        """
        Smooth the stretches and join them into a loop across the passages between them.

        Stretches shorter than ``MIN_STRETCH_WIDTHS`` line widths become part of a passage.

        :param stretches: (N, 2) arrays of clean centre-line points, in order around the loop.
        :param cyclic: whether there is one stretch running all around the loop.
        :return: ``(loop, owners)``: (M, 2) points of the loop and, for each, the index of its
            stretch among those kept (-1 for points rebuilt in a passage).
        """
        half_window = int(round(SMOOTHING_HALF_WIDTHS * self._width_px / self._step_px))
        lengths_px = [np.sum(np.hypot(*np.diff(stretch, axis=0).T)) for stretch in stretches]
        if not cyclic and max(lengths_px) >= MIN_STRETCH_WIDTHS * self._width_px:
            stretches = [stretch for stretch, length_px in zip(stretches, lengths_px)
                         if length_px >= MIN_STRETCH_WIDTHS * self._width_px]
        if cyclic:
            loop = _moving_average(stretches[0], half_window, cyclic=True)
            return loop, np.zeros(len(loop), dtype=int)
        smoothed = [_moving_average(stretch, half_window, cyclic=False) for stretch in stretches]
        pieces = []
        owners = []
        for index, stretch in enumerate(smoothed):
            passage = self._passage(smoothed, index)
            pieces.extend([stretch, passage])
            owners.extend([np.full(len(stretch), index), np.full(len(passage), -1)])
        return np.concatenate(pieces), np.concatenate(owners)

    def _recentre(self, loop, owners):
        """
        Re-centre the stretch points of a loop across the loop's own tangents.

        :param loop: (N, 2) points of the closed loop.
        :param owners: for each point, the index of its stretch, -1 for passage points.
        :return: the re-centred stretches as (M, 2) arrays, points whose cross-section is not
            clean left out, and stretches left empty dropped.
        """
        reach = max(1, int(round(HEADING_BASELINE_WIDTHS * self._width_px / self._step_px)))
        tangents = np.roll(loop, -reach, axis=0) - np.roll(loop, reach, axis=0)
        kept = [[] for _ in range(np.max(owners) + 1)]
        min_width_px = RECENTRE_MIN_WIDTH_SHARE * self.median_section_width_px()
        for point, tangent, owner in zip(loop, tangents, owners):
            if owner < 0:
                continue
            section = self.section(point, _unit(tangent))
            if section.status == _SECTION_CLEAN and section.width_px >= min_width_px:
                kept[owner].append(section.centre_px)
                self._recentred_widths_px.append(section.width_px)
        return [np.array(points) for points in kept if points]

    def _context(self, stretches, index, step):
        """
        Gather the clean centre line on one side of a passage, across shorter stretches.

        :param stretches: the clean stretches, in order around the loop.
        :param index: the stretch next to the passage.
        :param step: -1 for the side before the passage (``index`` ends at it), +1 for the side
            after it (``index`` starts at it).
        :return: (N, 2) points in order of travel spanning about ``BRIDGE_CONTEXT_WIDTHS`` line
            widths, the point at the passage last (before) or first (after).
        """
        span_px = BRIDGE_CONTEXT_WIDTHS * self._width_px
        gathered = []
        for offset in range(len(stretches)):
            stretch = stretches[(index + step * offset) % len(stretches)]
            gathered.extend(stretch[::step])
            from_passage = np.array(gathered)
            if np.sum(np.hypot(*np.diff(from_passage, axis=0).T)) >= span_px:
                break
        return from_passage[::step]

    def _stretch_end(self, points):
        """
        Take the end of a stretch for fitting its tangent.

        :param points: (N, 2) points of a stretch in order of travel.
        :return: the last points, spanning about ``END_FIT_WIDTHS`` line widths.
        """
        count = max(2, int(round(END_FIT_WIDTHS * self._width_px / self._step_px)) + 1)
        return points[-count:]

    def _passage(self, stretches, index):
        """
        Rebuild the centre line between a clean stretch and the next one.

        A passage over paint turning sharply is a corner: the two stretches' lines meet at its
        vertex. Anything else (a crossing, a gap, a gentle bend) is bridged by a cubic fitted to
        the centre line on both sides.

        :param stretches: the clean stretches, in order around the loop.
        :param index: the stretch ending where the passage starts.
        :return: (K, 2) points strictly between the stretches.
        """
        before = stretches[index]
        after = stretches[(index + 1) % len(stretches)]
        start, end = before[-1], after[0]
        chord = end - start
        if math.hypot(*chord) < self._step_px:
            return np.empty((0, 2))
        start_tangent = (_end_tangent(self._stretch_end(before)) if len(before) > 1
                         else _unit(chord))
        end_tangent = (-_end_tangent(self._stretch_end(after[::-1])) if len(after) > 1
                       else _unit(chord))
        turn_sin = float(start_tangent[0] * end_tangent[1] - start_tangent[1] * end_tangent[0])
        turn_rad = abs(math.atan2(turn_sin, float(np.dot(start_tangent, end_tangent))))
        fractions = (np.arange(BRIDGE_PAINT_SAMPLES) + 0.5) / BRIDGE_PAINT_SAMPLES
        painted = np.min(self._sample(start + fractions[:, np.newaxis] * chord)) \
            >= MIN_PASSAGE_PAINT
        if painted and turn_rad >= CORNER_MIN_TURN_RAD:
            # Solve start + a start_tangent = end - b end_tangent.
            arms = np.linalg.solve(np.stack([start_tangent, end_tangent], axis=1), chord)
            max_arm_px = MAX_CORNER_ARM_WIDTHS * self._width_px
            if np.all(arms > 0.0) and np.all(arms < max_arm_px):
                return (start + arms[0] * start_tangent)[np.newaxis]
        return _fit_across(self._context(stretches, index, -1),
                           self._context(stretches, (index + 1) % len(stretches), 1),
                           self._step_px)
