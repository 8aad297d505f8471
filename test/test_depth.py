"""Tests of the depth image geometry of followbot_sim.depth: depth to points and back."""

import math

from followbot_sim.depth import depth_to_points
from followbot_sim.depth import project_points_px
import numpy as np
import pytest

# A 640x480 Kinect-like camera (60 degrees across) and a small one with an off-centre principal
# point and non-square pixels.
INTRINSICS_CASES = [
    ((640, 480), (554.2562584220407, 554.2562584220407, 319.5, 239.5)),
    ((40, 30), (50.0, 60.0, 17.0, 16.5)),
]
SEED = 3


@pytest.mark.parametrize('pixel_px, depth_m, point_m', [
    ((319.5, 239.5), 2.0, (0.0, 0.0, 2.0)),
    ((319.5 + 554.0, 239.5), 1.0, (1.0, 0.0, 1.0)),
    ((319.5, 239.5 - 277.0), 3.0, (0.0, -1.5, 3.0)),
])
def test_known_points_project_to_known_pixels(pixel_px, depth_m, point_m):
    intrinsics = (554.0, 554.0, 319.5, 239.5)
    assert project_points_px(point_m, *intrinsics) == pytest.approx(pixel_px)


@pytest.mark.parametrize('size_px, intrinsics', INTRINSICS_CASES)
def test_points_project_back_to_their_pixels(size_px, intrinsics):
    width_px, height_px = size_px
    depth_m = np.random.default_rng(SEED).uniform(0.3, 8.0, (height_px, width_px))
    points_m = depth_to_points(depth_m.astype(np.float32), *intrinsics)
    rows, columns = np.mgrid[0:height_px, 0:width_px]
    pixels_px = project_points_px(points_m, *intrinsics)
    # Whole-image comparisons: numpy's assertion is fast where pytest.approx is not.
    np.testing.assert_allclose(pixels_px[..., 0], columns, atol=1e-3)
    np.testing.assert_allclose(pixels_px[..., 1], rows, atol=1e-3)
    np.testing.assert_allclose(points_m[..., 2], depth_m, rtol=1e-6)


@pytest.mark.parametrize('size_px, intrinsics', INTRINSICS_CASES)
def test_known_points_round_trip_through_a_depth_image(size_px, intrinsics):
    width_px, height_px = size_px
    fx_px, fy_px, cx_px, cy_px = intrinsics
    # Points chosen on pixel rays: (column, row, depth).
    samples = [(0, 0, 0.5), (width_px - 1, height_px - 1, 4.0), (width_px // 2, 3, 7.5)]
    depth_m = np.full((height_px, width_px), np.nan, np.float32)
    for column, row, depth in samples:
        depth_m[row, column] = depth
    points_m = depth_to_points(depth_m, *intrinsics)
    for column, row, depth in samples:
        expected_m = ((column - cx_px) * depth / fx_px, (row - cy_px) * depth / fy_px, depth)
        assert points_m[row, column] == pytest.approx(expected_m, rel=1e-6)


def test_nan_depths_give_nan_points():
    depth_m = np.ones((4, 5), np.float32)
    depth_m[1, 2] = np.nan
    points_m = depth_to_points(depth_m, 5.0, 5.0, 2.0, 1.5)
    assert np.all(np.isnan(points_m[1, 2]))
    assert np.count_nonzero(np.isnan(points_m)) == 3
    assert points_m.dtype == np.float32


def test_output_array_is_filled_and_returned():
    depth_m = np.full((3, 4), 2.0, np.float32)
    out = np.zeros((3, 4, 3), np.float32)
    assert depth_to_points(depth_m, 4.0, 4.0, 1.5, 1.0, out=out) is out
    assert out[..., 2] == pytest.approx(np.full((3, 4), 2.0))


def test_points_behind_the_camera_do_not_project():
    pixels_px = project_points_px([[0.0, 0.0, -1.0], [0.1, 0.0, 0.0], [0.0, 0.0, 1.0]],
                                  100.0, 100.0, 50.0, 50.0)
    assert np.all(np.isnan(pixels_px[:2]))
    assert pixels_px[2] == pytest.approx((50.0, 50.0))


@pytest.mark.parametrize('depth_m, intrinsics, out', [
    (np.ones((3, 4, 1), np.float32), (4.0, 4.0, 1.5, 1.0), None),
    (np.ones((3, 4), np.float32), (0.0, 4.0, 1.5, 1.0), None),
    (np.ones((3, 4), np.float32), (4.0, -4.0, 1.5, 1.0), None),
    (np.ones((3, 4), np.float32), (4.0, 4.0, math.nan, 1.0), None),
    (np.ones((3, 4), np.float32), (4.0, 4.0, 1.5, 1.0), np.zeros((4, 3, 3), np.float32)),
    (np.ones((3, 4), np.float32), (4.0, 4.0, 1.5, 1.0), np.zeros((3, 4, 3), np.float64)),
], ids=['3-d-depth', 'zero-fx', 'negative-fy', 'nan-cx', 'out-shape', 'out-dtype'])
def test_bad_inputs_are_rejected(depth_m, intrinsics, out):
    with pytest.raises(ValueError):
        depth_to_points(depth_m, *intrinsics, out=out)


def test_projecting_needs_three_coordinates():
    with pytest.raises(ValueError, match=r'\(\.\.\., 3\)'):
        project_points_px([[1.0, 2.0]], 4.0, 4.0, 1.5, 1.0)
