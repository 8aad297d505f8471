"""
The simulator's Kinect-style interface over real DDS, checked against the simulator's geometry.

Each test runs the simulator node in this process with a client node, as ``ros2 topic echo``
would see it: camera images and camera_info, depth and point cloud, odometry, joint states, the
robot's frames, the cmd_vel message type, and the pause, step and reset services.
"""

import math

from conftest import run_domain_id, SimHarness
from followbot import frames
from followbot import messages
from followbot.image_conversion import image_to_array
from followbot_sim import sim_node
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2

# A floor point this far ahead of the start along the line is in view of the tilted camera.
LOOK_AHEAD_M = 0.6
# A point this far beside the line is bare floor.
BESIDE_LINE_M = 0.3
PROJECTION_TOLERANCE_PX = 1.5
DEPTH_TOLERANCE_M = 0.01
ODOMETRY_TOLERANCE = 0.01
STRAIGHT_SPEED_MPS = 0.3
STRAIGHT_DRIVE_S = 4.0
COMMAND_PERIOD_S = 0.2
# Rows around the book's band (3/4 of the image height, 20 rows), among those the follower reads.
BAND_ROWS = slice(350, 371)
STEPS_PER_CALL = 10
PHYSICS_STEP_S = 0.002


def world_from_frame(harness, frame: str) -> np.ndarray:
    """Return the 4x4 pose of a robot frame in the world, from ground truth and /tf_static."""
    pose = frames.FrameTransform.planar(frames.WORLD_FRAME, frames.BASE_FOOTPRINT_FRAME,
                                        *harness.world.robot_pose())
    return frames.chain_transforms([pose, *harness.world.sensor_frames()],
                                   frames.WORLD_FRAME, frame).as_matrix()


def project(info: CameraInfo, camera_in_world: np.ndarray, point_xyz) -> tuple:
    """Project a world point through a camera pose and its camera_info P; return (u, v)."""
    point_camera = np.linalg.inv(camera_in_world) @ np.append(point_xyz, 1.0)
    projection = np.array(info.p).reshape(3, 4) @ point_camera
    return projection[0] / projection[2], projection[1] / projection[2]


class Recorder:
    """Keep the newest message of each topic a client subscribes to."""

    def __init__(self, harness, topics: dict, qos=10):
        self.latest = {}
        for topic, message_type in topics.items():
            harness.client.create_subscription(
                message_type, topic, lambda msg, topic=topic: self.latest.__setitem__(topic, msg),
                qos)

    def has(self, *topics) -> bool:
        return all(topic in self.latest for topic in topics)


def test_camera_info_projects_floor_points_where_the_image_draws_them(sim):
    recorder = Recorder(sim, {'camera/rgb/image_raw': Image,
                              'camera/rgb/camera_info': CameraInfo})
    sim.spin_until(lambda: recorder.has('camera/rgb/image_raw', 'camera/rgb/camera_info'))
    # The robot stands at the start, at rest: the pose now is the pose of the frame.
    image = image_to_array(recorder.latest['camera/rgb/image_raw'])
    info = recorder.latest['camera/rgb/camera_info']
    camera = world_from_frame(sim, frames.CAMERA_RGB_OPTICAL_FRAME)
    x_m, y_m, _ = sim.world.course.point_at(LOOK_AHEAD_M)
    u_px, v_px = project(info, camera, (x_m, y_m, 0.0))
    row = image[int(round(v_px))].astype(int)
    # BGR: the yellow line has a strong red, little blue; the grey floor has equal channels.
    yellow_columns = np.flatnonzero(row[:, 2] - row[:, 0] > 100)
    assert yellow_columns.size > 0
    assert np.mean(yellow_columns) == pytest.approx(u_px, abs=PROJECTION_TOLERANCE_PX)
    beside_xyz = (*sim.world.course.point_at(LOOK_AHEAD_M, BESIDE_LINE_M)[:2], 0.0)
    u_px, v_px = project(info, camera, beside_xyz)
    pixel = image[int(round(v_px)), int(round(u_px))].astype(int)
    assert max(pixel) - min(pixel) < 10


def test_depth_at_the_band_rows_matches_the_floor_geometry(sim):
    recorder = Recorder(sim, {'camera/depth/image_raw': Image,
                              'camera/depth/camera_info': CameraInfo})
    sim.spin_until(lambda: recorder.has('camera/depth/image_raw', 'camera/depth/camera_info'))
    depth_msg = recorder.latest['camera/depth/image_raw']
    assert (depth_msg.encoding, depth_msg.header.frame_id) == (
        '32FC1', frames.CAMERA_DEPTH_OPTICAL_FRAME)
    depth_m = image_to_array(depth_msg)
    info = recorder.latest['camera/depth/camera_info']
    assert info.header.stamp == depth_msg.header.stamp
    fx, _, cx, _, fy, cy, _, _, _ = info.k
    camera = world_from_frame(sim, frames.CAMERA_DEPTH_OPTICAL_FRAME)
    rows, columns = np.mgrid[BAND_ROWS, 0:depth_m.shape[1]]
    rays_camera = np.stack([(columns - cx) / fx, (rows - cy) / fy, np.ones(rows.shape)], -1)
    rays_world = rays_camera @ camera[:3, :3].T
    # Where a ray with unit optical z meets the floor, its length factor is the depth.
    expected_m = -camera[2, 3] / rays_world[..., 2]
    np.testing.assert_allclose(depth_m[BAND_ROWS], expected_m, atol=DEPTH_TOLERANCE_M)


def test_point_cloud_is_the_depth_image_in_metres(sim):
    recorder = Recorder(sim, {'camera/depth/image_raw': Image,
                              'camera/depth/points': PointCloud2})
    sim.spin_until(lambda: recorder.has('camera/depth/image_raw', 'camera/depth/points')
                   and recorder.latest['camera/depth/image_raw'].header.stamp
                   == recorder.latest['camera/depth/points'].header.stamp)
    cloud = recorder.latest['camera/depth/points']
    depth_m = image_to_array(recorder.latest['camera/depth/image_raw'])
    assert (cloud.height, cloud.width) == depth_m.shape
    assert [field.name for field in cloud.fields] == ['x', 'y', 'z']
    assert cloud.header.frame_id == frames.CAMERA_DEPTH_OPTICAL_FRAME
    assert not cloud.is_dense
    points = np.frombuffer(cloud.data, dtype=np.float32).reshape(*depth_m.shape, 3)
    np.testing.assert_array_equal(points[..., 2], depth_m)
    fx, fy, cx, cy = sim.world.camera_intrinsics()
    row, column = 400, 100
    assert points[row, column, 0] == pytest.approx((column - cx) / fx * depth_m[row, column])
    assert points[row, column, 1] == pytest.approx((row - cy) / fy * depth_m[row, column])


def test_streams_nobody_subscribes_to_are_not_rendered(sim, monkeypatch):
    renders = []
    render_depth = sim.world.render_depth
    monkeypatch.setattr(sim.world, 'render_depth',
                        lambda: renders.append(1) or render_depth())
    sim.run_until(sim.world.time_s + 1.0)
    assert not renders
    recorder = Recorder(sim, {'camera/depth/image_raw': Image})
    sim.spin_until(lambda: recorder.has('camera/depth/image_raw'))
    assert renders


def test_odometry_matches_ground_truth_on_a_straight_drive(sim):
    recorder = Recorder(sim, {'odom': Odometry, 'ground_truth/odom': Odometry,
                              'joint_states': JointState})
    start_x_m, start_y_m, _ = sim.world.robot_pose()
    start_s = sim.world.time_s
    while sim.world.time_s < start_s + STRAIGHT_DRIVE_S:
        sent_s = sim.command(STRAIGHT_SPEED_MPS)
        sim.run_until(sent_s + COMMAND_PERIOD_S)
    sim.spin_until(lambda: recorder.has('odom', 'ground_truth/odom', 'joint_states'))
    odom = recorder.latest['odom']
    truth = recorder.latest['ground_truth/odom']
    assert odom.header.stamp == truth.header.stamp
    assert (odom.header.frame_id, odom.child_frame_id) == (
        frames.ODOM_FRAME, frames.BASE_FOOTPRINT_FRAME)
    assert (truth.header.frame_id, truth.child_frame_id) == (
        frames.WORLD_FRAME, frames.BASE_FOOTPRINT_FRAME)
    true_distance_m = math.hypot(truth.pose.pose.position.x - start_x_m,
                                 truth.pose.pose.position.y - start_y_m)
    odom_distance_m = math.hypot(odom.pose.pose.position.x, odom.pose.pose.position.y)
    assert true_distance_m > 1.0
    assert odom_distance_m == pytest.approx(true_distance_m, rel=ODOMETRY_TOLERANCE)
    assert odom.twist.twist.linear.x == pytest.approx(STRAIGHT_SPEED_MPS, rel=0.02)
    joints = recorder.latest['joint_states']
    assert list(joints.name) == ['wheel_left_joint', 'wheel_right_joint']
    wheel_speed_radps = STRAIGHT_SPEED_MPS / sim.world.limits.wheel_radius_m
    assert list(joints.velocity) == pytest.approx([wheel_speed_radps] * 2, rel=0.03)


def test_without_tf2_msgs_the_simulator_says_so_once(sim):
    if sim_node.TFMessage is not None:
        pytest.skip('tf2_msgs is installed: /tf is published (see the next test)')
    sim.run_until(sim.world.time_s + 0.5)
    sim.spin_until(lambda: sim.warnings)
    assert len([text for text in sim.warnings if 'tf2_msgs' in text]) == 1


def test_tf_carries_odometry_and_the_static_frames(sim):
    if sim_node.TFMessage is None:
        pytest.skip('tf2_msgs is not importable here (not on PyPI): make setup builds it')
    recorder = Recorder(sim, {'/tf': sim_node.TFMessage})
    # Static frames are sent once, latched for late joiners as tf2's static listener expects.
    latched = Recorder(sim, {'/tf_static': sim_node.TFMessage}, sim_node.TF_STATIC_QOS)
    sim.spin_until(lambda: recorder.has('/tf') and latched.has('/tf_static'))
    static = {transform.child_frame_id: transform.header.frame_id
              for transform in latched.latest['/tf_static'].transforms}
    assert static[frames.CAMERA_RGB_OPTICAL_FRAME] == frames.CAMERA_RGB_FRAME
    assert static[frames.CAMERA_DEPTH_OPTICAL_FRAME] == frames.CAMERA_DEPTH_FRAME
    moving = recorder.latest['/tf'].transforms[0]
    assert (moving.header.frame_id, moving.child_frame_id) == (
        frames.ODOM_FRAME, frames.BASE_FOOTPRINT_FRAME)


def test_rgb8_encoding_puts_red_first(ros_context):
    harness = SimHarness(ros_context, Parameter('image_encoding', value='rgb8'))
    try:
        recorder = Recorder(harness, {'camera/rgb/image_raw': Image})
        harness.spin_until(lambda: recorder.has('camera/rgb/image_raw'))
        msg = recorder.latest['camera/rgb/image_raw']
        assert msg.encoding == 'rgb8'
        image = image_to_array(msg).astype(int)
        # The line is in view at the bottom centre: yellow is red and green, no blue.
        assert np.max(image[..., 0] - image[..., 2]) > 100
    finally:
        harness.close()


def test_twist_stamped_drives_when_asked_for(ros_context):
    harness = SimHarness(ros_context, Parameter('cmd_vel_stamped', value=True),
                         command_type=TwistStamped)
    try:
        sent_s = harness.command(STRAIGHT_SPEED_MPS)
        harness.run_until(sent_s + 0.4)
        assert harness.world.robot_twist()[0] == pytest.approx(STRAIGHT_SPEED_MPS, rel=0.03)
    finally:
        harness.close()


def test_a_cmd_vel_of_the_wrong_type_is_reported_once_with_the_fix(ros_context):
    harness = SimHarness(ros_context, Parameter('cmd_vel_stamped', value=True),
                         command_type=TwistStamped)
    # Another process sends plain Twist: the Jazzy mismatch whose commands never arrive.
    other_context = Context()
    rclpy.init(context=other_context, domain_id=run_domain_id())
    other = Node('teleop', context=other_context)
    try:
        other.create_publisher(Twist, 'cmd_vel', 10).publish(Twist())
        harness.spin_until(lambda: harness.errors)
        for _ in range(3):
            harness.run_until(harness.world.time_s + 1.0)
        assert len(harness.errors) == 1
        assert '/teleop publishes /cmd_vel as geometry_msgs/msg/Twist' in harness.errors[0]
        assert 'cmd_vel_stamped:=false' in harness.errors[0]
        assert harness.simulator.commands_received == 0
    finally:
        other.destroy_node()
        rclpy.try_shutdown(context=other_context)
        harness.close()


def test_pause_step_and_reset_services(ros_context):
    harness = SimHarness(ros_context, Parameter('start_paused', value=True),
                         Parameter('step_physics_steps', value=STEPS_PER_CALL))
    try:
        for _ in range(20):
            harness.executor.spin_once(timeout_sec=0.01)
        assert harness.world.time_s == 0.0
        response = harness.step()
        assert response.success, response.message
        assert harness.world.time_s == pytest.approx(STEPS_PER_CALL * PHYSICS_STEP_S)
        harness.command(STRAIGHT_SPEED_MPS)
        for _ in range(20):
            harness.step()
        assert harness.world.robot_twist()[0] > 0.1
        assert harness.pause(False).success
        assert not harness.step().success
        harness.run_until(harness.world.time_s + 0.5)
        moved_x_m, moved_y_m, _ = harness.world.robot_pose()
        time_before_reset_s = harness.world.time_s
        assert harness.reset().success
        x_m, y_m, yaw_rad = harness.world.robot_pose()
        assert (x_m, y_m, yaw_rad) == pytest.approx(harness.world.course.start_pose(), abs=1e-6)
        assert (x_m, y_m) != pytest.approx((moved_x_m, moved_y_m), abs=0.05)
        # Simulated time never runs backwards: /clock subscribers would drop their buffers.
        assert harness.world.time_s >= time_before_reset_s
        assert harness.simulator.lap_tracker.progress_m == pytest.approx(0.0, abs=0.01)
    finally:
        harness.close()


def drive_paused(context, commands) -> tuple:
    """Drive a paused, noisy simulator step by step; return its trajectory and last frame."""
    harness = SimHarness(context, Parameter('start_paused', value=True),
                         Parameter('step_physics_steps', value=STEPS_PER_CALL),
                         Parameter('camera_noise_stddev_levels', value=8.0),
                         Parameter('random_seed', value=7))
    recorder = Recorder(harness, {'camera/rgb/image_raw': Image})
    trajectory = []
    try:
        for linear_mps, angular_radps in commands:
            harness.command(linear_mps, angular_radps)
            for _ in range(5):
                assert harness.step().success
            trajectory.append(harness.world.data.qpos.copy())
        harness.spin_until(lambda: recorder.has('camera/rgb/image_raw')
                           and messages.seconds(recorder.latest[
                               'camera/rgb/image_raw'].header.stamp)
                           >= harness.world.time_s - 0.05)
        frame = np.array(image_to_array(recorder.latest['camera/rgb/image_raw']))
    finally:
        harness.close()
    return np.array(trajectory), frame


def test_the_same_inputs_and_seed_give_the_same_run(ros_context):
    commands = [(0.3, 0.0), (0.4, 0.8), (0.2, -1.2), (0.0, 2.0), (0.5, 0.1)] * 4
    first_trajectory, first_frame = drive_paused(ros_context, commands)
    second_trajectory, second_frame = drive_paused(ros_context, commands)
    np.testing.assert_array_equal(first_trajectory, second_trajectory)
    np.testing.assert_array_equal(first_frame, second_frame)
