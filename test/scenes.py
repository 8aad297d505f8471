"""
Camera images of lines on a floor, drawn from the floor's geometry, for the perception tests.

Every pixel below the horizon is put on the floor (ground_projection's pixel rays, tested on
their own against an independent ray intersection); it takes the line's colour when that floor
point lies within half the line's width of the line's centre polyline. Nothing here uses the
detector's code, so the pictures are a ground truth it is measured against.
"""

import math

from followbot.ground_projection import CameraGeometry
import numpy as np

WIDTH_PX = 640
HEIGHT_PX = 480
# The simulated Kinect: 60 degrees across 640 pixels, 0.30 m up, 0.10 m ahead of the robot's
# centre, tilted down 30 degrees.
KINECT_FOCAL_PX = (WIDTH_PX / 2) / math.tan(math.radians(30.0))
KINECT = CameraGeometry(fx_px=KINECT_FOCAL_PX, fy_px=KINECT_FOCAL_PX, cx_px=(WIDTH_PX - 1) / 2,
                        cy_px=(HEIGHT_PX - 1) / 2, height_m=0.30, pitch_rad=math.radians(30.0),
                        forward_m=0.10)
# The course's tape and floor.
LINE_WIDTH_M = 0.19
YELLOW_BGR = (0, 246, 255)
FLOOR_GREY = 116


def straight_line(lateral_m=0.0, heading_rad=0.0, length_m=50.0):
    """Return the centre of a straight line through (0, lateral) in the robot's frame."""
    direction = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    start = np.array([0.0, lateral_m]) - direction * 0.5
    return [tuple(start), tuple(start + direction * length_m)]


def arc_line(radius_m, lateral_m=0.0, length_m=3.0, points=120):
    """Return the centre of a bend leaving (0, lateral) straight ahead (positive: left)."""
    angles = np.linspace(0.0, length_m / abs(radius_m), points)
    side = math.copysign(1.0, radius_m)
    x_m = abs(radius_m) * np.sin(angles)
    y_m = lateral_m + side * abs(radius_m) * (1.0 - np.cos(angles))
    return [(-0.5, lateral_m)] + list(zip(x_m.tolist(), y_m.tolist()))


def floor_points(geometry=KINECT, size=(WIDTH_PX, HEIGHT_PX)):
    """Return the floor point of every pixel: (x_m, y_m) arrays of the image's shape."""
    width, height = size
    rows, columns = np.mgrid[0:height, 0:width]
    return geometry.pixels_to_floor(columns.astype(float), rows.astype(float))


def distance_to_polyline(x_m, y_m, polyline):
    """Return each floor point's distance to a polyline (NaN points stay NaN)."""
    best = np.full(np.shape(x_m), np.inf)
    for (x0, y0), (x1, y1) in zip(polyline, polyline[1:]):
        dx, dy = x1 - x0, y1 - y0
        length2 = dx * dx + dy * dy
        t = np.clip(((x_m - x0) * dx + (y_m - y0) * dy) / length2, 0.0, 1.0)
        best = np.minimum(best, np.hypot(x_m - (x0 + t * dx), y_m - (y0 + t * dy)))
    return best


def line_mask(polylines, width_m=LINE_WIDTH_M, geometry=KINECT, size=(WIDTH_PX, HEIGHT_PX),
              dash=None, dash_start_m=0.0):
    """
    Return a boolean image of where the line's paint is.

    :param polylines: centre polylines on the floor, (x, y) metres in the robot's frame.
    :param width_m: the line's width.
    :param geometry: the camera.
    :param size: (width, height) of the image.
    :param dash: (dash length, gap length) in metres along x for a dashed line, or None.
    :param dash_start_m: where along x a dash starts (dashes repeat from there both ways).
    :return: (height, width) bool array.
    """
    x_m, y_m = floor_points(geometry, size)
    mask = np.zeros(x_m.shape, bool)
    with np.errstate(invalid='ignore'):
        for polyline in polylines:
            mask |= distance_to_polyline(x_m, y_m, polyline) <= width_m / 2.0
        if dash is not None:
            dash_m, gap_m = dash
            mask &= np.mod(x_m - dash_start_m, dash_m + gap_m) < dash_m
    return mask


def scene(polylines=(), width_m=LINE_WIDTH_M, line_bgr=YELLOW_BGR, floor_bgr=None,
          geometry=KINECT, size=(WIDTH_PX, HEIGHT_PX), dash=None, dash_start_m=0.0,
          above_horizon_bgr=None):
    """
    Return a BGR camera image of lines on a floor.

    :param polylines: the lines' centre polylines on the floor.
    :param width_m: their width.
    :param line_bgr: their colour.
    :param floor_bgr: the floor's colour (the course's grey by default).
    :param geometry: the camera.
    :param size: (width, height) of the image.
    :param dash: (dash, gap) lengths in metres for dashed lines.
    :param dash_start_m: where along x a dash starts.
    :param above_horizon_bgr: the colour of what the camera sees above the floor's horizon
        (walls); the floor's colour by default.
    :return: the (height, width, 3) uint8 image.
    """
    floor_bgr = (FLOOR_GREY,) * 3 if floor_bgr is None else floor_bgr
    width, height = size
    image = np.empty((height, width, 3), np.uint8)
    image[:] = floor_bgr
    if above_horizon_bgr is not None:
        x_m, _ = floor_points(geometry, size)
        image[np.isnan(x_m)] = above_horizon_bgr
    if polylines:
        image[line_mask(polylines, width_m, geometry, size, dash, dash_start_m)] = line_bgr
    return image


def add_noise(image, stddev, seed=0):
    """Return the image with Gaussian camera noise of a standard deviation (8-bit levels)."""
    noise = np.random.default_rng(seed).normal(0.0, stddev, image.shape)
    return np.clip(image + noise, 0, 255).astype(np.uint8)
