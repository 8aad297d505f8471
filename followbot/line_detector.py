"""
Find the line in horizontal bands of a camera image, and say how sure that is.

The algorithm of the Follow-bot in "Programming Robots with ROS" (ch. 12), made to hold on real
camera frames. Only bands of rows are read (not the whole frame). In each band the line's
pixels form stripes; which stripe, if any, is the line is decided with what the follower knows:

- **Where the floor is.** With the camera's geometry (its camera_info and mounting) a band at
  or above the horizon sees no floor, so no line: it is not searched. Below it, the line of
  ``line_width_m`` must look a known number of pixels wide; a stripe far wider or narrower (a
  whole floor passing a colour bound under a cast, a speck of noise) is not the line. A
  diagonal stripe is measured across its slope, so a line running across the view still fits.
  Stripes a hairline apart (``SPLIT_GAP_M`` on the floor, at most ``SPLIT_GAP_SHARE`` of the
  line's width) are one line split lengthwise: two strips of tape, a scratch, a highlight.
- **What colour the line is, relative to its floor.** A first, fast look applies the colour
  preset's fixed HSV bounds exactly (see :mod:`followbot.colour_rule`). When that leaves any
  doubt (a band below the horizon with no stripe, several stripes, a stripe of the wrong width)
  the bands are judged again relative to their floor, white-balanced and exposure-free (see
  :mod:`followbot.line_colour`), which finds pale and far tape and ignores colour casts. A
  stretch of black far too wide for the tape may be a deep shadow: the tape in it, darker
  than the shadow, is looked for against the shadow itself.
- **That the line is one line.** The stripes of the bands, put on the floor, must form a
  smooth path: from one band to the next the line may turn, but not jump sideways by more than
  ``max_stripe_jump_m``, nor zigzag. Among all chains of stripes through the bands, the one
  with the most well-coloured, well-sized stripes and the smoothest path is taken (dynamic
  programming over the bands). A stripe that stood in a band in the previous frame's reported
  line must be near where it was (``max_stripe_jump_m`` on the floor); there, a line leaving
  the image at its side (into a sharp corner) is still seen however little of it shows, as is
  a sliver at the side the nearer band's stripe reaches (the line running on out of the image).
- **How sure.** The detection's confidence is the share of the searchable bands that its
  chain covers, each weighed by how well its stripe's width and colour fit, lowered when
  another chain of similar strength competes. A lone yellow object, a half-matching stripe,
  two candidate lines: all give low confidence, and the controller slows down or stops.

Without camera geometry (no camera_info yet) the bands are all searched, widths are bounded by
a share of the image, and jumps are measured in the image.
"""

from dataclasses import dataclass
import math
from typing import NamedTuple

import cv2
from followbot import line_colour
from followbot.colour_rule import colour_rule, RULE_YES
from followbot.image_conversion import check_array, ImageConversionError, to_bgr
import numpy as np

# OpenCV stores 8-bit hue as degrees / 2, so it ranges over 0..179.
OPENCV_HUE_MAX = 179
# Saturation and value of 8-bit HSV images range over 0..255.
HSV_CHANNEL_MAX = 255

DEBUG_BAND_COLOUR_BGR = (0, 255, 0)
DEBUG_UNSEARCHED_BAND_COLOUR_BGR = (128, 128, 128)
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
# Levels of an 8-bit channel.
_LEVELS = 256
# Columns summed at once as the bytes of one uint64 (sums of at most 255 cannot carry).
_LANES = 8
# Up to this many stripes in all bands are gone through one by one in Python; more (specks
# of noise) are cut down to those large enough, and searched, with whole-array operations.
_STRIPES_LISTED = 32

# A band is searched when the line there looks at least this wide: nearer the horizon it is
# a few pixels of blur.
MIN_SEARCH_WIDTH_PX = 2.0
# A stripe is the line when its width across its slope is within these multiples of the
# line's expected width (a far dash seen at a slant, a worn edge, blur).
MIN_WIDTH_RATIO = 0.55
MAX_WIDTH_RATIO = 2.6
# Width fit: the quality falls to exp(-1/2) at a width this many times too wide or narrow.
WIDTH_TOLERANCE_RATIO = 2.0
LOG_WIDTH_TOLERANCE = math.log(WIDTH_TOLERANCE_RATIO)
# A stripe must cover at least this share of a band of the line's expected width.
MIN_AREA_SHARE = 0.25
# A stripe wider than this many expected widths is measured across its slope (row by row).
SLANT_CHECK_RATIO = 1.5
# Without camera geometry: a stripe wider than this share of the image is not the line, and
# a jump between bands (or frames) is measured as a share of the image width.
NO_GEOMETRY_MAX_WIDTH_SHARE = 0.6
NO_GEOMETRY_JUMP_SHARE = 0.2
# A stripe wider than MAX_WIDTH_RATIO may be the line running across the view (a corner
# ahead, a crossing): it then fills this share of the band over its run, the line's thickness
# in rows is at least ALONG_BAND_MIN_ROWS_SHARE of the band, and its width fits this well.
ALONG_BAND_FILL = 0.6
ALONG_BAND_MIN_ROWS_SHARE = 0.75
ALONG_BAND_QUALITY = 0.5
# How well a stripe narrower than the line fits when it touches the image's edge.
EDGE_QUALITY = 0.7
# Colour evidence: a stripe whose pixels are on average this many times past their threshold
# counts as fully coloured; a first-look stripe (fixed bounds) always does.
GOOD_STRENGTH = 2.0
# A stripe's fill of its bounding box (solid tape ~1, scattered specks much less).
GOOD_FILL = 0.6
# Quality below which a stripe is too doubtful to take part.
MIN_QUALITY = 0.15
# From one band's point of the line to the next, the line may turn at most this much (per
# link), and a first link may leave the robot's heading by at most FIRST_LINK_TURN.
MAX_LINK_TURN_RAD = math.radians(50.0)
FIRST_LINK_TURN_RAD = math.radians(75.0)
TAN_MAX_LINK_TURN = math.tan(MAX_LINK_TURN_RAD)
TAN_FIRST_LINK_TURN = math.tan(FIRST_LINK_TURN_RAD)
# Cost of a turn at the limit, against 1 per stripe of perfect quality.
TURN_COST = 0.3
# Cost of each band a chain skips (a gap between dashes, or a missed stripe).
GAP_COST = 0.05
# Only this many of a band's best stripes take part in the chain search.
MAX_CANDIDATES_PER_BAND = 5
# A reported detection fixes where each band's stripe may be in the next frame: within the jump
# limit of where it was, a stripe a whole limit away losing this share of its quality.
TRACKING_WEIGHT = 0.5
# A first look is accepted without the second when its confidence reaches this and each of
# its stripes' quality reaches CLEAN_QUALITY.
CLEAN_CONFIDENCE = 0.8
CLEAN_QUALITY = 0.8
# Support of a link between two bands' stripes: image samples every LINK_SAMPLE_SPACING_PX
# rows (at least MIN_LINK_SAMPLES, at most MAX_LINK_SAMPLES), each across the line's width at
# these offsets (in half widths); a link with none of FULL_LINK_SUPPORT costs this much.
LINK_SAMPLE_SPACING_PX = 4.0
MIN_LINK_SAMPLES = 3
MAX_LINK_SAMPLES = 16
LINK_OFFSETS = np.array([-0.5, 0.0, 0.5])
LINK_NO_GEOMETRY_HALF_WIDTH_PX = 4.0
FULL_LINK_SUPPORT = 0.6
# How deep beyond the band the turn of a hairpin may lie, as shares of half the distance
# between its arms (the arc's depth depends on the bend's shape and the camera's view).
HAIRPIN_DEPTH_SHARES = (0.15, 0.3, 0.5, 0.75, 1.0)
# Rows between the samples of the floor's middle between two arms, where a hairpin's turn
# is looked for; the samples are taken on the middle itself.
TURN_STEP_PX = 2.0
ON_THE_MIDDLE = np.array([0.0])
# Where the floor must show beside such an arc, in half widths of the line either side (a
# bright patch or a wall joins any two stripes; only a thin line joins them along an arc).
BESIDE_LINE_OFFSETS = np.array([-3.0, 3.0])
UNSUPPORTED_LINK_COST = 1.0
# Each band farther from the robot counts this much less in the chain search: the line the
# robot follows comes from near it, and far stripes are more often something else.
NEAR_BAND_WEIGHT = 0.7
# A tie-breaker, less than any stripe's worth: chains starting nearer the robot's path win.
CENTRE_PREFERENCE = 0.05
# Fewer points than this are put on the floor one by one (arrays cost more for a few).
FEW_POINTS = 16
# A rival chain as strong as the chosen one takes this share of the confidence.
RIVAL_WEIGHT = 0.8
# Stripes of one line split lengthwise by a hairline (the seam of a line laid as two strips of
# tape, a scratch or a highlight along it) are one stripe: joined across a gap as wide as this
# on the floor, but at most SPLIT_GAP_SHARE of the line's width (a narrow tape's halves are
# not two lines' worth apart), and at least MIN_SPLIT_GAP_PX (the camera blurs a hairline
# over a few pixels), or MIN_SPLIT_GAP_PX where the width is not known.
SPLIT_GAP_M = 0.01
SPLIT_GAP_SHARE = 0.25
MIN_SPLIT_GAP_PX = 3.0
# A stretch of a band far too wide for the line is a shadow with the line in it when what
# stands out within it covers at most this share of it.
MAX_SHADOWED_SHARE = 0.5
# How much a band that cannot see a line which left the view at the image's side counts
# against it: not fully (it cannot see it), not nothing (the robot turns blind there; on
# realistic frames full trust had the robot enter corners faster and lose the line after them).
OUT_OF_VIEW_BAND_WEIGHT = 0.5


@dataclass(frozen=True)
class DetectorConfig:
    """
    The line's colour and width, the bands searched, and the limits of a jump.

    ``line_colour`` is a preset of :mod:`followbot.line_colour` (``yellow``, ``white``,
    ``black``), or ``custom``: then the HSV bounds (hue in OpenCV units 0-179, saturation and
    value 0-255; the hue range does not wrap around 0) are the line's colour. The presets'
    fixed bounds are in ``line_colour.PRESET_HSV_BOUNDS``; the HSV fields default to the
    yellow preset's.

    The detector looks in ``band_count`` bands of ``band_height_px`` rows: the nearest is
    centred on ``band_center_fraction`` of the image height, each further one
    ``band_spacing_fraction`` of the height above the previous. With the default 30 degree
    camera tilt the six default bands see the floor from ~0.34 m to ~0.87 m ahead of the
    robot: where the line goes, not only where it is (a single band, as in the book, is
    ``band_count`` 1). Bands are 4 rows tall: on every built-in course the follower laps
    exactly as with 12, and a frame costs a third less.

    ``line_width_m`` is the tape's width on the floor; ``max_stripe_jump_m`` how far, on the
    floor, a band's stripe may lie sideways from where the line leads (or from where it was in
    the previous frame); ``min_area_px`` the fewest pixels a stripe needs, whatever the
    geometry says (the geometry asks for more where the line looks wide). A detection less
    confident than ``min_confidence`` reports no line at all: the follower then drives on its
    memory of the line, stops or searches, instead of steering by a guess.
    """

    line_colour: str = 'yellow'
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
    min_area_px: int = 4
    line_width_m: float = 0.19
    max_stripe_jump_m: float = 0.15
    min_confidence: float = 0.1

    def __post_init__(self):
        """Reject thresholds and band geometry that cannot describe a detection."""
        if self.line_colour not in line_colour.LINE_COLOURS:
            raise ValueError(f'line_colour must be one of '
                             f'{", ".join(line_colour.LINE_COLOURS)}, got {self.line_colour!r}.')
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
        for name in ('line_width_m', 'max_stripe_jump_m'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f'{name} must be a number, got {value!r}.')
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be positive and finite, got {value}.')
        if isinstance(self.min_confidence, bool) or not isinstance(self.min_confidence,
                                                                   (int, float)):
            raise TypeError(f'min_confidence must be a number, got {self.min_confidence!r}.')
        if not 0.0 <= self.min_confidence <= 1.0:
            raise ValueError(f'min_confidence must be in [0, 1], got {self.min_confidence}.')
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
    (or, when nothing was found, all matching pixels of the band). ``searched`` is False for a
    band at or above the horizon, where no line can be. ``quality`` (0-1) says how well the
    stripe's width and colour fit the line's. ``at_side`` is True when the stripe reaches the
    image's left or right edge: the line may go on out of the view there. An immutable record
    like a frozen dataclass, made six times a frame at a seventh of the cost.
    """

    found: bool
    centroid_x_px: float
    centroid_y_px: float
    area_px: int
    top_px: int
    bottom_px: int
    searched: bool = True
    quality: float = 0.0
    at_side: bool = False


@dataclass(frozen=True)
class Detection:
    """
    Result of looking for the line in one image: one BandDetection per band, nearest first.

    ``error`` is the nearest seen stripe's horizontal offset from the image centre normalised
    to [-1, 1], positive when the line is right of centre: (centroid_x_px - w/2) / (w/2); 0.0
    when no band saw the line. ``confidence`` (0-1) is how sure the detector is that what it
    reports is the line: see the module docstring.
    """

    bands: tuple
    image_width_px: int
    image_height_px: int
    confidence: float = 0.0

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
    Return the fixed colour bounds of the detector's first look, as OpenCV takes them.

    :param config: a DetectorConfig.
    :return: (lower, upper) HSV uint8 arrays for ``cv2.inRange``: the preset's, or for
        ``custom`` the configured ones.
    """
    if config.line_colour == 'custom':
        low = (config.hue_min, config.saturation_min, config.value_min)
        high = (config.hue_max, config.saturation_max, config.value_max)
    else:
        low, high = line_colour.PRESET_HSV_BOUNDS[config.line_colour]
    return np.array(low, np.uint8), np.array(high, np.uint8)


class _Quality(float):
    """A stripe's quality (0 to 1), which knows whether the line runs along the band."""

    def __new__(cls, value, along_band=False):
        """Make the quality; ``along_band`` marks a line across the view."""
        quality = super().__new__(cls, value)
        quality.along_band = along_band
        return quality


class _Candidate(NamedTuple):
    """A stripe that may be the line: where it is, how well it fits, and its floor point."""

    band: int
    x_px: float
    y_px: float
    area_px: int
    quality: float
    point: tuple
    # Whether the stripe reaches the image's left or right side (the line may go on beyond).
    at_side: bool = False
    # For a line running across the view through the band, the columns it spans (first, last
    # + 1): another line crossing it passes through the band anywhere within them.
    span_px: tuple | None = None


@dataclass(frozen=True)
class _BandPlan:
    """What the geometry says of each band: searched, the line's width there, its floor."""

    searched: tuple
    expected_width_px: tuple
    across_rows_px: tuple
    min_area_px: tuple
    # The widest gap across a band's stripe that still leaves it one stripe (pixels).
    split_gap_px: tuple
    # Where a stripe at column x of a band stands, to within its few rows: (forward[band],
    # left_per_px[band] * (x - centre_px)) on the floor, or in the image without geometry;
    # None for a camera with lens distortion, whose points are projected one by one.
    forward: tuple
    left_per_px: tuple
    centre_px: float
    jump: float
    has_geometry: bool
    # The image row of the floor's horizon, or None without geometry.
    horizon_px: float | None = None

    def point(self, band: int, x_px: float) -> tuple:
        """Return where a stripe's centroid at a column of a band stands (see the fields)."""
        return self.forward[band], self.left_per_px[band] * (x_px - self.centre_px)


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
    Find the line's stripe in each band of rows of each image, and how sure that is.

    Only the bands' rows are read: viewed in place when the image is contiguous and the bands
    equally tall and spaced, else gathered into a buffer. The first look classifies each pixel
    with the preset's fixed HSV bounds, for all bands at once, and one reduction gives every
    band's per-column counts of line pixels and of their rows; in each band the matching
    columns form stripes. The stripes that could be the line (see the module docstring) are
    chained through the bands; when the first look leaves doubt, the second look judges the
    bands' pixels against their floor and chains again. The buffers are made once per image
    size and reused.
    """

    def __init__(self, config=DetectorConfig()):
        """
        Make a detector that has not seen the line yet.

        The first detector for a set of fixed bounds checks the fast colour rule against
        OpenCV on every colour (a tenth of a second); later ones reuse that verdict.

        :param config: colour, width, bands and limits; the defaults suit the simulated course.
        """
        self._config = config
        self._lower_hsv, self._upper_hsv = hsv_bounds(config)
        self._rule = colour_rule(int(self._lower_hsv[0]), int(self._upper_hsv[0]),
                                 int(self._lower_hsv[1]), int(self._upper_hsv[1]),
                                 int(self._lower_hsv[2]), int(self._upper_hsv[2]))
        self._image_shape = None
        self._layout = None
        self._bands = []
        self._plans = {}
        self._previous_points = []
        self._previous_heading = None
        self._stacked_mask_current = False
        self._strength = None

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
                cv2.threshold(band_mask, 0, RULE_YES, cv2.THRESH_BINARY, dst=stacked_rows)
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
        """Forget where the line was seen: the next image is searched without expectations."""
        self._previous_points = [None] * len(self._bands)
        self._previous_heading = None

    def detect(self, image, encoding='bgr8', geometry=None):
        """
        Find the line in the bands of an image.

        :param image: an array in the given encoding, as from image_conversion.image_to_array;
            it is only read. Encodings other than the 8-bit BGR/RGB(A)/mono ones are converted
            to BGR first.
        :param encoding: the image's encoding.
        :param geometry: the camera's ground_projection.CameraGeometry, or None when not known:
            then every band is searched and widths and jumps are judged in the image.
        :return: a Detection with one BandDetection per band, nearest first.
        :raises image_conversion.ImageConversionError: if the image does not match the
            encoding, has no colour (depth), or is grey while the line's colour is not.
        """
        check_array(image, encoding)
        pixel_layout = _PIXEL_LAYOUT_BY_ENCODING.get(encoding)
        if pixel_layout is None:
            image, encoding = to_bgr(image, encoding), 'bgr8'
            pixel_layout = _PIXEL_LAYOUT_BY_ENCODING[encoding]
        if (pixel_layout[0] == _GREY_CHANNELS
                and self._config.line_colour in line_colour.CHROMATIC_COLOURS + ('custom',)):
            raise ImageConversionError(
                f'A {encoding} image shows no {self._config.line_colour} line: set '
                'line_colour to white or black for a grey camera.')
        height, width = image.shape[:2]
        if self._image_shape != (height, width):
            self._prepare(height, width)
        plan = self._plan(geometry)
        band_pixels = self._band_pixels(image, pixel_layout[0])
        self._classify(band_pixels, pixel_layout)
        self._stacked_mask_current = False
        self._strength = None
        detection = self._clean_detection(self._stripes(), plan, geometry, width, height)
        if detection is not None:
            return detection
        self._look_image = (image, pixel_layout)
        self._second_look(band_pixels, pixel_layout, plan)
        # A column belongs to a stripe when most of the band's rows agree: specks of camera
        # noise neither split the line nor join the floor to it.
        stripes = self._stripes(max(1, self._layout.rows // 2))
        chain, confidence = self._chain(self._candidates(stripes, plan, geometry), plan)
        return self._detection(chain, confidence, plan, width, height)

    def _prepare(self, height, width):
        self._image_shape = (height, width)
        self._layout = _BandLayout(height, width, self._config)
        self._bands = self._layout.bands
        self._plans = {}
        self.reset()

    def _plan(self, geometry) -> _BandPlan:
        """Return what the geometry says of each band (cached per geometry)."""
        plan = self._plans.get(geometry)
        if plan is not None:
            return plan
        config = self._config
        width = self._image_shape[1]
        heights = [bottom - top for top, bottom in self._bands]
        if geometry is None:
            count = len(self._bands)
            height = self._image_shape[0]
            plan = _BandPlan(searched=(True,) * count, expected_width_px=(None,) * count,
                             across_rows_px=(None,) * count,
                             min_area_px=(config.min_area_px,) * count,
                             split_gap_px=(MIN_SPLIT_GAP_PX,) * count,
                             forward=tuple((height - (top + bottom - 1) / 2.0) / width
                                           for top, bottom in self._bands),
                             left_per_px=(-1.0 / width,) * count, centre_px=width / 2.0,
                             jump=NO_GEOMETRY_JUMP_SHARE, has_geometry=False)
        else:
            centres = [(top + bottom - 1) / 2.0 for top, bottom in self._bands]
            widths = [float(value) for value in
                      geometry.line_width_px(centres, config.line_width_m)]
            across = geometry.across_line_rows_px(centres, config.line_width_m)
            plan = _BandPlan(
                searched=tuple(value >= MIN_SEARCH_WIDTH_PX for value in widths),
                expected_width_px=tuple(widths),
                across_rows_px=tuple(float(value) for value in across),
                min_area_px=tuple(max(config.min_area_px,
                                      int(MIN_AREA_SHARE * value * rows))
                                  for value, rows in zip(widths, heights)),
                split_gap_px=tuple(max(MIN_SPLIT_GAP_PX, value * min(
                    SPLIT_GAP_SHARE, SPLIT_GAP_M / config.line_width_m)) for value in widths),
                forward=tuple(geometry.floor_point(geometry.cx_px, centre)[0]
                              for centre in centres),
                left_per_px=tuple(geometry.floor_point(geometry.cx_px + 1.0, centre)[1]
                                  for centre in centres),
                centre_px=geometry.cx_px,
                jump=config.max_stripe_jump_m, has_geometry=True,
                horizon_px=geometry.horizon_row_px)
        self._plans = {geometry: plan}
        return plan

    def _second_look(self, band_pixels, pixel_layout, plan):
        """Judge the bands' pixels against their floor; write the mask and the strength."""
        layout = self._layout
        channels, blue_index, red_index = pixel_layout
        if channels == _GREY_CHANNELS:
            pixels = band_pixels
        else:
            pixels = band_pixels[..., [blue_index, 1, red_index]]
        count = len(self._bands)
        # The plan counts bands nearest first; the buffers hold them top down.
        on_floor = [count - 1 - index for index, searched in enumerate(plan.searched)
                    if searched]
        gains = line_colour.white_balance(pixels, on_floor, self._config.line_colour)
        bounds = (tuple(int(value) for value in self._lower_hsv),
                  tuple(int(value) for value in self._upper_hsv))
        mask, strength, self._floor_model = line_colour.classify(
            self._config.line_colour, pixels, gains, layout.width, on_floor, bounds)
        for index, first_padding_pixel in layout.padding:
            mask[index, first_padding_pixel:] = 0
        np.copyto(layout.mask, mask)
        self._strength = strength * mask

    def _candidates(self, stripes_by_band, plan, geometry):
        """Return, per band nearest first, the stripes that may be the line, best first."""
        layout = self._layout
        rows_of = [bottom - top for top, bottom in self._bands]
        strength_sums = None
        if self._strength is not None:
            count, rows, width = len(self._bands), layout.rows, layout.width
            strength_sums = self._strength.reshape(count, rows, width).sum(axis=1)
        image_width = self._image_shape[1]
        found = []
        # Whether the nearer band's stripes reach the image's left side, and its right side.
        nearer_reach = (False, False)
        for index, stripes in enumerate(stripes_by_band):
            if stripes is None or not plan.searched[index]:
                nearer_reach = (False, False)
                continue
            reach_left = reach_right = False
            top = self._bands[index][0]
            rows = rows_of[index]
            if isinstance(stripes, np.ndarray):
                stripes = [tuple(column) for column in stripes.T.tolist()]
            if len(stripes) > 1:
                stripes = _joined(stripes, plan.split_gap_px[index])
            stripes = self._without_shadows(index, stripes, plan)
            for start, end, area, x_moment, y_moment in stripes:
                at_left, at_right = start == 0, end == image_width
                at_side = at_left or at_right
                # A line leaving the image at its side (into a sharp corner, or coming into
                # view out of one) shows less and less of itself there. A sliver at the edge
                # is still the line where the band saw the line a frame ago (the jump limit
                # below keeps it where it was), or where the nearer band's stripe reaches the
                # same side (the line runs on out of the image); alone, it may be anything.
                if area < plan.min_area_px[index] and not (
                        at_side and self._previous_points[index] is not None
                        or at_left and nearer_reach[0] or at_right and nearer_reach[1]):
                    continue
                quality = self._stripe_quality(index, start, end, area, rows, plan,
                                               strength_sums)
                if quality < MIN_QUALITY:
                    continue
                reach_left, reach_right = reach_left or at_left, reach_right or at_right
                y_px = top + y_moment / area
                if quality.along_band:
                    # The line runs through the band: where it enters and where it leaves are
                    # the points that chain with the bands above and below.
                    half_px = 0.5 * plan.expected_width_px[index]
                    for x_px, at_side in ((start + half_px, start == 0),
                                          (end - half_px, end == image_width)):
                        found.append((index, x_px, y_px, area, float(quality), at_side,
                                      (start, end)))
                    continue
                found.append((index, start + (x_moment - start * area) / area, y_px, area,
                              float(quality), at_side, None))
            nearer_reach = (reach_left, reach_right)
        if not found:
            return [[] for _ in self._bands]
        points = self._points([item[1] for item in found], [item[2] for item in found],
                              geometry)
        candidates = [[] for _ in self._bands]
        for (index, x_px, y_px, area, quality, at_side, span), point in zip(found, points):
            previous = self._previous_points[index]
            if previous is not None:
                moved = math.dist(previous, point) / plan.jump
                if moved > 1.0:
                    continue
                # Where the line was a frame ago it most likely is still.
                quality *= 1.0 - TRACKING_WEIGHT * moved * moved
            candidates[index].append(
                _Candidate(index, x_px, y_px, area, quality, point, at_side, span))
        return [sorted(band, key=lambda candidate: -candidate.quality)[
            :MAX_CANDIDATES_PER_BAND] for band in candidates]

    def _without_shadows(self, index, stripes, plan):
        """
        Return a band's stripes, each far too wide one replaced by the stripes within it.

        A deep shadow on the floor passes the black preset over a stretch far wider than the
        line. Judged against that stretch's own floor, the tape in it still stands out: where
        that finds stripes over at most MAX_SHADOWED_SHARE of the stretch, they are its
        stripes. A stretch that is dark all over is the line itself (running across the
        view) and stays whole, as does a stripe of the line's width measured across its
        slope (a diagonal line).
        """
        expected = plan.expected_width_px[index]
        if (self._strength is None or expected is None
                or self._floor_model.colour not in line_colour.SHADOWED_COLOURS):
            return stripes
        widest_px = MAX_WIDTH_RATIO * expected
        result = []
        for stripe in stripes:
            start, end, area = stripe[:3]
            inner = None
            if (end - start > widest_px
                    and self._slanted_width(index, start, end, area)[0] > widest_px):
                inner = self._stripes_within(index, start, end)
            if inner is None:
                result.append(stripe)
            else:
                result.extend(inner)
        if len(result) > 1:
            result = _joined(result, plan.split_gap_px[index])
        return result

    def _stripes_within(self, index, start, end):
        """
        Return the stripes that stand out within a stretch of a band, as _stripes gives them.

        :return: the stripes, left to right, or None when nothing stands out or it covers
            more than MAX_SHADOWED_SHARE of the stretch.
        """
        top, bottom = self._bands[index]
        rows = bottom - top
        image, (channels, blue, red) = self._look_image
        width = self._image_shape[1]
        reach = line_colour.SMOOTHING_KERNEL_PX[0] // 2
        first, last = max(0, start - reach), min(width, end + reach)
        pixels = image[top:bottom, first:last].astype(np.float32)
        if channels > _GREY_CHANNELS:
            pixels = pixels[..., [blue, 1, red]]
        pixels = line_colour.smoothed(pixels, last - first)[:, start - first:end - first]
        top_down = len(self._bands) - 1 - index
        strength = line_colour.strength_within(self._floor_model, pixels, top_down)
        if strength is None:
            return None
        layout = self._layout
        mask = layout.mask[top_down].reshape(layout.rows, layout.width)[:rows, start:end]
        inside = (strength >= 1.0) & (mask != 0)
        counts = inside.sum(axis=0)
        occupied = np.concatenate(([False], counts >= max(1, rows // 2), [False]))
        edges = np.flatnonzero(occupied[1:] != occupied[:-1]).reshape(-1, 2)
        if not len(edges) or (edges[:, 1] - edges[:, 0]).sum() > MAX_SHADOWED_SHARE * (
                end - start):
            return None
        row_sums = (inside * np.arange(rows)[:, np.newaxis]).sum(axis=0)
        columns = np.arange(start, end)
        return [(start + first_column, start + end_column,
                 int(counts[first_column:end_column].sum()),
                 int((counts * columns)[first_column:end_column].sum()),
                 int(row_sums[first_column:end_column].sum()))
                for first_column, end_column in edges.tolist()]

    def _points(self, x_px, y_px, geometry):
        """Return the points candidates stand for: on the floor (metres), or in the image."""
        if geometry is None:
            height, width = self._image_shape
            return [((height - y) / width, (width / 2.0 - x) / width)
                    for x, y in zip(x_px, y_px)]
        if len(x_px) < FEW_POINTS:
            return [geometry.floor_point(x, y) for x, y in zip(x_px, y_px)]
        forward_m, left_m = geometry.pixels_to_floor(x_px, y_px)
        return list(zip(forward_m.tolist(), left_m.tolist()))

    def _stripe_quality(self, index, start, end, area, rows, plan, strength_sums):
        """
        Return how well a stripe fits the line (0 to 1; 0 if it cannot be the line).

        :return: a _Quality: the number, and whether the stripe is the line running along
            the band (across the view) rather than through it.
        """
        extent = end - start
        fill = area / (extent * rows)
        image_width = self._image_shape[1]
        at_edge = start == 0 or end == image_width
        expected = plan.expected_width_px[index]
        along_band = False
        if expected is None:
            if extent > NO_GEOMETRY_MAX_WIDTH_SHARE * image_width:
                return _Quality(0.0)
            width_quality = 1.0
        else:
            across = extent
            if extent > SLANT_CHECK_RATIO * expected:
                across, fill = self._slanted_width(index, start, end, area)
            ratio = across / expected
            if ratio > MAX_WIDTH_RATIO:
                if not self._runs_along_band(index, start, end, area, rows, plan):
                    return _Quality(0.0)
                width_quality, fill, along_band = ALONG_BAND_QUALITY, 1.0, True
            elif ratio < MIN_WIDTH_RATIO:
                # A line leaving the image shows only part of its width.
                if not at_edge:
                    return _Quality(0.0)
                width_quality = EDGE_QUALITY
            else:
                width_quality = math.exp(-0.5 * (math.log(ratio) / LOG_WIDTH_TOLERANCE) ** 2)
        colour_quality = 1.0
        if strength_sums is not None:
            top_down = len(self._bands) - 1 - index
            strength = float(strength_sums[top_down, start:end].sum()) / area
            colour_quality = min(1.0, 0.5 + 0.5 * (strength - 1.0) / (GOOD_STRENGTH - 1.0))
        return _Quality(width_quality * min(1.0, fill / GOOD_FILL) * max(colour_quality, 0.0),
                        along_band)

    def _runs_along_band(self, index, start, end, area, rows, plan) -> bool:
        """
        Tell whether a wide stripe can be the line running across the view through the band.

        Such a line fills most rows of the band over its run, as the line is thicker, in
        rows, than the band there. In the first look a stripe from one image edge to the
        other may be a whole floor passing fixed colour bounds under a cast; judged against
        the floor (the second look) it is the line running right across the view.
        """
        if (start == 0 and end == self._image_shape[1]) and self._strength is None:
            return False
        if plan.across_rows_px[index] < ALONG_BAND_MIN_ROWS_SHARE * rows:
            return False
        return area >= ALONG_BAND_FILL * (end - start) * rows

    def _slanted_width(self, index, start, end, area):
        """
        Measure a wide stripe row by row: its width across its slope, and its fill.

        :return: (width in pixels across the stripe's direction, share of its rows' runs
            covered).
        """
        layout = self._layout
        top, bottom = self._bands[index]
        top_down = len(self._bands) - 1 - index
        rows = layout.mask[top_down].reshape(layout.rows, layout.width)
        mask = rows[:bottom - top, start:end]
        counts = mask.sum(axis=1, dtype=np.int64)
        occupied = np.flatnonzero(counts)
        if len(occupied) < 2:
            return float(end - start), area / float(end - start)
        columns = np.arange(start, end, dtype=np.float64)
        centres = (mask[occupied] * columns).sum(axis=1) / counts[occupied]
        slope = float(np.polyfit(occupied.astype(np.float64), centres, 1)[0])
        chord = float(counts[occupied].mean())
        return chord / math.sqrt(1.0 + slope * slope), 1.0

    def _chain(self, candidates, plan):
        """
        Return the best chain of candidates through the bands, and the detection's confidence.

        Each chained stripe counts by its quality, shared with the band's other stripes that
        could take its place in the chain (as well linked to its neighbours): a band crowded
        with line-like stripes (a robot's black cables over black tape) is doubtful. The sum
        over the searchable bands is lowered further by a rival chain of the remaining stripes
        (another line of the same colour).

        :param candidates: per band nearest first, its candidates.
        :param plan: the bands' plan.
        :return: (the chosen candidates, nearest first; confidence 0 to 1).
        """
        support = _LinkSupport(self, plan)
        best_score, chain = _best_chain(candidates, plan, self._previous_heading, support)
        if not chain:
            return [], 0.0
        chosen = {id(candidate) for candidate in chain}
        by_band = {candidate.band: candidate for candidate in chain}
        # The other arm of a bend the chain takes is the same line, not a rival.
        neighbours = {candidate.band: chain[position + 1 if position + 1 < len(chain) else
                                            position - 1] if len(chain) > 1 else None
                      for position, candidate in enumerate(chain)}
        rivals = [[candidate for candidate in band if id(candidate) not in chosen and not (
            candidate.band in by_band and support.joined(
                by_band[candidate.band], candidate, neighbours[candidate.band]))]
            for band in candidates]
        rival_score, rival = _best_chain(rivals, plan, self._previous_heading, support)
        continuation = []
        if rival and _continues(chain, rival, self._previous_heading, plan.jump):
            # Stripes beyond the chain's far end, ahead along it, that it did not take for
            # want of paint between them (the gaps of a dashed line): the line's continuation,
            # not another line. The best chain of the other stripes is the rival.
            continuation = rival
            taken = {id(candidate) for candidate in continuation}
            rival_score, _ = _best_chain(
                [[candidate for candidate in band if id(candidate) not in taken]
                 for band in rivals], plan, self._previous_heading, support)
        evidence = _gap_evidence(chain, candidates, plan, support)
        for position, candidate in enumerate(chain):
            before = chain[position - 1] if position > 0 else None
            after = chain[position + 1] if position + 1 < len(chain) else None
            stand_ins = sum(other.quality for other in rivals[candidate.band]
                            if _could_replace(other, before, after, plan.jump))
            evidence += candidate.quality * candidate.quality / (candidate.quality + stand_ins)
        if continuation:
            # It shows the line's way as far as paint across the gap to it does.
            share = _paint_share(support(chain[-1], continuation[0]))
            evidence += share * (
                sum(candidate.quality for candidate in continuation)
                + _gap_evidence([chain[-1], *continuation], candidates, plan, support))
        coverage = evidence / max(self._bands_in_view(chain, candidates, plan), 1)
        rivalry = min(rival_score / best_score, 1.0) if best_score > 0.0 else 0.0
        confidence = min(1.0, coverage) * (1.0 - RIVAL_WEIGHT * rivalry * rivalry)
        if confidence < self._config.min_confidence:
            return [], confidence
        return chain, confidence

    def _bands_in_view(self, chain, candidates, plan) -> float:
        """
        Return how many searched bands could see the line the chain found.

        Where the chain's last stripe reaches the image's side, the last two lead, going on
        straight, out of the image before a farther band, and no farther band holds a stripe,
        the line has left the view (a sharp turn): the bands beyond cannot see it, and their
        seeing nothing counts only OUT_OF_VIEW_BAND_WEIGHT against it.
        """
        searched = plan.searched
        if len(chain) < 2 or not chain[-1].at_side or any(candidates[chain[-1].band + 1:]):
            return sum(searched)
        near, far = chain[-2], chain[-1]
        width = self._image_shape[1]
        in_view = sum(searched[:far.band + 1])
        for band in range(far.band + 1, len(searched)):
            top, bottom = self._bands[band]
            centre_y_px = 0.5 * (top + bottom - 1)
            if not 0.0 <= _column_at_row(near, far, centre_y_px) <= width - 1:
                break
            in_view += searched[band]
        return in_view + OUT_OF_VIEW_BAND_WEIGHT * (sum(searched) - in_view)

    def _clean_detection(self, stripes_by_band, plan, geometry, width, height):
        """
        Return the first look's Detection when it is beyond doubt, else None.

        Beyond doubt: every searched band holds exactly one stripe, each of the line's size,
        linked into a line without a sharp turn, each where the last frame saw the line. The
        usual case on a clean floor, so it is worked out in plain arithmetic, and the record
        built as it goes: every array or helper call would cost microseconds.
        """
        if geometry is not None and geometry.intrinsics is not None and (
                geometry.intrinsics.distortion):
            return None
        bands = self._bands
        searched = plan.searched
        expected_widths = plan.expected_width_px
        previous_points = self._previous_points
        jump = plan.jump
        direction_x, direction_y = self._previous_heading or (1.0, 0.0)
        tan_turn = TAN_FIRST_LINK_TURN
        last = first = second = None
        total_quality = 0.0
        records = []
        points = []
        for index, stripes in enumerate(stripes_by_band):
            top, bottom = bands[index]
            if not searched[index]:
                records.append(BandDetection(False, math.nan, math.nan, 0, top, bottom, False,
                                             0.0))
                points.append(None)
                continue
            if type(stripes) is not list or len(stripes) != 1:
                return None
            start, end, area, x_moment, y_moment = stripes[0]
            if area < plan.min_area_px[index]:
                return None
            extent = end - start
            fill = area / (extent * (bottom - top))
            expected = expected_widths[index]
            if expected is None:
                if extent > NO_GEOMETRY_MAX_WIDTH_SHARE * width:
                    return None
                quality = min(1.0, fill / GOOD_FILL)
            else:
                ratio = extent / expected
                if not MIN_WIDTH_RATIO <= ratio <= SLANT_CHECK_RATIO:
                    return None
                spread = math.log(ratio) / LOG_WIDTH_TOLERANCE
                quality = math.exp(-0.5 * spread * spread) * min(1.0, fill / GOOD_FILL)
            if quality < CLEAN_QUALITY:
                return None
            x_px = start + (x_moment - start * area) / area
            point = (plan.forward[index], plan.left_per_px[index] * (x_px - plan.centre_px))
            previous = previous_points[index]
            if previous is not None and math.hypot(previous[0] - point[0],
                                                   previous[1] - point[1]) > jump:
                return None
            if last is not None:
                dx, dy = point[0] - last[0], point[1] - last[1]
                along = dx * direction_x + dy * direction_y
                if (along < -jump or abs(dx * direction_y - dy * direction_x)
                        > jump + max(along, 0.0) * tan_turn):
                    return None
                length = math.hypot(dx, dy)
                if length > 0.0:
                    direction_x, direction_y = dx / length, dy / length
                tan_turn = TAN_MAX_LINK_TURN
            if first is None:
                first = point
            elif second is None:
                second = point
            last = point
            points.append(point)
            records.append(BandDetection(True, x_px, top + y_moment / area, area, top, bottom,
                                         True, quality, start == 0 or end == width))
            total_quality += quality
        if first is None:
            return None
        confidence = min(1.0, total_quality / sum(searched))
        if confidence < CLEAN_CONFIDENCE:
            return None
        self._previous_points = points
        self._previous_heading = _heading(first, second) if second is not None else None
        return Detection(tuple(records), width, height, confidence)

    def _detection(self, chain, confidence, plan, width, height):
        """Make the Detection of a chain, and remember it for the next frame."""
        by_band = {candidate.band: candidate for candidate in chain}
        bands = []
        band_totals = None
        for index, (top, bottom) in enumerate(self._bands):
            candidate = by_band.get(index)
            if candidate is None:
                if band_totals is None:
                    band_totals = np.add.reduce(
                        self._layout.column_stats[0].reshape(len(self._bands), -1),
                        axis=1).tolist()[::-1]
                bands.append(BandDetection(False, math.nan, math.nan, band_totals[index],
                                           top, bottom, plan.searched[index], 0.0))
            else:
                bands.append(BandDetection(True, candidate.x_px, candidate.y_px,
                                           candidate.area_px, top, bottom, True,
                                           candidate.quality, candidate.at_side))
        # Even a doubtful line the robot steers by is where the next frame looks first: two
        # lines side by side (a hairpin's legs, the turn into it) are told apart by where
        # the line was, not by a single frame.
        self._previous_points = [by_band[index].point if index in by_band else None
                                 for index in range(len(self._bands))]
        self._previous_heading = (_heading(chain[0].point, chain[1].point)
                                  if len(chain) >= 2 else None)
        return Detection(tuple(bands), width, height, confidence)

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
        cv2.threshold(verdict, RULE_YES - 1, 1, cv2.THRESH_BINARY, dst=layout.mask)
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
        undecided = cv2.threshold(layout.verdict, RULE_YES - 1, RULE_YES,
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

    def _stripes(self, min_column_pixels=1):
        """
        Return each band's stripes of line pixels that are large enough, nearest band first.

        :param min_column_pixels: a column is part of a stripe when at least this many of
            its pixels in the band are the line's.
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
        if min_column_pixels == 1:
            np.not_equal(column_sums[0], layout.no_pixels, out=occupied[1:])
        else:
            np.greater_equal(column_sums[0], min_column_pixels, out=occupied[1:])
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


def _joined(stripes, max_gap_px):
    """
    Return a band's stripes, left to right, with those at most ``max_gap_px`` apart joined.

    :param stripes: (first column, end column, pixels, sum of their columns, sum of their
        rows) tuples, left to right.
    :param max_gap_px: the widest gap of bare columns a line's stripe may have.
    :return: the stripes, as tuples of the same form.
    """
    joined = [stripes[0]]
    for stripe in stripes[1:]:
        start, end, area, x_moment, y_moment = stripe
        first, last_end, last_area, last_x_moment, last_y_moment = joined[-1]
        if start - last_end <= max_gap_px:
            joined[-1] = (first, end, last_area + area, last_x_moment + x_moment,
                          last_y_moment + y_moment)
        else:
            joined.append(stripe)
    return joined


def _heading(near, far):
    """Return the unit vector from one point to another, or None if they coincide."""
    dx, dy = far[0] - near[0], far[1] - near[1]
    length = math.hypot(dx, dy)
    if length == 0.0:
        return None
    return dx / length, dy / length


def _link_cost(near, far, direction, max_turn_rad, jump):
    """
    Return the cost of the line going from one band's point to a farther band's, or None.

    :param near: the nearer point.
    :param far: the farther point.
    :param direction: the unit vector the line leads in at the nearer point.
    :param max_turn_rad: the most the line may turn on this link.
    :param jump: sideways distance allowed whatever the turn (noise, a short link).
    :return: the cost (0 straight on, TURN_COST at the limit), None beyond the limit or when
        the far point lies back behind the near one.
    """
    dx, dy = far[0] - near[0], far[1] - near[1]
    along = dx * direction[0] + dy * direction[1]
    if along < -jump:
        return None
    sideways = abs(dx * direction[1] - dy * direction[0])
    tolerance = jump + max(along, 0.0) * math.tan(max_turn_rad)
    if sideways > tolerance:
        return None
    return TURN_COST * (sideways / tolerance) ** 2


def _paint_share(link_support):
    """Return how surely a link's paint shows the line's way, 0 to 1."""
    return min(1.0, link_support / FULL_LINK_SUPPORT)


def _gap_evidence(chain, candidates, plan, support):
    """
    Return what the searched bands in the gaps a chain crosses add to its evidence.

    A band between two chained stripes that holds no stripe at all (a dash gap) counts as
    far as paint along their link shows the line's way there; not where the line left the
    view between them (nothing of it was seen there).
    """
    evidence = 0.0
    for near, far in zip(chain, chain[1:]):
        skipped = sum(plan.searched[band] and (
            not candidates[band]
            or _crossing(near, far, candidates[band], plan.expected_width_px[band]) is not None)
            for band in range(near.band + 1, far.band))
        if skipped and support.in_view(near, far):
            evidence += skipped * min(near.quality, far.quality) * _paint_share(
                support(near, far))
    return evidence


def _column_at_row(near, far, y_px):
    """Return the column at an image row of the straight line through two stripes."""
    rows = far.y_px - near.y_px
    if not rows:
        return far.x_px
    return far.x_px + (far.x_px - near.x_px) * (y_px - far.y_px) / rows


def _crossing(near, far, band_candidates, expected_width_px):
    """
    Return the line across the view that a link between two stripes crosses, or None.

    :param near: the nearer stripe of the link.
    :param far: the farther stripe.
    :param band_candidates: the candidates of a band between them.
    :param expected_width_px: the line's width in that band, or None without geometry.
    :return: the best of the band's stripes running along it (another line crossing the view)
        whose columns hold the link's column at its row, more than half the line's width
        inside where a line running through the band would enter or leave it (there, the
        stripe is that line, which the chain takes itself).
    """
    if expected_width_px is None:
        return None
    best = None
    for other in band_candidates:
        if other.span_px is None:
            continue
        x_px = _column_at_row(near, far, other.y_px)
        first, last = other.span_px
        inside = min(x_px - first, last - x_px) - expected_width_px
        if inside > 0.0 and (best is None or other.quality > best.quality):
            best = other
    return best


def _continues(chain, other, prior_heading, jump):
    """Tell whether a chain lies wholly beyond another's far end and leads on from it."""
    last = chain[-1]
    if other[0].band <= last.band:
        return False
    direction = (_heading(chain[-2].point, last.point) if len(chain) > 1 else None) or (
        prior_heading or (1.0, 0.0))
    return _link_cost(last.point, other[0].point, direction, MAX_LINK_TURN_RAD,
                      jump) is not None


def _could_replace(other, before, after, jump):
    """Tell whether a stripe links to a chain member's neighbours as well as a line would."""
    for near, far in ((before, other), (other, after)):
        if near is None or far is None:
            continue
        direction = _heading(near.point, far.point)
        if direction is None:
            continue
        if _link_cost(near.point, far.point, direction, MAX_LINK_TURN_RAD, jump) is None:
            return False
    if before is not None and math.dist(before.point, other.point) > (
            math.dist(before.point, after.point) if after is not None else math.inf):
        return False
    return True


class _LinkSupport:
    """
    How much of the image between two bands' stripes is the line's colour (0 to 1), cached.

    A line runs on between the bands: along the segment joining its stripes in two bands,
    most pixels (a solid line) or a good share (a dashed one) are the line's colour, judged
    against the floor of the nearer band. Between the line and a yellow object beside it
    there is bare floor: that link has no support.
    """

    def __init__(self, detector, plan):
        self._image, (self._channels, blue, red) = detector._look_image
        self._order = [blue, 1, red]
        self._model = detector._floor_model
        self._count = len(detector._bands)
        self._plan = plan
        # (id of the nearer, id of the farther) -> (support, whether it came from a path
        # inside the view rather than along its edge)
        self._cache = {}

    def __call__(self, near, far) -> float:
        """Return the support of the link from a nearer candidate to a farther one."""
        return self._measured(near, far)[0]

    def in_view(self, near, far) -> bool:
        """Tell whether the link's support comes from a path inside the view, not its edge."""
        return self._measured(near, far)[1]

    def _measured(self, near, far) -> tuple:
        key = (id(near), id(far))
        if key not in self._cache:
            self._cache[key] = self._measure(near, far)
        return self._cache[key]

    def _measure(self, near, far) -> tuple:
        straight = self._path_support([(near.x_px, near.y_px), (far.x_px, far.y_px)], near, far)
        if straight >= FULL_LINK_SUPPORT:
            return straight, True
        # A line bending between two stripes near one side of the view may run out of it
        # and back: look along the image's edge there too.
        width = self._image.shape[1]
        rows = abs(near.y_px - far.y_px)
        for edge_px in (0.0, width - 1.0):
            if max(abs(near.x_px - edge_px), abs(far.x_px - edge_px)) < rows:
                detour = [(near.x_px, near.y_px), (edge_px, 0.5 * (near.y_px + far.y_px)),
                          (far.x_px, far.y_px)]
                along_edge = self._path_support(detour, near, far)
                if along_edge > straight:
                    return along_edge, False
                return straight, True
        return straight, True

    def joined(self, chosen, other, neighbour=None) -> bool:
        """
        Tell whether two stripes of one band are the two arms of one bend.

        Where the line turns back (a hairpin, a U seen from above), the band crosses it twice.
        The arms are joined by line-coloured pixels along an arc below or above the band, and
        the turn crosses the floor's middle between them on that side; a second line does
        neither.

        :param neighbour: the chain's stripe next to ``chosen`` (the arms' direction), or None.
        """
        half_px = 0.5 * abs(other.x_px - chosen.x_px)
        along = (np.arange(MAX_LINK_SAMPLES) + 0.5) / MAX_LINK_SAMPLES
        # Whether the turn crosses the middle on each side, once asked.
        turns = {}
        for share in HAIRPIN_DEPTH_SHARES:
            for side in (1.0, -1.0):
                if turns.get(side) is False:
                    continue
                # A quadratic Bezier arc whose middle lies that deep beyond the band.
                control_x = 0.5 * (chosen.x_px + other.x_px)
                control_y = chosen.y_px + side * 2.0 * share * half_px
                x_px = ((1 - along) ** 2 * chosen.x_px + 2 * along * (1 - along) * control_x
                        + along ** 2 * other.x_px)
                y_px = ((1 - along) ** 2 * chosen.y_px + 2 * along * (1 - along) * control_y
                        + along ** 2 * other.y_px)
                if self._support(x_px, y_px, chosen, other) < FULL_LINK_SUPPORT:
                    continue
                # Beside the arc, across its direction, the floor must show.
                tangent_x = 2 * (1 - along) * (control_x - chosen.x_px) + 2 * along * (
                    other.x_px - control_x)
                tangent_y = 2 * (1 - along) * (control_y - chosen.y_px) + 2 * along * (
                    other.y_px - control_y)
                length = np.maximum(np.hypot(tangent_x, tangent_y), 1e-9)
                across = (-tangent_y / length, tangent_x / length)
                if self._support(x_px, y_px, chosen, other, BESIDE_LINE_OFFSETS,
                                 across) > 1.0 - FULL_LINK_SUPPORT:
                    continue
                if side not in turns:
                    turns[side] = self._turn_between(chosen, other, neighbour, side)
                if turns[side]:
                    return True
        return False

    def _turn_between(self, chosen, other, neighbour, side) -> bool:
        """
        Tell whether the line crosses the floor's middle between two stripes of a band.

        Two parallel lines run on each side of their middle, in the image toward their
        vanishing point on the horizon; the turn of a hairpin crosses it. The middle is
        followed beyond the band on one side (1 below, -1 above) as far as the image shows
        the floor, every TURN_STEP_PX rows: the turn may lie beyond the arcs' reach.

        :param neighbour: the chain's stripe next to ``chosen``, which gives the arms'
            direction (their vanishing point), or None: then the middle is an image column.
        """
        last_row = self._image.shape[0] - 1
        end = last_row + TURN_STEP_PX if side > 0 else -TURN_STEP_PX
        rows = np.arange(chosen.y_px + side * TURN_STEP_PX, end, side * TURN_STEP_PX)
        horizon = self._plan.horizon_px
        # The turn lies on the floor: above the horizon a yellow wall would pass for it.
        first_row = 0 if horizon is None else max(0.0, math.floor(horizon) + 1.0)
        rows = rows[(rows >= first_row) & (rows <= last_row)]
        if not len(rows):
            return False
        middle_x = 0.5 * (chosen.x_px + other.x_px)
        columns_per_row = 0.0
        if (neighbour is not None and horizon is not None and horizon < chosen.y_px
                and neighbour.y_px != chosen.y_px):
            vanishing_x = chosen.x_px + (neighbour.x_px - chosen.x_px) * (
                horizon - chosen.y_px) / (neighbour.y_px - chosen.y_px)
            columns_per_row = (vanishing_x - middle_x) / (horizon - chosen.y_px)
        columns = middle_x + columns_per_row * (rows - chosen.y_px)
        # On the middle itself: farther up the arms, narrowing with distance, come nearer to
        # it than the band's half width.
        return self._support(columns, rows, chosen, other, ON_THE_MIDDLE) > 0.0

    def _path_support(self, waypoints, near, far) -> float:
        """Return the support along a path of straight pieces from a stripe to another."""
        lengths = [abs(y1 - y0) for (_, y0), (_, y1) in zip(waypoints, waypoints[1:])]
        total = sum(lengths)
        samples = int(min(max(total / LINK_SAMPLE_SPACING_PX, MIN_LINK_SAMPLES),
                          MAX_LINK_SAMPLES))
        distance = (np.arange(samples) + 0.5) / samples * max(total, 1e-9)
        x_px = np.empty(samples)
        y_px = np.empty(samples)
        start = 0.0
        for (x0, y0), (x1, y1), length in zip(waypoints, waypoints[1:], lengths):
            inside = (distance >= start) & (distance <= start + length)
            t = (distance[inside] - start) / max(length, 1e-9)
            x_px[inside] = x0 + t * (x1 - x0)
            y_px[inside] = y0 + t * (y1 - y0)
            start += length
        return self._support(x_px, y_px, near, far)

    def _support(self, x_px, y_px, near, far, offsets=LINK_OFFSETS, across=None) -> float:
        """
        Return the share of points that are the line's colour, judged on the line's width.

        Each point is judged against the floor of the band of the stripe it is nearer (in
        rows), at offsets (in half widths of the line there) along the row, or along the
        given unit vectors ``across`` (x, y arrays), and counts when any of them is.
        """
        height, width = self._image.shape[:2]
        samples = len(x_px)
        widths = [self._plan.expected_width_px[near.band],
                  self._plan.expected_width_px[far.band]]
        span = far.y_px - near.y_px
        towards_far = np.clip((y_px - near.y_px) / span, 0.0, 1.0) if span else np.zeros(samples)
        if widths[0] is None:
            half_px = np.full(samples, LINK_NO_GEOMETRY_HALF_WIDTH_PX)
        else:
            half_px = 0.5 * (widths[0] + towards_far * (widths[1] - widths[0]))
        if across is None:
            columns = x_px[:, np.newaxis] + half_px[:, np.newaxis] * offsets
            rows_px = np.repeat(y_px[:, np.newaxis], len(offsets), axis=1)
        else:
            reach_px = half_px[:, np.newaxis] * offsets
            columns = x_px[:, np.newaxis] + reach_px * across[0][:, np.newaxis]
            rows_px = y_px[:, np.newaxis] + reach_px * across[1][:, np.newaxis]
        column = np.rint(columns).astype(np.intp)
        row = np.clip(np.rint(rows_px).astype(np.intp), 0, height - 1)
        # The mean of each sample's row neighbours, as the bands' pixels were smoothed.
        reach = line_colour.SMOOTHING_KERNEL_PX[0] // 2
        column = np.clip(column, reach, width - 1 - reach)
        total = 0.0
        for column_offset in range(-reach, reach + 1):
            total = total + self._image[row, column + column_offset].astype(np.float32)
        pixels = total / (2 * reach + 1)
        if self._channels > 1:
            pixels = pixels[..., self._order]
        band_of = np.where(towards_far < 0.5, self._count - 1 - near.band,
                           self._count - 1 - far.band)
        band_of = np.repeat(band_of[:, np.newaxis], len(offsets), axis=1)
        strength = line_colour.pixel_strength(
            self._model, pixels.reshape((-1,) + pixels.shape[2:]), band_of.reshape(-1))
        return float((strength.reshape(samples, -1).max(axis=1) >= 1.0).mean())


def _best_chain(candidates, plan, prior_heading, support=None):
    """
    Find the chain of candidates, at most one a band, nearest first, that best forms a line.

    A chain scores the sum of its candidates' qualities, less the cost of each turn (which
    needs the two links around it: the search runs over pairs of candidates) and of each
    searched band it skips.

    :param candidates: per band nearest first, its candidates.
    :param plan: the bands' plan (which bands are searched, the jump allowance).
    :param prior_heading: the unit vector the line leads in from the nearest band (the last
        frame's), or None for straight ahead.
    :return: (score, chain nearest first); (0, []) without candidates.
    """
    flat = [candidate for band in candidates for candidate in band
            if all(math.isfinite(value) for value in candidate.point)]
    if not flat:
        return 0.0, []
    searched_before = [0]
    for searched in plan.searched:
        searched_before.append(searched_before[-1] + searched)
    prior = prior_heading or (1.0, 0.0)
    # (index of the previous candidate or -1, index of this one) -> (score, key it came from)
    states = {}
    ends = [[] for _ in flat]
    for current, candidate in enumerate(flat):
        weight = NEAR_BAND_WEIGHT ** candidate.band
        worth = candidate.quality * weight
        states[(-1, current)] = (worth, None)
        ends[current].append(-1)
        for previous in range(current):
            before = flat[previous]
            if before.band >= candidate.band:
                break
            best = None
            link_cost = None
            for earlier in ends[previous]:
                score = states[(earlier, previous)][0]
                if earlier == -1:
                    direction, turn = prior, FIRST_LINK_TURN_RAD
                else:
                    direction = _heading(flat[earlier].point, before.point) or prior
                    turn = MAX_LINK_TURN_RAD
                cost = _link_cost(before.point, candidate.point, direction, turn, plan.jump)
                if cost is None:
                    continue
                if support is not None:
                    if link_cost is None:
                        link_cost = UNSUPPORTED_LINK_COST * (
                            1.0 - _paint_share(support(before, candidate)))
                    cost += link_cost
                if best is None or score - cost > best[0]:
                    best = (score - cost, (earlier, previous))
            if best is not None:
                skipped = searched_before[candidate.band] - searched_before[before.band + 1]
                # A line crossing the view that this link passes through hides nothing of it:
                # the band saw the line there.
                crossed = [crossing.quality * NEAR_BAND_WEIGHT ** crossing.band
                           for crossing in (_crossing(before, candidate, candidates[band],
                                                      plan.expected_width_px[band])
                                            for band in range(before.band + 1, candidate.band))
                           if crossing is not None]
                states[(previous, current)] = (best[0] + worth + sum(crossed)
                                               - GAP_COST * (skipped - len(crossed)), best[1])
                ends[current].append(previous)
    ends = {}
    for key, (score, back) in states.items():
        first = key[1]
        while back is not None:
            first, back = back[1], states[back][1]
        # Between chains as good, the one starting nearest the robot's path wins.
        ends[key] = score - CENTRE_PREFERENCE * abs(flat[first].point[1]) / (
            abs(flat[first].point[1]) + plan.jump)
    key = max(ends, key=ends.get)
    score = states[key][0]
    chain = []
    while key is not None:
        chain.append(flat[key[1]])
        key = states[key][1]
    return score, chain[::-1]


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
            DEBUG_BAND_COLOUR_BGR if band.searched else DEBUG_UNSEARCHED_BAND_COLOUR_BGR,
            DEBUG_LINE_THICKNESS_PX)
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
