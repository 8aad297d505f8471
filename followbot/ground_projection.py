"""
Project image pixels onto the floor, in the robot's frame.

A pinhole camera (intrinsics from its CameraInfo) mounted ``height_m`` above the floor,
``forward_m`` ahead of the robot's centre and tilted down by ``pitch_rad`` sees the floor
point of pixel (u, v) where the pixel's ray meets the floor. Points are returned in the
robot's base_footprint frame (REP-103): x forward, y to the left, in metres.

:class:`CameraIntrinsics` reads a ``sensor_msgs/CameraInfo`` as REP-104 and image_geometry's
PinholeCameraModel do (binning and region of interest shrink and shift the image; ``D`` with
the ``plumb_bob``, ``rational_polynomial`` or ``equidistant`` model undistorts pixels) and
refuses what no camera can be: focal lengths that give a field of view outside 1-179 degrees,
a principal point outside the image, non-finite numbers. A message from a broken driver must
not steer the robot.
"""

from dataclasses import dataclass
import math

import cv2
import numpy as np

# Distortion models of sensor_msgs/distortion_models.hpp and how many coefficients each takes.
DISTORTION_COEFFICIENTS = {'plumb_bob': 5, 'rational_polynomial': 8, 'equidistant': 4}
# A camera's field of view across the image lies between these (a pinhole cannot reach 180).
MIN_FIELD_OF_VIEW_DEG = 1.0
MAX_FIELD_OF_VIEW_DEG = 179.0
# Pixels are nearly square: fy / fx within these bounds.
MAX_PIXEL_ASPECT = 4.0
# Binning of 0 or 1 means none (REP-104).
NO_BINNING = 1


class CameraInfoError(ValueError):
    """A CameraInfo describes no usable camera; the message says what is wrong."""


def _finite(name, values):
    numbers = [float(value) for value in values]
    if not all(math.isfinite(value) for value in numbers):
        raise CameraInfoError(f'{name} has a non-finite number: {numbers}.')
    return numbers


@dataclass(frozen=True)
class CameraIntrinsics:
    """
    What a camera's image is: its size, pinhole intrinsics and lens distortion.

    ``width_px`` and ``height_px`` are 0 when the CameraInfo did not say; ``distortion`` is
    empty for an ideal pinhole.
    """

    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion_model: str = ''
    distortion: tuple = ()

    def __post_init__(self):
        """Refuse intrinsics no camera has."""
        for name in ('fx_px', 'fy_px', 'cx_px', 'cy_px'):
            if not math.isfinite(getattr(self, name)):
                raise CameraInfoError(f'{name} must be finite, got {getattr(self, name)}.')
        if self.fx_px <= 0.0 or self.fy_px <= 0.0:
            raise CameraInfoError(
                f'The focal lengths must be positive, got fx {self.fx_px}, fy {self.fy_px}.')
        if self.width_px < 0 or self.height_px < 0:
            raise CameraInfoError(
                f'The image size must not be negative, got {self.width_px}x{self.height_px}.')
        if self.width_px and self.height_px:
            self.check_image_size(self.width_px, self.height_px)
        aspect = self.fy_px / self.fx_px
        if not 1.0 / MAX_PIXEL_ASPECT <= aspect <= MAX_PIXEL_ASPECT:
            raise CameraInfoError(
                f'fy / fx is {aspect:.3g}: pixels that far from square are not a camera.')
        if self.distortion:
            expected = DISTORTION_COEFFICIENTS.get(self.distortion_model)
            if expected is None:
                raise CameraInfoError(
                    f'Unknown distortion model {self.distortion_model!r} with non-zero D; '
                    f'known models: {", ".join(DISTORTION_COEFFICIENTS)}.')
            if len(self.distortion) < expected:
                raise CameraInfoError(
                    f'The {self.distortion_model} model needs {expected} coefficients in D, '
                    f'got {len(self.distortion)}.')
            _finite('D', self.distortion)

    @classmethod
    def from_camera_info(cls, info) -> 'CameraIntrinsics':
        """
        Read the intrinsics of the image a CameraInfo describes, binning and ROI applied.

        :param info: a sensor_msgs/msg/CameraInfo (or an object with its fields).
        :return: the intrinsics of the published image.
        :raises CameraInfoError: if the message describes no usable camera.
        """
        k = list(info.k)
        if len(k) != 9:
            raise CameraInfoError(f'K must have 9 elements, got {len(k)}.')
        fx, _, cx, _, fy, cy, _, _, _ = _finite('K', k)
        binning_x = max(int(info.binning_x), NO_BINNING)
        binning_y = max(int(info.binning_y), NO_BINNING)
        width, height = int(info.width), int(info.height)
        roi = info.roi
        if roi.width and roi.height:
            # REP-104: the image is the region of interest of the full-resolution sensor.
            cx, cy = cx - int(roi.x_offset), cy - int(roi.y_offset)
            width, height = int(roi.width), int(roi.height)
        distortion = tuple(_finite('D', info.d))
        if not any(distortion):
            distortion = ()
        return cls(width_px=width // binning_x, height_px=height // binning_y,
                   fx_px=fx / binning_x, fy_px=fy / binning_y,
                   cx_px=cx / binning_x, cy_px=cy / binning_y,
                   distortion_model=str(info.distortion_model), distortion=distortion)

    def check_image_size(self, width_px: int, height_px: int) -> None:
        """
        Check that these intrinsics can describe an image of a size.

        :param width_px: the image's width.
        :param height_px: the image's height.
        :raises CameraInfoError: if the CameraInfo gave another size, or the focal lengths or
            the principal point do not fit an image of this size.
        """
        if self.width_px and self.height_px and (
                (self.width_px, self.height_px) != (width_px, height_px)):
            raise CameraInfoError(
                f'camera_info describes a {self.width_px}x{self.height_px} image, but the '
                f'image is {width_px}x{height_px}.')
        for axis, size, focal in (('horizontal', width_px, self.fx_px),
                                  ('vertical', height_px, self.fy_px)):
            field_of_view_deg = math.degrees(2.0 * math.atan(size / (2.0 * focal)))
            if not MIN_FIELD_OF_VIEW_DEG <= field_of_view_deg <= MAX_FIELD_OF_VIEW_DEG:
                raise CameraInfoError(
                    f'The focal length {focal:.6g} px gives a {axis} field of view of '
                    f'{field_of_view_deg:.3g} degrees over {size} px: no camera sees that.')
        if not (0.0 <= self.cx_px <= width_px and 0.0 <= self.cy_px <= height_px):
            raise CameraInfoError(
                f'The principal point ({self.cx_px:.1f}, {self.cy_px:.1f}) lies outside the '
                f'{width_px}x{height_px} image.')

    def undistort(self, u_px, v_px):
        """
        Return where pixels would be in an ideal pinhole image with the same K.

        :param u_px: pixel columns (array-like).
        :param v_px: pixel rows (array-like), the same shape.
        :return: (u_px, v_px) float arrays; the input itself (as floats) without distortion.
        """
        u_px = np.asarray(u_px, dtype=float)
        v_px = np.asarray(v_px, dtype=float)
        if not self.distortion or u_px.size == 0:
            return u_px, v_px
        points = np.stack((u_px.reshape(-1), v_px.reshape(-1)), axis=1).reshape(-1, 1, 2)
        matrix = np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px],
                           [0.0, 0.0, 1.0]])
        coefficients = np.asarray(self.distortion, dtype=float)
        if self.distortion_model == 'equidistant':
            ideal = cv2.fisheye.undistortPoints(points, matrix, coefficients[:4], P=matrix)
        else:
            ideal = cv2.undistortPoints(points, matrix, coefficients, P=matrix)
        ideal = ideal.reshape(-1, 2)
        return ideal[:, 0].reshape(u_px.shape), ideal[:, 1].reshape(v_px.shape)


@dataclass(frozen=True)
class CameraGeometry:
    """A pinhole camera's intrinsics and its mounting on the robot."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    height_m: float
    pitch_rad: float
    forward_m: float = 0.0
    intrinsics: CameraIntrinsics | None = None

    def __post_init__(self):
        """Reject geometry with which no pixel can be projected."""
        for name in ('fx_px', 'fy_px', 'height_m'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be finite and positive, got {value}.')
        for name in ('cx_px', 'cy_px', 'pitch_rad', 'forward_m'):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f'{name} must be finite, got {getattr(self, name)}.')

    @classmethod
    def from_camera_matrix(cls, k, height_m, pitch_rad, forward_m=0.0):
        """
        Make the geometry from a CameraInfo's row-major 3x3 intrinsic matrix K.

        :param k: the nine numbers of K (fx 0 cx / 0 fy cy / 0 0 1).
        :param height_m: height of the camera above the floor.
        :param pitch_rad: downward tilt of the optical axis from the horizontal.
        :param forward_m: distance of the camera ahead of the robot's centre.
        :return: the CameraGeometry.
        :raises ValueError: if K is not nine numbers or has no positive focal lengths.
        """
        if len(k) != 9:
            raise ValueError(f'K must have 9 elements, got {len(k)}.')
        return cls(fx_px=float(k[0]), fy_px=float(k[4]), cx_px=float(k[2]),
                   cy_px=float(k[5]), height_m=height_m, pitch_rad=pitch_rad,
                   forward_m=forward_m)

    @classmethod
    def from_intrinsics(cls, intrinsics, height_m, pitch_rad, forward_m=0.0):
        """
        Make the geometry of a camera with known intrinsics mounted on the robot.

        :param intrinsics: the CameraIntrinsics (from the camera's CameraInfo).
        :param height_m: height of the camera above the floor.
        :param pitch_rad: downward tilt of the optical axis from the horizontal.
        :param forward_m: distance of the camera ahead of the robot's centre.
        :return: the CameraGeometry; its pixels are undistorted before projection.
        """
        return cls(fx_px=intrinsics.fx_px, fy_px=intrinsics.fy_px, cx_px=intrinsics.cx_px,
                   cy_px=intrinsics.cy_px, height_m=height_m, pitch_rad=pitch_rad,
                   forward_m=forward_m, intrinsics=intrinsics)

    @property
    def horizon_row_px(self) -> float:
        """Return the image row of the floor's horizon (rows below it see the floor)."""
        return self.cy_px - self.fy_px * math.tan(self.pitch_rad)

    def line_width_px(self, v_px, width_m):
        """
        Return how wide, along a row, a line of a width running straight ahead looks.

        :param v_px: image rows (array-like).
        :param width_m: the line's width on the floor.
        :return: the widths in pixels; 0 at and above the horizon.
        """
        down = (np.asarray(v_px, dtype=float) - self.cy_px) / self.fy_px
        descent = math.sin(self.pitch_rad) + math.cos(self.pitch_rad) * down
        return np.maximum(descent, 0.0) * self.fx_px * width_m / self.height_m

    def across_line_rows_px(self, v_px, width_m):
        """
        Return how many rows a line of a width running across the view spans at given rows.

        :param v_px: image rows (array-like).
        :param width_m: the line's width on the floor.
        :return: its thickness in rows, centred on each row; 0 at and above the horizon.
        """
        v_px = np.asarray(v_px, dtype=float)
        down_rad = np.arctan((v_px - self.cy_px) / self.fy_px)
        below_horizon_rad = self.pitch_rad + down_rad
        with np.errstate(divide='ignore', invalid='ignore'):
            ahead_m = np.where(below_horizon_rad > 0.0,
                               self.height_m / np.tan(below_horizon_rad), np.inf)
            # Past the camera's foot (a camera looking down beyond the vertical) the floor's
            # distance ahead is negative; arctan2 keeps its angles right there too.
            near_rad = np.arctan2(self.height_m, ahead_m - width_m / 2.0)
            far_rad = np.arctan2(self.height_m, ahead_m + width_m / 2.0)
            rows = self.fy_px * (np.tan(near_rad - self.pitch_rad)
                                 - np.tan(far_rad - self.pitch_rad))
        return np.where(below_horizon_rad > 0.0, rows, 0.0)

    def floor_point(self, u_px: float, v_px: float) -> tuple[float, float]:
        """
        Return the floor point one pixel sees, as :meth:`pixels_to_floor` does, for one pixel.

        Plain float arithmetic: a few microseconds, where arrays cost tens for a few points.

        :param u_px: the pixel's column.
        :param v_px: the pixel's row.
        :return: (x_m, y_m) in the robot's frame; NaNs at or above the horizon.
        """
        if self.intrinsics is not None and self.intrinsics.distortion:
            x_m, y_m = self.pixels_to_floor(u_px, v_px)
            return float(x_m), float(y_m)
        down = (v_px - self.cy_px) / self.fy_px
        cos_pitch, sin_pitch = math.cos(self.pitch_rad), math.sin(self.pitch_rad)
        descent = sin_pitch + cos_pitch * down
        if descent <= 0.0:
            return math.nan, math.nan
        scale_m = self.height_m / descent
        return (self.forward_m + scale_m * (cos_pitch - sin_pitch * down),
                -scale_m * (u_px - self.cx_px) / self.fx_px)

    def pixels_to_floor(self, u_px, v_px):
        """
        Return the floor points that pixels see, in the robot's frame.

        :param u_px: pixel columns (array-like), x to the right.
        :param v_px: pixel rows (array-like), y down.
        :return: (x_m, y_m) float arrays: forward and leftward distances from the robot's
            centre; NaN for pixels at or above the horizon, whose rays never meet the floor.
        """
        if self.intrinsics is not None:
            u_px, v_px = self.intrinsics.undistort(u_px, v_px)
        right = (np.asarray(u_px, dtype=float) - self.cx_px) / self.fx_px
        down = (np.asarray(v_px, dtype=float) - self.cy_px) / self.fy_px
        cos_pitch, sin_pitch = math.cos(self.pitch_rad), math.sin(self.pitch_rad)
        # The ray (right, down, 1) of the optical frame in the robot's frame: the optical axis
        # points forward and down by the pitch, image down points down and back.
        forward = cos_pitch - sin_pitch * down
        left = -right
        descent = sin_pitch + cos_pitch * down
        with np.errstate(divide='ignore', invalid='ignore'):
            scale_m = np.where(descent > 0.0, self.height_m / descent, np.nan)
        return self.forward_m + scale_m * forward, scale_m * left
