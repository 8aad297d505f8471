"""
Convert between sensor_msgs/msg/Image and NumPy arrays, replacing cv_bridge.

cv_bridge is not available without a ROS install and breaks under NumPy 2, so followbot owns
the small part of it that it needs: the 8-bit colour and mono encodings, and 32FC1 for depth
images in metres. Row padding (``step``) and byte order are honoured, every field is validated,
and one error type is raised.
"""

import array
import sys

import cv2
import numpy as np
from sensor_msgs.msg import Image

SUPPORTED_ENCODINGS = ('bgr8', 'rgb8', 'bgra8', 'rgba8', 'mono8', '32FC1')

CHANNELS_BY_ENCODING = {
    'bgr8': 3,
    'rgb8': 3,
    'bgra8': 4,
    'rgba8': 4,
    'mono8': 1,
    '32FC1': 1,
}

# Element type of each channel; 32FC1 is a float32 per pixel (depth in metres, NaN = no return).
DTYPE_BY_ENCODING = {
    '32FC1': np.dtype(np.float32),
}
BYTE_DTYPE = np.dtype(np.uint8)

# cv2.cvtColor codes that turn each encoding into BGR; bgr8 needs no conversion.
_BGR_CONVERSION_BY_ENCODING = {
    'rgb8': cv2.COLOR_RGB2BGR,
    'bgra8': cv2.COLOR_BGRA2BGR,
    'rgba8': cv2.COLOR_RGBA2BGR,
    'mono8': cv2.COLOR_GRAY2BGR,
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
    :return: 1, 3 or 4.
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
    :return: (height, width) for mono8, else (height, width, channels).
    :raises ImageConversionError: if the encoding is not supported.
    """
    channels = channels_of(encoding)
    if channels == 1:
        return (height, width)
    return (height, width, channels)


def check_array(image, encoding):
    """
    Check that an array holds a non-empty image of the given encoding.

    Only the row and column counts are free; the number of dimensions and channels follow
    from the encoding.

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


def _as_flat_bytes(data):
    """
    Return the message data as a read-only flat uint8 array, without copying if possible.

    rclpy stores Image.data as array.array('B'), which exposes the buffer protocol; plain
    lists (from hand-made message-like objects) are copied.
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
        (height, width) for mono8 and 32FC1; uint8, or float32 for 32FC1.
    :raises ImageConversionError: if the encoding is unsupported, a size is zero, the step
        is shorter than a row or not a whole number of elements, or the data is shorter than
        step * height.
    """
    channels = channels_of(msg.encoding)
    dtype = dtype_of(msg.encoding)
    height = int(msg.height)
    width = int(msg.width)
    step = int(msg.step)
    if height < 1 or width < 1:
        raise ImageConversionError(
            f'Image has zero size: height {height}, width {width}.')
    row_bytes = width * channels * dtype.itemsize
    if step < row_bytes:
        raise ImageConversionError(
            f'Image step {step} is smaller than a row of {row_bytes} bytes '
            f'(width * channels * {dtype.itemsize}).')
    if step % dtype.itemsize:
        raise ImageConversionError(
            f'Image step {step} is not a whole number of {dtype.itemsize}-byte elements.')
    flat = _as_flat_bytes(msg.data)
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

    Works on any row slice of an image from image_to_array, padded or not.

    :param image: a uint8 array of the shape the encoding needs.
    :param encoding: one of COLOUR_ENCODINGS.
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
    :raises ImageConversionError: if the encoding is not supported or a size is not positive.
    """
    if height < 1 or width < 1:
        raise ImageConversionError(f'Image has zero size: height {height}, width {width}.')
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
