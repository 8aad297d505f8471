"""Tests of CompressedImage decoding and encoding, as image_transport's compressed plugin."""

import array
import re
import struct
from types import SimpleNamespace
import zlib

import cv2
from followbot.compressed_image import array_to_compressed
from followbot.compressed_image import compressed_header
from followbot.compressed_image import compressed_to_array
from followbot.compressed_image import CompressedHeader
from followbot.compressed_image import ENCODABLE_ENCODINGS
from followbot.compressed_image import JPEG
from followbot.compressed_image import MAX_DECODED_SIDE_PX
from followbot.compressed_image import PNG
from followbot.compressed_image import PNG_END
from followbot.compressed_image import PNG_SIGNATURE
from followbot.image_conversion import ImageConversionError
from followbot.image_conversion import to_bgr
import numpy as np
import pytest
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import Header

HEIGHT_PX = 48
WIDTH_PX = 64
# JPEG keeps flat patches within a few levels; the mean over a smooth image stays lower.
JPEG_PATCH_TOLERANCE = 6
JPEG_MEAN_TOLERANCE = 3.0
# Patch edges where JPEG's 8x8 blocks blur neighbouring colours.
PATCH_EDGE_PX = 4
PATCH_PX = 16
# Four flat colours, each different in all three channels, in a 2 x 4 grid of patches.
PATCH_COLOURS_BGR = ((0, 246, 255), (116, 116, 116), (30, 120, 220), (200, 40, 90))
GREY_LEVEL = 116
# A 16-bit PNG sample, as a depth image in millimetres would hold.
DEPTH_MM = 1500


def patches_bgr():
    """Return a BGR image of flat colour patches, PATCH_PX square, in two rows."""
    bgr = np.empty((HEIGHT_PX, WIDTH_PX, 3), np.uint8)
    for index in range((HEIGHT_PX // PATCH_PX) * (WIDTH_PX // PATCH_PX)):
        row, column = divmod(index, WIDTH_PX // PATCH_PX)
        bgr[row * PATCH_PX:(row + 1) * PATCH_PX, column * PATCH_PX:(column + 1) * PATCH_PX] = (
            PATCH_COLOURS_BGR[index % len(PATCH_COLOURS_BGR)])
    return bgr


def patch_centres(image):
    """Return the inner pixels of every patch, away from the blurred edges, as one array."""
    inner = slice(PATCH_EDGE_PX, PATCH_PX - PATCH_EDGE_PX)
    return np.stack([image[row + inner.start:row + inner.stop, column + inner.start:
                           column + inner.stop]
                     for row in range(0, HEIGHT_PX, PATCH_PX)
                     for column in range(0, WIDTH_PX, PATCH_PX)])


def image_in(encoding):
    """Return the test picture in an encoding: its colours, or a grey gradient for mono8."""
    if encoding == 'mono8':
        return np.tile(np.linspace(40, 220, WIDTH_PX).astype(np.uint8), (HEIGHT_PX, 1))
    bgr = patches_bgr()
    conversion = {'rgb8': cv2.COLOR_BGR2RGB, 'bgra8': cv2.COLOR_BGR2BGRA,
                  'rgba8': cv2.COLOR_BGR2RGBA}.get(encoding)
    return bgr if conversion is None else cv2.cvtColor(bgr, conversion)


def encoded(image, extension, *parameters):
    """Return an array compressed by OpenCV, as bytes."""
    succeeded, data = cv2.imencode(extension, image, parameters)
    assert succeeded
    return data.tobytes()


COLOUR_JPEG = encoded(patches_bgr(), '.jpg', cv2.IMWRITE_JPEG_QUALITY, 95)
# An old publisher compressed colour in RGB order without saying so.
RGB_ORDER_JPEG = encoded(patches_bgr()[:, :, ::-1], '.jpg', cv2.IMWRITE_JPEG_QUALITY, 95)
GREY_JPEG = encoded(np.full((HEIGHT_PX, WIDTH_PX), GREY_LEVEL, np.uint8), '.jpg')
COLOUR_PNG = encoded(patches_bgr(), '.png')
GREY_PNG = encoded(np.full((HEIGHT_PX, WIDTH_PX), GREY_LEVEL, np.uint8), '.png')
DEPTH_PNG = encoded(np.full((HEIGHT_PX, WIDTH_PX), DEPTH_MM, np.uint16), '.png')
COLOUR_16_BIT_PNG = encoded(np.full((HEIGHT_PX, WIDTH_PX, 3), DEPTH_MM, np.uint16), '.png')
TIFF = encoded(patches_bgr(), '.tiff')


def message(format_text, data):
    """Return a CompressedImage with this format and data."""
    return CompressedImage(format=format_text, data=array.array('B', data))


def png_header_claiming(width, height, bit_depth=8, colour_type=2):
    """Return a PNG signature, an IHDR chunk for this size, and IEND: no pixels at all."""
    ihdr = b'IHDR' + struct.pack('>IIBBBBB', width, height, bit_depth, colour_type, 0, 0, 0)
    return (PNG_SIGNATURE + struct.pack('>I', len(ihdr) - 4) + ihdr
            + struct.pack('>I', zlib.crc32(ihdr)) + PNG_END)


def jpeg_claiming(width, height):
    """Return COLOUR_JPEG with its frame header changed to state another size."""
    frame = COLOUR_JPEG.index(b'\xff\xc0')
    size_at = frame + 5  # marker (2), length (2), precision (1)
    return (COLOUR_JPEG[:size_at] + struct.pack('>HH', height, width)
            + COLOUR_JPEG[size_at + 4:])


def with_exif_orientation(jpeg, orientation):
    """Return a JPEG with an EXIF APP1 segment stating an orientation (6: turn 90 degrees)."""
    ifd = struct.pack('>HHHIHH', 1, 0x0112, 3, 1, orientation, 0) + struct.pack('>I', 0)
    payload = b'Exif\x00\x00' + b'MM\x00\x2a' + struct.pack('>I', 8) + ifd
    app1 = b'\xff\xe1' + struct.pack('>H', len(payload) + 2) + payload
    return jpeg[:2] + app1 + jpeg[2:]


# Format strings as compressed_image_transport writes them (and as older publishers and
# other drivers do), with the data they come with and what they must decode to.
@pytest.mark.parametrize('format_text, data, encoding', (
    ('jpeg', COLOUR_JPEG, 'bgr8'),
    ('png', COLOUR_PNG, 'bgr8'),
    ('', COLOUR_JPEG, 'bgr8'),
    ('bgr8; jpeg compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('rgb8; jpeg compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('bgra8; jpeg compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('rgba8; jpeg compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('rgb16; jpeg compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('rgb8; jpeg compressed rgb8', RGB_ORDER_JPEG, 'bgr8'),
    ('bgr8; jpeg compressed rgb8', RGB_ORDER_JPEG, 'bgr8'),
    ('mono8; jpeg compressed mono8', GREY_JPEG, 'mono8'),
    ('mono16; jpeg compressed mono8', GREY_JPEG, 'mono8'),
    ('bayer_rggb8; jpeg compressed mono8', GREY_JPEG, 'mono8'),
    ('yuv422; jpeg compressed mono8', GREY_JPEG, 'mono8'),
    ('bgr8; png compressed bgr8', COLOUR_PNG, 'bgr8'),
    ('rgb8; png compressed bgr8', COLOUR_PNG, 'bgr8'),
    ('bgra8; png compressed bgr8', COLOUR_PNG, 'bgr8'),
    ('mono8; png compressed ', GREY_PNG, 'mono8'),
    # The bytes' magic number wins over the text.
    ('png', COLOUR_JPEG, 'bgr8'),
    ('jpeg', COLOUR_PNG, 'bgr8'),
    ('bgr8; png compressed bgr8', COLOUR_JPEG, 'bgr8'),
    ('mono8; jpeg compressed mono8', COLOUR_JPEG, 'bgr8'),
    ('bgr8; jpeg compressed bgr8', GREY_PNG, 'mono8'),
))
def test_every_format_decodes_to_its_colours(format_text, data, encoding):
    image, result_encoding = compressed_to_array(message(format_text, data))
    assert result_encoding == encoding
    assert image.dtype == np.uint8 and image.flags.c_contiguous
    if encoding == 'mono8':
        assert image.shape == (HEIGHT_PX, WIDTH_PX)
        assert np.abs(image.astype(int) - GREY_LEVEL).max() <= JPEG_PATCH_TOLERANCE
    else:
        assert image.shape == (HEIGHT_PX, WIDTH_PX, 3)
        difference = patch_centres(image).astype(int) - patch_centres(patches_bgr())
        assert np.abs(difference).max() <= JPEG_PATCH_TOLERANCE


@pytest.mark.parametrize('format_text, data, message_part', (
    ('16UC1; compressedDepth png', bytes(12) + DEPTH_PNG, 'is a depth image'),
    ('32FC1; compressedDepth rvl', bytes(40), 'is a depth image'),
    ('32FC1; compressedDepth', bytes(12) + DEPTH_PNG, 'is a depth image'),
    ('16UC1; png compressed ', DEPTH_PNG, 'is a depth image'),
    ('32FC1; jpeg compressed mono8', GREY_JPEG, 'is a depth image'),
    ('mono16; png compressed ', DEPTH_PNG, '16-bit samples'),
    ('png', DEPTH_PNG, '16-bit samples'),
    ('bgr16; png compressed bgr16', COLOUR_16_BIT_PNG, '16-bit samples'),
    ('bgr8; tiff compressed bgr8', TIFF, 'neither JPEG nor PNG'),
))
def test_depth_and_other_codecs_are_refused(format_text, data, message_part):
    with pytest.raises(ImageConversionError, match=message_part):
        compressed_to_array(message(format_text, data))


def cut(data, fraction):
    """Return the first fraction of some bytes."""
    return data[:int(len(data) * fraction)]


def spoil(data, start_fraction, replacement):
    """Return bytes with a run replaced from a fraction of their length on."""
    start = int(len(data) * start_fraction)
    return data[:start] + replacement + data[start + len(replacement):]


def bad_png_crc(data):
    """Return a PNG whose IHDR checksum is wrong."""
    crc_at = len(PNG_SIGNATURE) + 8 + 13
    return data[:crc_at] + bytes(4) + data[crc_at + 4:]


def jpeg_segment_length(data, length):
    """Return a JPEG whose first segment after SOI states another length."""
    return data[:4] + struct.pack('>H', length) + data[6:]


@pytest.mark.parametrize('data, message_part', (
    (b'', 'has no data'),
    (b'\xff', 'cut short: 1 bytes'),
    (PNG_SIGNATURE[:5], 'cut short: 5 bytes'),
    (COLOUR_JPEG[:3], 'cut short: 3 bytes'),
    (cut(COLOUR_JPEG, 0.02), 'cut short'),
    (cut(COLOUR_JPEG, 0.5), 'cut short: it has no end'),
    (COLOUR_JPEG[:-1], 'cut short: it has no end'),
    (COLOUR_JPEG[:2] + b'\x00' + COLOUR_JPEG[2:], 'neither JPEG nor PNG'),
    (COLOUR_JPEG[:3] + b'\x00' + COLOUR_JPEG[4:], '0x00 at byte 3 is not a marker'),
    (jpeg_segment_length(COLOUR_JPEG, 0), 'segment at byte 4 is 0 bytes long'),
    (jpeg_segment_length(COLOUR_JPEG, 40000), 'cut short before its frame header'),
    (COLOUR_JPEG[:2] + b'\xff\xda' + COLOUR_JPEG[2:], 'has no frame header'),
    (cut(COLOUR_PNG, 0.5), 'cut short: it has no end'),
    (COLOUR_PNG[:20], 'cut short before the end of its header'),
    (COLOUR_PNG[:-1], 'cut short: it has no end'),
    (bad_png_crc(COLOUR_PNG), 'IHDR header chunk is not valid'),
    (spoil(COLOUR_PNG, 0.5, bytes(20)), 'corrupt'),
    (png_header_claiming(WIDTH_PX, HEIGHT_PX), 'corrupt'),
    (png_header_claiming(0, HEIGHT_PX), 'size of 0 x 48'),
    (TIFF, 'starts with 49 49 2a 00'),
))
def test_cut_short_or_corrupt_data_is_one_clear_error(data, message_part):
    with pytest.raises(ImageConversionError, match=re.escape(message_part)):
        compressed_to_array(message('jpeg', data))


@pytest.mark.parametrize('data', (
    png_header_claiming(100_000, 100_000),
    png_header_claiming(MAX_DECODED_SIDE_PX + 1, MAX_DECODED_SIDE_PX),
    jpeg_claiming(65_535, 65_535),
    jpeg_claiming(MAX_DECODED_SIDE_PX, MAX_DECODED_SIDE_PX + 1),
), ids=('png-100000', 'png-4097', 'jpeg-65535', 'jpeg-4097'))
def test_oversized_images_are_refused_before_decoding(data):
    with pytest.raises(ImageConversionError, match='larger than the most followbot decodes'):
        compressed_to_array(message('png', data))


def test_the_largest_image_allowed_decodes():
    side = MAX_DECODED_SIDE_PX
    data = encoded(np.zeros((side, side), np.uint8), '.png')
    image, encoding = compressed_to_array(message('mono8; png compressed ', data))
    assert (image.shape, encoding) == ((side, side), 'mono8')


@pytest.mark.parametrize('data, header', (
    (COLOUR_JPEG, CompressedHeader(JPEG, WIDTH_PX, HEIGHT_PX, grey=False)),
    (GREY_JPEG, CompressedHeader(JPEG, WIDTH_PX, HEIGHT_PX, grey=True)),
    (with_exif_orientation(COLOUR_JPEG, 6), CompressedHeader(JPEG, WIDTH_PX, HEIGHT_PX, False)),
    (COLOUR_PNG, CompressedHeader(PNG, WIDTH_PX, HEIGHT_PX, grey=False)),
    (GREY_PNG, CompressedHeader(PNG, WIDTH_PX, HEIGHT_PX, grey=True)),
    (png_header_claiming(7, 3, colour_type=4), CompressedHeader(PNG, 7, 3, grey=True)),
    (png_header_claiming(7, 3, colour_type=3), CompressedHeader(PNG, 7, 3, grey=False)),
))
def test_compressed_header_reads_size_and_colour(data, header):
    assert compressed_header(data) == header


def test_exif_orientation_is_ignored_as_ros_does():
    image, _ = compressed_to_array(message('jpeg', with_exif_orientation(COLOUR_JPEG, 6)))
    assert image.shape == (HEIGHT_PX, WIDTH_PX, 3)


@pytest.mark.parametrize('msg, message_part', (
    (SimpleNamespace(format=None, data=COLOUR_JPEG), 'format must be a string'),
    (SimpleNamespace(format='jpeg', data='not bytes'), 'not a sequence of bytes'),
    (SimpleNamespace(format='jpeg', data=[255, 216, 300]), 'not a sequence of bytes'),
))
def test_malformed_messages_are_refused(msg, message_part):
    with pytest.raises(ImageConversionError, match=message_part):
        compressed_to_array(msg)


@pytest.mark.parametrize('data_type', (bytes, bytearray, list))
def test_message_like_objects_decode(data_type):
    image, encoding = compressed_to_array(
        SimpleNamespace(format='png', data=data_type(COLOUR_PNG)))
    assert encoding == 'bgr8'
    np.testing.assert_array_equal(image, patches_bgr())


# Encoding, as the simulator will publish: format strings as the plugin writes them.
@pytest.mark.parametrize('encoding, codec, format_text', (
    ('bgr8', JPEG, 'bgr8; jpeg compressed bgr8'),
    ('rgb8', JPEG, 'rgb8; jpeg compressed bgr8'),
    ('bgra8', JPEG, 'bgra8; jpeg compressed bgr8'),
    ('rgba8', JPEG, 'rgba8; jpeg compressed bgr8'),
    ('mono8', JPEG, 'mono8; jpeg compressed mono8'),
    ('bgr8', PNG, 'bgr8; png compressed bgr8'),
    ('rgb8', PNG, 'rgb8; png compressed bgr8'),
    ('bgra8', PNG, 'bgra8; png compressed bgr8'),
    ('rgba8', PNG, 'rgba8; png compressed bgr8'),
    ('mono8', PNG, 'mono8; png compressed '),
))
def test_array_to_compressed_writes_the_plugins_format(encoding, codec, format_text):
    msg = array_to_compressed(image_in(encoding), encoding, codec)
    assert isinstance(msg, CompressedImage)
    assert msg.format == format_text
    assert isinstance(msg.data, array.array)


@pytest.mark.parametrize('encoding', ENCODABLE_ENCODINGS)
def test_png_round_trip_is_exact(encoding):
    image = image_in(encoding)
    decoded, decoded_encoding = compressed_to_array(array_to_compressed(image, encoding, PNG))
    if encoding == 'mono8':
        assert decoded_encoding == 'mono8'
        np.testing.assert_array_equal(decoded, image)
    else:
        assert decoded_encoding == 'bgr8'
        np.testing.assert_array_equal(decoded, to_bgr(image, encoding))


@pytest.mark.parametrize('encoding', ENCODABLE_ENCODINGS)
@pytest.mark.parametrize('quality', (80, 95))
def test_jpeg_round_trip_is_close_in_colour(encoding, quality):
    image = image_in(encoding)
    msg = array_to_compressed(image, encoding, JPEG, jpeg_quality=quality)
    decoded, decoded_encoding = compressed_to_array(msg)
    expected = image if encoding == 'mono8' else to_bgr(image, encoding)
    assert decoded_encoding == ('mono8' if encoding == 'mono8' else 'bgr8')
    difference = np.abs(decoded.astype(int) - expected)
    assert difference.mean() <= JPEG_MEAN_TOLERANCE
    if encoding != 'mono8':
        assert np.abs(patch_centres(decoded).astype(int)
                      - patch_centres(expected)).max() <= JPEG_PATCH_TOLERANCE


def test_jpeg_quality_changes_the_size():
    image = np.random.default_rng(0).integers(0, 256, (HEIGHT_PX, WIDTH_PX, 3), np.uint8)
    low = array_to_compressed(image, 'bgr8', JPEG, jpeg_quality=10)
    high = array_to_compressed(image, 'bgr8', JPEG, jpeg_quality=100)
    assert len(low.data) < len(high.data) / 2


def test_array_to_compressed_fills_a_given_message_and_keeps_its_header():
    msg = CompressedImage(header=Header(frame_id='camera_rgb_optical_frame'))
    assert array_to_compressed(patches_bgr(), 'bgr8', PNG, msg=msg) is msg
    assert msg.header.frame_id == 'camera_rgb_optical_frame'
    np.testing.assert_array_equal(compressed_to_array(msg)[0], patches_bgr())
    array_to_compressed(image_in('mono8'), 'mono8', JPEG, msg=msg)
    assert compressed_to_array(msg)[1] == 'mono8'


def test_array_to_compressed_accepts_non_contiguous_arrays():
    view = patches_bgr()[::2, ::-1]
    decoded, _ = compressed_to_array(array_to_compressed(view, 'bgr8', PNG))
    np.testing.assert_array_equal(decoded, view)


@pytest.mark.parametrize('image, encoding, options, error_type, message_part', (
    (np.zeros((4, 4, 2), np.uint8), 'yuv422', {}, ImageConversionError, 'Cannot compress'),
    (np.zeros((4, 4), np.float32), '32FC1', {}, ImageConversionError, 'Cannot compress'),
    (np.zeros((4, 4), np.uint8), 'bgr8', {}, ImageConversionError, r'shape \(H, W, 3\)'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'codec': 'tiff'}, ValueError, 'codec must be'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'jpeg_quality': 0}, ValueError,
     r'jpeg_quality must be in \[1, 100\], got 0'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'jpeg_quality': 101}, ValueError, 'got 101'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'jpeg_quality': '95'}, TypeError,
     'jpeg_quality must be an int, got str'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'jpeg_quality': True}, TypeError, 'got bool'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'codec': PNG, 'png_level': 10}, ValueError,
     r'png_level must be in \[0, 9\], got 10'),
    (np.zeros((4, 4, 3), np.uint8), 'bgr8', {'codec': PNG, 'png_level': 2.0}, TypeError,
     'png_level must be an int, got float'),
))
def test_array_to_compressed_refuses_bad_input(image, encoding, options, error_type,
                                               message_part):
    with pytest.raises(error_type, match=message_part):
        array_to_compressed(image, encoding, **options)
