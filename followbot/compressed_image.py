"""
Decode and encode sensor_msgs/msg/CompressedImage as image_transport's compressed plugin does.

A camera's images usually cross Wi-Fi as JPEG on ``<camera>/image_raw/compressed``.
compressed_image_transport writes the ``format`` field as ``<original encoding>; <codec>
compressed <target>``: ``bgr8; jpeg compressed bgr8``, ``rgb8; jpeg compressed bgr8`` (the
pixels were turned to BGR before compression), ``mono8; jpeg compressed mono8``,
``bgr8; png compressed bgr8``, and for single-channel PNG nothing after ``compressed ``
(``mono8; png compressed ``). Older publishers and other drivers write only ``jpeg`` or
``png``. The bytes' own magic number decides the codec, whatever the text says; the text still
tells depth images (``compressedDepth``, ``16UC1``) apart, and which colour order old
publishers compressed.

Decoding is refused before it starts when the image is larger than MAX_DECODED_PIXELS (a few
hundred bytes can claim gigabytes of pixels), or when the data is cut short: width and height
come from the JPEG frame header or the PNG IHDR chunk, read here. Every failure is one
:class:`~followbot.image_conversion.ImageConversionError`.
"""

from typing import NamedTuple
import zlib

import cv2
from followbot.image_conversion import check_array
from followbot.image_conversion import fill_message_data
from followbot.image_conversion import flat_bytes
from followbot.image_conversion import ImageConversionError
from followbot.image_conversion import to_bgr
import numpy as np
from sensor_msgs.msg import CompressedImage

JPEG = 'jpeg'
PNG = 'png'
CODECS = (JPEG, PNG)
_FILE_EXTENSION_BY_CODEC = {JPEG: '.jpg', PNG: '.png'}

# compressed_image_transport's default parameters, and the ranges it accepts.
DEFAULT_JPEG_QUALITY = 95
DEFAULT_PNG_LEVEL = 3
JPEG_QUALITY_RANGE = (1, 100)
PNG_LEVEL_RANGE = (0, 9)

# The largest image decoded: 4096 x 4096 pixels (48 MiB as BGR), twice a 4K UHD camera frame.
MAX_DECODED_SIDE_PX = 4096
MAX_DECODED_PIXELS = MAX_DECODED_SIDE_PX * MAX_DECODED_SIDE_PX

# Encodings an array may have to be compressed; colour ones are compressed as BGR.
ENCODABLE_ENCODINGS = ('bgr8', 'rgb8', 'bgra8', 'rgba8', 'mono8')
# Original encodings that compressed_image_transport's subscriber treats as colour.
COLOUR_ORIGINAL_ENCODINGS = (
    'bgr8', 'rgb8', 'bgra8', 'rgba8', 'bgr16', 'rgb16', 'bgra16', 'rgba16')
# Original encodings of depth images: distances, not a picture of the line.
DEPTH_ENCODINGS = ('16UC1', '32FC1')
DEPTH_FORMAT_MARK = 'compressedDepth'
# Since 2012 the publisher turns colour into BGR before compressing and says so; before, the
# compressed pixels were in RGB order, as the subscriber still assumes when this is missing.
BGR_TARGET_MARK = 'compressed bgr'
FORMAT_SEPARATOR = ';'
GREY_ENCODING = 'mono8'
COLOUR_ENCODING = 'bgr8'

# The decoder ignores EXIF orientation, as compressed_image_transport does: a robot's camera
# image keeps the geometry its camera_info describes.
_GREY_READ_FLAGS = cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION
_COLOUR_READ_FLAGS = cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION

# JPEG (ITU T.81): a stream of segments, each a 0xFF byte, a marker byte and, for most
# markers, a two-byte big-endian length that counts itself.
JPEG_SOI = b'\xff\xd8'
JPEG_EOI = b'\xff\xd9'
_JPEG_MAGIC = b'\xff\xd8\xff'
_JPEG_MARKER_PREFIX = 0xFF
_JPEG_SOS = 0xDA
_JPEG_EOI_MARKER = 0xD9
# Start-of-frame markers: 0xC0-0xCF except DHT (0xC4), JPG (0xC8) and DAC (0xCC).
_JPEG_SOF_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers that stand alone, without a length: TEM and RST0-RST7.
_JPEG_STANDALONE_MARKERS = frozenset({0x01, *range(0xD0, 0xD8)})
# Markers below this one are reserved, or (0x00) stuffing inside compressed data.
_JPEG_FIRST_SEGMENT_MARKER = 0xC0
_JPEG_LENGTH_BYTES = 2
_JPEG_HEIGHT_BYTES = slice(1, 3)
_JPEG_WIDTH_BYTES = slice(3, 5)
# Frame header after its length: precision (1 byte), height (2), width (2), components (1).
_JPEG_FRAME_BYTES = 6
_JPEG_SAMPLE_BITS = 8
_JPEG_GREY_COMPONENTS = 1

# PNG: an 8-byte signature, then chunks of length (4), type (4), data, CRC (4); IHDR first,
# IEND (12 bytes, always the same) last.
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
PNG_END = b'\x00\x00\x00\x00IEND\xaeB`\x82'
_PNG_IHDR = b'IHDR'
_PNG_IHDR_DATA_BYTES = 13
_PNG_CHUNK_FIELD_BYTES = 4
_PNG_HEADER_END = len(PNG_SIGNATURE) + 3 * _PNG_CHUNK_FIELD_BYTES + _PNG_IHDR_DATA_BYTES
# IHDR data: width (4 bytes), height (4), bit depth (1), colour type (1), then three methods.
_PNG_WIDTH_BYTES = slice(0, 4)
_PNG_HEIGHT_BYTES = slice(4, 8)
_PNG_BIT_DEPTH_INDEX = 8
_PNG_COLOUR_TYPE_INDEX = 9
_PNG_SAMPLE_BITS_MAX = 8
# IHDR colour types without colour: grey (0) and grey with alpha (4).
_PNG_GREY_COLOUR_TYPES = frozenset({0, 4})


class CompressedHeader(NamedTuple):
    """What a JPEG or PNG stream says about its image before it is decoded."""

    codec: str
    width: int
    height: int
    grey: bool


def compressed_to_array(msg):
    """
    Decode a CompressedImage into a BGR or greyscale array.

    :param msg: a sensor_msgs/msg/CompressedImage, or any object with ``format`` and ``data``.
    :return: (array, encoding): a C-contiguous uint8 (height, width, 3) array and 'bgr8' for
        colour, a (height, width) array and 'mono8' for greyscale. Alpha is dropped.
    :raises ImageConversionError: if the image is a depth image, neither JPEG nor PNG, has
        more than 8 bits per sample or more than MAX_DECODED_PIXELS pixels, or is cut short
        or corrupt.
    """
    format_text = msg.format
    if not isinstance(format_text, str):
        raise ImageConversionError(
            f'CompressedImage format must be a string, got {type(format_text).__name__}.')
    original_encoding, _, compression = format_text.partition(FORMAT_SEPARATOR)
    original_encoding = original_encoding.strip()
    if DEPTH_FORMAT_MARK in format_text or original_encoding in DEPTH_ENCODINGS:
        raise ImageConversionError(
            f'CompressedImage format {format_text!r} is a depth image; followbot decodes '
            'colour and greyscale pictures only.')
    data = flat_bytes(msg.data)
    data_bytes = data.tobytes()
    try:
        header = compressed_header(data_bytes)
    except ImageConversionError as error:
        raise ImageConversionError(f'{error} Its format is {format_text!r}.') from None
    pixels = header.width * header.height
    if pixels > MAX_DECODED_PIXELS:
        raise ImageConversionError(
            f'Compressed {header.codec} image of {header.width} x {header.height} pixels is '
            f'larger than the most followbot decodes, {MAX_DECODED_SIDE_PX} x '
            f'{MAX_DECODED_SIDE_PX} pixels.')
    _check_complete(data_bytes, header.codec)
    flags = _GREY_READ_FLAGS if header.grey else _COLOUR_READ_FLAGS
    try:
        image = cv2.imdecode(data, flags)
    except cv2.error as error:
        raise ImageConversionError(
            f'Compressed {header.codec} image is corrupt: {error}.') from None
    expected_shape = (header.height, header.width)
    if image is None or image.shape[:2] != expected_shape:
        raise ImageConversionError(
            f'Compressed {header.codec} image is corrupt: it did not decode to '
            f'{header.width} x {header.height} pixels.')
    if header.grey:
        return image, GREY_ENCODING
    if _compressed_in_rgb_order(original_encoding, compression):
        cv2.cvtColor(image, cv2.COLOR_RGB2BGR, dst=image)
    return image, COLOUR_ENCODING


def _compressed_in_rgb_order(original_encoding, compression):
    """
    Tell whether a colour image was compressed with its channels in RGB order.

    As compressed_image_transport's subscriber decides: a format that names a colour
    original encoding but no BGR target comes from a publisher that compressed RGB.
    """
    return bool(compression) and original_encoding in COLOUR_ORIGINAL_ENCODINGS and (
        BGR_TARGET_MARK not in compression)


def compressed_header(data):
    """
    Read the codec, size and colour of a JPEG or PNG stream from its first bytes.

    :param data: the compressed bytes, as a bytes-like object or a flat uint8 array.
    :return: a CompressedHeader.
    :raises ImageConversionError: if the data is empty, neither JPEG nor PNG, cut short
        before the size, or states a size of zero or more than 8 bits per sample.
    """
    data = bytes(data)  # no copy when it is bytes already
    if not data:
        raise ImageConversionError('CompressedImage has no data.')
    if len(data) < len(PNG_SIGNATURE) and (
            PNG_SIGNATURE.startswith(data) or _JPEG_MAGIC.startswith(data)):
        raise ImageConversionError(
            f'Compressed data is cut short: {len(data)} bytes, the start of a header.')
    if data.startswith(_JPEG_MAGIC):
        return _jpeg_header(data)
    if data.startswith(PNG_SIGNATURE):
        return _png_header(data)
    raise ImageConversionError(
        f'Compressed data is neither JPEG nor PNG: it starts with {data[:8].hex(" ")}.')


def _jpeg_header(data):
    """Return the header of a JPEG stream from its frame (SOF) segment."""
    position = len(JPEG_SOI)
    while position < len(data):
        if data[position] != _JPEG_MARKER_PREFIX:
            raise ImageConversionError(
                f'JPEG data is corrupt: no segment marker at byte {position}.')
        while position < len(data) and data[position] == _JPEG_MARKER_PREFIX:
            position += 1  # fill bytes may pad before a marker
        if position == len(data):
            break
        marker = data[position]
        position += 1
        if marker in _JPEG_STANDALONE_MARKERS:
            continue
        if marker < _JPEG_FIRST_SEGMENT_MARKER:
            raise ImageConversionError(
                f'JPEG data is corrupt: 0x{marker:02x} at byte {position - 1} is not a marker.')
        if marker in (_JPEG_SOS, _JPEG_EOI_MARKER):
            raise ImageConversionError('JPEG data is corrupt: it has no frame header.')
        length = _big_endian(data[position:position + _JPEG_LENGTH_BYTES])
        if length < _JPEG_LENGTH_BYTES:
            raise ImageConversionError(
                f'JPEG data is corrupt: a segment at byte {position} is {length} bytes long.')
        segment_end = position + length
        if marker in _JPEG_SOF_MARKERS:
            return _jpeg_frame(data[position + _JPEG_LENGTH_BYTES:segment_end])
        position = segment_end
    raise ImageConversionError('JPEG data is cut short before its frame header.')


def _jpeg_frame(frame):
    """Return the header described by a JPEG frame segment (after its length)."""
    if len(frame) < _JPEG_FRAME_BYTES:
        raise ImageConversionError('JPEG data is cut short in its frame header.')
    precision = frame[0]
    height = _big_endian(frame[_JPEG_HEIGHT_BYTES])
    width = _big_endian(frame[_JPEG_WIDTH_BYTES])
    components = frame[5]
    if precision != _JPEG_SAMPLE_BITS:
        raise ImageConversionError(
            f'JPEG image has {precision}-bit samples; followbot decodes 8-bit JPEG only.')
    _check_size(JPEG, width, height)
    return CompressedHeader(JPEG, width, height, components == _JPEG_GREY_COMPONENTS)


def _png_header(data):
    """Return the header of a PNG stream from its IHDR chunk."""
    if len(data) < _PNG_HEADER_END:
        raise ImageConversionError('PNG data is cut short before the end of its header.')
    length_start = len(PNG_SIGNATURE)
    type_start = length_start + _PNG_CHUNK_FIELD_BYTES
    data_start = type_start + _PNG_CHUNK_FIELD_BYTES
    crc_start = data_start + _PNG_IHDR_DATA_BYTES
    length = _big_endian(data[length_start:type_start])
    chunk_type = data[type_start:data_start]
    crc = _big_endian(data[crc_start:_PNG_HEADER_END])
    if (chunk_type != _PNG_IHDR or length != _PNG_IHDR_DATA_BYTES
            or crc != zlib.crc32(data[type_start:crc_start])):
        raise ImageConversionError('PNG data is corrupt: its IHDR header chunk is not valid.')
    ihdr = data[data_start:crc_start]
    width = _big_endian(ihdr[_PNG_WIDTH_BYTES])
    height = _big_endian(ihdr[_PNG_HEIGHT_BYTES])
    bit_depth = ihdr[_PNG_BIT_DEPTH_INDEX]
    colour_type = ihdr[_PNG_COLOUR_TYPE_INDEX]
    if bit_depth > _PNG_SAMPLE_BITS_MAX:
        raise ImageConversionError(
            f'PNG image has {bit_depth}-bit samples (a depth or 16-bit image); followbot '
            'decodes 8-bit PNG only.')
    _check_size(PNG, width, height)
    return CompressedHeader(PNG, width, height, colour_type in _PNG_GREY_COLOUR_TYPES)


def _big_endian(field):
    """Return the unsigned integer stored big-endian in a bytes field."""
    return int.from_bytes(field, 'big')


def _check_size(codec, width, height):
    if width < 1 or height < 1:
        raise ImageConversionError(
            f'Compressed {codec} image states a size of {width} x {height} pixels.')


def _check_complete(data, codec):
    """Refuse a stream without its end marker: decoders fill what is missing with grey."""
    if codec == JPEG:
        complete = data.rfind(JPEG_EOI, len(JPEG_SOI)) >= 0
    else:
        complete = data.rfind(PNG_END, _PNG_HEADER_END) >= 0
    if not complete:
        raise ImageConversionError(f'Compressed {codec} image is cut short: it has no end.')


def array_to_compressed(image, encoding, codec=JPEG, jpeg_quality=DEFAULT_JPEG_QUALITY,
                        png_level=DEFAULT_PNG_LEVEL, msg=None):
    """
    Fill a CompressedImage with an array compressed as compressed_image_transport would.

    Colour is compressed as BGR, and ``format`` says so as the plugin writes it, such as
    ``rgb8; jpeg compressed bgr8`` or ``mono8; png compressed ``.

    :param image: an array of the shape the encoding needs, any memory layout.
    :param encoding: one of ENCODABLE_ENCODINGS, describing the array's channel order.
    :param codec: JPEG or PNG.
    :param jpeg_quality: JPEG quality, an int in JPEG_QUALITY_RANGE.
    :param png_level: PNG (zlib) compression level, an int in PNG_LEVEL_RANGE.
    :param msg: a CompressedImage to fill, keeping its header; a new one is made when omitted.
    :return: the filled message (``msg`` itself when given).
    :raises ImageConversionError: if the encoding or the array is not valid, or the image
        cannot be compressed.
    :raises ValueError: if the codec, quality or level is not one of the accepted values.
    :raises TypeError: if the quality or level is not an int.
    """
    if encoding not in ENCODABLE_ENCODINGS:
        raise ImageConversionError(
            f'Cannot compress encoding {encoding!r}; compressible encodings are '
            f'{", ".join(ENCODABLE_ENCODINGS)}.')
    check_array(image, encoding)
    grey = encoding == GREY_ENCODING
    if codec == JPEG:
        parameters = (cv2.IMWRITE_JPEG_QUALITY, _int_in('jpeg_quality', jpeg_quality,
                                                        JPEG_QUALITY_RANGE))
        target = GREY_ENCODING if grey else COLOUR_ENCODING
    elif codec == PNG:
        parameters = (cv2.IMWRITE_PNG_COMPRESSION, _int_in('png_level', png_level,
                                                           PNG_LEVEL_RANGE))
        target = '' if grey else COLOUR_ENCODING
    else:
        raise ValueError(f'codec must be one of {", ".join(CODECS)}, got {codec!r}.')
    pixels = np.ascontiguousarray(image) if grey else to_bgr(image, encoding)
    try:
        succeeded, encoded = cv2.imencode(_FILE_EXTENSION_BY_CODEC[codec], pixels, parameters)
    except cv2.error as error:
        succeeded, encoded = False, error
    if not succeeded:
        raise ImageConversionError(f'Cannot compress the image as {codec}: {encoded}.')
    if msg is None:
        msg = CompressedImage()
    msg.format = f'{encoding}{FORMAT_SEPARATOR} {codec} compressed {target}'
    return fill_message_data(msg, encoded)


def _int_in(name, value, value_range):
    lowest, highest = value_range
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f'{name} must be an int, got {type(value).__name__}.')
    if not lowest <= value <= highest:
        raise ValueError(f'{name} must be in [{lowest}, {highest}], got {value}.')
    return value
