"""Tests of the line detector on synthetic images: bands, stripes, the chain, the geometry."""

import dataclasses
import math

import cv2
from followbot.colour_rule import colour_rule, RULE_YES
from followbot.image_conversion import array_to_image
from followbot.image_conversion import image_to_array
from followbot.image_conversion import ImageConversionError
from followbot.line_detector import band_rows
from followbot.line_detector import BandDetection
from followbot.line_detector import Detection
from followbot.line_detector import DetectorConfig
from followbot.line_detector import draw_debug
from followbot.line_detector import hsv_bounds
from followbot.line_detector import LineDetector
from followbot.line_detector import MIN_SEARCH_WIDTH_PX
from followbot.line_detector import NO_GEOMETRY_JUMP_SHARE
import numpy as np
import pytest
import scenes
from sensor_msgs.msg import Image

WIDTH_PX = 640
HEIGHT_PX = 480
FLOOR_GREY = 116
LINE_HALF_WIDTH_PX = 7
LINE_WIDTH_PX = 2 * LINE_HALF_WIDTH_PX + 1
CENTRE_COLUMN = WIDTH_PX // 2
# The default bands of a 640x480 image, nearest first.
DEFAULT_BANDS = band_rows(HEIGHT_PX, DetectorConfig())
# The book's single band: 20 rows at 3/4 of a 480-row image, rows 360-380.
BOOK_CONFIG = DetectorConfig(
    band_count=1, band_center_fraction=0.7708333333333334, band_height_px=20)
BOOK_BAND_ROWS = (360, 380)

# The course's yellow RGB(255, 246, 0), in shade, and in deep shade (value 64).
YELLOWS_RGB = {
    'lit': (255, 246, 0),
    'shaded': (128, 123, 0),
    'deep_shade': (64, 62, 0),
}
LIT_YELLOW_RGB = YELLOWS_RGB['lit']

# Encodings are made from a BGR image with these OpenCV conversions.
CONVERSIONS_FROM_BGR = {
    'rgb8': cv2.COLOR_BGR2RGB,
    'bgra8': cv2.COLOR_BGR2BGRA,
    'rgba8': cv2.COLOR_BGR2RGBA,
}

# Camera noise like the simulator's camera_noise_stddev, drawn from a fixed seed.
CAMERA_NOISE_STDDEV = 8.0
NOISE_SEED = 20240611
# A noisy centroid stays this close to the noise-free one: the noise is symmetric.
NOISY_CENTROID_TOLERANCE_PX = 0.5

# Debug drawing colours (BGR), as the overlay's legend describes them.
RED_BGR = (0, 0, 255)
GREEN_BGR = (0, 255, 0)
BLUE_BGR = (255, 0, 0)
# The overlay's text sits in the top rows of the image, above every band.
TEXT_ROWS_PX = 60

# All 2**24 8-bit colours, shown as square images of this side: 16 blue levels each.
ALL_COLOURS_SIDE_PX = 1024
COLOUR_LEVELS = 256


def bgr(rgb):
    """Return an RGB colour as a BGR tuple."""
    return tuple(reversed(rgb))


def floor_image(height=HEIGHT_PX, width=WIDTH_PX, grey=FLOOR_GREY):
    """Return a BGR image of the bare grey floor."""
    return np.full((height, width, 3), grey, dtype=np.uint8)


def paint_line(image, column, rows=slice(None), half_width_px=LINE_HALF_WIDTH_PX,
               rgb=LIT_YELLOW_RGB):
    """
    Paint a vertical stripe of the line's colour centred exactly on a column, in place.

    :param image: the BGR image to paint on.
    :param column: the stripe's centre column.
    :param rows: the rows to paint, all by default.
    :param half_width_px: columns either side of the centre column.
    :param rgb: the colour.
    :return: the image.
    """
    image[rows, max(column - half_width_px, 0):column + half_width_px + 1] = bgr(rgb)
    return image


def vertical_line_image(column, height=HEIGHT_PX, width=WIDTH_PX,
                        half_width_px=LINE_HALF_WIDTH_PX, rgb=LIT_YELLOW_RGB):
    """Return a floor image with a full-height line centred exactly on a column."""
    return paint_line(floor_image(height, width), column, half_width_px=half_width_px, rgb=rgb)


def lines_image(*columns):
    """Return a floor image with full-height lines centred on the given columns."""
    image = floor_image()
    for column in columns:
        paint_line(image, column)
    return image


def band_slice(band):
    """Return the rows of a (top, bottom) band as a slice."""
    top, bottom = band
    return slice(top, bottom)


def expected_error(column, width=WIDTH_PX):
    """Return the normalised error of a line centred on a column."""
    return (column - width / 2) / (width / 2)


def centroids_px(detection):
    """Return the centroid columns of a detection's bands, NaN where a band saw nothing."""
    return [band.centroid_x_px for band in detection.bands]


def add_camera_noise(image_bgr, generator):
    """Return an image with Gaussian noise added to every channel, saturating at 0 and 255."""
    noise = np.rint(generator.normal(0.0, CAMERA_NOISE_STDDEV, image_bgr.shape))
    return np.clip(image_bgr + noise, 0, 255).astype(np.uint8)


def band_result(found, centroid_x_px, top_px, area_px):
    """Return a BandDetection of 10 rows from top_px, centred on its rows where found."""
    centroid_y_px = top_px + 4.5 if found else math.nan
    return BandDetection(found=found, centroid_x_px=centroid_x_px, centroid_y_px=centroid_y_px,
                         area_px=area_px, top_px=top_px, bottom_px=top_px + 10)


def all_colour_images():
    """
    Yield BGR images that between them hold every 8-bit colour once.

    Each image holds 16 blue levels: row y has blue 16 * k + y // 64 and green
    4 * (y % 64) + x // 256 in column x, whose red is x % 256.
    """
    rows = np.arange(ALL_COLOURS_SIDE_PX).reshape(-1, 1)
    columns = np.arange(ALL_COLOURS_SIDE_PX).reshape(1, -1)
    blue_levels = ALL_COLOURS_SIDE_PX * ALL_COLOURS_SIDE_PX // COLOUR_LEVELS ** 2
    green_rows = COLOUR_LEVELS * COLOUR_LEVELS // ALL_COLOURS_SIDE_PX
    image = np.empty((ALL_COLOURS_SIDE_PX, ALL_COLOURS_SIDE_PX, 3), np.uint8)
    image[..., 1] = (rows % green_rows) * (ALL_COLOURS_SIDE_PX // COLOUR_LEVELS) \
        + columns // COLOUR_LEVELS
    image[..., 2] = columns % COLOUR_LEVELS
    for first_blue in range(0, COLOUR_LEVELS, blue_levels):
        image[..., 0] = first_blue + rows // green_rows
        yield image


def arc_image(center, radius):
    """Return a floor image with a 15-pixel wide arc of the line, and the arc's mask."""
    arc_mask = np.zeros((HEIGHT_PX, WIDTH_PX), dtype=np.uint8)
    cv2.circle(arc_mask, center, radius, 255, thickness=15, lineType=cv2.LINE_8)
    image = floor_image()
    image[arc_mask > 0] = bgr(LIT_YELLOW_RGB)
    return image, arc_mask


# Band geometry.

def test_default_config_searches_six_bands_up_the_image_nearest_first():
    config = DetectorConfig()
    assert len(DEFAULT_BANDS) == config.band_count == 6
    spacing_px = config.band_spacing_fraction * HEIGHT_PX
    for index, (top, bottom) in enumerate(DEFAULT_BANDS):
        assert 0 <= top < bottom <= HEIGHT_PX
        assert bottom - top == config.band_height_px
        nominal_centre = HEIGHT_PX * config.band_center_fraction - index * spacing_px
        assert abs((top + bottom) / 2 - nominal_centre) <= 1.0
    for (near_top, _), (_, far_bottom) in zip(DEFAULT_BANDS, DEFAULT_BANDS[1:]):
        assert far_bottom <= near_top, 'bands must not overlap and go up the image'


def test_bands_are_exactly_one_spacing_apart():
    config = DetectorConfig(band_count=6, band_center_fraction=0.95,
                            band_spacing_fraction=0.125, band_height_px=12)
    assert band_rows(HEIGHT_PX, config) == [
        (450, 462), (390, 402), (330, 342), (270, 282), (210, 222), (150, 162)]


def test_book_config_searches_rows_360_to_380():
    assert band_rows(HEIGHT_PX, BOOK_CONFIG) == [BOOK_BAND_ROWS]
    detection = LineDetector(BOOK_CONFIG).detect(vertical_line_image(420))
    assert [(band.top_px, band.bottom_px) for band in detection.bands] == [BOOK_BAND_ROWS]
    # The book steers with -(cx - w/2) / 100: cx = 420 at w = 640 is an error of 0.3125.
    assert detection.error == pytest.approx(0.3125)


# Fractions that are exact in binary, so every band centre is a whole row.
@pytest.mark.parametrize('fields, height, expected_bands', (
    # Twenty bands asked for; those falling above the image are left out.
    ({'band_count': 20, 'band_center_fraction': 0.9375, 'band_spacing_fraction': 0.125},
     HEIGHT_PX, [(444, 456), (384, 396), (324, 336), (264, 276), (204, 216), (144, 156),
                 (84, 96), (24, 36)]),
    # The third band's centre is row 0: it is clipped to the image, the fourth left out.
    ({'band_count': 6, 'band_center_fraction': 0.9375, 'band_spacing_fraction': 0.46875},
     HEIGHT_PX, [(444, 456), (219, 231), (0, 6)]),
    # Bands 80 rows high 60 rows apart would overlap: only the nearest is searched.
    ({'band_count': 6, 'band_center_fraction': 0.9375, 'band_spacing_fraction': 0.125,
      'band_height_px': 80}, HEIGHT_PX, [(410, 480)]),
    # No spacing: the further bands would repeat the nearest one's rows.
    ({'band_count': 6, 'band_spacing_fraction': 0.0, 'band_center_fraction': 0.5},
     HEIGHT_PX, [(234, 246)]),
    ({'band_count': 1, 'band_center_fraction': 0.99}, HEIGHT_PX, [(469, 480)]),
    ({'band_count': 1, 'band_center_fraction': 0.01, 'band_height_px': 30},
     HEIGHT_PX, [(0, 19)]),
    ({'band_count': 3, 'band_height_px': 1000}, HEIGHT_PX, [(0, HEIGHT_PX)]),
    ({'band_count': 1, 'band_center_fraction': 0.75, 'band_height_px': 1},
     HEIGHT_PX, [(360, 361)]),
    ({}, 1, [(0, 1)]),
    ({}, 3, [(0, 3)]),
))
def test_band_rows_clip_to_the_image_and_leave_out_overlapping_bands(
        fields, height, expected_bands):
    fields = {'band_height_px': 12, **fields}
    config = DetectorConfig(min_area_px=1, **fields)
    assert band_rows(height, config) == expected_bands

    detection = LineDetector(config).detect(vertical_line_image(480, height=height))
    assert [(band.top_px, band.bottom_px) for band in detection.bands] == expected_bands
    assert detection.confidence == 1.0
    for (top, bottom), band_detection in zip(expected_bands, detection.bands):
        assert band_detection.area_px == (bottom - top) * LINE_WIDTH_PX


@pytest.mark.parametrize('fields', (
    # The nearest band is clipped by the image's bottom edge: 9 rows where the others have 30.
    {'band_center_fraction': 0.99, 'band_height_px': 30},
    # The farthest band is clipped by the top edge: 6 rows where the others have 12.
    {'band_count': 3, 'band_center_fraction': 0.9375, 'band_spacing_fraction': 0.46875},
    # Band centres 53.28 rows apart: the bands are 53 and 54 rows apart.
    {'band_count': 5, 'band_center_fraction': 0.93, 'band_spacing_fraction': 0.111,
     'band_height_px': 9},
), ids=('clipped_nearest', 'clipped_farthest', 'uneven_spacing'))
def test_bands_of_unequal_height_or_spacing_each_see_only_their_own_rows(fields):
    config = DetectorConfig(min_area_px=1, **fields)
    bands = band_rows(HEIGHT_PX, config)
    heights = {bottom - top for top, bottom in bands}
    spacings = {upper[0] - lower[0] for upper, lower in zip(bands, bands[1:])}
    assert len(heights) > 1 or len(spacings) > 1, 'the bands must differ'
    image, arc_mask = arc_image((-200, 480), 700)
    detector = LineDetector(config)

    detection = detector.detect(image)

    assert detection.confidence > 0.99
    for (top, bottom), band_detection in zip(bands, detection.bands):
        rows, columns = np.nonzero(arc_mask[top:bottom])
        assert (band_detection.top_px, band_detection.bottom_px) == (top, bottom)
        assert band_detection.area_px == columns.size
        assert band_detection.centroid_x_px == pytest.approx(columns.mean(), abs=1e-9)
        assert band_detection.centroid_y_px == pytest.approx(top + rows.mean(), abs=1e-9)
    np.testing.assert_array_equal(
        detector.last_mask, np.concatenate([arc_mask[top:bottom] for top, bottom in bands]))
    expected_drawn = np.zeros_like(arc_mask)
    for top, bottom in bands:
        expected_drawn[top:bottom] = arc_mask[top:bottom]
    np.testing.assert_array_equal(
        detector.draw_mask(np.full((HEIGHT_PX, WIDTH_PX), 7, np.uint8)), expected_drawn)


# Finding the line.

@pytest.mark.parametrize('colour', YELLOWS_RGB)
def test_centred_line_gives_zero_error_in_every_band(colour):
    detection = LineDetector().detect(
        vertical_line_image(CENTRE_COLUMN, rgb=YELLOWS_RGB[colour]))
    assert detection.found
    assert detection.confidence == 1.0
    assert detection.error == pytest.approx(0.0, abs=1e-9)
    assert detection.seen_bands == detection.bands
    assert detection.nearest is detection.bands[0]
    assert detection.image_width_px == WIDTH_PX
    assert detection.image_height_px == HEIGHT_PX
    assert [(band.top_px, band.bottom_px) for band in detection.bands] == DEFAULT_BANDS
    for band_detection in detection.bands:
        rows = band_detection.bottom_px - band_detection.top_px
        assert band_detection.centroid_x_px == pytest.approx(CENTRE_COLUMN)
        assert band_detection.centroid_y_px == pytest.approx(
            (band_detection.top_px + band_detection.bottom_px) / 2 - 0.5)
        assert band_detection.area_px == LINE_WIDTH_PX * rows
        assert band_detection.searched and band_detection.quality == 1.0
    assert detection.area_px == sum(band_detection.area_px for band_detection in detection.bands)


@pytest.mark.parametrize('colour', YELLOWS_RGB)
@pytest.mark.parametrize('column, side', (
    (420, 1),
    (600, 1),
    (321, 1),
    (220, -1),
    (40, -1),
    (319, -1),
))
def test_offset_line_gives_error_of_its_side_and_size(column, side, colour):
    detection = LineDetector().detect(vertical_line_image(column, rgb=YELLOWS_RGB[colour]))
    assert detection.confidence == 1.0
    assert math.copysign(1.0, detection.error) == side
    assert abs(detection.nearest.centroid_x_px - column) <= 1.0
    assert detection.error == pytest.approx(expected_error(column), abs=1.0 / (WIDTH_PX / 2))


@pytest.mark.parametrize('center, radius, config', (
    ((-200, 480), 700, DetectorConfig()),
    ((840, 480), 700, DetectorConfig()),
    ((100, 480), 300, BOOK_CONFIG),
    ((640, 600), 350, BOOK_CONFIG),
))
def test_curved_line_centroid_is_the_arc_mean_in_each_band(center, radius, config):
    image, arc_mask = arc_image(center, radius)

    detection = LineDetector(config).detect(image)

    # A slanted stripe fills less of its band's box: a little less sure than a straight one.
    assert detection.confidence > 0.9
    for band_detection in detection.bands:
        rows, columns = np.nonzero(arc_mask[band_detection.top_px:band_detection.bottom_px])
        assert band_detection.area_px == columns.size
        assert band_detection.centroid_x_px == pytest.approx(columns.mean())
        assert band_detection.centroid_y_px == pytest.approx(band_detection.top_px + rows.mean())


@pytest.mark.parametrize('image', (
    floor_image(),
    floor_image(grey=0),
    floor_image(grey=40),
    floor_image(grey=200),
    floor_image(grey=255),
), ids=('grey116', 'black', 'dark_grey', 'light_grey', 'white'))
def test_no_line_is_not_found(image):
    detection = LineDetector().detect(image)
    assert not detection.found
    assert detection.error == 0.0
    assert detection.confidence == 0.0
    assert detection.nearest is None
    assert detection.seen_bands == ()
    assert detection.area_px == 0
    assert len(detection.bands) == len(DEFAULT_BANDS)
    for band_detection in detection.bands:
        assert not band_detection.found
        assert math.isnan(band_detection.centroid_x_px)
        assert math.isnan(band_detection.centroid_y_px)
        assert band_detection.area_px == 0


# A lone stripe is judged in the second look, whose smoothing along the rows (5 pixels)
# widens a sharp stripe by two pixels either side: 4x4 pixels count as 8x4.
@pytest.mark.parametrize('min_area_px, found', ((32, True), (33, False)))
def test_a_stripe_is_found_from_min_area_px_on(min_area_px, found):
    image = floor_image()
    top, bottom = DEFAULT_BANDS[0]
    assert bottom - top >= 4
    image[top:top + 4, 100:104] = bgr(LIT_YELLOW_RGB)
    detection = LineDetector(DetectorConfig(min_area_px=min_area_px)).detect(image)
    assert detection.found == found
    if found:
        assert detection.nearest.centroid_x_px == pytest.approx(101.5)
    else:
        assert detection.bands[0].area_px == 32
        assert detection.area_px == 0
        assert detection.error == 0.0


def test_a_stripe_in_one_band_only_is_a_doubtful_line():
    image = floor_image()
    paint_line(image, 200, band_slice(DEFAULT_BANDS[2]))
    detection = LineDetector().detect(image)
    assert [band.found for band in detection.bands] == [
        False, False, True, False, False, False]
    assert detection.confidence == pytest.approx(1 / len(DEFAULT_BANDS))


def test_many_specks_each_below_min_area_are_not_a_line():
    config = DetectorConfig(min_area_px=33)
    image = floor_image()
    speck_columns = range(20, WIDTH_PX - 20, 12)
    speck_side_px = 3
    for top, _ in DEFAULT_BANDS:
        for column in speck_columns:
            image[top + 1:top + 1 + speck_side_px, column:column + speck_side_px] = bgr(
                LIT_YELLOW_RGB)

    detection = LineDetector(config).detect(image)

    assert not detection.found


def rows_outside_the_bands():
    """Return slices of rows no default band covers: below, between and above them."""
    nearest_top, nearest_bottom = DEFAULT_BANDS[0]
    _, second_bottom = DEFAULT_BANDS[1]
    farthest_top, _ = DEFAULT_BANDS[-1]
    return (slice(nearest_bottom, HEIGHT_PX), slice(second_bottom, nearest_top),
            slice(0, farthest_top))


@pytest.mark.parametrize('rows', rows_outside_the_bands(), ids=('below', 'between', 'above'))
def test_line_only_outside_the_bands_is_not_found(rows):
    image = floor_image()
    image[rows, 300:340] = bgr(LIT_YELLOW_RGB)
    assert not LineDetector().detect(image).found


@pytest.mark.parametrize('colour_bgr', (
    (0, 0, 255),
    (0, 255, 0),
    (255, 0, 0),
    (0, 128, 255),
    (200, 220, 230),
), ids=('red', 'green', 'blue', 'orange', 'pale_yellow_white'))
def test_other_colours_are_not_the_line(colour_bgr):
    image = floor_image()
    image[:, 300:340] = colour_bgr
    assert not LineDetector().detect(image).found


@pytest.mark.parametrize('thresholds', (
    {},
    {'line_colour': 'custom', 'hue_min': 15, 'hue_max': 45, 'saturation_min': 150,
     'value_min': 80},
    {'line_colour': 'custom', 'hue_min': 0, 'hue_max': 10, 'saturation_min': 30},
), ids=('yellow_preset', 'wider_hue_brighter', 'red'))
def test_the_first_look_takes_a_colour_exactly_when_opencv_hsv_says_so(thresholds):
    config = DetectorConfig(**thresholds)
    lower, upper = hsv_bounds(config)
    rule = colour_rule(int(lower[0]), int(upper[0]), int(lower[1]), int(upper[1]),
                       int(lower[2]), int(upper[2]))
    if rule is None:
        pytest.skip('these bounds have no fast rule: the detector runs cvtColor itself')
    planes = [np.empty((1, ALL_COLOURS_SIDE_PX * ALL_COLOURS_SIDE_PX), np.uint8)
              for _ in range(5)]
    for image in all_colour_images():
        cv2.split(image.reshape(1, -1, 3), planes[:3])
        rule.classify(*planes)
        expected = cv2.inRange(cv2.cvtColor(image, cv2.COLOR_BGR2HSV), lower, upper)
        verdict = planes[4].reshape(expected.shape)
        # Sure yes and sure no agree with OpenCV; the rest the detector settles with it.
        assert not ((verdict == RULE_YES) & (expected == 0)).any()
        assert not ((verdict == 0) & (expected != 0)).any()


def test_first_look_mask_is_opencvs_on_a_clean_frame():
    image = vertical_line_image(CENTRE_COLUMN, rgb=YELLOWS_RGB['shaded'])
    detector = LineDetector()
    detector.detect(image)
    lower, upper = hsv_bounds(DetectorConfig())
    expected = cv2.inRange(cv2.cvtColor(image, cv2.COLOR_BGR2HSV), lower, upper)
    np.testing.assert_array_equal(
        detector.last_mask, np.concatenate([expected[top:bottom] for top, bottom in
                                            DEFAULT_BANDS]))


# Choosing the line's stripe.

@pytest.mark.parametrize('patch_columns, patch_rows', (
    (slice(400, 440), band_slice(DEFAULT_BANDS[2])),
    (slice(250, 290), slice(DEFAULT_BANDS[3][0], DEFAULT_BANDS[1][1])),
    (slice(0, 40), band_slice(DEFAULT_BANDS[0])),
), ids=('right_one_band', 'left_in_middle_bands', 'left_edge_nearest_band'))
def test_a_yellow_patch_beside_the_line_does_not_move_it(patch_columns, patch_rows):
    clean = vertical_line_image(CENTRE_COLUMN)
    patched = clean.copy()
    patched[patch_rows, patch_columns] = bgr(LIT_YELLOW_RGB)

    detection = LineDetector().detect(patched)

    # The line runs on between the bands; no paint joins the patch to it.
    assert centroids_px(detection) == pytest.approx([CENTRE_COLUMN] * len(DEFAULT_BANDS))
    assert detection.error == pytest.approx(0.0, abs=1e-9)
    assert detection.confidence > 0.5


@pytest.mark.parametrize('columns, chosen_column', (
    ((200, 500), 200),
    ((100, 400), 400),
    ((260, 360), 360),
    ((CENTRE_COLUMN, 600), CENTRE_COLUMN),
))
def test_of_two_lines_the_first_frame_takes_the_one_nearest_the_centre_and_doubts(
        columns, chosen_column):
    detection = LineDetector().detect(lines_image(*columns))
    # Two lines as good as each other: the follower may slow down or stop, but never takes
    # the farther one.
    assert detection.confidence < 0.75
    if detection.found:
        assert centroids_px(detection) == pytest.approx([chosen_column] * len(DEFAULT_BANDS))


def test_next_frame_follows_the_line_not_a_line_nearer_the_centre():
    detector = LineDetector()
    detector.detect(vertical_line_image(200))
    detection = detector.detect(lines_image(215, 300))

    assert centroids_px(detection) == pytest.approx([215] * len(DEFAULT_BANDS))
    assert detection.error == pytest.approx(expected_error(215))


def test_a_doubtful_line_is_followed_into_the_next_frame_not_a_line_beside_it():
    # Where the robot turns into a hairpin, its line and the hairpin's other leg run side by
    # side 0.30 m apart; the line it drives is the one it saw, however doubtfully, a frame ago.
    followed_m, beside_m = -0.17, 0.13
    detector = LineDetector()
    stub = detector.detect(scenes.scene([scenes.straight_line(followed_m, length_m=0.9)]),
                           'bgr8', scenes.KINECT)
    assert 0.1 <= stub.confidence < 0.5
    both = scenes.scene([scenes.straight_line(followed_m), scenes.straight_line(beside_m)])
    detection = detector.detect(both, 'bgr8', scenes.KINECT)
    # On its own the frame shows the line nearer the middle: the other one.
    alone = LineDetector().detect(both, 'bgr8', scenes.KINECT)
    assert [band.centroid_x_px for band in alone.seen_bands] == pytest.approx(
        [band.centroid_x_px for band in scenes_line_detection(beside_m).seen_bands], abs=2.0)
    assert [band.centroid_x_px for band in detection.seen_bands] == pytest.approx(
        [band.centroid_x_px for band in scenes_line_detection(followed_m).seen_bands], abs=2.0)


TWO_STRIP_TAPE_M = 0.05
BLACK_BGR = (30, 30, 30)


def two_strips_scene(seam_m, tape_m=TWO_STRIP_TAPE_M):
    """Return a black line laid straight ahead as two strips of tape a seam apart."""
    strip_m = (tape_m - seam_m) / 2.0
    offset_m = (strip_m + seam_m) / 2.0
    return scenes.add_noise(scenes.scene(
        [scenes.straight_line(-offset_m), scenes.straight_line(offset_m)], width_m=strip_m,
        line_bgr=BLACK_BGR), 4.0)


@pytest.mark.parametrize('seam_m', (0.002, 0.005))
def test_a_line_of_two_strips_of_tape_is_one_line_not_two(seam_m):
    # A wide line laid as two strips, or one with a scratch or a highlight along it: the seam
    # splits its stripe in every band, and the halves are not two rival lines.
    config = DetectorConfig(line_colour='black', line_width_m=TWO_STRIP_TAPE_M)
    whole = LineDetector(config).detect(two_strips_scene(0.0), 'bgr8', scenes.KINECT)
    split = LineDetector(config).detect(two_strips_scene(seam_m), 'bgr8', scenes.KINECT)
    assert whole.confidence > 0.99
    assert split.confidence > 0.9
    assert centroids_px(split) == pytest.approx(centroids_px(whole), abs=1.0)


def test_two_tapes_a_hand_apart_stay_two_lines():
    config = DetectorConfig(line_colour='black', line_width_m=TWO_STRIP_TAPE_M)
    image = scenes.add_noise(scenes.scene(
        [scenes.straight_line(-0.06), scenes.straight_line(0.06)], width_m=TWO_STRIP_TAPE_M,
        line_bgr=BLACK_BGR), 4.0)
    detection = LineDetector(config).detect(image, 'bgr8', scenes.KINECT)
    middle = LineDetector(config).detect(two_strips_scene(0.0), 'bgr8', scenes.KINECT)
    # Not joined into one line between them: one of the two.
    assert detection.found
    assert all(abs(x_px - centre_px) > 20.0 for x_px, centre_px in
               zip(centroids_px(detection), centroids_px(middle)))


NARROW_TAPE_M = 0.05
LIGHT_FLOOR_BGR = (150, 150, 150)


def black_tape_scene(polylines, width_m=NARROW_TAPE_M, shadow=None):
    """
    Return black tape on a light floor, with camera noise.

    :param shadow: None, or (from, to, darkening): the floor between those distances ahead
        (metres) darkened by that share, tape and all, as a shadow across the view.
    """
    image = scenes.scene(polylines, width_m=width_m, line_bgr=BLACK_BGR,
                         floor_bgr=LIGHT_FLOOR_BGR).astype(np.float64)
    if shadow is not None:
        near_m, far_m, darkening = shadow
        ahead_m, _ = scenes.floor_points()
        with np.errstate(invalid='ignore'):
            image[(ahead_m >= near_m) & (ahead_m <= far_m)] *= 1.0 - darkening
    return scenes.add_noise(image.astype(np.uint8), 3.0)


@pytest.mark.parametrize('encoding', ('bgr8', 'mono8'))
@pytest.mark.parametrize('shadow', ((0.35, 0.65, 0.7), (0.55, 0.85, 0.7), (0.4, 0.55, 0.75)),
                         ids=('near', 'far', 'narrow_deep'))
def test_black_tape_is_followed_through_a_deep_shadow_across_it(shadow, encoding):
    # A shadow 70% deep is as much darker than the floor as the tape: the black preset takes
    # it all. Within it the tape is darker still, and it is that the detector follows.
    config = DetectorConfig(line_colour='black', line_width_m=NARROW_TAPE_M)
    ahead = [scenes.straight_line(0.0)]

    def detect(image):
        if encoding == 'mono8':
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return LineDetector(config).detect(image, encoding, scenes.KINECT)

    clean = detect(black_tape_scene(ahead))
    shaded = detect(black_tape_scene(ahead, shadow=shadow))
    assert shaded.confidence > 0.9
    assert centroids_px(shaded) == pytest.approx(centroids_px(clean), abs=1.0)


def hairpin(turn_at_m, half_gap_m, points=40):
    """Return a hairpin's centre: arms half_gap_m either side, their turn turn_at_m ahead."""
    angles = np.linspace(-math.pi / 2, math.pi / 2, points)
    turn = [(turn_at_m + half_gap_m * math.cos(angle), half_gap_m * math.sin(angle))
            for angle in angles]
    return [(-0.5, -half_gap_m)] + turn + [(-0.5, half_gap_m)]


@pytest.mark.parametrize('half_gap_m', (0.05, 0.1))
@pytest.mark.parametrize('offset_m', (0.0, 0.05))
def test_two_parallel_tapes_are_two_lines_the_follower_doubts(half_gap_m, offset_m):
    # Seen in perspective, two parallel tapes pass for the two arms of a hairpin whose turn
    # lies beyond the view; but nothing crosses the floor between them.
    config = DetectorConfig(line_width_m=NARROW_TAPE_M)
    image = scenes.scene([scenes.straight_line(offset_m - half_gap_m),
                          scenes.straight_line(offset_m + half_gap_m)], width_m=NARROW_TAPE_M)
    assert LineDetector(config).detect(image, 'bgr8', scenes.KINECT).confidence < 0.3


@pytest.mark.parametrize('half_gap_m', (0.05, 0.1))
def test_the_arms_of_a_hairpin_whose_turn_is_in_view_are_one_line(half_gap_m):
    # The same two tapes joined by a turn beyond the bands (1.3 m ahead): one line.
    config = DetectorConfig(line_width_m=NARROW_TAPE_M)
    image = scenes.scene([hairpin(1.2, half_gap_m)], width_m=NARROW_TAPE_M)
    assert LineDetector(config).detect(image, 'bgr8', scenes.KINECT).confidence > 0.9


@pytest.mark.parametrize('side', (1.0, -1.0), ids=('left', 'right'))
def test_wide_black_tape_running_across_the_view_is_not_taken_for_a_shadow(side):
    # The leg after a square corner fills its band across the view, dark all over: nothing
    # stands out within it, so it stays the line's stripe there.
    config = DetectorConfig(line_colour='black')
    corner = [[(-0.5, 0.0), (0.55, 0.0), (0.55, 3.0 * side)]]
    detection = LineDetector(config).detect(
        black_tape_scene(corner, width_m=scenes.LINE_WIDTH_M), 'bgr8', scenes.KINECT)
    far_x_px = [band.centroid_x_px for band in detection.seen_bands][-1]
    # Where the leg leaves the view, not on the approach straight ahead.
    assert side * (CENTRE_COLUMN - far_x_px) > 80.0


def scenes_line_detection(lateral_m):
    """Return the detection of a lone straight line at a lateral offset, by a new detector."""
    return LineDetector().detect(scenes.scene([scenes.straight_line(lateral_m)]), 'bgr8',
                                 scenes.KINECT)


def test_line_jumping_farther_than_the_limit_is_rejected_then_found_again():
    # Without camera geometry a jump is measured as a share of the image width.
    jump_px = round(0.3 * WIDTH_PX)
    assert jump_px - LINE_WIDTH_PX > NO_GEOMETRY_JUMP_SHARE * WIDTH_PX
    detector = LineDetector()
    detector.detect(vertical_line_image(200))
    jumped = vertical_line_image(200 + jump_px)

    rejected = detector.detect(jumped)
    recovered = detector.detect(jumped)

    assert not rejected.found
    assert rejected.error == 0.0
    assert recovered.confidence == 1.0
    assert recovered.nearest.centroid_x_px == pytest.approx(200 + jump_px)


def test_line_moving_within_the_limit_is_followed():
    move_px = round(0.15 * WIDTH_PX)
    assert move_px < NO_GEOMETRY_JUMP_SHARE * WIDTH_PX
    detector = LineDetector()
    detector.detect(vertical_line_image(200))
    detection = detector.detect(vertical_line_image(200 + move_px))
    assert detection.confidence == 1.0
    assert detection.nearest.centroid_x_px == pytest.approx(200 + move_px)


@pytest.mark.parametrize('gap_band', range(len(DEFAULT_BANDS)))
def test_dash_gap_over_one_band_leaves_only_that_band_unseen(gap_band):
    image = vertical_line_image(420)
    top, bottom = DEFAULT_BANDS[gap_band]
    image[top - 3:bottom + 3] = FLOOR_GREY

    detection = LineDetector().detect(image)

    seen = [band_detection.found for band_detection in detection.bands]
    assert seen == [index != gap_band for index in range(len(DEFAULT_BANDS))]
    # A gap with the line seen on both sides is the line's way (a dash gap): it counts for
    # the line. Where the nearest or the farthest band sees nothing, nothing shows the line.
    between_seen = 0 < gap_band < len(DEFAULT_BANDS) - 1
    assert detection.confidence == pytest.approx(
        1.0 if between_seen else (len(DEFAULT_BANDS) - 1) / len(DEFAULT_BANDS))
    assert detection.error == pytest.approx(expected_error(420))
    assert detection.nearest is detection.bands[1 if gap_band == 0 else 0]


def test_dashes_keep_being_followed_across_frames():
    detector = LineDetector()
    for frame in range(len(DEFAULT_BANDS)):
        image = vertical_line_image(250 + 5 * frame)
        image[band_slice(DEFAULT_BANDS[frame])] = FLOOR_GREY
        detection = detector.detect(image)
        assert [band_detection.found for band_detection in detection.bands].count(False) == 1
        assert detection.seen_bands[0].centroid_x_px == pytest.approx(250 + 5 * frame)


def test_reset_forgets_where_the_line_was():
    detector = LineDetector()
    detector.detect(vertical_line_image(100))
    assert detector.detect(lines_image(100, 330)).nearest.centroid_x_px == pytest.approx(100)

    detector.reset()

    assert detector.detect(lines_image(100, 330)).nearest.centroid_x_px == pytest.approx(330)


def test_reset_before_any_image_is_harmless():
    detector = LineDetector()
    detector.reset()
    assert detector.detect(vertical_line_image(200)).confidence == 1.0


def test_new_image_size_forgets_where_the_line_was():
    detector = LineDetector(DetectorConfig(min_area_px=1))
    detector.detect(vertical_line_image(100))
    detection = detector.detect(vertical_line_image(130, 240, 320, half_width_px=3))
    # 130 of 320 is as far from 100 as a jump can be without geometry: only a forgotten
    # past lets it be taken at once.
    assert detection.nearest.centroid_x_px == pytest.approx(130)


def test_a_line_at_the_image_edge_stays_apart_from_the_next_band():
    # The line runs down the image's right edge: each band's columns end with the image, not
    # running on into the next band's first columns.
    image = floor_image()
    image[:, WIDTH_PX - 5:] = bgr(LIT_YELLOW_RGB)
    rows = DEFAULT_BANDS[0][1] - DEFAULT_BANDS[0][0]
    detector = LineDetector(DetectorConfig(min_area_px=1))

    bands = detector.detect(image).bands

    assert all(band.found for band in bands)
    for band in bands:
        assert band.centroid_x_px > WIDTH_PX - 6
        assert band.area_px <= 7 * rows
    mask = detector.draw_mask(np.empty((HEIGHT_PX, WIDTH_PX), np.uint8))
    assert not mask[:, :WIDTH_PX // 2].any()


def test_line_is_chosen_among_many_specks():
    image = vertical_line_image(400)
    speck_columns = [column for column in range(4, WIDTH_PX - 4, 12) if abs(column - 400) > 16]
    for top, _ in DEFAULT_BANDS:
        for column in speck_columns:
            image[top + 1:top + 3, column:column + 2] = bgr(LIT_YELLOW_RGB)

    detection = LineDetector(DetectorConfig(min_area_px=1)).detect(image)

    assert len(speck_columns) * len(DEFAULT_BANDS) > 100, 'the specks must be many'
    assert centroids_px(detection) == pytest.approx([400.0] * len(DEFAULT_BANDS))


# Camera noise.

def test_line_is_found_in_every_band_through_camera_noise():
    generator = np.random.default_rng(NOISE_SEED)
    for column in (CENTRE_COLUMN, 150, 500):
        clean = LineDetector().detect(vertical_line_image(column))
        noisy = LineDetector().detect(add_camera_noise(vertical_line_image(column), generator))
        assert noisy.confidence > 0.9
        assert centroids_px(noisy) == pytest.approx(
            centroids_px(clean), abs=NOISY_CENTROID_TOLERANCE_PX)


def test_noisy_bare_floor_has_no_line():
    generator = np.random.default_rng(NOISE_SEED)
    detector = LineDetector()
    for _ in range(5):
        assert not detector.detect(add_camera_noise(floor_image(), generator)).found


# The camera's geometry: where the floor is, and how wide the line looks on it.

def test_bands_above_the_horizon_are_not_searched_and_walls_there_are_not_the_line():
    # A level camera: the horizon is the principal row, and the upper bands look at a wall.
    level = dataclasses.replace(scenes.KINECT, pitch_rad=0.0)
    image = scenes.scene([scenes.straight_line()], geometry=level,
                         above_horizon_bgr=bgr(LIT_YELLOW_RGB))
    detection = LineDetector().detect(image, 'bgr8', level)
    searched = [band.searched for band in detection.bands]
    line_widths_px = level.line_width_px([(top + bottom - 1) / 2 for top, bottom in
                                          DEFAULT_BANDS], DetectorConfig().line_width_m)
    assert searched == [width_px >= MIN_SEARCH_WIDTH_PX for width_px in line_widths_px]
    assert not all(searched)
    assert [band.found for band in detection.bands] == searched
    assert detection.confidence > 0.9


def test_a_floor_passing_the_colour_bounds_under_a_cast_is_not_the_line():
    # A dark floor under a warm cast passes the yellow preset's fixed HSV bounds everywhere.
    warm_floor_bgr = (35, 70, 85)
    lower, upper = hsv_bounds(DetectorConfig())
    assert cv2.inRange(cv2.cvtColor(np.uint8([[warm_floor_bgr]]), cv2.COLOR_BGR2HSV), lower,
                       upper)[0, 0] == 255
    image = scenes.scene([scenes.straight_line(lateral_m=0.1)], floor_bgr=warm_floor_bgr,
                         line_bgr=(40, 200, 230))
    detection = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    expected = LineDetector().detect(scenes.scene([scenes.straight_line(lateral_m=0.1)]),
                                     'bgr8', scenes.KINECT)
    assert detection.confidence > 0.8
    assert centroids_px(detection) == pytest.approx(centroids_px(expected), abs=2.0)


def test_worn_tape_under_a_cold_lamp_without_white_balance_is_followed():
    # The colours of the harsh preset's seed 2 camera: a blue cast that leaves the yellow tape
    # cyan-grey as the camera gives it (gains of 1.2 could not bring it back).
    image = scenes.add_noise(scenes.scene([scenes.straight_line(lateral_m=0.1)],
                                          floor_bgr=(106, 83, 65), line_bgr=(140, 142, 113)), 3.0)
    detection = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    expected = LineDetector().detect(scenes.scene([scenes.straight_line(lateral_m=0.1)]),
                                     'bgr8', scenes.KINECT)
    assert detection.confidence > 0.7
    assert centroids_px(detection) == pytest.approx(centroids_px(expected), abs=2.0)


def test_a_speck_is_not_the_line_even_with_the_books_min_area_of_one_pixel():
    # The book's band and min_area_px 1: a single yellow pixel near the centre must not win
    # over the real line.
    config = dataclasses.replace(BOOK_CONFIG, min_area_px=1)
    image = scenes.scene([scenes.straight_line(lateral_m=0.25)])
    top, _ = BOOK_BAND_ROWS
    image[top + 10, CENTRE_COLUMN] = bgr(LIT_YELLOW_RGB)
    detection = LineDetector(config).detect(image, 'bgr8', scenes.KINECT)
    line = LineDetector(config).detect(scenes.scene([scenes.straight_line(lateral_m=0.25)]),
                                       'bgr8', scenes.KINECT)
    assert detection.nearest.centroid_x_px == pytest.approx(
        line.nearest.centroid_x_px, abs=0.5)


@pytest.mark.parametrize('heading_deg', (35.0, -50.0, 70.0))
def test_a_line_running_diagonally_is_followed_in_every_band(heading_deg):
    # The old limit (a fifth of the image width between bands) refused these. The line
    # crosses the robot's path 0.6 m ahead.
    heading_rad = math.radians(heading_deg)
    polyline = scenes.straight_line(lateral_m=-0.6 * math.tan(heading_rad),
                                    heading_rad=heading_rad)
    mask = scenes.line_mask([polyline])
    detection = LineDetector().detect(scenes.scene([polyline]), 'bgr8', scenes.KINECT)
    for band in detection.bands:
        columns = np.flatnonzero(mask[(band.top_px + band.bottom_px) // 2])
        if columns.size and 0 < columns[0] and columns[-1] < WIDTH_PX - 1:
            assert band.found
            assert columns[0] <= band.centroid_x_px <= columns[-1]
    # Steep lines run out of the image's sides in the nearest bands: less to see, less sure.
    assert detection.confidence > 0.4


def test_a_line_running_across_the_view_is_found_where_it_enters_the_bands():
    # A corner ahead: the line comes straight up to 0.55 m ahead, then runs off to the left.
    corner = [(-0.5, 0.0), (0.55, 0.0), (0.55, 2.0)]
    mask = scenes.line_mask([corner])
    detection = LineDetector().detect(scenes.scene([corner]), 'bgr8', scenes.KINECT)
    for band in detection.seen_bands:
        row = mask[int(band.centroid_y_px)]
        assert row[int(round(band.centroid_x_px))], 'each seen band point lies on the line'
    assert sum(band.found for band in detection.bands) >= 4


@pytest.mark.parametrize('crossing_m', (0.5, 0.6))
@pytest.mark.parametrize('lateral_m', (0.0, 0.03))
def test_a_line_crossing_the_followed_one_is_neither_taken_nor_a_doubt(crossing_m, lateral_m):
    # A figure eight's crossing: another line runs across the view, right through ours.
    line = scenes.straight_line(lateral_m=lateral_m)
    crossing = [(crossing_m, -3.0), (crossing_m, 3.0)]
    mask = scenes.line_mask([line])
    detection = LineDetector().detect(scenes.scene([line, crossing]), 'bgr8', scenes.KINECT)
    for band in detection.seen_bands:
        assert mask[int(band.centroid_y_px), int(round(band.centroid_x_px))]
    assert detection.bands[0].found and detection.bands[-1].found
    assert detection.confidence > 0.9


def test_jumps_are_measured_on_the_floor():
    detector = LineDetector()
    config = detector.config
    detector.detect(scenes.scene([scenes.straight_line(lateral_m=0.0)]), 'bgr8',
                    scenes.KINECT)
    moved = detector.detect(scenes.scene([scenes.straight_line(
        lateral_m=0.8 * config.max_stripe_jump_m)]), 'bgr8', scenes.KINECT)
    assert moved.found and moved.confidence > 0.9
    jumped = detector.detect(scenes.scene([scenes.straight_line(
        lateral_m=0.8 * config.max_stripe_jump_m + 1.5 * config.max_stripe_jump_m)]),
        'bgr8', scenes.KINECT)
    assert not jumped.found


def test_a_duck_beside_the_line_is_not_the_line():
    # A yellow object standing beside the line fills a few bands' worth of rows over there.
    line = scenes.straight_line(lateral_m=0.05)
    image = scenes.scene([line])
    mask = scenes.line_mask([line])
    top, bottom = DEFAULT_BANDS[3][0] - 30, DEFAULT_BANDS[2][1] + 5
    image[top:bottom, 500:540] = bgr(LIT_YELLOW_RGB)
    detection = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    for band in detection.bands:
        assert band.found
        assert mask[int(band.centroid_y_px), int(round(band.centroid_x_px))]


@pytest.mark.parametrize('dash', ((0.1, 0.1), (0.05, 0.15)))
def test_a_dashed_line_is_found_in_the_bands_its_dashes_cross(dash):
    line = scenes.straight_line(lateral_m=-0.05, heading_rad=0.2)
    mask = scenes.line_mask([line], dash=dash)
    detection = LineDetector().detect(scenes.scene([line], dash=dash), 'bgr8', scenes.KINECT)
    crossed = [mask[(band.top_px + band.bottom_px) // 2].any() for band in detection.bands]
    for band in detection.bands:
        if band.found:
            assert mask[int(band.centroid_y_px), int(round(band.centroid_x_px))]
    # The nearest dash is always seen; farther ones across long gaps, where the paint between
    # the bands gives the chain little support, may be left out (they count for little).
    if any(crossed):
        assert detection.bands[crossed.index(True)].found


# The dashed course's paint: 0.30 m dashes, 0.15 m gaps; each phase a robot meets on it.
COURSE_DASH_M = (0.30, 0.15)
COURSE_DASH_PHASES_M = np.arange(0.0, sum(COURSE_DASH_M), 0.015)
DASHED_LINES = {'straight': scenes.straight_line(), 'bend': scenes.arc_line(1.5)}


@pytest.mark.parametrize('shape', DASHED_LINES)
def test_dashes_ahead_never_make_the_line_less_sure_than_its_nearest_dash(shape):
    x_m, _ = scenes.floor_points()
    nearest_band_row = sum(DEFAULT_BANDS[0]) // 2
    nearest_band_m = float(x_m[nearest_band_row, CENTRE_COLUMN])
    dash_m, period_m = COURSE_DASH_M[0], sum(COURSE_DASH_M)
    line = DASHED_LINES[shape]
    for start_m in COURSE_DASH_PHASES_M:
        image = scenes.scene([line], dash=COURSE_DASH_M, dash_start_m=start_m)
        # The same picture with only the first dash that reaches the nearest band's floor.
        first_dash_end_m = start_m + dash_m + period_m * math.ceil(
            (nearest_band_m - start_m - dash_m) / period_m)
        nearest_dash = image.copy()
        with np.errstate(invalid='ignore'):
            nearest_dash[~(x_m < first_dash_end_m)] = scenes.FLOOR_GREY
        whole = LineDetector().detect(image, 'bgr8', scenes.KINECT)
        alone = LineDetector().detect(nearest_dash, 'bgr8', scenes.KINECT)
        # Farther dashes the chain leaves out across a gap are the line going on, not a
        # second line.
        assert whole.confidence >= alone.confidence - 1e-9, start_m


@pytest.mark.parametrize('shape', DASHED_LINES)
def test_a_dashed_line_seen_across_a_gap_is_trusted_like_a_solid_one(shape):
    line = DASHED_LINES[shape]
    crossed = 0
    for start_m in COURSE_DASH_PHASES_M:
        detection = LineDetector().detect(
            scenes.scene([line], dash=COURSE_DASH_M, dash_start_m=start_m), 'bgr8',
            scenes.KINECT)
        seen = [index for index, band in enumerate(detection.bands) if band.found]
        if len(seen) == seen[-1] - seen[0] + 1:
            continue
        crossed += 1
        # The bands in a dash gap between seen dashes count for the line: the follower
        # keeps full speed (confidence_for_full_speed 0.5) and more.
        assert detection.confidence >= 0.6, start_m
    assert crossed >= 5


def test_bands_where_the_line_is_out_of_view_do_not_count_for_it():
    # The line runs out of the view on the right between the second and the fifth band and
    # comes back: along the image's edge, the link between them has the line's colour.
    line = [(-0.5, -0.12), (0.30, -0.16), (0.42, -0.6), (0.58, -0.6), (0.68, -0.2),
            (1.5, -0.2)]
    detection = LineDetector().detect(scenes.scene([line]), 'bgr8', scenes.KINECT)
    seen = [band.found for band in detection.bands]
    assert seen == [True, True, False, False, True, True]
    assert detection.confidence <= sum(seen) / len(seen)


@pytest.mark.parametrize('heading_deg', (60.0, 70.0))
def test_bands_a_line_leaving_the_view_at_the_side_cannot_reach_count_less_against_it(heading_deg):
    # A sharp turn: the line crosses the near bands 0.30 m ahead and leaves the image on
    # the left.
    heading_rad = math.radians(heading_deg)
    line = scenes.straight_line(lateral_m=-0.30 * math.tan(heading_rad), heading_rad=heading_rad)
    detection = LineDetector().detect(scenes.scene([line]), 'bgr8', scenes.KINECT)
    seen = [band.found for band in detection.bands]
    assert seen[0] and not seen[-1]
    # More sure than the share of bands that see it: those beyond count only half.
    assert detection.confidence > sum(seen) / len(seen)


def _corner_view(lateral_m):
    """Return a view into a square corner: the line slides out of the image's left side."""
    line = scenes.straight_line(lateral_m=lateral_m, heading_rad=math.radians(70.0))
    return scenes.scene([line])


def test_a_followed_line_leaving_at_the_side_stays_seen_however_little_shows():
    # In the third band only a sliver of the line is left at the edge, a few pixels wide.
    detector = LineDetector()
    before = detector.detect(_corner_view(-0.78), 'bgr8', scenes.KINECT)
    assert before.bands[2].found and before.bands[2].at_side
    after = detector.detect(_corner_view(-0.74), 'bgr8', scenes.KINECT)
    assert after.bands[2].found and after.bands[2].at_side
    assert after.bands[2].centroid_x_px < before.bands[2].centroid_x_px
    assert after.bands[2].area_px < before.bands[2].area_px


def test_a_sliver_at_the_side_the_nearer_band_leaves_by_is_the_line_at_first_sight():
    # Turning out of a corner the next leg comes into view at the image's side: the band
    # beyond the nearer one, which reaches that side, shows a sliver of it.
    first_sight = LineDetector().detect(_corner_view(-0.74), 'bgr8', scenes.KINECT)
    assert first_sight.bands[1].at_side
    assert first_sight.bands[2].found and first_sight.bands[2].at_side
    assert first_sight.bands[2].centroid_x_px < first_sight.bands[1].centroid_x_px


def test_a_lone_sliver_at_the_side_is_not_the_line_at_first_sight():
    # The same sliver with nothing of the line below it may be anything at the edge.
    image = _corner_view(-0.74)
    below_px = LineDetector().detect(image, 'bgr8', scenes.KINECT).bands[2].bottom_px + 2
    image[below_px:, :] = image[below_px:, -1:]
    detection = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    assert not detection.found


def test_bands_beyond_a_line_ending_in_view_count_against_it():
    # The same bands see nothing, but the line ends in the middle of the view: it may be
    # anything, as far as those bands tell.
    line = [(-0.5, 0.0), (0.52, 0.0)]
    detection = LineDetector().detect(scenes.scene([line]), 'bgr8', scenes.KINECT)
    seen = [band.found for band in detection.bands]
    assert seen[0] and not seen[-1]
    assert detection.confidence <= sum(seen) / len(seen) + 1e-9


def test_the_nearest_stripe_in_driving_order_matches_the_first_look_exactly():
    # The clean path's floor points are the band centres'; the chain is the same line.
    line = scenes.arc_line(1.5)
    image = scenes.scene([line])
    fast = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    assert fast.confidence > 0.95
    for band in fast.bands:
        assert band.quality > 0.8


# Image formats and sizes.

def test_padded_step_image_gives_the_same_detection():
    image = vertical_line_image(451)
    row_bytes = WIDTH_PX * 3
    step = row_bytes + 7
    rows = np.full((HEIGHT_PX, step), 255, dtype=np.uint8)
    rows[:, :row_bytes] = image.reshape(HEIGHT_PX, row_bytes)
    # The padding bytes are yellow-ish garbage: they must not be counted.
    rows[:, row_bytes:] = (0, 246, 255, 0, 246, 255, 0)
    msg = Image(height=HEIGHT_PX, width=WIDTH_PX, encoding='bgr8', step=step,
                data=rows.tobytes())
    padded_view = image_to_array(msg)
    assert not padded_view.flags.c_contiguous

    detection = LineDetector().detect(padded_view, 'bgr8')

    assert detection == LineDetector().detect(image)
    assert detection.confidence == 1.0


@pytest.mark.parametrize('encoding', CONVERSIONS_FROM_BGR)
def test_every_colour_encoding_gives_the_same_detection(encoding):
    image = vertical_line_image(151, rgb=YELLOWS_RGB['shaded'])
    converted = cv2.cvtColor(image, CONVERSIONS_FROM_BGR[encoding])
    detection = LineDetector().detect(converted, encoding)
    assert detection.confidence == 1.0
    assert detection == LineDetector().detect(image, 'bgr8')


@pytest.mark.parametrize('encoding', CONVERSIONS_FROM_BGR)
def test_every_colour_encoding_through_a_message_gives_the_same_detection(encoding):
    image = vertical_line_image(500)
    converted = cv2.cvtColor(image, CONVERSIONS_FROM_BGR[encoding])
    view = image_to_array(array_to_image(converted, encoding))
    assert LineDetector().detect(view, encoding) == LineDetector().detect(image)


def test_a_grey_image_shows_no_yellow_line_and_says_so():
    grey = cv2.cvtColor(vertical_line_image(CENTRE_COLUMN), cv2.COLOR_BGR2GRAY)
    with pytest.raises(ImageConversionError, match='line_colour to white or black'):
        LineDetector().detect(grey, 'mono8')


@pytest.mark.parametrize('line_grey, preset', ((235, 'white'), (20, 'black')))
def test_a_grey_image_shows_white_and_black_tape(line_grey, preset):
    image = floor_image(grey=120)
    image[:, 300:330] = line_grey
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    detection = LineDetector(DetectorConfig(line_colour=preset)).detect(grey, 'mono8')
    assert detection.confidence > 0.9
    assert centroids_px(detection) == pytest.approx([314.5] * len(DEFAULT_BANDS))


@pytest.mark.parametrize('height, width', ((240, 320), (480, 640), (720, 1280), (61, 99)))
@pytest.mark.parametrize('column_fraction', (0.5, 0.8, 0.25))
def test_normalised_error_does_not_depend_on_resolution(height, width, column_fraction):
    column = round(column_fraction * width)
    image = vertical_line_image(column, height, width, half_width_px=max(width // 90, 1))
    detection = LineDetector(DetectorConfig(min_area_px=1)).detect(image)
    assert detection.confidence == 1.0
    assert detection.image_width_px == width
    assert detection.error == pytest.approx(2 * column_fraction - 1, abs=1.0 / (width / 2))


def test_one_detector_handles_changing_resolutions():
    detector = LineDetector()
    for height, width in ((480, 640), (240, 320), (720, 1280), (480, 640)):
        column = width // 4
        detection = detector.detect(vertical_line_image(column, height, width))
        assert detection.error == pytest.approx(expected_error(column, width))
        searched_rows = sum(band_detection.bottom_px - band_detection.top_px
                            for band_detection in detection.bands)
        assert detector.last_mask.shape == (searched_rows, width)


def test_last_mask_stacks_the_band_rows_nearest_first():
    detector = LineDetector()
    assert detector.last_mask is None
    image = floor_image()
    stripe_columns = [100 + 20 * index for index in range(len(DEFAULT_BANDS))]
    for rows, column in zip(DEFAULT_BANDS, stripe_columns):
        paint_line(image, column, band_slice(rows))

    detection = detector.detect(image)

    mask = detector.last_mask
    assert detection.confidence == 1.0
    assert mask.dtype == np.uint8
    assert mask.shape == (sum(bottom - top for top, bottom in DEFAULT_BANDS), WIDTH_PX)
    assert set(np.unique(mask)) == {0, 255}
    assert np.count_nonzero(mask) == detection.area_px
    first_row = 0
    for (top, bottom), column in zip(DEFAULT_BANDS, stripe_columns):
        band_mask = mask[first_row:first_row + bottom - top]
        first_row += bottom - top
        stripe = slice(column - LINE_HALF_WIDTH_PX, column + LINE_HALF_WIDTH_PX + 1)
        np.testing.assert_array_equal(np.flatnonzero(band_mask.any(axis=0)),
                                      np.arange(stripe.start, stripe.stop))
        assert np.all(band_mask[:, stripe] == 255)


def test_draw_mask_puts_the_band_masks_at_their_rows_of_the_image():
    detector = LineDetector()
    image = vertical_line_image(200)
    detector.detect(image)
    # Whatever the buffer held before is overwritten.
    mask = detector.draw_mask(np.full((HEIGHT_PX, WIDTH_PX), 7, np.uint8))

    expected = np.zeros((HEIGHT_PX, WIDTH_PX), np.uint8)
    for top, bottom in DEFAULT_BANDS:
        expected[top:bottom] = np.where(np.all(image[top:bottom] == bgr(LIT_YELLOW_RGB),
                                               axis=2), 255, 0)
    np.testing.assert_array_equal(mask, expected)


@pytest.mark.parametrize('shape', [(HEIGHT_PX, WIDTH_PX - 1), (HEIGHT_PX // 2, WIDTH_PX)])
def test_draw_mask_refuses_an_array_not_the_image_size(shape):
    detector = LineDetector()
    with pytest.raises(ValueError, match='image size'):
        detector.draw_mask(np.zeros((HEIGHT_PX, WIDTH_PX), np.uint8))  # before any image
    detector.detect(floor_image())
    with pytest.raises(ValueError, match='image size'):
        detector.draw_mask(np.zeros(shape, np.uint8))


def test_detect_does_not_modify_the_image():
    image = vertical_line_image(200)
    original = image.copy()
    LineDetector().detect(image)
    np.testing.assert_array_equal(image, original)


@pytest.mark.parametrize('image, encoding', (
    (np.zeros((4, 4, 3), np.uint8), 'mono8'),
    (np.zeros((4, 4), np.uint8), 'bgr8'),
    (np.zeros((4, 4, 3), np.float32), 'bgr8'),
    (np.zeros((4, 4, 3), np.uint8), 'hsv8'),
    (np.zeros((4, 4), np.float32), '32FC1'),
    (np.zeros((0, 4, 3), np.uint8), 'bgr8'),
))
def test_detect_rejects_images_not_matching_the_encoding(image, encoding):
    with pytest.raises(ImageConversionError):
        LineDetector().detect(image, encoding)


def raw_camera_image(bgr_image, encoding):
    """Return what a raw camera would send of a BGR image: 4:2:2 YUV or a Bayer mosaic."""
    if encoding in ('yuv422', 'uyvy', 'yuv422_yuy2', 'yuyv'):
        yuv = cv2.cvtColor(bgr_image, cv2.COLOR_BGR2YUV)
        packed = np.empty(bgr_image.shape[:2] + (2,), np.uint8)
        packed[..., 0 if encoding in ('yuv422_yuy2', 'yuyv') else 1] = yuv[..., 0]
        chroma = packed[..., 1 if encoding in ('yuv422_yuy2', 'yuyv') else 0]
        chroma[:, 0::2] = yuv[:, 0::2, 1]
        chroma[:, 1::2] = yuv[:, 0::2, 2]
        return packed
    pattern = encoding.removeprefix('bayer_').removesuffix('8')
    channel_of = {'b': 0, 'g': 1, 'r': 2}
    mosaic = np.empty(bgr_image.shape[:2], np.uint8)
    for index, letter in enumerate(pattern):
        row, column = divmod(index, 2)
        mosaic[row::2, column::2] = bgr_image[row::2, column::2, channel_of[letter]]
    return mosaic


# What raw cameras send is converted to BGR first: the line is where it is in BGR.
@pytest.mark.parametrize('encoding', ('yuv422', 'yuyv', 'bayer_rggb8', 'bayer_bggr8',
                                      'bayer_gbrg8', 'bayer_grbg8'))
def test_raw_camera_encodings_give_the_line_where_bgr_does(encoding):
    image = scenes.scene([scenes.straight_line(lateral_m=0.12, heading_rad=-0.3)])
    raw = image_to_array(array_to_image(raw_camera_image(image, encoding), encoding))
    expected = LineDetector().detect(image, 'bgr8', scenes.KINECT)
    detection = LineDetector().detect(raw, encoding, scenes.KINECT)
    assert detection.confidence > 0.9
    assert centroids_px(detection) == pytest.approx(centroids_px(expected), abs=1.5)


# Configuration.

def test_detector_keeps_its_config():
    config = DetectorConfig(hue_min=25)
    assert LineDetector(config).config is config


@pytest.mark.parametrize('fields, error_type, message_part', (
    ({'hue_max': 255}, ValueError, r'hue_max must be in \[0, 179\]'),
    ({'hue_min': -1}, ValueError, r'hue_min must be in \[0, 179\]'),
    ({'hue_min': 41, 'hue_max': 40}, ValueError, 'hue_min 41 must not exceed hue_max 40'),
    ({'saturation_max': 256}, ValueError, r'saturation_max must be in \[0, 255\]'),
    ({'saturation_min': 200, 'saturation_max': 100}, ValueError, 'must not exceed'),
    ({'value_min': -5}, ValueError, r'value_min must be in \[0, 255\]'),
    ({'value_min': 250, 'value_max': 190}, ValueError, 'value_min 250 must not exceed'),
    ({'band_center_fraction': 0.0}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': 1.0}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': 1.5}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': math.nan}, ValueError, 'strictly between 0 and 1'),
    ({'band_spacing_fraction': -0.1}, ValueError, 'at least 0 and less than 1'),
    ({'band_spacing_fraction': 1.0}, ValueError, 'at least 0 and less than 1'),
    ({'band_spacing_fraction': math.nan}, ValueError, 'at least 0 and less than 1'),
    ({'max_stripe_jump_m': 0.0}, ValueError, 'max_stripe_jump_m must be positive and finite'),
    ({'max_stripe_jump_m': math.inf}, ValueError, 'positive and finite'),
    ({'line_width_m': -0.1}, ValueError, 'line_width_m must be positive and finite'),
    ({'line_width_m': math.nan}, ValueError, 'positive and finite'),
    ({'line_width_m': '0.19'}, TypeError, 'line_width_m must be a number'),
    ({'min_confidence': 1.5}, ValueError, r'min_confidence must be in \[0, 1\]'),
    ({'min_confidence': None}, TypeError, 'min_confidence must be a number'),
    ({'line_colour': 'purple'}, ValueError, 'line_colour must be one of yellow, white'),
    ({'band_count': 0}, ValueError, 'band_count must be at least 1'),
    ({'band_height_px': 0}, ValueError, 'band_height_px must be at least 1'),
    ({'min_area_px': 0}, ValueError, 'min_area_px must be at least 1'),
    ({'band_count': 2.0}, TypeError, 'band_count must be an integer'),
    ({'band_height_px': 20.0}, TypeError, 'band_height_px must be an integer'),
    ({'hue_min': 20.5}, TypeError, 'hue_min must be an integer'),
    ({'min_area_px': True}, TypeError, 'min_area_px must be an integer'),
))
def test_detector_config_rejects_invalid_values(fields, error_type, message_part):
    with pytest.raises(error_type, match=message_part):
        DetectorConfig(**fields)


@pytest.mark.parametrize('fields', (
    {'band_spacing_fraction': 0.0},
    {'max_stripe_jump_m': 5.0, 'min_confidence': 0.0},
    {'line_colour': 'custom'},
    {'band_count': np.int64(3), 'min_area_px': np.int32(1)},
    {'hue_min': 0, 'hue_max': 179, 'value_min': 0, 'value_max': 255},
))
def test_detector_config_accepts_boundary_values(fields):
    config = DetectorConfig(**fields)
    assert LineDetector(config).detect(vertical_line_image(CENTRE_COLUMN)).found


# Detection's summary of its bands.

def test_detection_sums_up_its_bands():
    detection = Detection(bands=(
        band_result(False, math.nan, 100, area_px=7),
        band_result(True, 480.0, 80, area_px=150),
        band_result(False, math.nan, 60, area_px=0),
        band_result(True, 160.0, 40, area_px=90),
    ), image_width_px=WIDTH_PX, image_height_px=HEIGHT_PX, confidence=0.42)
    assert detection.found
    assert detection.nearest is detection.bands[1]
    assert detection.seen_bands == (detection.bands[1], detection.bands[3])
    assert detection.error == pytest.approx(0.5)
    assert detection.confidence == 0.42
    assert detection.area_px == 240


def test_nothing_seen_is_a_lost_line():
    detection = Detection.nothing_seen(WIDTH_PX, HEIGHT_PX)
    assert detection.bands == ()
    assert not detection.found
    assert detection.nearest is None
    assert detection.error == 0.0
    assert detection.confidence == 0.0
    assert detection.area_px == 0
    assert (detection.image_width_px, detection.image_height_px) == (WIDTH_PX, HEIGHT_PX)


# The debug overlay.

def test_draw_debug_marks_every_seen_band_and_keeps_the_input():
    image = vertical_line_image(420)
    original = image.copy()
    detection = LineDetector().detect(image)

    debug = draw_debug(image, detection)

    np.testing.assert_array_equal(image, original)
    assert debug.shape == image.shape
    assert debug.dtype == np.uint8
    assert debug.flags.c_contiguous
    for band_detection in detection.bands:
        centroid = (round(band_detection.centroid_y_px), round(band_detection.centroid_x_px))
        assert tuple(debug[centroid]) == RED_BGR
        assert tuple(debug[band_detection.top_px, 0]) == GREEN_BGR
        assert tuple(debug[band_detection.bottom_px - 1, WIDTH_PX - 1]) == GREEN_BGR
    assert tuple(debug[0, WIDTH_PX // 2]) == BLUE_BGR


def test_draw_debug_marks_a_lost_line_without_centroids():
    image = floor_image()
    lost = LineDetector().detect(image)
    found = Detection(bands=tuple(
        BandDetection(found=True, centroid_x_px=320.0, centroid_y_px=(top + bottom) / 2,
                      area_px=300, top_px=top, bottom_px=bottom)
        for top, bottom in DEFAULT_BANDS), image_width_px=WIDTH_PX, image_height_px=HEIGHT_PX)

    debug = draw_debug(image, lost)
    found_debug = draw_debug(image, found)

    red = np.all(debug == RED_BGR, axis=2)
    for top, bottom in DEFAULT_BANDS:
        assert not np.any(red[top - 5:bottom + 5, 310:331])
        assert tuple(debug[top, 0]) == GREEN_BGR
    # The text at the top differs: "LINE LOST" against the error and confidence.
    assert not np.array_equal(debug[:TEXT_ROWS_PX], found_debug[:TEXT_ROWS_PX])
    assert not np.array_equal(debug, image)


def test_draw_debug_rejects_non_bgr_images():
    with pytest.raises(ImageConversionError):
        draw_debug(np.zeros((4, 4), np.uint8), LineDetector().detect(floor_image(4, 4)))
