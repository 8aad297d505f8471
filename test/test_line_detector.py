"""Tests of the yellow-line detector on synthetic images of the course."""

import math

import cv2
from followbot.image_conversion import array_to_image
from followbot.image_conversion import image_to_array
from followbot.image_conversion import ImageConversionError
from followbot.line_detector import band_rows
from followbot.line_detector import Detection
from followbot.line_detector import DetectorConfig
from followbot.line_detector import draw_debug
from followbot.line_detector import LineDetector
import numpy as np
import pytest
from sensor_msgs.msg import Image

WIDTH_PX = 640
HEIGHT_PX = 480
FLOOR_GREY = 116
LINE_HALF_WIDTH_PX = 7
# The default band of a 640x480 image: 20 rows centred on row 360.
DEFAULT_BAND_ROWS = (350, 370)

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


def bgr(rgb):
    """Return an RGB colour as a BGR tuple."""
    return tuple(reversed(rgb))


def floor_image(height=HEIGHT_PX, width=WIDTH_PX, grey=FLOOR_GREY):
    """Return a BGR image of the bare grey floor."""
    return np.full((height, width, 3), grey, dtype=np.uint8)


def vertical_line_image(column, height=HEIGHT_PX, width=WIDTH_PX,
                        half_width_px=LINE_HALF_WIDTH_PX, rgb=LIT_YELLOW_RGB):
    """Return a floor image with a full-height line centred exactly on a column."""
    image = floor_image(height, width)
    image[:, max(column - half_width_px, 0):column + half_width_px + 1] = bgr(rgb)
    return image


def expected_error(column, width=WIDTH_PX):
    """Return the normalised error of a line centred on a column."""
    return (column - width / 2) / (width / 2)


def test_default_band_is_centred_on_three_quarters_of_the_height():
    assert band_rows(HEIGHT_PX, DetectorConfig()) == DEFAULT_BAND_ROWS


@pytest.mark.parametrize('colour', YELLOWS_RGB)
def test_centred_line_gives_zero_error(colour):
    detection = LineDetector().detect(
        vertical_line_image(WIDTH_PX // 2, rgb=YELLOWS_RGB[colour]))
    assert detection.found
    assert detection.error == pytest.approx(0.0, abs=1e-9)
    assert detection.centroid_x_px == pytest.approx(WIDTH_PX / 2)
    assert detection.centroid_y_px == pytest.approx(sum(DEFAULT_BAND_ROWS) / 2 - 0.5)
    assert detection.area_px == (2 * LINE_HALF_WIDTH_PX + 1) * 20
    assert (detection.band_top_px, detection.band_bottom_px) == DEFAULT_BAND_ROWS
    assert detection.image_width_px == WIDTH_PX


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
    assert detection.found
    assert math.copysign(1.0, detection.error) == side
    assert abs(detection.centroid_x_px - column) <= 1.0
    assert detection.error == pytest.approx(expected_error(column), abs=1.0 / (WIDTH_PX / 2))


def test_book_example_offset():
    # The book steers with -(cx - w/2) / 100: cx = 420 at w = 640 is an error of 0.3125.
    assert LineDetector().detect(vertical_line_image(420)).error == pytest.approx(0.3125)


@pytest.mark.parametrize('center, radius', (
    ((100, 480), 300),
    ((640, 600), 350),
    ((320, 100), 255),
))
def test_curved_line_centroid_is_the_arc_mean_column_in_the_band(center, radius):
    arc_mask = np.zeros((HEIGHT_PX, WIDTH_PX), dtype=np.uint8)
    cv2.circle(arc_mask, center, radius, 255, thickness=15, lineType=cv2.LINE_8)
    image = floor_image()
    image[arc_mask > 0] = bgr(LIT_YELLOW_RGB)
    top, bottom = DEFAULT_BAND_ROWS
    rows, columns = np.nonzero(arc_mask[top:bottom])
    assert columns.size > 0, 'the arc must cross the band'

    detection = LineDetector().detect(image)

    assert detection.found
    assert detection.area_px == columns.size
    assert detection.centroid_x_px == pytest.approx(columns.mean())
    assert detection.centroid_y_px == pytest.approx(top + rows.mean())


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
    assert math.isnan(detection.centroid_x_px)
    assert math.isnan(detection.centroid_y_px)
    assert detection.area_px == 0


def test_speck_smaller_than_min_area_is_not_found():
    image = floor_image()
    image[355:359, 100:104] = bgr(LIT_YELLOW_RGB)
    detection = LineDetector(DetectorConfig(min_area_px=20)).detect(image)
    assert not detection.found
    assert detection.area_px == 16
    assert detection.error == 0.0


def test_speck_of_min_area_is_found():
    image = floor_image()
    image[355:360, 100:104] = bgr(LIT_YELLOW_RGB)
    detection = LineDetector(DetectorConfig(min_area_px=20)).detect(image)
    assert detection.found
    assert detection.area_px == 20


@pytest.mark.parametrize('rows', (
    slice(0, 350),
    slice(370, HEIGHT_PX),
    slice(100, 200),
))
def test_line_only_outside_the_band_is_not_found(rows):
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

    assert LineDetector().detect(padded_view, 'bgr8') == LineDetector().detect(image)


@pytest.mark.parametrize('encoding', CONVERSIONS_FROM_BGR)
def test_every_colour_encoding_gives_the_same_detection(encoding):
    image = vertical_line_image(151, rgb=YELLOWS_RGB['shaded'])
    converted = cv2.cvtColor(image, CONVERSIONS_FROM_BGR[encoding])
    detection = LineDetector().detect(converted, encoding)
    assert detection.found
    assert detection == LineDetector().detect(image, 'bgr8')


@pytest.mark.parametrize('encoding', CONVERSIONS_FROM_BGR)
def test_every_colour_encoding_through_a_message_gives_the_same_detection(encoding):
    image = vertical_line_image(500)
    converted = cv2.cvtColor(image, CONVERSIONS_FROM_BGR[encoding])
    view = image_to_array(array_to_image(converted, encoding))
    assert LineDetector().detect(view, encoding) == LineDetector().detect(image)


def test_mono8_image_has_no_colour_so_no_line():
    grey = cv2.cvtColor(vertical_line_image(320), cv2.COLOR_BGR2GRAY)
    detection = LineDetector().detect(grey, 'mono8')
    assert not detection.found
    assert detection.area_px == 0


@pytest.mark.parametrize('height, width', ((240, 320), (480, 640), (720, 1280), (61, 99)))
@pytest.mark.parametrize('column_fraction', (0.5, 0.8, 0.25))
def test_normalised_error_does_not_depend_on_resolution(height, width, column_fraction):
    column = round(column_fraction * width)
    image = vertical_line_image(column, height, width, half_width_px=max(width // 90, 1))
    detection = LineDetector().detect(image)
    assert detection.found
    assert detection.image_width_px == width
    assert detection.error == pytest.approx(2 * column_fraction - 1, abs=1.0 / (width / 2))


def test_one_detector_handles_changing_resolutions():
    detector = LineDetector()
    for height, width in ((480, 640), (240, 320), (720, 1280), (480, 640)):
        column = width // 4
        detection = detector.detect(vertical_line_image(column, height, width))
        assert detection.error == pytest.approx(expected_error(column, width))
        assert detector.last_mask.shape == (detection.band_bottom_px - detection.band_top_px,
                                            width)


@pytest.mark.parametrize('config, height, expected_rows', (
    (DetectorConfig(band_center_fraction=0.99), HEIGHT_PX, (465, 480)),
    (DetectorConfig(band_center_fraction=0.01, band_height_px=30), HEIGHT_PX, (0, 19)),
    (DetectorConfig(band_height_px=1000), HEIGHT_PX, (0, HEIGHT_PX)),
    (DetectorConfig(band_height_px=1), HEIGHT_PX, (360, 361)),
    (DetectorConfig(), 1, (0, 1)),
    (DetectorConfig(), 3, (0, 3)),
))
def test_band_is_clipped_to_the_image(config, height, expected_rows):
    top, bottom = expected_rows
    assert band_rows(height, config) == expected_rows
    detection = LineDetector(DetectorConfig(
        band_center_fraction=config.band_center_fraction,
        band_height_px=config.band_height_px, min_area_px=1)).detect(
            vertical_line_image(480, height=height))
    assert detection.found
    assert (detection.band_top_px, detection.band_bottom_px) == expected_rows
    assert detection.area_px == (bottom - top) * (2 * LINE_HALF_WIDTH_PX + 1)


def test_last_mask_is_the_band_mask():
    detector = LineDetector()
    assert detector.last_mask is None
    detection = detector.detect(vertical_line_image(100))
    mask = detector.last_mask
    assert mask.dtype == np.uint8
    assert mask.shape == (20, WIDTH_PX)
    assert np.count_nonzero(mask) == detection.area_px
    assert set(np.unique(mask)) == {0, 255}
    assert np.all(mask[:, 100 - LINE_HALF_WIDTH_PX:100 + LINE_HALF_WIDTH_PX + 1] == 255)


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
))
def test_detect_rejects_images_not_matching_the_encoding(image, encoding):
    with pytest.raises(ImageConversionError):
        LineDetector().detect(image, encoding)


def test_detector_keeps_its_config():
    config = DetectorConfig(hue_min=25)
    assert LineDetector(config).config is config


@pytest.mark.parametrize('fields, error_type, message_part', (
    ({'hue_max': 255}, ValueError, r'hue_max must be in \[0, 179\]'),
    ({'hue_min': -1}, ValueError, r'hue_min must be in \[0, 179\]'),
    ({'hue_min': 41}, ValueError, 'hue_min 41 must not exceed hue_max 40'),
    ({'saturation_max': 256}, ValueError, r'saturation_max must be in \[0, 255\]'),
    ({'saturation_min': 200, 'saturation_max': 100}, ValueError, 'must not exceed'),
    ({'value_min': -5}, ValueError, r'value_min must be in \[0, 255\]'),
    ({'value_min': 250, 'value_max': 190}, ValueError, 'value_min 250 must not exceed'),
    ({'band_center_fraction': 0.0}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': 1.0}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': 1.5}, ValueError, 'strictly between 0 and 1'),
    ({'band_center_fraction': math.nan}, ValueError, 'strictly between 0 and 1'),
    ({'band_height_px': 0}, ValueError, 'band_height_px must be at least 1'),
    ({'min_area_px': 0}, ValueError, 'min_area_px must be at least 1'),
    ({'band_height_px': 20.0}, TypeError, 'band_height_px must be an integer'),
    ({'hue_min': 20.5}, TypeError, 'hue_min must be an integer'),
    ({'min_area_px': True}, TypeError, 'min_area_px must be an integer'),
))
def test_detector_config_rejects_invalid_values(fields, error_type, message_part):
    with pytest.raises(error_type, match=message_part):
        DetectorConfig(**fields)


def test_detector_config_defaults_are_the_documented_ones():
    assert DetectorConfig() == DetectorConfig(
        hue_min=20, hue_max=40, saturation_min=100, saturation_max=255, value_min=50,
        value_max=255, band_center_fraction=0.75, band_height_px=20, min_area_px=20)


def test_draw_debug_marks_a_found_line_and_keeps_the_input():
    image = vertical_line_image(420)
    original = image.copy()
    detection = LineDetector().detect(image)
    debug = draw_debug(image, detection)
    np.testing.assert_array_equal(image, original)
    assert debug.shape == image.shape
    assert debug.dtype == np.uint8
    centroid = (round(detection.centroid_y_px), round(detection.centroid_x_px))
    assert tuple(debug[centroid]) == (0, 0, 255)
    assert tuple(debug[detection.band_top_px, 0]) != (FLOOR_GREY,) * 3
    assert tuple(debug[0, WIDTH_PX // 2]) != (FLOOR_GREY,) * 3


def test_draw_debug_marks_a_lost_line_without_a_centroid():
    image = floor_image()
    detection = LineDetector().detect(image)
    debug = draw_debug(image, detection)
    found_debug = draw_debug(image, Detection(
        found=True, centroid_x_px=320.0, centroid_y_px=360.0, error=0.0, area_px=300,
        band_top_px=350, band_bottom_px=370, image_width_px=WIDTH_PX))
    assert not np.any(np.all(debug == (0, 0, 255), axis=2)[355:366, 310:331])
    assert not np.array_equal(debug, found_debug)
    assert not np.array_equal(debug, image)


def test_draw_debug_rejects_non_bgr_images():
    with pytest.raises(ImageConversionError):
        draw_debug(np.zeros((4, 4), np.uint8), LineDetector().detect(floor_image(4, 4)))
