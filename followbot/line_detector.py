"""
Find a yellow line in a horizontal band of a camera image.

The algorithm of the Follow-bot in "Programming Robots with ROS" (ch. 12), made right: only
the band of rows is converted to HSV (not the whole frame), the hue bounds use OpenCV's
0-179 hue scale, the value bounds accept both shaded and fully lit yellow, band rows are
integers, and the centroid comes from the binary mask's image moments.
"""

from dataclasses import dataclass
import math

import cv2
from followbot.image_conversion import check_array
from followbot.image_conversion import to_bgr
import numpy as np

# OpenCV stores 8-bit hue as degrees / 2, so it ranges over 0..179.
OPENCV_HUE_MAX = 179
# Saturation and value of 8-bit HSV images range over 0..255.
HSV_CHANNEL_MAX = 255

DEBUG_BAND_COLOUR_BGR = (0, 255, 0)
DEBUG_CENTRE_LINE_COLOUR_BGR = (255, 0, 0)
DEBUG_CENTROID_COLOUR_BGR = (0, 0, 255)
DEBUG_TEXT_COLOUR_BGR = (0, 0, 255)
DEBUG_LINE_THICKNESS_PX = 1
DEBUG_CENTROID_RADIUS_PX = 8
DEBUG_TEXT_ORIGIN_PX = (10, 30)
DEBUG_FONT_SCALE = 0.8
DEBUG_TEXT_THICKNESS_PX = 2
LINE_LOST_TEXT = 'LINE LOST'


@dataclass(frozen=True)
class DetectorConfig:
    """
    Thresholds and band geometry of the line detector.

    Hue is in OpenCV units (0-179); saturation and value in 0-255. The hue range does not
    wrap around 0, which yellow (hue ~29) does not need. The defaults accept the course's
    yellow RGB(255, 246, 0) from fully lit down to deep shade (value ~60) and reject the
    unsaturated grey floor.

    The detector looks in ``band_count`` bands of ``band_height_px`` rows: the nearest is
    centred on ``band_center_fraction`` of the image height, each further one
    ``band_spacing_fraction`` of the height above the previous. With the default 30 degree
    camera tilt the six default bands see the floor from ~0.34 m to ~0.87 m ahead of the
    robot: where the line goes, not only where it is (a single band, as in the book, is
    ``band_count`` 1). A band takes a stripe only within ``max_stripe_jump_fraction`` of the
    image width of where it expects the line.
    """

    hue_min: int = 20
    hue_max: int = 40
    saturation_min: int = 100
    saturation_max: int = 255
    value_min: int = 50
    value_max: int = 255
    band_count: int = 6
    band_center_fraction: float = 0.95
    band_spacing_fraction: float = 0.125
    band_height_px: int = 12
    min_area_px: int = 100
    max_stripe_jump_fraction: float = 0.2

    def __post_init__(self):
        """Reject thresholds and band geometry that cannot describe a detection."""
        channel_ranges = (
            ('hue', self.hue_min, self.hue_max, OPENCV_HUE_MAX),
            ('saturation', self.saturation_min, self.saturation_max, HSV_CHANNEL_MAX),
            ('value', self.value_min, self.value_max, HSV_CHANNEL_MAX),
        )
        for name, lower, upper, channel_max in channel_ranges:
            for bound_name, bound in ((f'{name}_min', lower), (f'{name}_max', upper)):
                _require_int(bound_name, bound)
                if not 0 <= bound <= channel_max:
                    raise ValueError(
                        f'{bound_name} must be in [0, {channel_max}], got {bound}.')
            if lower > upper:
                raise ValueError(
                    f'{name}_min {lower} must not exceed {name}_max {upper}.')
        if not 0.0 < self.band_center_fraction < 1.0:
            raise ValueError(
                'band_center_fraction must be strictly between 0 and 1, got '
                f'{self.band_center_fraction}.')
        if not 0.0 <= self.band_spacing_fraction < 1.0:
            raise ValueError(
                'band_spacing_fraction must be at least 0 and less than 1, got '
                f'{self.band_spacing_fraction}.')
        if not 0.0 < self.max_stripe_jump_fraction <= 1.0:
            raise ValueError(
                'max_stripe_jump_fraction must be above 0 and at most 1, got '
                f'{self.max_stripe_jump_fraction}.')
        for name in ('band_count', 'band_height_px', 'min_area_px'):
            value = getattr(self, name)
            _require_int(name, value)
            if value < 1:
                raise ValueError(f'{name} must be at least 1, got {value}.')


def _require_int(name, value):
    """Raise TypeError unless value is an integer (bools excluded): it is used as an index."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f'{name} must be an integer, got {value!r}.')


@dataclass(frozen=True)
class BandDetection:
    """
    What one band of rows saw: the centroid of the line's stripe in it, if any.

    Coordinates are in pixels of the full image, x to the right and y down; the centroid is
    NaN when the band did not see the line. ``area_px`` counts the chosen stripe's pixels
    (or, when nothing was found, all matching pixels of the band, too few to count).
    """

    found: bool
    centroid_x_px: float
    centroid_y_px: float
    area_px: int
    top_px: int
    bottom_px: int


@dataclass(frozen=True)
class Detection:
    """
    Result of looking for the line in one image: one BandDetection per band, nearest first.

    ``error`` is the nearest seen stripe's horizontal offset from the image centre normalised
    to [-1, 1], positive when the line is right of centre: (centroid_x_px - w/2) / (w/2); 0.0
    when no band saw the line. ``confidence`` is the fraction of bands that saw it.
    """

    bands: tuple
    image_width_px: int
    image_height_px: int

    @classmethod
    def nothing_seen(cls, image_width_px=0, image_height_px=0):
        """
        Return the detection of an image that could not be used at all.

        :param image_width_px: width of the image, when known.
        :param image_height_px: height of the image, when known.
        :return: a Detection with no bands: not found, confidence 0.
        """
        return cls(bands=(), image_width_px=image_width_px, image_height_px=image_height_px)

    @property
    def seen_bands(self):
        """Return the bands that saw the line, nearest first."""
        return tuple(band for band in self.bands if band.found)

    @property
    def found(self):
        """Return whether any band saw the line."""
        return any(band.found for band in self.bands)

    @property
    def nearest(self):
        """Return the nearest band that saw the line, or None."""
        return next((band for band in self.bands if band.found), None)

    @property
    def error(self):
        """Return the nearest seen stripe's normalised offset from the image centre."""
        nearest = self.nearest
        if nearest is None:
            return 0.0
        half_width_px = self.image_width_px / 2.0
        return (nearest.centroid_x_px - half_width_px) / half_width_px

    @property
    def confidence(self):
        """Return the fraction of bands that saw the line, 0 to 1."""
        if not self.bands:
            return 0.0
        return len(self.seen_bands) / len(self.bands)

    @property
    def area_px(self):
        """Return the line pixels counted in all bands."""
        return sum(band.area_px for band in self.seen_bands)


def band_rows(image_height_px, config):
    """
    Return the bands of rows to search, nearest first, each clipped to the image.

    :param image_height_px: height of the image in pixels (at least 1).
    :param config: the DetectorConfig giving the band centres, spacing and height.
    :return: a list of (top, bottom) integer row pairs, 0 <= top < bottom <= image height;
        bands that would repeat rows already searched, or fall above the image, are left out.
    """
    bands = []
    for index in range(config.band_count):
        fraction = config.band_center_fraction - index * config.band_spacing_fraction
        # Rounded before truncating: 0.95 - 4 * 0.125 is 0.44999999999999996 in binary.
        center_row = int(round(image_height_px * fraction, 6))
        top = max(center_row - config.band_height_px // 2, 0)
        bottom = min(center_row - config.band_height_px // 2 + config.band_height_px,
                     image_height_px)
        if bottom <= top or (bands and bottom > bands[-1][0]):
            break
        bands.append((top, bottom))
    return bands


def _stripes(column_counts):
    """
    Split a band's per-column line pixel counts into stripes of adjacent columns.

    :param column_counts: 1-D array of line pixels per column.
    :return: (starts, ends) arrays: stripe k covers columns starts[k] to ends[k] - 1.
    """
    occupied = np.concatenate(([0], (column_counts > 0).view(np.int8), [0]))
    edges = np.flatnonzero(np.diff(occupied))
    return edges[0::2], edges[1::2]


class LineDetector:
    """
    Find the line's stripe in each band of rows of each image.

    All bands are converted to HSV and thresholded in one go. In each band the matching
    columns form stripes; the detector takes the stripe nearest to where it expects the line:
    where that band saw it in the previous frame, else where the next nearer band that saw it
    in this frame did. A stripe farther than ``max_stripe_jump_fraction`` of the width from
    that is not the line (a yellow patch beside it, the other leg of a hairpin, the other
    branch at a crossing), so the band saw nothing. With no expectation at all (the line not
    seen before) the stripe nearest the image centre is taken. Stripes smaller than
    ``min_area_px`` are noise. The buffers are reused between calls of the same image size.
    """

    def __init__(self, config=DetectorConfig()):
        """
        Make a detector that has not seen the line yet.

        :param config: thresholds and band geometry; the defaults suit the course.
        """
        self._config = config
        self._lower_hsv = np.array(
            (config.hue_min, config.saturation_min, config.value_min), dtype=np.uint8)
        self._upper_hsv = np.array(
            (config.hue_max, config.saturation_max, config.value_max), dtype=np.uint8)
        self._image_shape = None
        self._bands = []
        self._band_row_index = None
        self._hsv_rows = None
        self._mask_rows = None
        self._previous_x_px = []

    @property
    def config(self):
        """Return the DetectorConfig this detector was made with."""
        return self._config

    @property
    def last_mask(self):
        """
        Return the uint8 mask (255 = line) of the last detect call's band rows, or None.

        The rows of all bands are stacked, nearest band first. The buffer is reused by the
        next ``detect`` call: copy it to keep it.
        """
        return self._mask_rows

    def draw_mask(self, out):
        """
        Draw the last detect call's band masks at their rows of a full-size image.

        :param out: a (H, W) uint8 array the size of the last image; rows outside the bands
            become 0.
        :return: ``out``.
        :raises ValueError: before any detect call, or if ``out`` is not the image's size.
        """
        if self._image_shape is None or out.shape != self._image_shape:
            raise ValueError(f'The mask needs an array of the last image size '
                             f'{self._image_shape}, got {out.shape}.')
        out[:] = 0
        out[self._band_row_index] = self._mask_rows
        return out

    def reset(self):
        """Forget where the line was seen: the next image is searched from the centre."""
        self._previous_x_px = [math.nan] * len(self._bands)

    def detect(self, image, encoding='bgr8'):
        """
        Find the line in the bands of an image.

        :param image: a uint8 array in the given encoding, as from
            image_conversion.image_to_array; it is only read.
        :param encoding: one of image_conversion.SUPPORTED_ENCODINGS. A mono8 image has no
            colour, so no line is ever found in it.
        :return: a Detection with one BandDetection per band, nearest first.
        :raises image_conversion.ImageConversionError: if the image does not match the
            encoding.
        """
        check_array(image, encoding)
        height, width = image.shape[:2]
        if self._image_shape != (height, width):
            self._prepare(height, width)
        band_bgr = to_bgr(np.take(image, self._band_row_index, axis=0), encoding)
        cv2.cvtColor(band_bgr, cv2.COLOR_BGR2HSV, dst=self._hsv_rows)
        cv2.inRange(self._hsv_rows, self._lower_hsv, self._upper_hsv, dst=self._mask_rows)
        bands = []
        first_row = 0
        neighbour_x_px = math.nan
        max_jump_px = self._config.max_stripe_jump_fraction * width
        for index, (top, bottom) in enumerate(self._bands):
            rows = bottom - top
            band_mask = self._mask_rows[first_row:first_row + rows]
            first_row += rows
            expected_x_px = self._previous_x_px[index]
            if not math.isfinite(expected_x_px):
                expected_x_px = neighbour_x_px
            band = self._detect_in_band(band_mask, top, bottom, expected_x_px, max_jump_px)
            bands.append(band)
            if band.found:
                neighbour_x_px = band.centroid_x_px
            self._previous_x_px[index] = band.centroid_x_px
        return Detection(bands=tuple(bands), image_width_px=width, image_height_px=height)

    def _prepare(self, height, width):
        self._image_shape = (height, width)
        self._bands = band_rows(height, self._config)
        self._band_row_index = np.concatenate(
            [np.arange(top, bottom) for top, bottom in self._bands])
        self._hsv_rows = np.empty((len(self._band_row_index), width, 3), dtype=np.uint8)
        self._mask_rows = np.empty((len(self._band_row_index), width), dtype=np.uint8)
        self.reset()

    def _detect_in_band(self, band_mask, top, bottom, expected_x_px, max_jump_px):
        column_counts = np.count_nonzero(band_mask, axis=0)
        starts, ends = _stripes(column_counts)
        areas = np.add.reduceat(column_counts, starts) if len(starts) else starts
        large = areas >= self._config.min_area_px
        if not np.any(large):
            return BandDetection(False, math.nan, math.nan, int(column_counts.sum()), top,
                                 bottom)
        starts, ends = starts[large], ends[large]
        if not math.isfinite(expected_x_px):
            expected_x_px, max_jump_px = band_mask.shape[1] / 2.0, math.inf
        # Distance from the expected column to each stripe, 0 inside it.
        distances_px = np.maximum(np.maximum(starts - expected_x_px, expected_x_px - ends), 0)
        chosen = int(np.argmin(distances_px))
        if distances_px[chosen] > max_jump_px:
            return BandDetection(False, math.nan, math.nan, int(column_counts.sum()), top,
                                 bottom)
        start, end = int(starts[chosen]), int(ends[chosen])
        moments = cv2.moments(band_mask[:, start:end], binaryImage=True)
        return BandDetection(
            found=True, centroid_x_px=start + moments['m10'] / moments['m00'],
            centroid_y_px=top + moments['m01'] / moments['m00'],
            area_px=int(moments['m00']), top_px=top, bottom_px=bottom)


def draw_debug(image_bgr, detection):
    """
    Return a BGR copy of an image annotated with a detection, for a debug image topic.

    Draws each band's outline, a vertical line at the image centre, each seen stripe's
    centroid as a filled red circle, and the error and confidence (or "LINE LOST") as text.

    :param image_bgr: the (H, W, 3) uint8 BGR image the detection was made on.
    :param detection: the Detection to draw.
    :return: a new contiguous (H, W, 3) uint8 array; the input is not modified.
    :raises image_conversion.ImageConversionError: if the image is not a BGR uint8 array.
    """
    check_array(image_bgr, 'bgr8')
    canvas = np.array(image_bgr, dtype=np.uint8, order='C', copy=True)
    height, width = canvas.shape[:2]
    centre_column = width // 2
    cv2.line(
        canvas, (centre_column, 0), (centre_column, height - 1),
        DEBUG_CENTRE_LINE_COLOUR_BGR, DEBUG_LINE_THICKNESS_PX)
    for band in detection.bands:
        cv2.rectangle(
            canvas, (0, band.top_px), (width - 1, band.bottom_px - 1),
            DEBUG_BAND_COLOUR_BGR, DEBUG_LINE_THICKNESS_PX)
        if band.found:
            centroid = (round(band.centroid_x_px), round(band.centroid_y_px))
            cv2.circle(
                canvas, centroid, DEBUG_CENTROID_RADIUS_PX, DEBUG_CENTROID_COLOUR_BGR,
                cv2.FILLED)
    if detection.found:
        text = f'error {detection.error:+.2f} confidence {detection.confidence:.2f}'
    else:
        text = LINE_LOST_TEXT
    cv2.putText(
        canvas, text, DEBUG_TEXT_ORIGIN_PX, cv2.FONT_HERSHEY_SIMPLEX, DEBUG_FONT_SCALE,
        DEBUG_TEXT_COLOUR_BGR, DEBUG_TEXT_THICKNESS_PX, cv2.LINE_AA)
    return canvas
