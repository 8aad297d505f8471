"""Tests of the Image <-> NumPy conversion that replaces cv_bridge."""

import array
import re
from types import SimpleNamespace

import cv2
from followbot import image_conversion
from followbot.image_conversion import array_to_image
from followbot.image_conversion import BAYER_ENCODINGS
from followbot.image_conversion import CHANNELS_BY_ENCODING
from followbot.image_conversion import COLOUR_ENCODINGS
from followbot.image_conversion import dtype_of
from followbot.image_conversion import image_to_array
from followbot.image_conversion import ImageConversionError
from followbot.image_conversion import message_pixels
from followbot.image_conversion import SUPPORTED_ENCODINGS
from followbot.image_conversion import to_bgr
from followbot.image_conversion import UYVY_ENCODINGS
from followbot.image_conversion import YUV422_ENCODINGS
import numpy as np
import pytest
from sensor_msgs.msg import Image
from std_msgs.msg import Header

SIZES_HW = ((1, 1), (3, 5), (4, 7), (480, 640))
# 4:2:2 YUV pixels come in pairs: its images have even widths (and any height).
EVEN_WIDTH_SIZES_HW = ((1, 2), (3, 6), (5, 8), (480, 640))
ENCODING_SIZES = [
    (encoding, height, width)
    for encoding in SUPPORTED_ENCODINGS
    for height, width in (EVEN_WIDTH_SIZES_HW if encoding in YUV422_ENCODINGS else SIZES_HW)]
EIGHT_BIT_ENCODINGS = tuple(encoding for encoding in SUPPORTED_ENCODINGS if encoding != '32FC1')
PADDING_BYTES = 7
GARBAGE_BYTE = 0xAB

# One known pixel, the course's yellow RGB(255, 246, 0), in each encoding's channel order,
# with the BGR it must convert to (the encodings that store a whole pixel in each element).
YELLOW_BY_ENCODING = {
    'bgr8': ((0, 246, 255), (0, 246, 255)),
    'rgb8': ((255, 246, 0), (0, 246, 255)),
    'bgra8': ((0, 246, 255, 200), (0, 246, 255)),
    'rgba8': ((255, 246, 0, 200), (0, 246, 255)),
    'mono8': (116, (116, 116, 116)),
}


def random_image(height, width, encoding, seed=0):
    """Return a random array of the element type and shape an encoding needs."""
    channels = CHANNELS_BY_ENCODING[encoding]
    shape = (height, width) if channels == 1 else (height, width, channels)
    generator = np.random.default_rng(seed)
    if dtype_of(encoding) == np.float32:
        # Depth in metres, with pixels that saw nothing.
        depth_m = generator.uniform(0.3, 10.0, size=shape).astype(np.float32)
        depth_m[generator.random(shape) < 0.1] = np.nan
        return depth_m
    return generator.integers(0, 256, size=shape, dtype=np.uint8)


def padded_message(image, encoding, padding_elements=PADDING_BYTES):
    """Return an Image whose rows carry garbage padding after the pixels."""
    height, width = image.shape[:2]
    row_bytes = width * CHANNELS_BY_ENCODING[encoding] * image.itemsize
    step = row_bytes + padding_elements * image.itemsize
    rows = np.full((height, step), GARBAGE_BYTE, dtype=np.uint8)
    rows[:, :row_bytes] = image.reshape(height, -1).view(np.uint8)
    return Image(
        height=height, width=width, encoding=encoding, is_bigendian=0, step=step,
        data=array.array('B', rows.tobytes()))


def fake_message(**overrides):
    """Return a message-like object describing a valid 2x2 bgr8 image, with overrides."""
    fields = {
        'height': 2, 'width': 2, 'encoding': 'bgr8', 'is_bigendian': 0, 'step': 6,
        'data': bytes(12),
    }
    fields.update(overrides)
    return SimpleNamespace(**fields)


@pytest.mark.parametrize('encoding, height, width', ENCODING_SIZES)
def test_round_trip(encoding, height, width):
    image = random_image(height, width, encoding)
    msg = array_to_image(image, encoding)
    assert (msg.height, msg.width, msg.encoding) == (height, width, encoding)
    assert msg.step == width * CHANNELS_BY_ENCODING[encoding] * image.itemsize
    assert msg.is_bigendian == 0
    assert len(msg.data) == msg.step * height
    result = image_to_array(msg)
    assert result.dtype == image.dtype
    np.testing.assert_array_equal(result, image)


@pytest.mark.parametrize('encoding, height, width', ENCODING_SIZES)
def test_padded_step_skips_the_padding(encoding, height, width):
    image = random_image(height, width, encoding, seed=1)
    result = image_to_array(padded_message(image, encoding))
    np.testing.assert_array_equal(result, image)


@pytest.mark.parametrize('encoding', COLOUR_ENCODINGS)
def test_padded_step_garbage_does_not_reach_bgr(encoding):
    image = np.zeros(random_image(3, 6, encoding).shape, dtype=np.uint8)
    result = to_bgr(image_to_array(padded_message(image, encoding)), encoding)
    assert not np.any(result == GARBAGE_BYTE)


def test_image_to_array_views_the_message_data_without_copying():
    msg = array_to_image(random_image(4, 6, 'bgr8'), 'bgr8')
    result = image_to_array(msg)
    assert isinstance(msg.data, array.array)
    assert np.shares_memory(result, np.frombuffer(msg.data, dtype=np.uint8))


def test_image_to_array_result_is_read_only():
    result = image_to_array(array_to_image(random_image(2, 3, 'rgb8'), 'rgb8'))
    with pytest.raises(ValueError):
        result[0, 0, 0] = 1


@pytest.mark.parametrize('encoding', EIGHT_BIT_ENCODINGS)
@pytest.mark.parametrize('is_bigendian', (0, 1, False, True))
def test_image_to_array_ignores_byte_order_of_8_bit_data(encoding, is_bigendian):
    image = random_image(3, 4, encoding)
    msg = array_to_image(image, encoding)
    msg.is_bigendian = is_bigendian
    np.testing.assert_array_equal(image_to_array(msg), image)


def test_depth_in_big_endian_byte_order_reads_as_the_same_metres():
    depth_m = random_image(3, 4, '32FC1')
    msg = array_to_image(depth_m.byteswap(), '32FC1')
    msg.is_bigendian = 1
    np.testing.assert_array_equal(image_to_array(msg), depth_m)


def test_depth_step_must_hold_whole_floats():
    msg = array_to_image(random_image(2, 2, '32FC1'), '32FC1')
    msg.step = 9
    with pytest.raises(ImageConversionError, match='whole number of 4-byte'):
        image_to_array(msg)


def test_depth_is_not_a_colour_image():
    with pytest.raises(ImageConversionError, match='not a colour image'):
        to_bgr(random_image(2, 2, '32FC1'), '32FC1')


@pytest.mark.parametrize('data_type', (bytes, bytearray, list, array.array))
def test_image_to_array_accepts_message_like_objects(data_type):
    pixels = list(range(12))
    data = array.array('B', pixels) if data_type is array.array else data_type(pixels)
    result = image_to_array(fake_message(data=data))
    np.testing.assert_array_equal(result, np.arange(12, dtype=np.uint8).reshape(2, 2, 3))


def test_image_to_array_accepts_data_longer_than_needed():
    result = image_to_array(fake_message(data=bytes(range(20))))
    np.testing.assert_array_equal(result.reshape(-1), np.arange(12, dtype=np.uint8))


def test_real_image_message_round_trip_keeps_header():
    header = Header(frame_id='camera_optical_frame')
    msg = Image(header=header)
    image = random_image(480, 640, 'bgr8')
    filled = array_to_image(image, 'bgr8', msg)
    assert filled is msg
    assert filled.header.frame_id == 'camera_optical_frame'
    assert isinstance(filled.data, array.array)
    np.testing.assert_array_equal(image_to_array(filled), image)


def test_array_to_image_accepts_checked_message_fields():
    msg = Image(check_fields=True)
    image = random_image(5, 3, 'mono8')
    array_to_image(image, 'mono8', msg)
    np.testing.assert_array_equal(image_to_array(msg), image)


def test_array_to_image_refills_a_message_of_the_same_size_in_place():
    msg = array_to_image(random_image(4, 5, 'rgb8', seed=3), 'rgb8')
    data = msg.data
    image = random_image(4, 5, 'rgb8', seed=4)
    assert array_to_image(image, 'rgb8', msg) is msg
    assert msg.data is data
    np.testing.assert_array_equal(image_to_array(msg), image)


def test_array_to_image_refills_a_message_of_another_size():
    msg = array_to_image(random_image(4, 5, 'rgb8'), 'rgb8')
    image = random_image(3, 2, 'mono8')
    array_to_image(image, 'mono8', msg)
    assert (msg.height, msg.width, msg.step, msg.encoding) == (3, 2, 2, 'mono8')
    np.testing.assert_array_equal(image_to_array(msg), image)


def test_array_to_image_refills_a_message_from_a_view_of_its_own_data():
    image = random_image(4, 5, 'bgr8', seed=5)
    msg = array_to_image(image, 'bgr8')
    array_to_image(image_to_array(msg)[:, ::-1], 'bgr8', msg)
    np.testing.assert_array_equal(image_to_array(msg), image[:, ::-1])


@pytest.mark.parametrize('encoding', SUPPORTED_ENCODINGS)
def test_pixels_written_into_message_pixels_are_the_messages_image(encoding):
    msg = Image()
    image = random_image(4, 6, encoding, seed=6)
    pixels = message_pixels(msg, 4, 6, encoding)
    assert pixels.flags.c_contiguous and pixels.flags.writeable
    pixels[...] = image
    assert (msg.height, msg.width, msg.encoding) == (4, 6, encoding)
    np.testing.assert_array_equal(image_to_array(msg), image)


def test_opencv_converts_straight_into_message_pixels():
    rgb = random_image(6, 7, 'rgb8', seed=7)
    msg = Image()
    cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR, dst=message_pixels(msg, 6, 7, 'bgr8'))
    np.testing.assert_array_equal(image_to_array(msg), rgb[:, :, ::-1])


def test_message_pixels_reuse_the_data_of_a_message_of_that_size():
    msg = Image()
    message_pixels(msg, 4, 5, 'bgr8')
    data = msg.data
    message_pixels(msg, 4, 5, 'bgr8')[...] = 9
    assert msg.data is data
    message_pixels(msg, 5, 5, 'bgr8')
    assert msg.data is not data and len(msg.data) == 5 * 5 * 3


@pytest.mark.parametrize('height, width', [(0, 5), (5, 0)])
def test_message_pixels_refuse_an_empty_image(height, width):
    with pytest.raises(ImageConversionError, match='zero size'):
        message_pixels(Image(), height, width, 'bgr8')


def test_array_to_image_packs_non_contiguous_arrays():
    image = random_image(6, 8, 'bgr8')
    view = image[::2, ::-1]
    np.testing.assert_array_equal(image_to_array(array_to_image(view, 'bgr8')), view)


@pytest.mark.parametrize('overrides, message_part', (
    ({'encoding': 'nv21'}, "Unsupported encoding 'nv21'"),
    ({'encoding': '16UC1'}, 'supported encodings are bgr8, rgb8, bgra8, rgba8, mono8'),
    ({'data': bytes(11)}, 'data length 11 is shorter than step*height 12'),
    ({'data': array.array('B')}, 'data length 0 is shorter than step*height 12'),
    ({'step': 5}, 'step 5 is smaller than a row of 6 bytes'),
    ({'width': 0, 'step': 0}, 'zero size'),
    ({'height': 0, 'data': b''}, 'zero size'),
    ({'data': [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 256]}, 'not a sequence of bytes'),
    ({'data': 'twelve chars'}, 'not a sequence of bytes'),
))
def test_image_to_array_rejects_bad_messages(overrides, message_part):
    with pytest.raises(ImageConversionError, match=re.escape(message_part)):
        image_to_array(fake_message(**overrides))


@pytest.mark.parametrize('image, encoding, message_part', (
    (np.zeros((2, 2, 3), np.uint8), 'nv21', 'Unsupported encoding'),
    (np.zeros((2, 2, 3), np.uint8), 'yuv422', r'shape \(H, W, 2\)'),
    (np.zeros((2, 2, 2), np.uint8), 'bayer_rggb8', r'shape \(H, W\)'),
    (np.zeros((2, 2, 3), np.uint16), 'bgr8', 'dtype uint16'),
    (np.zeros((2, 2, 3), np.float32), 'rgb8', 'dtype float32'),
    (np.zeros((2, 2), np.float64), '32FC1', 'float32 array'),
    (np.zeros((2, 2, 1), np.float32), '32FC1', r'shape \(H, W\)'),
    (np.zeros((2, 2), np.uint8), 'bgr8', r'shape \(H, W, 3\)'),
    (np.zeros((2, 2, 4), np.uint8), 'bgr8', r'shape \(H, W, 3\)'),
    (np.zeros((2, 2, 3), np.uint8), 'rgba8', r'shape \(H, W, 4\)'),
    (np.zeros((2, 2, 1), np.uint8), 'mono8', r'shape \(H, W\)'),
    (np.zeros(6, np.uint8), 'mono8', r'shape \(H, W\)'),
    (np.zeros((0, 2, 3), np.uint8), 'bgr8', 'zero size'),
    (np.zeros((2, 0), np.uint8), 'mono8', 'zero size'),
    ([[0, 0], [0, 0]], 'mono8', 'numpy.ndarray'),
))
def test_array_to_image_rejects_bad_arrays(image, encoding, message_part):
    with pytest.raises(ImageConversionError, match=message_part):
        array_to_image(image, encoding)


def test_conversion_error_is_a_value_error():
    assert issubclass(ImageConversionError, ValueError)


@pytest.mark.parametrize('encoding', YELLOW_BY_ENCODING)
def test_to_bgr_converts_a_known_pixel(encoding):
    pixel, expected_bgr = YELLOW_BY_ENCODING[encoding]
    image = np.zeros(random_image(2, 3, encoding).shape, dtype=np.uint8)
    image[1, 2] = pixel
    result = to_bgr(image, encoding)
    assert result.shape == (2, 3, 3)
    assert result.dtype == np.uint8
    assert result.flags.c_contiguous
    assert tuple(result[1, 2]) == expected_bgr


@pytest.mark.parametrize(
    'encoding', [encoding for encoding in COLOUR_ENCODINGS if encoding not in BAYER_ENCODINGS])
def test_to_bgr_works_on_row_slices_of_padded_images(encoding):
    image = random_image(10, 8, encoding, seed=2)
    view = image_to_array(padded_message(image, encoding))
    np.testing.assert_array_equal(to_bgr(view[4:7], encoding), to_bgr(image, encoding)[4:7])


def test_to_bgr_returns_contiguous_bgr8_as_is():
    image = random_image(4, 5, 'bgr8')
    assert to_bgr(image, 'bgr8') is image


def test_to_bgr_copies_non_contiguous_bgr8():
    image = random_image(4, 5, 'bgr8')
    view = image[:, 1:4]
    result = to_bgr(view, 'bgr8')
    assert result.flags.c_contiguous
    np.testing.assert_array_equal(result, view)


@pytest.mark.parametrize('image, encoding', (
    (np.zeros((2, 2, 3), np.uint8), 'mono16'),
    (np.zeros((2, 2, 3), np.uint8), 'mono8'),
    (np.zeros((2, 2, 3), np.int16), 'bgr8'),
))
def test_to_bgr_rejects_bad_arrays(image, encoding):
    with pytest.raises(ImageConversionError):
        to_bgr(image, encoding)


# What cameras send raw: 4:2:2 YUV and Bayer mosaics.

# Flat colours, BGR, each different in all three channels so that a swapped channel shows.
PATCH_COLOURS_BGR = (
    (0, 246, 255), (116, 116, 116), (30, 120, 220), (200, 40, 90), (0, 0, 0), (255, 255, 255),
    (90, 200, 10))
PATCH_WIDTH_PX = 8
# Rows and columns at a patch's edge that demosaicing blends with its neighbour.
BAYER_BLEND_PX = 2
# OpenCV's fixed-point YUV conversion and the rounding of Y, U and V to bytes, in levels.
YUV_TOLERANCE = 2
# BT.601 studio range: Y in 16-235, U and V in 16-240 around 128 (ITU-R BT.601, per 255).
STUDIO_Y_OFFSET = 16
CHROMA_OFFSET = 128
Y_FROM_RGB = (65.481, 128.553, 24.966)
U_FROM_RGB = (-37.797, -74.203, 112.0)
V_FROM_RGB = (112.0, -93.786, -18.214)
FULL_SCALE = 255.0
BAYER_CHANNEL_BY_LETTER = {'b': 0, 'g': 1, 'r': 2}


def patches_bgr(height):
    """Return a BGR image of PATCH_COLOURS_BGR side by side, PATCH_WIDTH_PX each."""
    return np.repeat(np.array([PATCH_COLOURS_BGR], np.uint8), PATCH_WIDTH_PX, axis=1).repeat(
        height, axis=0)


def bayer_mosaic(bgr, encoding):
    """Sample a BGR image as the encoding's mosaic: its name spells the top-left 2x2 cell."""
    pattern = encoding.removeprefix('bayer_').removesuffix('8')
    mosaic = np.empty(bgr.shape[:2], np.uint8)
    for index, letter in enumerate(pattern):
        row, column = divmod(index, 2)
        mosaic[row::2, column::2] = bgr[row::2, column::2, BAYER_CHANNEL_BY_LETTER[letter]]
    return mosaic


def yuv422_bytes(bgr, encoding):
    """Return the 4:2:2 bytes of a BGR image by BT.601, chroma from each pixel pair's mean."""
    red, green, blue = (bgr[..., channel].astype(float) for channel in (2, 1, 0))

    def weigh(weights):
        return (weights[0] * red + weights[1] * green + weights[2] * blue) / FULL_SCALE

    luma = STUDIO_Y_OFFSET + weigh(Y_FROM_RGB)
    u = CHROMA_OFFSET + weigh(U_FROM_RGB)
    v = CHROMA_OFFSET + weigh(V_FROM_RGB)
    chroma = np.empty_like(luma)
    chroma[:, 0::2] = (u[:, 0::2] + u[:, 1::2]) / 2
    chroma[:, 1::2] = (v[:, 0::2] + v[:, 1::2]) / 2
    planes = (chroma, luma) if encoding in UYVY_ENCODINGS else (luma, chroma)
    return np.clip(np.rint(np.stack(planes, axis=2)), 0, 255).astype(np.uint8)


def stored_and_converted(image, encoding, pad):
    """Put an array in an Image (packed, or padded with garbage) and convert the view to BGR."""
    msg = padded_message(image, encoding) if pad else array_to_image(image, encoding)
    view = image_to_array(msg)
    np.testing.assert_array_equal(view, image)
    result = to_bgr(view, encoding)
    assert result.shape == image.shape[:2] + (3,) and result.flags.c_contiguous
    return result


@pytest.mark.parametrize('encoding', BAYER_ENCODINGS)
@pytest.mark.parametrize('pad', (False, True))
def test_bayer_mosaic_demosaics_to_the_colours_it_was_made_from(encoding, pad):
    result = stored_and_converted(bayer_mosaic(patches_bgr(height=8), encoding), encoding, pad)
    inner_rows = slice(BAYER_BLEND_PX, -BAYER_BLEND_PX)
    for index, colour in enumerate(PATCH_COLOURS_BGR):
        left = index * PATCH_WIDTH_PX + BAYER_BLEND_PX
        patch = result[inner_rows, left:left + PATCH_WIDTH_PX - 2 * BAYER_BLEND_PX]
        assert np.all(patch == colour), (colour, patch[0, 0])


@pytest.mark.parametrize('encoding', BAYER_ENCODINGS)
def test_bayer_slice_from_an_even_row_keeps_its_inner_rows(encoding):
    mosaic = random_image(12, 10, encoding, seed=8)
    whole = to_bgr(mosaic, encoding)
    sliced = to_bgr(image_to_array(padded_message(mosaic, encoding))[4:10], encoding)
    np.testing.assert_array_equal(sliced[1:-1], whole[5:9])


@pytest.mark.parametrize('encoding', YUV422_ENCODINGS)
@pytest.mark.parametrize('pad', (False, True))
def test_yuv422_converts_to_the_colours_it_was_made_from(encoding, pad):
    bgr = patches_bgr(height=3)
    result = stored_and_converted(yuv422_bytes(bgr, encoding), encoding, pad)
    assert np.abs(result.astype(int) - bgr).max() <= YUV_TOLERANCE


@pytest.mark.parametrize('encoding', YUV422_ENCODINGS)
def test_yuv422_byte_order_matters(encoding):
    bgr = patches_bgr(height=1)
    other_order = YUV422_ENCODINGS[0] if encoding not in UYVY_ENCODINGS else 'yuyv'
    result = to_bgr(yuv422_bytes(bgr, other_order), encoding)
    assert np.abs(result.astype(int) - bgr).max() > 10 * YUV_TOLERANCE


@pytest.mark.parametrize('encoding', YUV422_ENCODINGS)
@pytest.mark.parametrize('convert', (
    lambda encoding: image_to_array(fake_message(encoding=encoding, width=3, step=6)),
    lambda encoding: array_to_image(np.zeros((2, 3, 2), np.uint8), encoding),
    lambda encoding: to_bgr(np.zeros((2, 3, 2), np.uint8), encoding),
    lambda encoding: message_pixels(Image(), 2, 3, encoding),
), ids=('image_to_array', 'array_to_image', 'to_bgr', 'message_pixels'))
def test_yuv422_refuses_an_odd_width(encoding, convert):
    with pytest.raises(ImageConversionError, match='width must be even; got 3'):
        convert(encoding)


@pytest.mark.parametrize('encoding', SUPPORTED_ENCODINGS)
def test_data_one_byte_short_is_refused(encoding):
    msg = array_to_image(random_image(3, 4, encoding), encoding)
    msg.data = msg.data[:-1]
    with pytest.raises(ImageConversionError, match='shorter than step\\*height'):
        image_to_array(msg)


@pytest.mark.parametrize('encoding', (*YUV422_ENCODINGS, *BAYER_ENCODINGS))
def test_raw_camera_encodings_are_colour_encodings(encoding):
    assert encoding in COLOUR_ENCODINGS
    assert encoding in SUPPORTED_ENCODINGS


# Writing a renderer's RGB image as a camera of each kind would send it.

@pytest.mark.parametrize('encoding', [encoding for encoding in
                                      image_conversion.SUPPORTED_ENCODINGS
                                      if encoding != '32FC1'])
def test_from_rgb_writes_what_to_bgr_reads_back(encoding):
    rgb = np.zeros((16, 24, 3), np.uint8)
    rgb[:, :12] = (200, 150, 40)
    rgb[:, 12:] = (30, 60, 220)
    out = np.empty(image_conversion.expected_shape(16, 24, encoding), np.uint8)
    assert image_conversion.from_rgb(rgb, encoding, out) is out
    back = image_conversion.to_bgr(out, encoding)[..., ::-1]
    if encoding == 'mono8':
        expected = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        assert (back[..., 0] == expected).all()
        return
    # Flat patches come back within a level or two (YUV rounding), away from their border,
    # where 4:2:2 and Bayer interpolate across it.
    for columns in (slice(2, 9), slice(15, 22)):
        assert np.abs(back[2:-2, columns].astype(int) - rgb[2:-2, columns]).max() <= 2


def test_from_rgb_refuses_depth_and_wrong_sizes():
    rgb = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(image_conversion.ImageConversionError):
        image_conversion.from_rgb(rgb, '32FC1', np.zeros((4, 4), np.float32))
    with pytest.raises(image_conversion.ImageConversionError, match='must be'):
        image_conversion.from_rgb(rgb, 'bgr8', np.zeros((4, 6, 3), np.uint8))
