"""
A working detector configuration from one camera frame: the pure core of ``calibrate``.

The user shows a piece of the line (:mod:`followbot.line_sample`: a pixel on it, or a box
around it), or nothing: then the line is looked for with every colour preset.

1. **The proposal** (:func:`propose`): each colour preset (yellow, white, black) is tried,
   then, when none finds the line shown, a ``custom`` HSV range taken from the piece's
   colours (percentiles with a margin), narrowed until it takes few floor pixels
   (:func:`custom_bounds`).
2. **The verification** (:func:`verify`): a configuration is tried by running the follower's
   own detector on the frame with it. The line shown is the patch of the configuration's
   colour judgement (made on the whole frame, :func:`colour_mask`) that holds the piece; the
   colour must take most of the piece, and the detector's stripes must lie on the patch in
   at least half the bands crossing it, and more often than elsewhere.
3. **The bands** (:func:`bands_over`): bands beyond the rows where the line is seen (above
   the horizon of a camera looking ahead, or below the line of a camera looking down at it)
   see only other things; then the bands are spread over the line's rows.
4. **The output**: the follower's parameters (:func:`follower_parameters`,
   :func:`parameters_yaml`) and a picture (:func:`picture`).

No rclpy here: reading frames from files, recordings and topics is :mod:`followbot.calibrate`'s.
"""

import dataclasses
import math
from typing import NamedTuple

import cv2
from followbot import line_colour
from followbot.ground_projection import CameraInfoError, CameraIntrinsics
from followbot.line_detector import (band_rows, DetectorConfig, draw_debug, LineDetector,
                                     MIN_SEARCH_WIDTH_PX)
from followbot.line_sample import CalibrationError
import numpy as np
import yaml

PRESETS = ('yellow', 'white', 'black')
GREY_PRESETS = ('white', 'black')
CUSTOM = 'custom'
# A camera_matrix is 3x3, row by row.
CAMERA_MATRIX_SIZE = 9
# The colour judgement is made for the whole image in strips of this many rows.
STRIP_ROWS = 8
# The patch of a configuration's colour judgement holding the piece: closed with this kernel
# (bridging specks of noise), overlapping the piece's core.
CLOSE_KERNEL_PX = 3
# Custom bounds are checked against the frame outside the piece grown by this much.
PIECE_REACH_PX = 2
# A band crosses the line when the line's patch has at least this many pixels in its rows.
MIN_BAND_LINE_PX = 4
# The line runs on through rows where its colour's patch is at most this many times as wide
# as the piece shown; the bands are moved only over a line spanning this share of the image.
MAX_ROW_WIDTHS = 5.0
MIN_LINE_ROWS_SHARE = 0.15
# A configuration's colour must take at least this share of the piece's (core) pixels.
MIN_PIECE_SHARE = 0.5
# A detector stripe is on the line when the line's patch lies within this many columns of
# its centroid, in the band's rows.
ON_LINE_TOLERANCE_PX = 4
# The line must be found in at least this share of the bands it crosses.
MIN_FOUND_SHARE = 0.5
# Band placement fractions are written with this many decimals.
FRACTION_DECIMALS = 3
WIDTH_DECIMALS = 3
# Without a piece of line shown, the most confident preset must reach this confidence.
AUTOMATIC_MIN_CONFIDENCE = 0.3
# Custom HSV bounds: percentiles of the piece's colours and margins, widest first; the first
# that takes at most MAX_LOCAL_FLOOR_SHARE of the floor around the piece and at most
# MAX_FRAME_SHARE of the whole frame is kept.
CUSTOM_TRIES = (
    # (low percentile, high percentile, hue margin, saturation and value margin)
    (2.0, 98.0, 4, 25),
    (5.0, 95.0, 3, 15),
    (10.0, 90.0, 2, 8),
    (20.0, 80.0, 1, 0),
)
MAX_LOCAL_FLOOR_SHARE = 0.02
MAX_FRAME_SHARE = 0.25
# A line less saturated than this (median, 0-255) has no meaningful hue: any hue is taken.
MIN_HUE_SATURATION = 40
OPENCV_HUE_MAX = 179
HSV_CHANNEL_MAX = 255
# OpenCV hue is circular: hues within this distance of 0 or 179 are a red that wraps around.
HUE_WRAP_GUARD = 10
# Picture: the line pixels' tint, the piece's outline, how dark the frame under the mask is.
MASK_COLOUR_BGR = (255, 0, 255)
PIECE_COLOUR_BGR = (255, 255, 0)
MASK_BACKGROUND_SHARE = 0.4
PIECE_LINE_PX = 1
FOLLOWER_NODE_KEY = '/**/follower'
PARAMETERS_KEY = 'ros__parameters'


def intrinsics_from_yaml(text):
    """
    Read a camera's intrinsics from a calibration file as camera_calibration writes it.

    :param text: the YAML text (``image_width``, ``image_height``, ``camera_matrix``,
        ``distortion_model``, ``distortion_coefficients``).
    :return: the CameraIntrinsics.
    :raises CalibrationError: if the text is no such file or describes no usable camera.
    """
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise CalibrationError(f'The camera info is not YAML: {error}'.replace('\n', ' '))
    if not isinstance(document, dict) or 'camera_matrix' not in document:
        raise CalibrationError('The camera info has no camera_matrix: give a CameraInfo YAML '
                               'file as camera_calibration writes it.')
    try:
        matrix = [float(value) for value in document['camera_matrix']['data']]
        distortion = document.get('distortion_coefficients') or {}
        coefficients = tuple(float(value) for value in distortion.get('data') or ())
        size = (int(document.get('image_width', 0)), int(document.get('image_height', 0)))
    except (KeyError, TypeError, ValueError) as error:
        raise CalibrationError(f'The camera info cannot be read: {error}.') from None
    if len(matrix) != CAMERA_MATRIX_SIZE:
        raise CalibrationError(f'camera_matrix must hold {CAMERA_MATRIX_SIZE} numbers, got '
                               f'{len(matrix)}.')
    try:
        return CameraIntrinsics(
            width_px=size[0], height_px=size[1], fx_px=matrix[0], fy_px=matrix[4],
            cx_px=matrix[2], cy_px=matrix[5],
            distortion_model=str(document.get('distortion_model', '')),
            distortion=coefficients if any(coefficients) else ())
    except CameraInfoError as error:
        raise CalibrationError(f'The camera info describes no usable camera: {error}') \
            from None


def colour_mask(image, config, geometry=None):
    """
    Return which pixels of the whole frame a configuration's colour judgement takes.

    The judgement is the detector's second look (:func:`line_colour.classify`: each strip of
    rows white-balanced and judged against its floor), made on every row, not only the
    bands'. With a camera geometry, rows that see no floor are left out.

    :param image: the frame, (H, W, 3) BGR or (H, W) grey uint8.
    :param config: the DetectorConfig.
    :param geometry: the CameraGeometry, or None.
    :return: (H, W) bool.
    """
    height, width = image.shape[:2]
    starts = list(range(0, height - STRIP_ROWS + 1, STRIP_ROWS))
    if not starts or starts[-1] + STRIP_ROWS < height:
        starts.append(max(height - STRIP_ROWS, 0))
    rows = min(STRIP_ROWS, height)
    strips = np.stack([image[start:start + rows] for start in starts])
    strips = strips.reshape((len(starts), rows * width) + image.shape[2:])
    if geometry is None:
        on_floor = list(range(len(starts)))
    else:
        centres = [start + (rows - 1) / 2.0 for start in starts]
        seen = geometry.line_width_px(centres, config.line_width_m) >= MIN_SEARCH_WIDTH_PX
        on_floor = [index for index, searched in enumerate(seen) if searched]
    gains = line_colour.white_balance(strips, on_floor, config.line_colour)
    bounds = ((config.hue_min, config.saturation_min, config.value_min),
              (config.hue_max, config.saturation_max, config.value_max))
    strip_mask, _, _ = line_colour.classify(config.line_colour, strips, gains, width, on_floor,
                                            bounds)
    mask = np.zeros((height, width), bool)
    for index in sorted(on_floor, reverse=True):
        start = starts[index]
        mask[start:start + rows] = strip_mask[index].reshape(rows, width) != 0
    return mask


def line_patch(mask, sample):
    """
    Return the patch of a colour mask that holds the piece of line shown.

    :param mask: (H, W) bool, from :func:`colour_mask`.
    :param sample: the LineSample.
    :return: (H, W) bool: the connected patches of the (closed) mask touching the piece.
    """
    kernel = np.ones((CLOSE_KERNEL_PX, CLOSE_KERNEL_PX), np.uint8)
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, kernel)
    _, labels = cv2.connectedComponents(closed, connectivity=8)
    touched = np.unique(labels[sample.core & (closed != 0)])
    return np.isin(labels, touched[touched != 0]) & mask


class Verdict(NamedTuple):
    """
    Whether a configuration found the line shown, and how.

    ``piece_share`` is the share of the piece's pixels the configuration's colour takes;
    ``line_bands`` how many searched bands cross the line shown, ``on_line`` in how many the
    detector's stripe lies on it, ``elsewhere`` how many stripes lie off it.
    """

    passed: bool
    piece_share: float
    line_bands: int
    on_line: int
    elsewhere: int
    confidence: float

    def describe(self):
        """
        Say in words what the verification saw.

        :return: a clause such as ``the detector finds the line shown in 4 of the 5 bands
            that cross it, confidence 0.61``.
        """
        if self.piece_share < MIN_PIECE_SHARE:
            return f"its colour takes only {100 * self.piece_share:.0f}% of the line's pixels"
        if self.line_bands == 0:
            return ('the detector searches no band crossing the line, confidence '
                    f'{self.confidence:.2f}')
        text = (f'the detector finds the line shown in {self.on_line} of the '
                f'{self.line_bands} bands that cross it, confidence {self.confidence:.2f}')
        if self.elsewhere:
            text += (f', and {self.elsewhere} stripe(s) elsewhere: another line or something '
                     'else of its colour')
        return text


def searched_bands(height, config, geometry):
    """
    Return the bands the detector searches in a frame, nearest first.

    :param height: the frame's height.
    :param config: the DetectorConfig.
    :param geometry: the CameraGeometry or None (every band is searched).
    :return: (top, bottom) row pairs.
    """
    bands = band_rows(height, config)
    if geometry is None:
        return bands
    centres = [(top + bottom - 1) / 2.0 for top, bottom in bands]
    widths = geometry.line_width_px(centres, config.line_width_m)
    return [band for band, width in zip(bands, widths) if width >= MIN_SEARCH_WIDTH_PX]


def verify(detection, patch, piece_share, config, geometry):
    """
    Judge whether a detection found the line shown.

    :param detection: the Detection of the frame with the configuration.
    :param patch: (H, W) bool, the line shown as the configuration sees it
        (:func:`line_patch`).
    :param piece_share: the share of the piece's pixels the configuration's colour takes.
    :param config: the configuration.
    :param geometry: the CameraGeometry, or None.
    :return: the Verdict: passed when the colour takes at least MIN_PIECE_SHARE of the
        piece, and the detector found the line on its patch in at least MIN_FOUND_SHARE of
        the searched bands crossing it, and in more bands than anywhere else.
    """
    height = patch.shape[0]
    crossing = [band for band in searched_bands(height, config, geometry)
                if np.count_nonzero(patch[band[0]:band[1]]) >= MIN_BAND_LINE_PX]
    on_line = elsewhere = 0
    for band in detection.bands:
        if not band.found:
            continue
        column = int(round(band.centroid_x_px))
        first = max(column - ON_LINE_TOLERANCE_PX, 0)
        if patch[band.top_px:band.bottom_px, first:column + ON_LINE_TOLERANCE_PX + 1].any():
            on_line += 1
        else:
            elsewhere += 1
    passed = bool(piece_share >= MIN_PIECE_SHARE and crossing
                  and on_line >= MIN_FOUND_SHARE * len(crossing) and on_line > elsewhere)
    return Verdict(passed, piece_share, len(crossing), on_line, elsewhere,
                   detection.confidence)


def line_rows(patch, sample):
    """
    Return the rows over which the line shown runs on, from the piece's rows up and down.

    The patch of the line's colour may hold more than the line: the robot, its shadow, a
    chair's legs of the same colour touching it. The line runs on through the rows where the
    patch is at most MAX_ROW_WIDTHS times as wide as the piece is in its own rows (the line
    crossing a row once or twice, nearer or farther); a row much wider is something else.

    :param patch: (H, W) bool, the line shown as a configuration sees it.
    :param sample: the LineSample.
    :return: (first row, last row), or None when the piece's own rows are not line-like.
    """
    piece_rows = np.count_nonzero(sample.piece, axis=1)
    piece_width = float(np.median(piece_rows[piece_rows > 0]))
    counts = np.count_nonzero(patch, axis=1)
    line_like = (counts > 0) & (counts <= MAX_ROW_WIDTHS * piece_width)
    seed_row = sample.seed_px[1]
    if not line_like[seed_row]:
        return None
    first = last = seed_row
    while first > 0 and line_like[first - 1]:
        first -= 1
    while last + 1 < len(counts) and line_like[last + 1]:
        last += 1
    return first, last


def bands_over(rows, config, geometry, height):
    """
    Return the configuration with its bands within the rows where the line is seen.

    Bands beyond the line's nearest or farthest row (or the floor's horizon) can only see
    other things: walls, furniture, the robot. When any searched band lies there, and the
    line spans at least MIN_LINE_ROWS_SHARE of the image (not a dash), the nearest band is
    centred on the line's lowest row (no lower than the configured nearest band), the
    farthest on its highest row on the floor, and the others evenly between.

    :param rows: (first row, last row) of the line (:func:`line_rows`), or None.
    :param config: the DetectorConfig.
    :param geometry: the CameraGeometry, or None.
    :param height: the frame's height.
    :return: the DetectorConfig to use.
    """
    if rows is None or config.band_count < 2:
        return config
    first_row, last_row = rows
    if geometry is not None:
        floor_rows = np.flatnonzero(geometry.line_width_px(
            np.arange(height, dtype=float), config.line_width_m) >= MIN_SEARCH_WIDTH_PX)
        if len(floor_rows):
            first_row = max(first_row, int(floor_rows[0]))
    if last_row - first_row < MIN_LINE_ROWS_SHARE * height:
        return config
    bands = band_rows(height, config)
    if len(bands) == config.band_count and all(
            bottom > first_row and top <= last_row for top, bottom in bands):
        return config
    half_band = config.band_height_px / 2.0
    nearest = min(config.band_center_fraction * height, last_row + 1 - half_band)
    farthest = first_row + half_band
    spacing = (nearest - farthest) / (config.band_count - 1)
    return dataclasses.replace(
        config, band_center_fraction=round(nearest / height, FRACTION_DECIMALS),
        band_spacing_fraction=round(spacing / height, FRACTION_DECIMALS))


def custom_bounds(image_bgr, sample, elsewhere):
    """
    Return HSV bounds that take the piece's colours and few floor pixels, or None.

    The bounds come from the piece's core colours as the camera gives them and as the
    detector's white balance makes them (both its looks must take the line): a percentile
    range with a margin, the widest of CUSTOM_TRIES that takes at most MAX_LOCAL_FLOOR_SHARE
    of the floor around the piece and MAX_FRAME_SHARE of the frame.

    :param image_bgr: the (H, W, 3) uint8 frame.
    :param sample: the LineSample.
    :param elsewhere: (H, W) bool, the pixels the frame-wide share is counted on (all but
        the piece).
    :return: ((hue, saturation, value) low, (hue, saturation, value) high), or None.
    """
    hsv = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)
    gains = line_colour.white_balance(image_bgr.reshape(1, -1, 3), [0], 'custom')
    balanced = np.clip(image_bgr.astype(np.float32) * gains, 0, HSV_CHANNEL_MAX).astype(np.uint8)
    balanced_hsv = cv2.cvtColor(balanced, cv2.COLOR_BGR2HSV)
    line = np.concatenate((hsv[sample.core], balanced_hsv[sample.core])).astype(np.int32)
    hues = _unwrapped_hues(line[:, 0])
    grey = np.median(line[:, 1]) < MIN_HUE_SATURATION
    for low_percentile, high_percentile, hue_margin, margin in CUSTOM_TRIES:
        low = np.percentile(line, low_percentile, axis=0)
        high = np.percentile(line, high_percentile, axis=0)
        if grey:
            hue = (0, OPENCV_HUE_MAX)
        else:
            hue = _hue_range(np.percentile(hues, low_percentile) - hue_margin,
                             np.percentile(hues, high_percentile) + hue_margin)
        bounds = ((hue[0], _level(low[1] - margin), _level(low[2] - margin)),
                  (hue[1], _level(high[1] + margin), _level(high[2] + margin)))
        lower, upper = (np.array(bound, np.uint8) for bound in bounds)
        taken = (cv2.inRange(hsv, lower, upper) != 0) | (
            cv2.inRange(balanced_hsv, lower, upper) != 0)
        local = np.count_nonzero(taken & sample.floor) / max(np.count_nonzero(sample.floor), 1)
        frame = np.count_nonzero(taken & elsewhere) / max(np.count_nonzero(elsewhere), 1)
        if local <= MAX_LOCAL_FLOOR_SHARE and frame <= MAX_FRAME_SHARE:
            return bounds
    return None


def _unwrapped_hues(hues):
    """Return hues moved across 0 when they straddle it (a red), so that they are contiguous."""
    hues = hues.astype(np.float64)
    high = hues > OPENCV_HUE_MAX - HUE_WRAP_GUARD
    low = hues < HUE_WRAP_GUARD
    if high.any() and low.any():
        if np.count_nonzero(high) > np.count_nonzero(low):
            return np.where(low, hues + OPENCV_HUE_MAX + 1, hues)
        return np.where(high, hues - OPENCV_HUE_MAX - 1, hues)
    return hues


def _hue_range(low, high):
    """Return an OpenCV hue range within 0-179 (a range across 0 keeps its larger side)."""
    if low < 0 and high > OPENCV_HUE_MAX:
        return 0, OPENCV_HUE_MAX
    if low < 0:
        return (0, int(math.ceil(high))) if high >= -low else (
            int(math.floor(low + OPENCV_HUE_MAX + 1)), OPENCV_HUE_MAX)
    if high > OPENCV_HUE_MAX:
        wrapped = high - OPENCV_HUE_MAX - 1
        return (int(math.floor(low)), OPENCV_HUE_MAX) if OPENCV_HUE_MAX - low >= wrapped else (
            0, int(math.ceil(wrapped)))
    return int(math.floor(low)), int(math.ceil(high))


def _level(value):
    """Return a saturation or value level clipped to 0-255."""
    return int(min(max(round(float(value)), 0), HSV_CHANNEL_MAX))


class Attempt(NamedTuple):
    """One configuration tried: what the detector saw with it, and the verdict."""

    config: DetectorConfig
    detection: object
    mask: np.ndarray
    verdict: Verdict


class Proposal(NamedTuple):
    """The configuration proposed (the best attempt) and every attempt made."""

    best: Attempt
    attempts: tuple
    automatic: bool

    @property
    def config(self):
        """Return the configuration proposed."""
        return self.best.config

    @property
    def passed(self):
        """Return whether the proposed configuration was verified."""
        return self.best.verdict.passed


def _attempt(image, encoding, config, geometry, sample):
    """Try one configuration on the frame: its colour mask, bands, detection and verdict."""
    mask = colour_mask(image, config, geometry)
    if sample is None:
        detection = _detect(image, encoding, config, geometry)
        passed = bool(detection.found and detection.confidence >= AUTOMATIC_MIN_CONFIDENCE)
        verdict = Verdict(passed, 1.0, 0, len(detection.seen_bands), 0, detection.confidence)
        return Attempt(config, detection, mask, verdict)
    piece_share = float(np.count_nonzero(mask & sample.core) / np.count_nonzero(sample.core))
    patch = line_patch(mask, sample)
    if piece_share >= MIN_PIECE_SHARE:
        config = bands_over(line_rows(patch, sample), config, geometry, image.shape[0])
    detection = _detect(image, encoding, config, geometry)
    verdict = verify(detection, patch, piece_share, config, geometry)
    return Attempt(config, detection, mask, verdict)


def _detect(image, encoding, config, geometry):
    """Run the follower's detector, as on a first frame, with a configuration."""
    return LineDetector(config).detect(image, encoding, geometry)


def _rank(attempt):
    """Order attempts: verified, taking the piece, the share of the line found, confidence."""
    verdict = attempt.verdict
    share = verdict.on_line / verdict.line_bands if verdict.line_bands else 0.0
    return (verdict.passed, verdict.piece_share >= MIN_PIECE_SHARE, share, verdict.confidence)


def propose(image, encoding, sample=None, geometry=None, line_width_m=None):
    """
    Find the configuration whose detector finds the line shown (or, without, any line).

    :param image: the frame, (H, W, 3) BGR or (H, W) grey uint8.
    :param encoding: 'bgr8' or 'mono8' (a grey camera: only white and black tape).
    :param sample: the LineSample shown, or None to look for the line with each preset.
    :param geometry: the CameraGeometry, or None.
    :param line_width_m: the tape's width, or None for the default.
    :return: the Proposal; its best attempt may have failed (see ``passed``).
    """
    base = DetectorConfig()
    if line_width_m is not None:
        base = dataclasses.replace(base, line_width_m=line_width_m)
    presets = GREY_PRESETS if encoding == 'mono8' else PRESETS
    attempts = [_attempt(image, encoding, dataclasses.replace(base, line_colour=colour),
                         geometry, sample) for colour in presets]
    best = max(attempts, key=_rank)
    if not best.verdict.passed and sample is not None and encoding != 'mono8':
        outside = ~cv2.dilate(sample.piece.astype(np.uint8),
                              np.ones((2 * PIECE_REACH_PX + 1,) * 2, np.uint8)).astype(bool)
        bounds = custom_bounds(image, sample, outside)
        if bounds is not None:
            (hue_min, saturation_min, value_min), (hue_max, saturation_max, value_max) = bounds
            config = dataclasses.replace(
                base, line_colour=CUSTOM, hue_min=hue_min, hue_max=hue_max,
                saturation_min=saturation_min, saturation_max=saturation_max,
                value_min=value_min, value_max=value_max)
            attempts.append(_attempt(image, encoding, config, geometry, sample))
            if _rank(attempts[-1]) > _rank(best):
                best = attempts[-1]
    return Proposal(best, tuple(attempts), sample is None)


def follower_parameters(config, camera_height_m=None, camera_pitch_deg=None):
    """
    Return the follower parameters that set a configuration: those that differ from defaults.

    :param config: the DetectorConfig proposed.
    :param camera_height_m: the camera's height, when given.
    :param camera_pitch_deg: the camera's downward tilt, when given.
    :return: parameter name -> value, ``line_colour`` always first.
    """
    default = DetectorConfig()
    parameters = {'line_colour': config.line_colour}
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        if field.name != 'line_colour' and value != getattr(default, field.name):
            parameters[field.name] = value
    if config.line_colour == CUSTOM:
        for name in ('hue_min', 'hue_max', 'saturation_min', 'saturation_max', 'value_min',
                     'value_max'):
            parameters[name] = getattr(config, name)
    if camera_height_m is not None:
        parameters['camera_height_m'] = float(camera_height_m)
    if camera_pitch_deg is not None:
        parameters['camera_pitch_deg'] = float(camera_pitch_deg)
    return parameters


def parameters_yaml(parameters, comments=()):
    """
    Return a ROS 2 parameters file for the follower node.

    :param parameters: parameter name -> value.
    :param comments: lines written as comments at the top.
    :return: the YAML text (``/**/follower: ros__parameters: ...``), valid for
        ``--params-file``.
    """
    header = ''.join(f'# {line}\n' for line in comments)
    document = {FOLLOWER_NODE_KEY: {PARAMETERS_KEY: dict(parameters)}}
    return header + yaml.safe_dump(document, sort_keys=False, default_flow_style=False)


def picture(image, encoding, attempt, sample=None):
    """
    Draw the proposal: the frame with its colour mask, and the detector's view, side by side.

    :param image: the frame, (H, W, 3) BGR or (H, W) grey uint8.
    :param encoding: 'bgr8' or 'mono8'.
    :param attempt: the Attempt drawn.
    :param sample: the LineSample shown, outlined, or None.
    :return: (H, 2 W, 3) uint8 BGR.
    """
    frame = image if encoding == 'bgr8' else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    left = (frame * MASK_BACKGROUND_SHARE).astype(np.uint8)
    left[attempt.mask] = MASK_COLOUR_BGR
    if sample is not None:
        contours, _ = cv2.findContours(sample.piece.astype(np.uint8), cv2.RETR_EXTERNAL,
                                       cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(left, contours, -1, PIECE_COLOUR_BGR, PIECE_LINE_PX)
    right = draw_debug(np.ascontiguousarray(frame), attempt.detection)
    return np.hstack((left, right))
