"""
Build ROS messages from plain values: stamps, camera info, point clouds, odometry, transforms.

Only message packages are imported here, not rclpy, so the builders are tested without a node.
Builders that run every frame fill a message in place, so a publisher can reuse one message and
its buffers.
"""

from builtin_interfaces.msg import Time
from followbot.frames import FrameTransform, quaternion_from_yaw
from followbot.image_conversion import fill_message_data
from geometry_msgs.msg import Transform, TransformStamped
from nav_msgs.msg import Odometry
import numpy as np
from sensor_msgs.msg import CameraInfo, JointState, PointCloud2, PointField

NANOSECONDS_PER_SECOND = 1_000_000_000
# x, y and z as float32 one after the other: the layout PCL and RViz read directly.
POINT_FIELDS = tuple(PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32,
                                count=1) for index, name in enumerate('xyz'))
POINT_STEP_BYTES = 12
# Pose covariance as a Kobuki's driver reports it: x, y and yaw are estimated, while z, roll
# and pitch are fixed by the floor and flagged unknown with a huge variance (row-major 6x6).
ODOMETRY_POSE_VARIANCES = (0.1, 0.1, 1e6, 1e6, 1e6, 0.2)
ODOMETRY_TWIST_VARIANCES = (0.1, 0.1, 1e6, 1e6, 1e6, 0.2)
# Ground truth is exact; a tiny variance keeps consumers that invert covariances working.
GROUND_TRUTH_VARIANCES = (1e-9,) * 6


def stamp(time_s: float) -> Time:
    """
    Convert seconds to a ``builtin_interfaces/Time``, rounded to the nearest nanosecond.

    :param time_s: non-negative time in seconds.
    :return: the stamp.
    """
    nanoseconds = round(time_s * NANOSECONDS_PER_SECOND)
    return Time(sec=nanoseconds // NANOSECONDS_PER_SECOND,
                nanosec=nanoseconds % NANOSECONDS_PER_SECOND)


def seconds(time_msg: Time) -> float:
    """
    Convert a ``builtin_interfaces/Time`` to seconds.

    :param time_msg: the stamp.
    :return: seconds as a float.
    """
    return time_msg.sec + time_msg.nanosec / NANOSECONDS_PER_SECOND


def camera_info(intrinsics: tuple, size_px: tuple, frame_id: str) -> CameraInfo:
    """
    Describe an ideal pinhole camera: no distortion, rectified image equal to the raw one.

    :param intrinsics: (fx, fy, cx, cy) in pixels.
    :param size_px: (width, height) in pixels.
    :param frame_id: the camera's optical frame.
    :return: the message, unstamped.
    """
    fx_px, fy_px, cx_px, cy_px = intrinsics
    info = CameraInfo()
    info.header.frame_id = frame_id
    info.width, info.height = (int(value) for value in size_px)
    info.distortion_model = 'plumb_bob'
    info.d = [0.0] * 5
    info.k = [fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0]
    info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    info.p = [fx_px, 0.0, cx_px, 0.0, 0.0, fy_px, cy_px, 0.0, 0.0, 0.0, 1.0, 0.0]
    return info


def fill_point_cloud(points_xyz: np.ndarray, msg: PointCloud2) -> PointCloud2:
    """
    Fill an organised PointCloud2 with x, y, z float32 points, reusing its buffer when it fits.

    :param points_xyz: (height, width, 3) float32 points; NaN marks a pixel with no return.
    :param msg: the message to fill; its header is kept.
    :return: ``msg``.
    :raises ValueError: if the array is not (H, W, 3) float32.
    """
    if points_xyz.dtype != np.float32 or points_xyz.ndim != 3 or points_xyz.shape[2] != 3:
        raise ValueError(
            f'points_xyz must be an (H, W, 3) float32 array, got {points_xyz.dtype} '
            f'{points_xyz.shape}.')
    height, width = points_xyz.shape[:2]
    msg.height = int(height)
    msg.width = int(width)
    msg.fields = list(POINT_FIELDS)
    msg.is_bigendian = False
    msg.point_step = POINT_STEP_BYTES
    msg.row_step = POINT_STEP_BYTES * int(width)
    msg.is_dense = False
    return fill_message_data(msg, points_xyz)


def _diagonal_6x6(variances: tuple) -> list:
    covariance = [0.0] * 36
    for index, variance in enumerate(variances):
        covariance[7 * index] = float(variance)
    return covariance


def fill_odometry(msg: Odometry, pose: tuple, twist: tuple, exact: bool = False) -> Odometry:
    """
    Fill a planar Odometry message in place; frames and stamp are left to the caller.

    :param msg: the message to fill.
    :param pose: (x m, y m, yaw rad) of the child frame in the header frame.
    :param twist: (forward m/s, yaw rate rad/s) in the child frame.
    :param exact: whether the values are ground truth (tiny covariance) rather than an
        odometry estimate.
    :return: ``msg``.
    """
    x_m, y_m, yaw_rad = pose
    linear_mps, angular_radps = twist
    msg.pose.pose.position.x = float(x_m)
    msg.pose.pose.position.y = float(y_m)
    msg.pose.pose.position.z = 0.0
    orientation = msg.pose.pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = quaternion_from_yaw(yaw_rad)
    msg.twist.twist.linear.x = float(linear_mps)
    msg.twist.twist.angular.z = float(angular_radps)
    msg.pose.covariance = _diagonal_6x6(
        GROUND_TRUTH_VARIANCES if exact else ODOMETRY_POSE_VARIANCES)
    msg.twist.covariance = _diagonal_6x6(
        GROUND_TRUTH_VARIANCES if exact else ODOMETRY_TWIST_VARIANCES)
    return msg


def transform_stamped(frame_transform: FrameTransform, time_msg: Time) -> TransformStamped:
    """
    Make the stamped message of a transform: a fixed frame of the robot, or odom -> base.

    :param frame_transform: the child frame's pose in its parent.
    :param time_msg: the stamp.
    :return: the transform.
    """
    transform = Transform()
    (transform.translation.x, transform.translation.y,
     transform.translation.z) = (float(value) for value in frame_transform.translation_m)
    (transform.rotation.x, transform.rotation.y, transform.rotation.z,
     transform.rotation.w) = (float(value) for value in frame_transform.rotation_xyzw)
    stamped = TransformStamped(transform=transform, child_frame_id=frame_transform.child)
    stamped.header.stamp = time_msg
    stamped.header.frame_id = frame_transform.parent
    return stamped


def joint_state(names: tuple, positions_rad: tuple, velocities_radps: tuple,
                time_msg: Time) -> JointState:
    """
    Make a JointState of revolute joints, without efforts.

    :param names: joint names.
    :param positions_rad: joint angles in radians.
    :param velocities_radps: joint speeds in rad/s.
    :param time_msg: the stamp.
    :return: the message.
    """
    msg = JointState(name=list(names), position=[float(value) for value in positions_rad],
                     velocity=[float(value) for value in velocities_radps])
    msg.header.stamp = time_msg
    return msg
