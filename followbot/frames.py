"""
Coordinate frames of the simulated TurtleBot 2: names, rigid transforms and quaternion helpers.

A pure NumPy module (no ROS, no MuJoCo). Conventions follow ROS:

- REP-103: body frames have x forward, y left, z up; optical frames (``*_optical_frame``) have
  z forward along the optical axis, x right and y down in the image.
- REP-105: ``world`` (here the simulator's ground truth, a stand-in for ``map``) -> ``odom`` ->
  ``base_footprint`` -> ``base_link`` -> sensor frames.
- A :class:`FrameTransform` from ``parent`` to ``child`` is the pose of the child in the parent,
  as in a TF message: a point with coordinates ``p`` in the child frame has coordinates
  ``R p + t`` in the parent frame. Quaternions are in ROS order (x, y, z, w).
"""

from collections import deque
from dataclasses import dataclass
import math

import numpy as np

WORLD_FRAME = 'world'
ODOM_FRAME = 'odom'
BASE_FOOTPRINT_FRAME = 'base_footprint'
BASE_LINK_FRAME = 'base_link'
CAMERA_LINK_FRAME = 'camera_link'
CAMERA_RGB_FRAME = 'camera_rgb_frame'
CAMERA_RGB_OPTICAL_FRAME = 'camera_rgb_optical_frame'
CAMERA_DEPTH_FRAME = 'camera_depth_frame'
CAMERA_DEPTH_OPTICAL_FRAME = 'camera_depth_optical_frame'

IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)
# REP-103: a body frame turns into its optical frame by roll -pi/2 then yaw -pi/2 (fixed axes).
OPTICAL_ROLL_RAD = -math.pi / 2.0
OPTICAL_PITCH_RAD = 0.0
OPTICAL_YAW_RAD = -math.pi / 2.0
# Quaternions within this of unit norm are rounding noise and get normalised; farther ones are
# a caller's mistake (e.g. (w, x, y, z) order mix-ups keep the norm, but zeros do not).
UNIT_NORM_TOLERANCE = 1e-3
# A 3x3 rotation matrix whose columns are orthonormal to this tolerance is accepted.
ORTHONORMAL_TOLERANCE = 1e-6


def quaternion_from_yaw(yaw_rad: float) -> tuple[float, float, float, float]:
    """
    Return the quaternion of a rotation about z.

    :param yaw_rad: rotation angle about z in radians, positive counter-clockwise.
    :return: (x, y, z, w).
    """
    half_rad = yaw_rad / 2.0
    return 0.0, 0.0, math.sin(half_rad), math.cos(half_rad)


def quaternion_from_rpy(roll_rad: float, pitch_rad: float,
                        yaw_rad: float) -> tuple[float, float, float, float]:
    """
    Return the quaternion of roll, pitch and yaw about the fixed x, y and z axes, in that order.

    This is the URDF ``rpy`` convention: the rotation matrix is Rz(yaw) Ry(pitch) Rx(roll).

    :param roll_rad: rotation about x in radians.
    :param pitch_rad: rotation about y in radians.
    :param yaw_rad: rotation about z in radians.
    :return: (x, y, z, w).
    """
    cos_roll, sin_roll = math.cos(roll_rad / 2.0), math.sin(roll_rad / 2.0)
    cos_pitch, sin_pitch = math.cos(pitch_rad / 2.0), math.sin(pitch_rad / 2.0)
    cos_yaw, sin_yaw = math.cos(yaw_rad / 2.0), math.sin(yaw_rad / 2.0)
    return (sin_roll * cos_pitch * cos_yaw - cos_roll * sin_pitch * sin_yaw,
            cos_roll * sin_pitch * cos_yaw + sin_roll * cos_pitch * sin_yaw,
            cos_roll * cos_pitch * sin_yaw - sin_roll * sin_pitch * cos_yaw,
            cos_roll * cos_pitch * cos_yaw + sin_roll * sin_pitch * sin_yaw)


def yaw_from_quaternion(rotation_xyzw) -> float:
    """
    Return the heading of a rotation: the angle of its x axis projected on the xy plane.

    :param rotation_xyzw: a unit quaternion (x, y, z, w).
    :return: yaw in radians, in [-pi, pi].
    """
    x, y, z, w = (float(value) for value in rotation_xyzw)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def matrix_from_quaternion(rotation_xyzw) -> np.ndarray:
    """
    Return the rotation matrix of a unit quaternion.

    :param rotation_xyzw: a unit quaternion (x, y, z, w).
    :return: a 3x3 float array whose columns are the rotated frame's axes.
    """
    x, y, z, w = (float(value) for value in rotation_xyzw)
    return np.array([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ])


def quaternion_from_matrix(rotation) -> tuple[float, float, float, float]:
    """
    Return the unit quaternion of a rotation matrix, with w >= 0.

    Takes the square root of the largest of 1 + trace and the diagonal-based candidates, so it
    stays accurate near 180-degree rotations.

    :param rotation: a 3x3 rotation matrix (orthonormal, determinant +1).
    :return: (x, y, z, w).
    :raises ValueError: if the matrix is not a 3x3 proper rotation.
    """
    matrix = np.asarray(rotation, dtype=float)
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
        raise ValueError(f'A rotation must be a finite 3x3 matrix, got shape {matrix.shape}.')
    if (not np.allclose(matrix.T @ matrix, np.eye(3), atol=ORTHONORMAL_TOLERANCE)
            or np.linalg.det(matrix) < 0.0):
        raise ValueError('A rotation matrix must be orthonormal with determinant +1; '
                         f'got {matrix.tolist()}.')
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = matrix
    trace = m00 + m11 + m22
    largest = max(trace, m00, m11, m22)
    if largest == trace:
        scale = 2.0 * math.sqrt(1.0 + trace)
        quaternion = ((m21 - m12) / scale, (m02 - m20) / scale, (m10 - m01) / scale,
                      scale / 4.0)
    elif largest == m00:
        scale = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        quaternion = (scale / 4.0, (m01 + m10) / scale, (m02 + m20) / scale,
                      (m21 - m12) / scale)
    elif largest == m11:
        scale = 2.0 * math.sqrt(1.0 - m00 + m11 - m22)
        quaternion = ((m01 + m10) / scale, scale / 4.0, (m12 + m21) / scale,
                      (m02 - m20) / scale)
    else:
        scale = 2.0 * math.sqrt(1.0 - m00 - m11 + m22)
        quaternion = ((m02 + m20) / scale, (m12 + m21) / scale, scale / 4.0,
                      (m10 - m01) / scale)
    sign = -1.0 if quaternion[3] < 0.0 else 1.0
    return tuple(float(sign * value) for value in quaternion)


def _as_vector(values, length: int, name: str) -> tuple[float, ...]:
    try:
        vector = tuple(float(value) for value in values)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be {length} numbers, got {values!r}.') from None
    if len(vector) != length or not all(math.isfinite(value) for value in vector):
        raise ValueError(f'{name} must be {length} finite numbers, got {values!r}.')
    return vector


@dataclass(frozen=True)
class FrameTransform:
    """
    The pose of frame ``child`` in frame ``parent``: maps child coordinates to parent ones.

    ``rotation_xyzw`` is normalised on construction (within ``UNIT_NORM_TOLERANCE`` of unit
    norm); both vectors are stored as tuples of floats.
    """

    parent: str
    child: str
    translation_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW

    def __post_init__(self):
        """
        Check the frame names and vectors, and normalise the quaternion.

        :raises ValueError: for an empty frame name, a parent equal to the child, a translation
            that is not 3 finite numbers or a rotation that is not a unit quaternion.
        """
        for role in ('parent', 'child'):
            name = getattr(self, role)
            if not isinstance(name, str) or not name:
                raise ValueError(f'The {role} frame must be a non-empty string, got {name!r}.')
        if self.parent == self.child:
            raise ValueError(f'A transform must join two different frames, got {self.parent!r} '
                             'for both.')
        translation_m = _as_vector(self.translation_m, 3, 'translation_m')
        rotation_xyzw = _as_vector(self.rotation_xyzw, 4, 'rotation_xyzw')
        norm = math.sqrt(sum(value * value for value in rotation_xyzw))
        if abs(norm - 1.0) > UNIT_NORM_TOLERANCE:
            raise ValueError('rotation_xyzw must be a unit quaternion (x, y, z, w); got '
                             f'{self.rotation_xyzw!r} of norm {norm:.6g}.')
        object.__setattr__(self, 'translation_m', translation_m)
        object.__setattr__(self, 'rotation_xyzw', tuple(value / norm for value in rotation_xyzw))

    @classmethod
    def from_matrix(cls, parent: str, child: str, matrix) -> 'FrameTransform':
        """
        Build a transform from a 4x4 homogeneous matrix.

        :param parent: the parent frame.
        :param child: the child frame.
        :param matrix: 4x4 matrix mapping child coordinates to parent coordinates.
        :return: the transform.
        :raises ValueError: if the matrix is not a 4x4 rigid transform.
        """
        matrix = np.asarray(matrix, dtype=float)
        if matrix.shape != (4, 4) or not np.allclose(matrix[3], (0.0, 0.0, 0.0, 1.0)):
            raise ValueError('A rigid transform must be a 4x4 matrix with last row 0 0 0 1; '
                             f'got shape {matrix.shape}.')
        return cls(parent, child, tuple(matrix[:3, 3]), quaternion_from_matrix(matrix[:3, :3]))

    @classmethod
    def planar(cls, parent: str, child: str, x_m: float, y_m: float,
               yaw_rad: float) -> 'FrameTransform':
        """
        Build the transform of a pose on the floor: a translation in xy and a yaw.

        :param parent: the parent frame (e.g. ``world`` or ``odom``).
        :param child: the child frame (e.g. ``base_footprint``).
        :param x_m: x of the child's origin in the parent frame in metres.
        :param y_m: y of the child's origin in the parent frame in metres.
        :param yaw_rad: heading of the child's x axis in the parent frame in radians.
        :return: the transform.
        """
        return cls(parent, child, (x_m, y_m, 0.0), quaternion_from_yaw(yaw_rad))

    def rotation_matrix(self) -> np.ndarray:
        """
        Return the rotation part as a matrix.

        :return: 3x3 float array whose columns are the child's axes in the parent frame.
        """
        return matrix_from_quaternion(self.rotation_xyzw)

    def as_matrix(self) -> np.ndarray:
        """
        Return the homogeneous matrix mapping child coordinates to parent coordinates.

        :return: a 4x4 float array.
        """
        matrix = np.eye(4)
        matrix[:3, :3] = self.rotation_matrix()
        matrix[:3, 3] = self.translation_m
        return matrix

    def inverse(self) -> 'FrameTransform':
        """
        Return the transform from the child back to the parent.

        :return: the transform with parent and child swapped.
        """
        rotation = self.rotation_matrix()
        x, y, z, w = self.rotation_xyzw
        return FrameTransform(self.child, self.parent,
                              tuple(-rotation.T @ np.asarray(self.translation_m)), (-x, -y, -z, w))

    def compose(self, child_transform: 'FrameTransform') -> 'FrameTransform':
        """
        Chain this transform with one from its child frame onward.

        :param child_transform: a transform whose parent is this transform's child.
        :return: the transform from this parent to ``child_transform``'s child.
        :raises ValueError: if ``child_transform`` does not start at this transform's child.
        """
        if child_transform.parent != self.child:
            raise ValueError(f'Cannot chain {self.parent}->{self.child} with '
                             f'{child_transform.parent}->{child_transform.child}: the second '
                             f'must start at {self.child!r}.')
        return FrameTransform.from_matrix(self.parent, child_transform.child,
                                          self.as_matrix() @ child_transform.as_matrix())

    def transform_points(self, points_xyz) -> np.ndarray:
        """
        Express points given in the child frame in the parent frame.

        :param points_xyz: an array of shape (..., 3) in the child frame, metres.
        :return: a float array of the same shape in the parent frame.
        """
        points_xyz = np.asarray(points_xyz, dtype=float)
        return points_xyz @ self.rotation_matrix().T + np.asarray(self.translation_m)


def chain_transforms(transforms, parent_frame: str, child_frame: str) -> FrameTransform:
    """
    Find the transform between two frames of a tree of transforms.

    Each transform may be walked in either direction (its inverse is used against it), so the
    path may climb towards a common ancestor and descend again, like TF's lookup.

    :param transforms: an iterable of :class:`FrameTransform`, e.g. the world's sensor frames
        plus a ``world -> base_footprint`` pose.
    :param parent_frame: the frame the result is expressed in.
    :param child_frame: the frame whose pose the result gives.
    :return: the transform from ``parent_frame`` to ``child_frame``.
    :raises ValueError: if the frames are equal, a frame has two parents, or no chain of the
        transforms joins the two frames.
    """
    if parent_frame == child_frame:
        raise ValueError(f'The two frames must differ, got {parent_frame!r} twice.')
    neighbours = {}
    parent_of = {}
    for transform in transforms:
        if parent_of.setdefault(transform.child, transform.parent) != transform.parent:
            raise ValueError(f'Frame {transform.child!r} has two parents, '
                             f'{parent_of[transform.child]!r} and {transform.parent!r}: '
                             'transforms must form a tree.')
        neighbours.setdefault(transform.parent, []).append((transform.child, transform))
        neighbours.setdefault(transform.child, []).append((transform.parent, transform.inverse()))
    # Breadth-first search from the parent frame, remembering how each frame was reached.
    reached_by = {parent_frame: None}
    frontier = deque([parent_frame])
    while frontier and child_frame not in reached_by:
        frame = frontier.popleft()
        for neighbour, step in neighbours.get(frame, ()):
            if neighbour not in reached_by:
                reached_by[neighbour] = step
                frontier.append(neighbour)
    if child_frame not in reached_by:
        known = ', '.join(sorted(neighbours)) or 'none'
        raise ValueError(f'No chain of transforms joins {parent_frame!r} to {child_frame!r}; '
                         f'known frames: {known}.')
    steps = []
    frame = child_frame
    while reached_by[frame] is not None:
        steps.append(reached_by[frame])
        frame = reached_by[frame].parent
    matrix = np.eye(4)
    for step in reversed(steps):
        matrix = matrix @ step.as_matrix()
    return FrameTransform.from_matrix(parent_frame, child_frame, matrix)


def optical_rotation_xyzw() -> tuple[float, float, float, float]:
    """
    Return the fixed rotation from a camera's body frame to its optical frame (REP-103).

    :return: (x, y, z, w) of RPY(-pi/2, 0, -pi/2).
    """
    return quaternion_from_rpy(OPTICAL_ROLL_RAD, OPTICAL_PITCH_RAD, OPTICAL_YAW_RAD)
