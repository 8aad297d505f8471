"""
Project image pixels onto the floor, in the robot's frame.

A pinhole camera (intrinsics from its CameraInfo) mounted ``height_m`` above the floor,
``forward_m`` ahead of the robot's centre and tilted down by ``pitch_rad`` sees the floor
point of pixel (u, v) where the pixel's ray meets the floor. Points are returned in the
robot's base_footprint frame (REP-103): x forward, y to the left, in metres.
"""

from dataclasses import dataclass
import math

import numpy as np


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

    def pixels_to_floor(self, u_px, v_px):
        """
        Return the floor points that pixels see, in the robot's frame.

        :param u_px: pixel columns (array-like), x to the right.
        :param v_px: pixel rows (array-like), y down.
        :return: (x_m, y_m) float arrays: forward and leftward distances from the robot's
            centre; NaN for pixels at or above the horizon, whose rays never meet the floor.
        """
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
