"""
Find a yellow line in horizontal bands of a camera image.

The algorithm of the Follow-bot in "Programming Robots with ROS" (ch. 12), made right: only
the bands of rows are looked at (not the whole frame), the hue bounds use OpenCV's 0-179 hue
scale, the value bounds accept both shaded and fully lit yellow, band rows are integers, and
the centroid comes from the binary mask's image moments.

A pixel is the line's exactly when ``cv2.inRange`` takes its ``cv2.cvtColor`` BGR-to-HSV
colour to be within the configured bounds. Converting every band pixel to HSV would cost more
than all the rest, so for bounds shaped like the defaults (a hue range centred on yellow, no
upper saturation or value bound) a few whole-array operations on the blue, green and red
planes decide instead: with g_r = max(red, green), the saturation and value bounds become
g_r > floor(c * blue) and g_r >= value_min, and the hue bound |red - green| <= k * (g_r -
blue). This rule is checked against cvtColor and inRange on all 16.7 million 8-bit colours
the first time a set of bounds is used (a tenth of a second; the verdict is cached), and is
used only if it never contradicts them. OpenCV's fixed-point hue rounds a few colours right at
the hue bound either way, so the rule leaves colours within a fraction of a level of that
bound undecided; frames with such pixels (none in clean renders, some with camera noise) get
those pixels from cvtColor itself. Bounds of other shapes take cvtColor and inRange on every
band pixel. Either way the mask is the HSV pipeline's, pixel for pixel.
"""

from dataclasses import dataclass
import functools
import math
from typing import NamedTuple

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

# How each encoding stores a pixel: (channels, index of blue, index of red); a grey value is
# copied to planes 0 to 2, which stand for blue, green and red alike.
_PIXEL_LAYOUT_BY_ENCODING = {
    'bgr8': (3, 0, 2),
    'rgb8': (3, 2, 0),
    'bgra8': (4, 0, 2),
    'rgba8': (4, 2, 0),
    'mono8': (1, 0, 2),
}
# cvtColor code from each colour order to HSV; cvtColor reads 3 or 4 channels alike.
_HSV_CONVERSION_BY_BLUE_INDEX = {0: cv2.COLOR_BGR2HSV, 2: cv2.COLOR_RGB2HSV}
# mono8 has one channel: no colour, and no channel axis in its arrays.
_GREY_CHANNELS = 1

# Pure yellow in OpenCV hue units; the fast rule needs a hue range centred on it.
_YELLOW_HUE = 30
# OpenCV hue units per hue sector (60 degrees) between two primary colours.
_HUE_SECTOR = 30
# Widths, in levels of |red - green|, of the band the fast rule leaves undecided about its
# hue bound, narrowest first: OpenCV's fixed-point hue strays from the exact bound by up to a
# quarter level for the default bounds, a little more for others.
_HUE_UNDECIDED_LEVELS = (0.26, 0.5, 1.0)
# The rule's three verdicts in its 8-bit output: no, undecided (anything between), yes.
_RULE_NO = 0
_RULE_YES = 255
# Half an 8-bit level: cv2 rounds to the nearest integer when it saturates to uint8.
_HALF_LEVEL = 0.5
# Colours are checked against cvtColor in blocks of this many blue levels (16 MB of scratch).
_CHECK_BLUE_LEVELS_PER_BLOCK = 16
# Levels of an 8-bit channel.
_LEVELS = 256
# Columns summed at once as the bytes of one uint64 (sums of at most 255 cannot carry).
_LANES = 8
# Up to this many stripes in all bands are gone through one by one in Python; more (specks
# of noise) are cut down to those large enough, and searched, with whole-array operations.
_STRIPES_LISTED = 32


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
    image width of where it expects the line. Bands are 4 rows tall: on every built-in course
    the follower laps exactly as with 12 (the scorecard's figures are equal), and a frame costs
    a third less; only heavy camera noise (24 levels) shows, in a max cross-track error of
    2.1 cm instead of 0.9 cm. ``min_area_px`` scales with the height (100 pixels for 12 rows).
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
    band_height_px: int = 4
    min_area_px: int = 33
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


class BandDetection(NamedTuple):
    """
    What one band of rows saw: the centroid of the line's stripe in it, if any.

    Coordinates are in pixels of the full image, x to the right and y down; the centroid is
    NaN when the band did not see the line. ``area_px`` counts the chosen stripe's pixels
    (or, when nothing was found, all matching pixels of the band, too few to count). An
    immutable record like a frozen dataclass, made six times a frame at a seventh of the cost.
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


def hsv_bounds(config):
    """
    Return the line's colour bounds as OpenCV takes them.

    :param config: a DetectorConfig.
    :return: (lower, upper) HSV uint8 arrays for ``cv2.inRange``.
    """
    lower = np.array((config.hue_min, config.saturation_min, config.value_min), np.uint8)
    upper = np.array((config.hue_max, config.saturation_max, config.value_max), np.uint8)
    return lower, upper


@dataclass(frozen=True)
class _ColourRule:
    """
    Decide whether colours are the line's from their blue, green and red planes.

    With g_r = max(red, green), a colour is the line's when g_r >= ``value_min``, g_r >
    floor(``value_per_blue`` * blue) (the saturation bound, blue being the smallest channel)
    and |red - green| <= ``hue_slope`` * (g_r - blue) (the hue bound, symmetric about yellow).
    The hue comparison answers yes or no only ``hue_undecided_levels`` or more away from its
    bound, and leaves the colour undecided nearer.
    """

    value_per_blue: float
    hue_slope: float
    value_min: int
    hue_undecided_levels: float

    def classify(self, blue, green, red, spare, out):
        """
        Write the verdict on each pixel of three equal uint8 planes, overwriting them.

        :param blue: the blue plane; green and red likewise. All three are overwritten.
        :param spare: a uint8 scratch array of the planes' shape.
        :param out: where the verdicts go: any uint8 array or view the planes reshape to.
            Each is _RULE_NO, _RULE_YES or, undecided, anything between.
        """
        np.maximum(red, green, out=spare)
        cv2.absdiff(red, green, dst=red)
        cv2.subtract(spare, blue, dst=green)
        # slope * chroma - |red - green|, scaled so that the undecided margin or more gives
        # _RULE_YES, and minus the margin or less _RULE_NO.
        gain = (_RULE_YES - _HALF_LEVEL) / (2 * self.hue_undecided_levels)
        cv2.addWeighted(green, gain * self.hue_slope, red, -gain, _RULE_YES / 2.0, dst=green)
        # floor(value_per_blue * blue): the largest max(red, green) still too unsaturated.
        cv2.convertScaleAbs(blue, dst=blue, alpha=self.value_per_blue, beta=-_HALF_LEVEL)
        cv2.threshold(spare, self.value_min - 1, _RULE_YES, cv2.THRESH_TOZERO, dst=spare)
        cv2.compare(spare, blue, cv2.CMP_GT, dst=blue)
        np.minimum(green.reshape(out.shape), blue.reshape(out.shape), out=out)


@functools.lru_cache(maxsize=None)
def _colour_rule(hue_min, hue_max, saturation_min, saturation_max, value_min, value_max):
    """
    Return the _ColourRule equal to cvtColor and inRange for these bounds, or None.

    :return: None when the bounds are not shaped like the rule (a hue range centred on yellow
        within the red-green sector, no upper saturation or value bound, a lower saturation
        bound) or no rule with an undecided margin of at most a level agrees with OpenCV on
        every colour.
    """
    centred_hue = hue_min + hue_max == 2 * _YELLOW_HUE and 0 < hue_min <= _YELLOW_HUE
    if not (centred_hue and saturation_min > 0 and saturation_max == HSV_CHANNEL_MAX
            and value_max == HSV_CHANNEL_MAX):
        return None
    ratio = _saturation_ratio(saturation_min, value_min)
    if ratio is None:
        return None
    lower = np.array((hue_min, saturation_min, value_min), np.uint8)
    upper = np.array((hue_max, saturation_max, value_max), np.uint8)
    for undecided_levels in _HUE_UNDECIDED_LEVELS:
        rule = _ColourRule(value_per_blue=1.0 / (1.0 - ratio),
                           hue_slope=(_HUE_SECTOR + _HALF_LEVEL - hue_min) / _HUE_SECTOR,
                           value_min=value_min, hue_undecided_levels=undecided_levels)
        if _rule_matches_opencv(rule, lower, upper):
            return rule
    return None


def _saturation_ratio(saturation_min, value_min):
    """
    Return c such that OpenCV's saturation >= saturation_min exactly when chroma >= c * value.

    :return: c, strictly inside the interval every value from value_min up allows, or None
        when no single ratio describes the bound.
    """
    levels = np.arange(_LEVELS)
    value, chroma = np.meshgrid(levels, levels, indexing='ij')
    value, chroma = value[chroma <= value], chroma[chroma <= value]
    # A grey-to-red ramp: blue = green = value - chroma, red = value.
    ramp = np.stack((value - chroma, value - chroma, value), axis=-1).astype(np.uint8)
    saturation = cv2.cvtColor(ramp[np.newaxis], cv2.COLOR_BGR2HSV)[0, :, 1]
    passes = saturation >= saturation_min
    above = value >= max(value_min, 1)
    low = max((chroma[~passes & above] / value[~passes & above]).max(initial=0.0), 0.0)
    high = (chroma[passes & above] / value[passes & above]).min(initial=1.0)
    if not low < high:
        return None
    return (low + high) / 2.0


def _rule_matches_opencv(rule, lower, upper):
    """Return whether the rule never contradicts cvtColor and inRange on any 8-bit colour."""
    levels = np.arange(_LEVELS, dtype=np.uint8)
    bgr = np.empty((1, _CHECK_BLUE_LEVELS_PER_BLOCK * _LEVELS * _LEVELS, 3), np.uint8)
    bgr[0, :, 1] = np.tile(np.repeat(levels, _LEVELS), _CHECK_BLUE_LEVELS_PER_BLOCK)
    bgr[0, :, 2] = np.tile(levels, _LEVELS * _CHECK_BLUE_LEVELS_PER_BLOCK)
    planes = [np.empty(bgr.shape[:2], np.uint8) for _ in range(5)]
    verdict = planes[4]
    expected = np.empty(bgr.shape[:2], np.uint8)
    for first_blue in range(0, _LEVELS, _CHECK_BLUE_LEVELS_PER_BLOCK):
        bgr[0, :, 0] = np.repeat(levels[first_blue:first_blue + _CHECK_BLUE_LEVELS_PER_BLOCK],
                                 _LEVELS * _LEVELS)
        cv2.split(bgr, planes[:3])
        rule.classify(*planes)
        cv2.inRange(cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV), lower, upper, dst=expected)
        wrong_yes = (verdict == _RULE_YES) & (expected == 0)
        wrong_no = (verdict == _RULE_NO) & (expected != 0)
        if wrong_yes.any() or wrong_no.any():
            return False
    return True


class _BandLayout:
    """
    Where the bands' rows are, and the buffers and views that work on them, for one image size.

    Every buffer holds the bands top down (the farthest first, the image's own row order) as
    (bands, rows * width), every band as tall as the tallest: a band clipped at the image edge
    is padded, and the padding masked out. Per-column statistics keep each band's columns
    followed by empty ones, which end its last stripe. The views are made here once, not per
    frame.
    """

    def __init__(self, height, width, config):
        """
        Lay out the bands of an image size and make their buffers.

        :param height: image height in pixels.
        :param width: image width in pixels.
        :param config: the DetectorConfig.
        """
        self.bands = band_rows(height, config)
        self.top_down = self.bands[::-1]
        self.width = width
        band_heights = [bottom - top for top, bottom in self.top_down]
        self.rows = max(band_heights)
        count = len(self.bands)
        tops = [top for top, _ in self.top_down]
        steps = {lower - upper for upper, lower in zip(tops, tops[1:])}
        # Equal bands at equal spacing are one strided view of a contiguous image: no copy.
        self.view_step_rows = None
        if len(set(band_heights)) == 1 and len(steps) <= 1:
            self.view_step_rows = steps.pop() if steps else 0
        # Rows gathered when the image cannot be viewed: a padded band repeats its last row.
        self.row_index = np.array(
            [min(top + row, bottom - 1) for top, bottom in self.top_down
             for row in range(self.rows)], dtype=np.intp)
        self.padding = [(index, rows * width) for index, rows in enumerate(band_heights)
                        if rows < self.rows]
        plane_shape = (count, self.rows * width)
        # Blue, green, red (or the image's order), a fourth (alpha, or scratch), the verdicts.
        self.planes = [np.empty(plane_shape, np.uint8) for _ in range(5)]
        self.verdict = self.planes[4]
        self.hsv = np.empty(plane_shape + (3,), np.uint8)
        self.gathered = {}
        # Per pixel: 1 for the line; and the pixel's row within its band where it is the line.
        # Summed down each column they give its line pixels and the sum of their rows.
        pixel_dtype = np.uint8 if self.rows <= _LEVELS else np.uint16
        self.weighted = np.zeros((2,) + plane_shape, pixel_dtype)
        self.mask_is_weighted = pixel_dtype == np.uint8
        self.mask = self.weighted[0] if self.mask_is_weighted else np.zeros(plane_shape,
                                                                            np.uint8)
        self.row_of_pixel = np.repeat(np.arange(self.rows), width).astype(pixel_dtype)
        # Sums of at most 255 cannot carry: then eight columns are summed at once in a uint64.
        sum_dtype = _sum_dtype(self.rows * (self.rows - 1) // 2 + 1)
        lanes = _LANES if sum_dtype == np.uint8 and width % _LANES == 0 else 1
        # Every band's columns padded with at least one empty column to a whole number of lanes.
        self.stride = (width // lanes + 1) * lanes
        columns = count * self.stride
        self.column_sums = np.zeros((2, columns), sum_dtype)
        weighted, sums = self.weighted, self.column_sums
        if lanes == _LANES:
            weighted, sums = weighted.view(np.uint64), sums.view(np.uint64)
        self.weighted_columns = weighted.reshape(2, count, self.rows, width // lanes)
        self.summed_columns = sums.reshape(2, count, -1)[:, :, :width // lanes]
        self.no_pixels = np.zeros(columns, sum_dtype)
        # Per column: line pixels, the sum of their rows, and of their columns (each column
        # once per pixel), as int64, which numpy sums per stripe the fastest.
        self.column_stats = np.zeros((3, columns), np.int64)
        self.column_index = np.tile(np.arange(self.stride, dtype=np.int64), count)
        # Whether each column has line pixels, after a leading empty one; where that changes.
        self.occupied = np.zeros(columns + 1, np.bool_)
        self.changes = np.empty(columns, np.bool_)
        self.stacked_mask = np.empty((sum(band_heights), width), np.uint8)
        self.stacked_bands = []
        last_row = len(self.stacked_mask)
        for index, rows in enumerate(band_heights):
            self.stacked_bands.append((self.mask[index, :rows * width],
                                       self.stacked_mask[last_row - rows:last_row].reshape(-1)))
            last_row -= rows

    def gathered_rows(self, channels):
        """Return the buffer that gathered rows of an image with these channels go to."""
        if channels not in self.gathered:
            shape = (len(self.bands) * self.rows, self.width)
            if channels > _GREY_CHANNELS:
                shape += (channels,)
            self.gathered[channels] = np.empty(shape, np.uint8)
        return self.gathered[channels]


def _sum_dtype(largest):
    """Return the smallest unsigned integer type that holds sums up to ``largest``."""
    for dtype in (np.uint8, np.uint16, np.uint32):
        if largest <= np.iinfo(dtype).max:
            return dtype
    return np.uint64


class LineDetector:
    """
    Find the line's stripe in each band of rows of each image.

    Only the bands' rows are read: viewed in place when the image is contiguous and the bands
    equally tall and spaced, else gathered into a buffer. Each pixel is classified as
    described in the module docstring, for all bands at once, and one reduction gives every
    band's per-column counts of line pixels and of their rows. In each band the matching
    columns form stripes; the detector takes the stripe nearest to where it expects the line:
    where that band saw it in the previous frame, else where the next nearer band that saw it
    in this frame did. A stripe farther than ``max_stripe_jump_fraction`` of the width from
    that is not the line (a yellow patch beside it, the other leg of a hairpin, the other
    branch at a crossing), so the band saw nothing. With no expectation at all (the line not
    seen before) the stripe nearest the image centre is taken. Stripes smaller than
    ``min_area_px`` are noise. A stripe's centroid is its pixels' mean column and row. The
    buffers are made once per image size and reused.
    """

    def __init__(self, config=DetectorConfig()):
        """
        Make a detector that has not seen the line yet.

        The first detector for a set of thresholds checks the fast colour rule against
        OpenCV on every colour (a tenth of a second); later ones reuse that verdict.

        :param config: thresholds and band geometry; the defaults suit the course.
        """
        self._config = config
        self._lower_hsv, self._upper_hsv = hsv_bounds(config)
        self._rule = _colour_rule(config.hue_min, config.hue_max, config.saturation_min,
                                  config.saturation_max, config.value_min, config.value_max)
        self._image_shape = None
        self._layout = None
        self._bands = []
        self._previous_x_px = []
        self._stacked_mask_current = False

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
        layout = self._layout
        if layout is None:
            return None
        if not self._stacked_mask_current:
            for band_mask, stacked_rows in layout.stacked_bands:
                cv2.threshold(band_mask, 0, _RULE_YES, cv2.THRESH_BINARY, dst=stacked_rows)
            self._stacked_mask_current = True
        return layout.stacked_mask

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
        first_row = 0
        stacked_mask = self.last_mask
        for top, bottom in self._bands:
            out[top:bottom] = stacked_mask[first_row:first_row + bottom - top]
            first_row += bottom - top
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
        pixel_layout = _PIXEL_LAYOUT_BY_ENCODING.get(encoding)
        if pixel_layout is None:
            to_bgr(image, encoding)  # raises: the encoding has no colour
        height, width = image.shape[:2]
        if self._image_shape != (height, width):
            self._prepare(height, width)
        band_pixels = self._band_pixels(image, pixel_layout[0])
        self._classify(band_pixels, pixel_layout)
        self._stacked_mask_current = False
        return self._choose(self._stripes(), width, height)

    def _prepare(self, height, width):
        self._image_shape = (height, width)
        self._layout = _BandLayout(height, width, self._config)
        self._bands = self._layout.bands
        self.reset()

    def _band_pixels(self, image, channels):
        """Return the bands' pixels, top down, as (bands, rows * width[, channels]) uint8."""
        layout = self._layout
        shape = (len(layout.bands), layout.rows * layout.width)
        if channels > _GREY_CHANNELS:
            shape += (channels,)
        if layout.view_step_rows is not None and image.flags.c_contiguous:
            row_bytes = layout.width * channels
            return np.ndarray(shape, np.uint8, buffer=image,
                              offset=layout.top_down[0][0] * row_bytes,
                              strides=(layout.view_step_rows * row_bytes,) + image.strides[1:])
        gathered = layout.gathered_rows(channels)
        np.take(image, layout.row_index, axis=0, out=gathered)
        return gathered.reshape(shape)

    def _classify(self, band_pixels, pixel_layout):
        """Write the bands' mask (1 = line) to the layout."""
        layout = self._layout
        channels, blue_index, red_index = pixel_layout
        verdict = layout.verdict
        if self._rule is None:
            self._exact_mask(band_pixels, pixel_layout, verdict)
        else:
            planes = layout.planes
            if channels == _GREY_CHANNELS:
                for plane in planes[:3]:
                    np.copyto(plane, band_pixels)
            else:
                cv2.split(band_pixels, planes[:channels])
            self._rule.classify(planes[blue_index], planes[1], planes[red_index], planes[3],
                                verdict)
        for index, first_padding_pixel in layout.padding:
            verdict[index, first_padding_pixel:] = 0
        cv2.threshold(verdict, _RULE_YES - 1, 1, cv2.THRESH_BINARY, dst=layout.mask)
        if self._rule is not None and (cv2.countNonZero(verdict)
                                       != cv2.countNonZero(layout.mask)):
            # Some pixels are neither sure yes nor sure no.
            self._settle_undecided(band_pixels, pixel_layout)

    def _exact_mask(self, band_pixels, pixel_layout, mask):
        """Write the bands' mask (255 = line) from cvtColor and inRange on every pixel."""
        layout = self._layout
        channels, blue_index, _ = pixel_layout
        if channels == _GREY_CHANNELS:
            colour = layout.gathered_rows(3).reshape(layout.hsv.shape)
            cv2.cvtColor(band_pixels, cv2.COLOR_GRAY2BGR, dst=colour)
            band_pixels, blue_index = colour, 0
        cv2.cvtColor(band_pixels, _HSV_CONVERSION_BY_BLUE_INDEX[blue_index], dst=layout.hsv)
        cv2.inRange(layout.hsv, self._lower_hsv, self._upper_hsv, dst=mask)

    def _settle_undecided(self, band_pixels, pixel_layout):
        """Decide the pixels the fast rule left undecided with cvtColor and inRange."""
        layout = self._layout
        # Verdicts other than yes, kept only when not no either; the blue plane is free now.
        undecided = cv2.threshold(layout.verdict, _RULE_YES - 1, _RULE_YES,
                                  cv2.THRESH_TOZERO_INV, dst=layout.planes[0])[1]
        band, pixel = np.divmod(np.flatnonzero(undecided.view(np.bool_)), undecided.shape[1])
        values = band_pixels[band, pixel]
        channels, blue_index, red_index = pixel_layout
        colours = np.empty((len(values), 1, 3), np.uint8)
        for channel, source in enumerate((blue_index, 1, red_index)):
            colours[:, 0, channel] = values if channels == _GREY_CHANNELS else values[:, source]
        line = cv2.inRange(cv2.cvtColor(colours, cv2.COLOR_BGR2HSV), self._lower_hsv,
                           self._upper_hsv)
        layout.mask[band, pixel] = line.reshape(-1) != 0

    def _stripes(self):
        """
        Return each band's stripes of line pixels that are large enough, nearest band first.

        :return: per band None, or its stripes left to right: a list of (first column, end
            column, pixels, sum of the pixels' columns, sum of their rows within the band)
            tuples, or, when all bands together have more than _STRIPES_LISTED, those five
            as the rows of an int64 array.
        """
        layout = self._layout
        count = len(layout.bands)
        weighted = layout.weighted
        if not layout.mask_is_weighted:
            np.copyto(weighted[0], layout.mask)
        np.multiply(weighted[0], layout.row_of_pixel, out=weighted[1])
        column_sums = layout.column_sums
        np.add.reduce(layout.weighted_columns, axis=2, dtype=layout.summed_columns.dtype,
                      out=layout.summed_columns)
        stats = layout.column_stats
        np.copyto(stats[:2], column_sums)
        occupied = layout.occupied
        np.not_equal(column_sums[0], layout.no_pixels, out=occupied[1:])
        np.not_equal(occupied[1:], occupied[:-1], out=layout.changes)
        edges = layout.changes.nonzero()[0]
        stripes_by_band = [None] * count
        if not edges.size:
            return stripes_by_band
        np.multiply(stats[0], layout.column_index, out=stats[2])
        bounds = edges.reshape(-1, 2)
        if len(bounds) <= _STRIPES_LISTED:
            # The usual case, a stripe or two a band: one conversion to Python numbers each
            # for the edges and the sums, as every NumPy call costs a microsecond or more.
            edge_list = edges.tolist()
            areas, y_moments, x_moments = np.add.reduceat(stats, edges, axis=1)[:, 0::2].tolist()
            return self._listed_stripes(stripes_by_band, edge_list[0::2], edge_list[1::2],
                                        areas, x_moments, y_moments)
        else:
            # Many specks: sum the areas, then the moments of the stripes large enough only.
            areas = np.add.reduceat(stats[0], edges)[0::2]
            large = np.flatnonzero(areas >= self._config.min_area_px)
            if not large.size:
                return stripes_by_band
            bounds, areas = bounds[large], areas[large]
            y_moments, x_moments = np.add.reduceat(stats[1:], bounds.reshape(-1),
                                                   axis=1)[:, 0::2]
        if len(bounds) > _STRIPES_LISTED:
            # Still many: each band's are a (5, stripes) slice of one table, searched whole.
            top_down_index, first_columns = np.divmod(bounds[:, 0], layout.stride)
            table = np.stack((first_columns, first_columns + bounds[:, 1] - bounds[:, 0],
                              areas, x_moments, y_moments))
            cuts = np.searchsorted(top_down_index, np.arange(count + 1)).tolist()
            for top_down, (first, last) in enumerate(zip(cuts, cuts[1:])):
                if last > first:
                    stripes_by_band[count - 1 - top_down] = table[:, first:last]
            return stripes_by_band
        return self._listed_stripes(stripes_by_band, bounds[:, 0].tolist(),
                                    bounds[:, 1].tolist(), areas.tolist(), x_moments.tolist(),
                                    y_moments.tolist())

    def _listed_stripes(self, stripes_by_band, starts, ends, areas, x_moments, y_moments):
        """Fill each band's list of large enough stripes from per-stripe Python numbers."""
        stride = self._layout.stride
        last_index = len(stripes_by_band) - 1
        min_area_px = self._config.min_area_px
        for start, end, area, x_moment, y_moment in zip(starts, ends, areas, x_moments,
                                                        y_moments):
            if area >= min_area_px:
                top_down_index, first_column = divmod(start, stride)
                index = last_index - top_down_index
                if stripes_by_band[index] is None:
                    stripes_by_band[index] = []
                stripes_by_band[index].append(
                    (first_column, end - start + first_column, area, x_moment, y_moment))
        return stripes_by_band

    def _choose(self, stripes_by_band, width, height):
        """Return the Detection taking, in each band, the stripe nearest where it expects."""
        bands = []
        neighbour_x_px = math.nan
        max_jump_px = self._config.max_stripe_jump_fraction * width
        previous_x_px = self._previous_x_px
        band_totals = None
        for index, (top, bottom) in enumerate(self._bands):
            stripe = None
            stripes = stripes_by_band[index]
            if stripes is not None:
                expected_x_px = previous_x_px[index]
                if not math.isfinite(expected_x_px):
                    expected_x_px = neighbour_x_px
                allowed_px = max_jump_px
                if not math.isfinite(expected_x_px):
                    expected_x_px, allowed_px = width / 2.0, math.inf
                if type(stripes) is list and len(stripes) == 1:
                    # The usual case, worth the few lines: no call per band.
                    stripe = stripes[0]
                    distance_px = max(stripe[0] - expected_x_px, expected_x_px - stripe[1], 0)
                else:
                    stripe, distance_px = _nearest_stripe(stripes, expected_x_px)
                if distance_px > allowed_px:
                    stripe = None
            if stripe is None:
                if band_totals is None:
                    band_totals = np.add.reduce(
                        self._layout.column_stats[0].reshape(len(self._bands), -1),
                        axis=1).tolist()[::-1]
                band = BandDetection(False, math.nan, math.nan, band_totals[index], top,
                                     bottom)
            else:
                start, _, area, x_moment, y_moment = stripe
                # The moments about the stripe's first column and the band's top row.
                band = BandDetection(True, start + (x_moment - start * area) / area,
                                     top + y_moment / area, area, top, bottom)
                neighbour_x_px = band.centroid_x_px
            previous_x_px[index] = band.centroid_x_px
            bands.append(band)
        return Detection(tuple(bands), width, height)


def _nearest_stripe(stripes, expected_x_px):
    """
    Return the first stripe nearest a column, and its distance (0 inside it).

    :param stripes: (first column, end column, pixels, x moment, y moment) tuples left to
        right, or those five as the rows of an int64 array.
    :param expected_x_px: the column.
    :return: (stripe tuple, distance in pixels).
    """
    if isinstance(stripes, np.ndarray):
        distances_px = np.maximum(
            np.maximum(stripes[0] - expected_x_px, expected_x_px - stripes[1]), 0)
        nearest = int(np.argmin(distances_px))
        return tuple(stripes[:, nearest].tolist()), float(distances_px[nearest])
    nearest = None
    nearest_distance_px = math.inf
    for stripe in stripes:
        distance_px = max(stripe[0] - expected_x_px, expected_x_px - stripe[1], 0)
        if distance_px < nearest_distance_px:
            nearest, nearest_distance_px = stripe, distance_px
    return nearest, nearest_distance_px


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
