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
    """

    hue_min: int = 20
    hue_max: int = 40
    saturation_min: int = 100
    saturation_max: int = 255
    value_min: int = 50
    value_max: int = 255
    band_center_fraction: float = 0.75
    band_height_px: int = 20
    min_area_px: int = 20

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
        _require_int('band_height_px', self.band_height_px)
        if self.band_height_px < 1:
            raise ValueError(f'band_height_px must be at least 1, got {self.band_height_px}.')
        _require_int('min_area_px', self.min_area_px)
        if self.min_area_px < 1:
            raise ValueError(f'min_area_px must be at least 1, got {self.min_area_px}.')


def _require_int(name, value):
    """Raise TypeError unless value is an integer (bools excluded): it is used as an index."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f'{name} must be an integer, got {value!r}.')


@dataclass(frozen=True)
class Detection:
    """
    Result of looking for the line in one image.

    Coordinates are in pixels of the full image, x to the right and y down. ``error`` is the
    centroid's horizontal offset from the image centre normalised to [-1, 1], positive when
    the line is right of centre: (centroid_x_px - w/2) / (w/2). When no line is found the
    centroid is NaN and the error 0.0.
    """

    found: bool
    centroid_x_px: float
    centroid_y_px: float
    error: float
    area_px: int
    band_top_px: int
    band_bottom_px: int
    image_width_px: int

    @classmethod
    def nothing_seen(cls, area_px=0, band_top_px=0, band_bottom_px=0, image_width_px=0):
        """
        Return the detection of an image in which no line was found (or that was unusable).

        :param area_px: matching pixels that were too few to count.
        :param band_top_px: first row searched.
        :param band_bottom_px: row after the last one searched.
        :param image_width_px: width of the image.
        :return: a Detection with ``found`` False, a NaN centroid and a zero error.
        """
        return cls(found=False, centroid_x_px=math.nan, centroid_y_px=math.nan, error=0.0,
                   area_px=area_px, band_top_px=band_top_px, band_bottom_px=band_bottom_px,
                   image_width_px=image_width_px)


def band_rows(image_height_px, config):
    """
    Return the band of rows to search, clipped to the image, as a [top, bottom) pair.

    :param image_height_px: height of the image in pixels (at least 1).
    :param config: the DetectorConfig giving the band centre and height.
    :return: (top, bottom) integer row indices with 0 <= top < bottom <= image_height_px.
    """
    center_row = int(image_height_px * config.band_center_fraction)
    top = center_row - config.band_height_px // 2
    bottom = top + config.band_height_px
    return max(top, 0), min(bottom, image_height_px)


class LineDetector:
    """
    Find the centroid of yellow pixels in a band of rows of each image.

    The HSV and mask buffers are reused between calls of the same band size, so ``detect``
    allocates almost nothing per frame.
    """

    def __init__(self, config=DetectorConfig()):
        """
        Make a detector.

        :param config: thresholds and band geometry; the defaults suit the course.
        """
        self._config = config
        self._lower_hsv = np.array(
            (config.hue_min, config.saturation_min, config.value_min), dtype=np.uint8)
        self._upper_hsv = np.array(
            (config.hue_max, config.saturation_max, config.value_max), dtype=np.uint8)
        self._hsv_band = None
        self._mask_band = None

    @property
    def config(self):
        """Return the DetectorConfig this detector was made with."""
        return self._config

    @property
    def last_mask(self):
        """
        Return the uint8 band mask (255 = line) of the last detect call, or None before one.

        The buffer is reused by the next ``detect`` call: copy it to keep it.
        """
        return self._mask_band

    def detect(self, image, encoding='bgr8'):
        """
        Find the line in the band of an image.

        :param image: a uint8 array in the given encoding, as from
            image_conversion.image_to_array; it is only read.
        :param encoding: one of image_conversion.SUPPORTED_ENCODINGS. A mono8 image has no
            colour, so no line is ever found in it.
        :return: a Detection; ``found`` is False when fewer than ``min_area_px`` pixels of
            the band match.
        :raises image_conversion.ImageConversionError: if the image does not match the
            encoding.
        """
        check_array(image, encoding)
        height, width = image.shape[:2]
        top, bottom = band_rows(height, self._config)
        band_bgr = to_bgr(image[top:bottom], encoding)
        if self._hsv_band is None or self._hsv_band.shape != band_bgr.shape:
            self._hsv_band = np.empty_like(band_bgr)
            self._mask_band = np.empty(band_bgr.shape[:2], dtype=np.uint8)
        cv2.cvtColor(band_bgr, cv2.COLOR_BGR2HSV, dst=self._hsv_band)
        cv2.inRange(self._hsv_band, self._lower_hsv, self._upper_hsv, dst=self._mask_band)
        moments = cv2.moments(self._mask_band, binaryImage=True)
        # With binaryImage the zeroth moment counts the matching pixels exactly.
        area_px = int(moments['m00'])
        if area_px < self._config.min_area_px:
            return Detection.nothing_seen(area_px, top, bottom, width)
        centroid_x_px = moments['m10'] / moments['m00']
        centroid_y_px = top + moments['m01'] / moments['m00']
        half_width_px = width / 2.0
        return Detection(
            found=True, centroid_x_px=centroid_x_px, centroid_y_px=centroid_y_px,
            error=(centroid_x_px - half_width_px) / half_width_px,
            area_px=area_px, band_top_px=top, band_bottom_px=bottom, image_width_px=width)


def draw_debug(image_bgr, detection):
    """
    Return a BGR copy of an image annotated with a detection, for a debug image topic.

    Draws the band outline, a vertical line at the image centre, the centroid as a filled
    red circle when the line was found, and the error (or "LINE LOST") as text.

    :param image_bgr: the (H, W, 3) uint8 BGR image the detection was made on.
    :param detection: the Detection to draw.
    :return: a new contiguous (H, W, 3) uint8 array; the input is not modified.
    :raises image_conversion.ImageConversionError: if the image is not a BGR uint8 array.
    """
    check_array(image_bgr, 'bgr8')
    canvas = np.array(image_bgr, dtype=np.uint8, order='C', copy=True)
    height, width = canvas.shape[:2]
    cv2.rectangle(
        canvas, (0, detection.band_top_px), (width - 1, detection.band_bottom_px - 1),
        DEBUG_BAND_COLOUR_BGR, DEBUG_LINE_THICKNESS_PX)
    centre_column = width // 2
    cv2.line(
        canvas, (centre_column, 0), (centre_column, height - 1),
        DEBUG_CENTRE_LINE_COLOUR_BGR, DEBUG_LINE_THICKNESS_PX)
    if detection.found:
        centroid = (round(detection.centroid_x_px), round(detection.centroid_y_px))
        cv2.circle(
            canvas, centroid, DEBUG_CENTROID_RADIUS_PX, DEBUG_CENTROID_COLOUR_BGR,
            cv2.FILLED)
        text = f'error {detection.error:+.2f}'
    else:
        text = LINE_LOST_TEXT
    cv2.putText(
        canvas, text, DEBUG_TEXT_ORIGIN_PX, cv2.FONT_HERSHEY_SIMPLEX, DEBUG_FONT_SCALE,
        DEBUG_TEXT_COLOUR_BGR, DEBUG_TEXT_THICKNESS_PX, cv2.LINE_AA)
    return canvas
