"""
Convert between sensor_msgs/msg/Image and NumPy arrays, replacing cv_bridge.

cv_bridge is not available without a ROS install and breaks under NumPy 2, so followbot owns
the small part of it that it needs: the 8-bit colour and mono encodings, what cameras send
raw (4:2:2 YUV in both byte orders, the four Bayer mosaics), and 32FC1 for depth images in
metres. Row padding (``step``) and byte order are honoured, every field is validated, and one
error type is raised. Arrays hold the pixels as the message stores them (two bytes per pixel
for YUV, the mosaic for Bayer); :func:`to_bgr` turns any of the colour encodings into BGR.
Compressed images are :mod:`followbot.compressed_image`'s subject.
"""

import array
import sys

import cv2
import numpy as np
from sensor_msgs.msg import Image

# 4:2:2 YUV: each two pixels side by side share one U and one V sample, four bytes in all.
# ROS's 'yuv422' is UYVY byte order and 'yuv422_yuy2' is YUYV (sensor_msgs/image_encodings.hpp);
# 'uyvy' and 'yuyv' name the same orders plainly.
UYVY_ENCODINGS = ('yuv422', 'uyvy')
YUYV_ENCODINGS = ('yuv422_yuy2', 'yuyv')
YUV422_ENCODINGS = (*UYVY_ENCODINGS, *YUYV_ENCODINGS)
# Pixels that share their chroma in 4:2:2 YUV: the width must be a multiple of this.
YUV422_PIXELS_PER_GROUP = 2
# 8-bit Bayer mosaics, named by the colours of the top-left 2x2 cell, row by row.
BAYER_ENCODINGS = ('bayer_rggb8', 'bayer_bggr8', 'bayer_gbrg8', 'bayer_grbg8')

SUPPORTED_ENCODINGS = (
    'bgr8', 'rgb8', 'bgra8', 'rgba8', 'mono8', *YUV422_ENCODINGS, *BAYER_ENCODINGS, '32FC1')

# Channels of an array holding each encoding as stored: YUV has two bytes per pixel (Y and one
# of U or V), a Bayer mosaic one sample per pixel.
CHANNELS_BY_ENCODING = {
    'bgr8': 3,
    'rgb8': 3,
    'bgra8': 4,
    'rgba8': 4,
    'mono8': 1,
    **dict.fromkeys(YUV422_ENCODINGS, 2),
    **dict.fromkeys(BAYER_ENCODINGS, 1),
    '32FC1': 1,
}

# Element type of each channel; 32FC1 is a float32 per pixel (depth in metres, NaN = no return).
DTYPE_BY_ENCODING = {
    '32FC1': np.dtype(np.float32),
}
BYTE_DTYPE = np.dtype(np.uint8)

# cv2.cvtColor codes that turn each encoding into BGR; bgr8 needs no conversion. OpenCV's YUV
# conversions use BT.601 with studio range (Y 16-235), as cameras and cv_bridge do. OpenCV
# names a Bayer mosaic by the second and third pixels of its second row, ROS by its top-left
# 2x2 cell: ROS's rggb is OpenCV's BG, as in cv_bridge (the tests check it on a mosaic).
_BGR_CONVERSION_BY_ENCODING = {
    'rgb8': cv2.COLOR_RGB2BGR,
    'bgra8': cv2.COLOR_BGRA2BGR,
    'rgba8': cv2.COLOR_RGBA2BGR,
    'mono8': cv2.COLOR_GRAY2BGR,
    **{encoding: cv2.COLOR_YUV2BGR_UYVY for encoding in UYVY_ENCODINGS},
    **{encoding: cv2.COLOR_YUV2BGR_YUYV for encoding in YUYV_ENCODINGS},
    'bayer_rggb8': cv2.COLOR_BayerBG2BGR,
    'bayer_bggr8': cv2.COLOR_BayerRG2BGR,
    'bayer_gbrg8': cv2.COLOR_BayerGR2BGR,
    'bayer_grbg8': cv2.COLOR_BayerGB2BGR,
}
COLOUR_ENCODINGS = ('bgr8', *_BGR_CONVERSION_BY_ENCODING)

BGR_CHANNELS = 3

# Messages are written in this machine's byte order, and read in either.
HOST_IS_BIG_ENDIAN = int(sys.byteorder == 'big')


class ImageConversionError(ValueError):
    """An Image message or array cannot be converted; the message says what is wrong."""


def channels_of(encoding):
    """
    Return the number of channels of a supported encoding.

    :param encoding: a sensor_msgs/msg/Image encoding string, such as 'bgr8'.
    :return: 1, 2, 3 or 4.
    :raises ImageConversionError: if the encoding is not one of SUPPORTED_ENCODINGS.
    """
    try:
        return CHANNELS_BY_ENCODING[encoding]
    except (KeyError, TypeError):
        raise ImageConversionError(
            f'Unsupported encoding {encoding!r}; supported encodings are '
            f'{", ".join(SUPPORTED_ENCODINGS)}.') from None


def dtype_of(encoding):
    """
    Return the NumPy element type of a supported encoding.

    :param encoding: one of SUPPORTED_ENCODINGS.
    :return: uint8 for the 8-bit encodings, float32 for 32FC1.
    :raises ImageConversionError: if the encoding is not supported.
    """
    channels_of(encoding)
    return DTYPE_BY_ENCODING.get(encoding, BYTE_DTYPE)


def expected_shape(height, width, encoding):
    """
    Return the array shape that holds an image of this size and encoding.

    :param height: image height in pixels.
    :param width: image width in pixels.
    :param encoding: one of SUPPORTED_ENCODINGS.
    :return: (height, width) for the one-channel encodings (mono8, Bayer, 32FC1), else
        (height, width, channels).
    :raises ImageConversionError: if the encoding is not supported.
    """
    channels = channels_of(encoding)
    if channels == 1:
        return (height, width)
    return (height, width, channels)


def check_array(image, encoding):
    """
    Check that an array holds a non-empty image of the given encoding.

    Only the row and column counts are free (the width even for 4:2:2 YUV); the number of
    dimensions and channels follow from the encoding.

    :param image: the array to check.
    :param encoding: one of SUPPORTED_ENCODINGS.
    :raises ImageConversionError: if the array is not an ndarray of the encoding's element
        type (uint8, or float32 for 32FC1) and shape.
    """
    channels = channels_of(encoding)
    dtype = dtype_of(encoding)
    if not isinstance(image, np.ndarray):
        raise ImageConversionError(
            f'Expected a numpy.ndarray, got {type(image).__name__}.')
    if image.dtype != dtype:
        raise ImageConversionError(
            f'Expected a {dtype} array for encoding {encoding!r}, got dtype {image.dtype}.')
    if channels == 1:
        shape_matches = image.ndim == 2
    else:
        shape_matches = image.ndim == 3 and image.shape[2] == channels
    if not shape_matches:
        needed = '(H, W)' if channels == 1 else f'(H, W, {channels})'
        raise ImageConversionError(
            f'Encoding {encoding!r} needs an array of shape {needed}, got {image.shape}.')
    if image.size == 0:
        raise ImageConversionError(f'Image has zero size: shape {image.shape}.')
    _check_width(image.shape[1], encoding)


def _check_width(width, encoding):
    """Refuse an odd width for 4:2:2 YUV, whose pixels come in pairs sharing their colour."""
    if encoding in YUV422_ENCODINGS and width % YUV422_PIXELS_PER_GROUP:
        raise ImageConversionError(
            f'Encoding {encoding!r} stores pixels in pairs that share their colour, so the '
            f'width must be even; got {width}.')


def flat_bytes(data):
    """
    Return a message's ``uint8[] data`` as a read-only flat uint8 array, copying only if needed.

    rclpy stores such data as array.array('B'), which exposes the buffer protocol and is
    viewed in place; plain lists (from hand-made message-like objects) are copied.

    :param data: the message's data: any buffer of bytes, or a sequence of ints 0-255.
    :return: a one-dimensional read-only uint8 array.
    :raises ImageConversionError: if the data is not a sequence of bytes.
    """
    try:
        flat = np.frombuffer(data, dtype=np.uint8)
    except TypeError:
        try:
            flat = np.asarray(data, dtype=np.uint8).reshape(-1)
        except (TypeError, ValueError, OverflowError) as error:
            raise ImageConversionError(
                f'Image data of type {type(data).__name__} is not a sequence of bytes: '
                f'{error}.') from None
    flat.flags.writeable = False
    return flat


def image_to_array(msg):
    """
    Return a read-only array viewing the pixels of an Image message.

    The array is a view over ``msg.data`` when the data exposes the buffer protocol (as
    rclpy's array.array('B') does): callers must not write to it, and it is marked
    read-only to enforce that. Row padding beyond a row's pixels is skipped by the view's
    strides, so a padded image gives a non-contiguous array. ``is_bigendian`` only matters
    for 32FC1, whose floats are viewed in the byte order the message declares.

    :param msg: a sensor_msgs/msg/Image, or any object with height, width, encoding,
        is_bigendian, step and data.
    :return: shape (height, width, channels) in the message's channel order, or
        (height, width) for mono8, the Bayer mosaics and 32FC1; uint8, or float32 for 32FC1.
        A 4:2:2 YUV image is (height, width, 2) as stored: Y, then U or V, for each pixel.
    :raises ImageConversionError: if the encoding is unsupported, a size is zero, a 4:2:2
        image's width is odd, the step is shorter than a row or not a whole number of
        elements, or the data is shorter than step * height.
    """
    channels = channels_of(msg.encoding)
    dtype = dtype_of(msg.encoding)
    height = int(msg.height)
    width = int(msg.width)
    step = int(msg.step)
    if height < 1 or width < 1:
        raise ImageConversionError(
            f'Image has zero size: height {height}, width {width}.')
    _check_width(width, msg.encoding)
    row_bytes = width * channels * dtype.itemsize
    if step < row_bytes:
        raise ImageConversionError(
            f'Image step {step} is smaller than a row of {row_bytes} bytes '
            f'(width * channels * {dtype.itemsize}).')
    if step % dtype.itemsize:
        raise ImageConversionError(
            f'Image step {step} is not a whole number of {dtype.itemsize}-byte elements.')
    flat = flat_bytes(msg.data)
    needed_bytes = step * height
    if flat.size < needed_bytes:
        raise ImageConversionError(
            f'Image data length {flat.size} is shorter than step*height {needed_bytes}.')
    rows = flat[:needed_bytes].reshape(height, step)[:, :row_bytes]
    if dtype != BYTE_DTYPE:
        byte_order = '>' if msg.is_bigendian else '<'
        rows = rows.view(dtype.newbyteorder(byte_order))
    return rows.reshape(expected_shape(height, width, msg.encoding))


def to_bgr(image, encoding):
    """
    Return a contiguous BGR copy of an image, or the image itself if it already is one.

    Works on any row slice of an image from image_to_array, padded or not. A slice of a Bayer
    mosaic must start on an even row to keep its pattern, and the rows at its edges are
    interpolated without the rows beyond it.

    :param image: a uint8 array of the shape the encoding needs.
    :param encoding: one of COLOUR_ENCODINGS: a 4:2:2 YUV image is converted with BT.601
        (studio range), a Bayer mosaic is demosaiced bilinearly.
    :return: a C-contiguous (H, W, 3) uint8 array. For bgr8 this is ``image`` itself when it
        is already contiguous, so it is as read-only as the input.
    :raises ImageConversionError: if the encoding has no colour (32FC1) or the encoding or
        the array is not valid.
    """
    check_array(image, encoding)
    if encoding not in COLOUR_ENCODINGS:
        raise ImageConversionError(
            f'Encoding {encoding!r} is not a colour image; colour encodings are '
            f'{", ".join(COLOUR_ENCODINGS)}.')
    conversion = _BGR_CONVERSION_BY_ENCODING.get(encoding)
    if conversion is None:
        return np.ascontiguousarray(image)
    return cv2.cvtColor(image, conversion)


# cv2.cvtColor codes that turn an RGB image (a renderer's) into each camera encoding.
_CONVERSION_FROM_RGB = {
    'bgr8': cv2.COLOR_RGB2BGR,
    'bgra8': cv2.COLOR_RGB2BGRA,
    'rgba8': cv2.COLOR_RGB2RGBA,
    'mono8': cv2.COLOR_RGB2GRAY,
    **{encoding: cv2.COLOR_RGB2YUV_UYVY for encoding in UYVY_ENCODINGS},
    **{encoding: cv2.COLOR_RGB2YUV_YUY2 for encoding in YUYV_ENCODINGS},
}
# Which colour plane each pixel of a Bayer pattern's 2x2 cell samples, in RGB order.
_RGB_PLANE = {'r': 0, 'g': 1, 'b': 2}
BAYER_CELL_PX = 2


def from_rgb(image_rgb, encoding, out):
    """
    Write an RGB image in a camera encoding: what a camera of that kind would send of it.

    :param image_rgb: a contiguous (H, W, 3) uint8 RGB image.
    :param encoding: an 8-bit encoding of SUPPORTED_ENCODINGS: 4:2:2 YUV is BT.601 studio
        range, a Bayer mosaic samples each pixel's own plane of its pattern.
    :param out: the array to write, of the encoding's shape (as from :func:`message_pixels`).
    :return: ``out``.
    :raises ImageConversionError: for 32FC1, or arrays of the wrong shape.
    """
    check_array(image_rgb, 'rgb8')
    check_array(out, encoding)
    if out.shape[:2] != image_rgb.shape[:2]:
        raise ImageConversionError(f'The output must be {image_rgb.shape[:2]}, got '
                                   f'{out.shape[:2]}.')
    if encoding == 'rgb8':
        np.copyto(out, image_rgb)
    elif encoding in BAYER_ENCODINGS:
        pattern = encoding.removeprefix('bayer_').removesuffix('8')
        for index, plane in enumerate(pattern):
            row, column = divmod(index, BAYER_CELL_PX)
            out[row::BAYER_CELL_PX, column::BAYER_CELL_PX] = image_rgb[
                row::BAYER_CELL_PX, column::BAYER_CELL_PX, _RGB_PLANE[plane]]
    elif encoding in _CONVERSION_FROM_RGB:
        cv2.cvtColor(image_rgb, _CONVERSION_FROM_RGB[encoding], dst=out)
    else:
        raise ImageConversionError(f'Cannot write an RGB image as {encoding!r}.')
    return out


def array_to_image(image, encoding, msg=None):
    """
    Fill an Image message with a copy of an array's pixels, packed without row padding.

    :param image: an array of the element type and shape the encoding needs, any memory
        layout.
    :param encoding: one of SUPPORTED_ENCODINGS, describing the array's channel order.
    :param msg: an Image to fill, keeping its header; a new Image is made when omitted.
        When its data already has the right length the pixels are copied into it in place,
        the fastest way to publish frame after frame: earlier views of that data (from
        image_to_array) then see the new pixels.
    :return: the filled message (``msg`` itself when given).
    :raises ImageConversionError: if the encoding or the array is not valid.
    """
    check_array(image, encoding)
    if msg is None:
        msg = Image()
    height, width = image.shape[:2]
    _describe_image(msg, height, width, encoding)
    return fill_message_data(msg, image)


def _describe_image(msg, height, width, encoding):
    msg.height = int(height)
    msg.width = int(width)
    msg.encoding = encoding
    msg.is_bigendian = HOST_IS_BIG_ENDIAN
    msg.step = int(width) * channels_of(encoding) * dtype_of(encoding).itemsize


def message_pixels(msg, height, width, encoding):
    """
    Size an Image message for an image and return a writable array over its pixel data.

    A producer then writes the pixels straight into the message (OpenCV's ``dst=``, NumPy's
    ``out=``) instead of into an array of its own that is copied afterwards. The message's
    data is reused when it already has the size, so frame after frame costs no allocation;
    the pixels are undefined until written.

    :param msg: the Image to fill; its header is kept.
    :param height: image height in pixels.
    :param width: image width in pixels.
    :param encoding: one of SUPPORTED_ENCODINGS.
    :return: a C-contiguous array of the shape and element type of the encoding, sharing
        memory with ``msg.data``; valid until ``msg.data`` is replaced.
    :raises ImageConversionError: if the encoding is not supported, a size is not positive,
        or a 4:2:2 image's width is odd.
    """
    if height < 1 or width < 1:
        raise ImageConversionError(f'Image has zero size: height {height}, width {width}.')
    _check_width(width, encoding)
    _describe_image(msg, height, width, encoding)
    size_bytes = msg.step * msg.height
    data = _reusable_data(msg, size_bytes)
    if data is None:
        # The setter copies the array unless the message checks its fields: view what it kept.
        msg.data = array.array('B', bytes(size_bytes))
        data = msg.data
    return np.frombuffer(data, dtype=dtype_of(encoding)).reshape(
        expected_shape(height, width, encoding))


def _reusable_data(msg, size_bytes):
    """Return the message's data when it is an array.array of bytes of this size, else None."""
    existing = msg.data
    if (isinstance(existing, array.array) and existing.typecode == 'B'
            and len(existing) == size_bytes):
        return existing
    return None


def fill_message_data(msg, values):
    """
    Copy an array's bytes into a message's ``uint8[] data`` (an Image's, a PointCloud2's).

    :param msg: the message; its data is overwritten in place when it already has the
        array's length in bytes, else replaced.
    :param values: the array, any element type and memory layout.
    :return: ``msg``.
    """
    # Measured for 640x480x3 on this machine (median, rclpy 7.1.6 message classes):
    # copying into the message's existing array.array('B') in place 26 us (no allocation);
    # array.array.frombytes(ndarray) 43 us, but up to 0.9 ms when each message is dropped
    # right away (glibc then maps and faults fresh pages for every frame);
    # msg.data = ndarray.tobytes() the same, but 78 ms when the message checks its fields
    # (the setter then validates every byte in Python); array.array('B', tobytes()) 0.74 ms.
    # The setter copies an array.array('B') with one memcpy (or keeps it as is when the
    # message checks its fields).
    existing = _reusable_data(msg, values.nbytes)
    if existing is not None:
        np.frombuffer(existing, dtype=values.dtype).reshape(values.shape)[...] = values
        return msg
    data = array.array('B')
    data.frombytes(np.ascontiguousarray(values).reshape(-1).view(np.uint8))
    msg.data = data
    return msg
