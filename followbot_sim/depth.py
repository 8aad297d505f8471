"""
Pinhole geometry of a depth image: from depth to 3-D points in the optical frame, and back.

A pure NumPy module (no ROS, no MuJoCo). Depth is the z coordinate in the camera's optical frame
(REP-103: z forward, x right, y down), in metres, as in a ROS ``32FC1`` depth image; pixel centres
sit at integer coordinates, so pixel (u, v) looks along ((u - cx) / fx, (v - cy) / fy, 1).
"""

import functools
import math

import numpy as np

# Distinct intrinsics kept by the ray cache: a node has one or two cameras; tests try a few.
RAY_CACHE_SIZE = 8


def _check_intrinsics(fx_px: float, fy_px: float, cx_px: float, cy_px: float) -> None:
    if not (math.isfinite(fx_px) and math.isfinite(fy_px) and fx_px > 0.0 and fy_px > 0.0):
        raise ValueError(f'Focal lengths must be positive and finite, got fx={fx_px}, '
                         f'fy={fy_px}.')
    if not (math.isfinite(cx_px) and math.isfinite(cy_px)):
        raise ValueError(f'The principal point must be finite, got ({cx_px}, {cy_px}).')


@functools.lru_cache(maxsize=RAY_CACHE_SIZE)
def _pixel_rays(width_px: int, height_px: int, fx_px: float, fy_px: float, cx_px: float,
                cy_px: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the x and y slopes of the rays through the columns and rows of an image.

    :return: (x / z per column, shape (width,); y / z per row, shape (height, 1)), read-only.
    """
    slope_x = ((np.arange(width_px) - cx_px) / fx_px).astype(np.float32)
    slope_y = ((np.arange(height_px) - cy_px) / fy_px).astype(np.float32)[:, np.newaxis]
    slope_x.setflags(write=False)
    slope_y.setflags(write=False)
    return slope_x, slope_y


def depth_to_points(depth_m: np.ndarray, fx_px: float, fy_px: float, cx_px: float,
                    cy_px: float, out: np.ndarray | None = None) -> np.ndarray:
    """
    Turn a depth image into the 3-D points it sees, in the camera's optical frame.

    NaN depths (nothing measured) give NaN points. The rays of each image size and set of
    intrinsics are computed once and cached.

    :param depth_m: an (H, W) array of depths along the optical axis in metres.
    :param fx_px: focal length along x in pixels.
    :param fy_px: focal length along y in pixels.
    :param cx_px: principal point column in pixels.
    :param cy_px: principal point row in pixels.
    :param out: an optional C-contiguous float32 (H, W, 3) array to fill and return.
    :return: a float32 (H, W, 3) array of (x right, y down, z forward) in metres.
    :raises ValueError: for a depth image that is not 2-D, bad intrinsics or an ``out`` of the
        wrong shape or type.
    """
    depth_m = np.asarray(depth_m, dtype=np.float32)
    if depth_m.ndim != 2:
        raise ValueError(f'depth_m must be a 2-D (H, W) image, got shape {depth_m.shape}.')
    _check_intrinsics(fx_px, fy_px, cx_px, cy_px)
    height_px, width_px = depth_m.shape
    if out is None:
        out = np.empty((height_px, width_px, 3), np.float32)
    elif (out.shape != (height_px, width_px, 3) or out.dtype != np.float32
            or not out.flags.c_contiguous):
        raise ValueError(f'out must be a C-contiguous float32 array of shape '
                         f'{(height_px, width_px, 3)}, got {out.dtype} {out.shape}.')
    slope_x, slope_y = _pixel_rays(width_px, height_px, float(fx_px), float(fy_px),
                                   float(cx_px), float(cy_px))
    np.multiply(depth_m, slope_x, out=out[..., 0])
    np.multiply(depth_m, slope_y, out=out[..., 1])
    out[..., 2] = depth_m
    return out


def project_points_px(points_xyz_m, fx_px: float, fy_px: float, cx_px: float,
                      cy_px: float) -> np.ndarray:
    """
    Project points given in a camera's optical frame to pixel coordinates.

    The inverse of :func:`depth_to_points` for points in front of the camera; points at or
    behind the camera plane (z <= 0) give NaN.

    :param points_xyz_m: an array of shape (..., 3) in the optical frame, metres.
    :param fx_px: focal length along x in pixels.
    :param fy_px: focal length along y in pixels.
    :param cx_px: principal point column in pixels.
    :param cy_px: principal point row in pixels.
    :return: a float array of shape (..., 2): (column, row), pixel centres at integers.
    :raises ValueError: for points whose last axis is not 3, or bad intrinsics.
    """
    points_xyz_m = np.asarray(points_xyz_m, dtype=float)
    if points_xyz_m.shape[-1:] != (3,):
        raise ValueError(f'Points must have shape (..., 3), got {points_xyz_m.shape}.')
    _check_intrinsics(fx_px, fy_px, cx_px, cy_px)
    depth_m = points_xyz_m[..., 2]
    in_front = depth_m > 0.0
    safe_depth_m = np.where(in_front, depth_m, 1.0)
    pixels_px = np.stack([cx_px + fx_px * points_xyz_m[..., 0] / safe_depth_m,
                          cy_px + fy_px * points_xyz_m[..., 1] / safe_depth_m], axis=-1)
    pixels_px[~in_front] = np.nan
    return pixels_px
