"""Tests of the frame names, rigid transforms and quaternion helpers of followbot.frames."""

import math

from followbot.frames import BASE_FOOTPRINT_FRAME
from followbot.frames import BASE_LINK_FRAME
from followbot.frames import CAMERA_LINK_FRAME
from followbot.frames import CAMERA_RGB_FRAME
from followbot.frames import CAMERA_RGB_OPTICAL_FRAME
from followbot.frames import chain_transforms
from followbot.frames import FrameTransform
from followbot.frames import matrix_from_quaternion
from followbot.frames import ODOM_FRAME
from followbot.frames import optical_rotation_xyzw
from followbot.frames import quaternion_from_matrix
from followbot.frames import quaternion_from_rpy
from followbot.frames import quaternion_from_yaw
from followbot.frames import WORLD_FRAME
from followbot.frames import yaw_from_quaternion
import numpy as np
import pytest

# (roll, pitch, yaw) in radians: ordinary angles, and rotations by pi about each axis, where
# a quaternion's w is zero and the trace-based formula alone breaks down.
RPY_CASES_RAD = [
    (0.0, 0.0, 0.0),
    (0.3, -0.2, 2.9),
    (-1.2, 0.7, -0.4),
    (math.pi, 0.0, 0.0),
    (0.0, math.pi, 0.0),
    (0.0, 0.0, math.pi),
    (math.pi / 2.0, 0.0, math.pi / 2.0),
    (0.1, math.pi / 2.0 - 1e-9, 0.2),
]
YAW_CASES_RAD = [0.0, 0.5, math.pi / 2.0, -math.pi / 2.0, 3.0, -3.0]
TOLERANCE = 1e-12


def rotation_about(axis, angle_rad):
    """
    Build the rotation matrix about a coordinate axis.

    :param axis: 0, 1 or 2 for x, y or z.
    :param angle_rad: angle in radians, right-handed.
    :return: a 3x3 array.
    """
    cos_angle, sin_angle = math.cos(angle_rad), math.sin(angle_rad)
    first, second = (axis + 1) % 3, (axis + 2) % 3
    matrix = np.eye(3)
    matrix[first, first] = matrix[second, second] = cos_angle
    matrix[second, first] = sin_angle
    matrix[first, second] = -sin_angle
    return matrix


def rpy_matrix(roll_rad, pitch_rad, yaw_rad):
    """Return Rz(yaw) Ry(pitch) Rx(roll), the URDF convention, built from axis rotations."""
    return rotation_about(2, yaw_rad) @ rotation_about(1, pitch_rad) @ rotation_about(0, roll_rad)


def camera_chain():
    """Return a small robot tree: base_footprint -> base_link -> camera_link -> rgb frames."""
    return [
        FrameTransform(BASE_FOOTPRINT_FRAME, BASE_LINK_FRAME, (0.0, 0.0, 0.01)),
        FrameTransform(BASE_LINK_FRAME, CAMERA_LINK_FRAME, (0.1, 0.0, 0.3),
                       quaternion_from_rpy(0.0, 0.4, 0.0)),
        FrameTransform(CAMERA_LINK_FRAME, CAMERA_RGB_FRAME, (0.0, -0.0125, 0.0)),
        FrameTransform(CAMERA_RGB_FRAME, CAMERA_RGB_OPTICAL_FRAME,
                       rotation_xyzw=optical_rotation_xyzw()),
    ]


@pytest.mark.parametrize('yaw_rad', YAW_CASES_RAD)
def test_yaw_quaternion_turns_x_axis_to_heading(yaw_rad):
    rotation = matrix_from_quaternion(quaternion_from_yaw(yaw_rad))
    assert rotation @ (1.0, 0.0, 0.0) == pytest.approx(
        (math.cos(yaw_rad), math.sin(yaw_rad), 0.0), abs=TOLERANCE)
    assert rotation @ (0.0, 0.0, 1.0) == pytest.approx((0.0, 0.0, 1.0), abs=TOLERANCE)


@pytest.mark.parametrize('yaw_rad', YAW_CASES_RAD)
def test_yaw_is_read_back_from_its_quaternion(yaw_rad):
    assert yaw_from_quaternion(quaternion_from_yaw(yaw_rad)) == pytest.approx(yaw_rad)


@pytest.mark.parametrize('roll_rad, pitch_rad, yaw_rad', RPY_CASES_RAD)
def test_rpy_quaternion_matches_fixed_axis_rotations(roll_rad, pitch_rad, yaw_rad):
    rotation = matrix_from_quaternion(quaternion_from_rpy(roll_rad, pitch_rad, yaw_rad))
    assert rotation == pytest.approx(rpy_matrix(roll_rad, pitch_rad, yaw_rad), abs=1e-9)


@pytest.mark.parametrize('roll_rad, pitch_rad, yaw_rad', RPY_CASES_RAD)
def test_matrix_to_quaternion_round_trips(roll_rad, pitch_rad, yaw_rad):
    rotation = rpy_matrix(roll_rad, pitch_rad, yaw_rad)
    quaternion = quaternion_from_matrix(rotation)
    assert math.fsum(value * value for value in quaternion) == pytest.approx(1.0)
    assert quaternion[3] >= 0.0
    assert matrix_from_quaternion(quaternion) == pytest.approx(rotation, abs=1e-9)


@pytest.mark.parametrize('matrix', [
    np.diag([1.0, 1.0, -1.0]),
    2.0 * np.eye(3),
    np.eye(4),
    np.full((3, 3), np.nan),
], ids=['reflection', 'scaled', '4x4', 'nan'])
def test_non_rotations_are_rejected(matrix):
    with pytest.raises(ValueError):
        quaternion_from_matrix(matrix)


def test_optical_frame_looks_forward_with_image_right_and_down():
    # Columns: the optical frame's x (image right), y (image down), z (optical axis) in the
    # body frame (x forward, y left, z up).
    rotation = matrix_from_quaternion(optical_rotation_xyzw())
    assert rotation[:, 0] == pytest.approx((0.0, -1.0, 0.0), abs=TOLERANCE)
    assert rotation[:, 1] == pytest.approx((0.0, 0.0, -1.0), abs=TOLERANCE)
    assert rotation[:, 2] == pytest.approx((1.0, 0.0, 0.0), abs=TOLERANCE)


def test_transform_maps_child_points_into_parent():
    transform = FrameTransform(WORLD_FRAME, BASE_FOOTPRINT_FRAME, (1.0, 2.0, 0.0),
                               quaternion_from_yaw(math.pi / 2.0))
    # One metre ahead of a robot facing +y lies one metre further along +y.
    assert transform.transform_points([1.0, 0.0, 0.0]) == pytest.approx((1.0, 3.0, 0.0))
    assert transform.transform_points([[0.0, 1.0, 0.5]]) == pytest.approx(
        np.array([[0.0, 2.0, 0.5]]))


def test_planar_transform_is_a_floor_pose():
    transform = FrameTransform.planar(ODOM_FRAME, BASE_FOOTPRINT_FRAME, 1.5, -2.0, 0.7)
    assert transform.translation_m == (1.5, -2.0, 0.0)
    assert transform.rotation_xyzw == pytest.approx(quaternion_from_yaw(0.7))


def test_matrix_holds_rotation_and_translation():
    transform = FrameTransform(WORLD_FRAME, ODOM_FRAME, (1.0, 2.0, 3.0),
                               quaternion_from_rpy(0.1, 0.2, 0.3))
    matrix = transform.as_matrix()
    assert matrix[:3, :3] == pytest.approx(rpy_matrix(0.1, 0.2, 0.3))
    assert matrix[:3, 3] == pytest.approx((1.0, 2.0, 3.0))
    assert matrix[3] == pytest.approx((0.0, 0.0, 0.0, 1.0))


def test_inverse_undoes_the_transform():
    transform = FrameTransform(WORLD_FRAME, ODOM_FRAME, (1.0, -2.0, 0.5),
                               quaternion_from_rpy(0.4, -0.3, 2.0))
    inverse = transform.inverse()
    assert (inverse.parent, inverse.child) == (ODOM_FRAME, WORLD_FRAME)
    assert transform.as_matrix() @ inverse.as_matrix() == pytest.approx(np.eye(4), abs=1e-12)


def test_compose_chains_parent_to_grandchild():
    first, second = camera_chain()[1:3]
    composed = first.compose(second)
    assert (composed.parent, composed.child) == (BASE_LINK_FRAME, CAMERA_RGB_FRAME)
    assert composed.as_matrix() == pytest.approx(first.as_matrix() @ second.as_matrix())


def test_compose_rejects_transforms_that_do_not_meet():
    first, _, third, _ = camera_chain()
    with pytest.raises(ValueError, match='must start at'):
        first.compose(third)


def test_chain_follows_the_tree_down():
    transforms = camera_chain()
    chained = chain_transforms(transforms, BASE_FOOTPRINT_FRAME, CAMERA_RGB_OPTICAL_FRAME)
    expected = np.eye(4)
    for transform in transforms:
        expected = expected @ transform.as_matrix()
    assert (chained.parent, chained.child) == (BASE_FOOTPRINT_FRAME, CAMERA_RGB_OPTICAL_FRAME)
    assert chained.as_matrix() == pytest.approx(expected)


def test_chain_walks_up_and_down_the_tree():
    # Two cameras on one link: the transform between them climbs to the link and descends.
    transforms = camera_chain() + [
        FrameTransform(CAMERA_LINK_FRAME, 'camera_depth_frame', (0.0, 0.0125, 0.0))]
    chained = chain_transforms(transforms, CAMERA_RGB_FRAME, 'camera_depth_frame')
    assert chained.translation_m == pytest.approx((0.0, 0.025, 0.0))
    assert chained.rotation_xyzw == pytest.approx((0.0, 0.0, 0.0, 1.0))


def test_chain_of_a_frame_to_its_ancestor_is_the_inverse():
    transforms = camera_chain()
    down = chain_transforms(transforms, BASE_LINK_FRAME, CAMERA_RGB_OPTICAL_FRAME)
    up = chain_transforms(transforms, CAMERA_RGB_OPTICAL_FRAME, BASE_LINK_FRAME)
    assert up.as_matrix() == pytest.approx(down.inverse().as_matrix())


@pytest.mark.parametrize('transforms, parent, child, message', [
    (camera_chain(), BASE_LINK_FRAME, WORLD_FRAME, 'No chain'),
    (camera_chain(), BASE_LINK_FRAME, BASE_LINK_FRAME, 'must differ'),
    (camera_chain() + [FrameTransform(WORLD_FRAME, BASE_LINK_FRAME)], WORLD_FRAME,
     CAMERA_LINK_FRAME, 'two parents'),
], ids=['disconnected', 'same-frame', 'two-parents'])
def test_chain_errors_say_what_is_wrong(transforms, parent, child, message):
    with pytest.raises(ValueError, match=message):
        chain_transforms(transforms, parent, child)


def test_nearly_unit_quaternion_is_normalised():
    transform = FrameTransform(WORLD_FRAME, ODOM_FRAME, rotation_xyzw=(0.0, 0.0, 0.0, 1.0001))
    assert transform.rotation_xyzw == (0.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize('arguments', [
    {'parent': '', 'child': ODOM_FRAME},
    {'parent': WORLD_FRAME, 'child': WORLD_FRAME},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'translation_m': (1.0, 2.0)},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'translation_m': (1.0, math.nan, 0.0)},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'translation_m': 'abc'},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'rotation_xyzw': (0.0, 0.0, 0.0, 0.0)},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'rotation_xyzw': (0.0, 0.0, 0.0, 2.0)},
    {'parent': WORLD_FRAME, 'child': ODOM_FRAME, 'rotation_xyzw': (0.0, 0.0, 1.0)},
], ids=['empty-name', 'same-frames', 'short-translation', 'nan-translation', 'text',
        'zero-quaternion', 'long-quaternion', 'short-quaternion'])
def test_bad_transforms_are_rejected(arguments):
    with pytest.raises(ValueError):
        FrameTransform(**arguments)


def test_from_matrix_rejects_a_non_rigid_matrix():
    matrix = np.eye(4)
    matrix[3, 0] = 1.0
    with pytest.raises(ValueError, match='last row'):
        FrameTransform.from_matrix(WORLD_FRAME, ODOM_FRAME, matrix)
