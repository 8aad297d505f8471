"""
Property-based fuzzing of the nodes over real DDS: any message or parameter, then good input.

Each test feeds one running node many generated inputs (hypothesis) and checks after each that
the node is still up and did nothing unsafe, then that it answers good input as before. The
number of examples is set by the hypothesis profile in conftest.py (``FOLLOWBOT_FUZZ_EXAMPLES``
for a longer run).
"""

import math

from conftest import SimHarness
from followbot import messages
from followbot.controller import ControllerConfig
from followbot.follower_node import FOLLOWER_PARAMETERS, FollowerSettings
from followbot.image_conversion import image_to_array, ImageConversionError
from followbot_sim.diff_drive import KOBUKI_MAX_ANGULAR_SPEED_RADPS, KOBUKI_MAX_LINEAR_SPEED_MPS
from followbot_sim.sim_node import SIMULATOR_PARAMETERS
from follower_harness import camera_frame, camera_info, FRAME_PERIOD_S, Harness, WIDTH_PX
from geometry_msgs.msg import Twist, TwistStamped, Vector3
from hypothesis import given, strategies
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import CameraInfo, Image

CENTRE_PX = WIDTH_PX // 2
ENCODING_NAMES = ('bgr8', 'rgb8', 'bgra8', 'rgba8', 'mono8', '32FC1', 'yuv422', 'uyvy',
                  'yuv422_yuy2', 'yuyv', 'bayer_rggb8', 'bayer_bggr8', 'bayer_gbrg8',
                  'bayer_grbg8', 'mono16', '16UC1', '8UC3', '')
# Small images keep an example fast; the sizes around them cover zero, odd and padded rows.
MAX_SIDE_PX = 40
MAX_DATA_BYTES = 8000
ANY_FLOAT = strategies.floats(allow_nan=True, allow_infinity=True)
# The simulator's physics settles a commanded speed within this much simulated time.
COMMAND_SETTLE_S = 0.1
SPEED_MARGIN = 1.05
# A good command drives the robot for this long, within the Kobuki's 0.6 s command timeout.
GOOD_COMMAND_S = 0.4


@strategies.composite
def image_messages(draw):
    """Draw an Image message: any encoding, size, step, data length and stamp."""
    msg = Image()
    msg.encoding = draw(strategies.sampled_from(ENCODING_NAMES)
                        | strategies.text(max_size=16))
    msg.width = draw(strategies.integers(0, MAX_SIDE_PX))
    msg.height = draw(strategies.integers(0, MAX_SIDE_PX))
    bytes_per_pixel = draw(strategies.integers(0, 5))
    msg.step = draw(strategies.just(msg.width * bytes_per_pixel)
                    | strategies.integers(0, 4 * MAX_SIDE_PX + 8))
    length = draw(strategies.just(msg.step * msg.height)
                  | strategies.integers(0, MAX_DATA_BYTES))
    msg.data = draw(strategies.binary(min_size=min(length, MAX_DATA_BYTES),
                                      max_size=min(length, MAX_DATA_BYTES)))
    msg.is_bigendian = draw(strategies.integers(0, 1))
    msg.header.stamp.sec = draw(strategies.integers(0, 2 ** 31 - 1))
    msg.header.stamp.nanosec = draw(strategies.integers(0, 999_999_999))
    return msg


@strategies.composite
def camera_infos(draw):
    """Draw a CameraInfo: any K, D, model, size, binning and region of interest."""
    info = CameraInfo()
    near_kinect = camera_info()
    info.k = draw(strategies.lists(ANY_FLOAT, min_size=9, max_size=9)
                  | strategies.just(list(near_kinect.k)))
    info.d = draw(strategies.lists(ANY_FLOAT, max_size=9))
    info.distortion_model = draw(strategies.sampled_from(
        ('', 'plumb_bob', 'rational_polynomial', 'equidistant', 'unknown')))
    info.width = draw(strategies.sampled_from((0, 640, 320, 2 ** 32 - 1)))
    info.height = draw(strategies.sampled_from((0, 480, 240, 2 ** 32 - 1)))
    info.binning_x = draw(strategies.integers(0, 2 ** 32 - 1))
    info.binning_y = draw(strategies.integers(0, 8))
    info.roi.x_offset = draw(strategies.integers(0, 2 ** 32 - 1))
    info.roi.width = draw(strategies.integers(0, 700))
    info.roi.height = draw(strategies.integers(0, 500))
    return info


@strategies.composite
def odometries(draw):
    """Draw an Odometry: any pose, orientation, twist and stamp, sane or not."""
    msg = Odometry()
    msg.header.stamp.sec = draw(strategies.integers(0, 2 ** 31 - 1) | strategies.just(1))
    msg.header.stamp.nanosec = draw(strategies.integers(0, 999_999_999))
    pose = msg.pose.pose
    pose.position.x, pose.position.y = draw(ANY_FLOAT), draw(ANY_FLOAT)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (draw(ANY_FLOAT) for _ in range(4))
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = draw(ANY_FLOAT), draw(ANY_FLOAT)
    return msg


def readable(msg: Image) -> bool:
    """Tell whether the follower could read a frame's pixels at all."""
    try:
        image_to_array(msg)
    except ImageConversionError:
        return False
    return True


def assert_safe(command: Twist, settings: FollowerSettings) -> None:
    """Check that a command is finite and within the follower's limits."""
    values = (command.linear.x, command.linear.y, command.linear.z, command.angular.x,
              command.angular.y, command.angular.z)
    assert all(math.isfinite(value) for value in values)
    assert values[1:5] == (0.0, 0.0, 0.0, 0.0)
    assert 0.0 <= command.linear.x <= settings.controller.linear_speed_mps + 1e-9
    assert abs(command.angular.z) <= settings.controller.max_angular_speed_radps + 1e-9


def test_follower_survives_any_image_and_never_drives_on_one_it_cannot_read(ros_context):
    harness = Harness(ros_context)

    @given(msg=image_messages())
    def send_any_image(msg):
        count = len(harness.cmd_vels)
        harness.images.publish(msg)
        harness.spin_until(lambda: len(harness.cmd_vels) > count)
        command = harness.cmd_vels[-1]
        assert_safe(command, harness.follower._settings)
        if not readable(msg):
            assert command == Twist()

    try:
        send_any_image()
        assert harness.send_many(CENTRE_PX).linear.x > 0.0
    finally:
        harness.close()


def test_follower_survives_any_camera_info(ros_context):
    harness = Harness(ros_context)

    @given(info=camera_infos())
    def send_any_camera_info(info):
        harness.camera_infos.publish(info)
        command = harness.send(camera_frame(CENTRE_PX + 60))
        assert_safe(command, harness.follower._settings)

    try:
        send_any_camera_info()
        harness.camera_infos.publish(camera_info())
        harness.spin_until(lambda: harness.send(camera_frame(CENTRE_PX)).linear.x > 0.0)
    finally:
        harness.close()


def test_follower_survives_any_odometry(ros_context):
    # The frames show a line ending ahead, then none: the follower drives on to the end by
    # odometry when it can use it.
    harness = Harness(ros_context)
    publisher = harness.client.create_publisher(Odometry, 'odom', 10)
    harness.spin_until(lambda: publisher.get_subscription_count() > 0)
    frames = [camera_frame(CENTRE_PX), camera_frame(CENTRE_PX, line_top_px=240),
              camera_frame(None), camera_frame(None)]

    # Each message may be stamped near its frame (then it is used), or anywhere.
    near_offsets_s = strategies.none() | strategies.floats(-0.6, 0.6)

    @given(msgs=strategies.lists(strategies.tuples(odometries(), near_offsets_s),
                                 min_size=len(frames), max_size=len(frames)))
    def send_any_odometry(msgs):
        for (msg, offset_s), frame in zip(msgs, frames):
            if offset_s is not None:
                msg.header.stamp = messages.stamp(harness.time_s + FRAME_PERIOD_S + offset_s)
            taken = harness.follower.odometry_messages
            publisher.publish(msg)
            harness.spin_until(lambda: harness.follower.odometry_messages > taken)
            assert_safe(harness.send(frame), harness.follower._settings)

    try:
        send_any_odometry()
        assert harness.send_many(CENTRE_PX).linear.x > 0.0
    finally:
        harness.close()


def parameter_values():
    """Draw a value of any type a ROS parameter can hold, sane or not."""
    return (ANY_FLOAT | strategies.integers(-2 ** 63, 2 ** 63 - 1) | strategies.booleans()
            | strategies.text(max_size=12) | strategies.sampled_from(('path', 'stop', 'search'))
            | strategies.lists(strategies.integers(-5, 5), max_size=3))


def test_follower_survives_any_parameter_change_and_keeps_consistent_settings(ros_context):
    harness = Harness(ros_context)
    writable = sorted(name for name, spec in FOLLOWER_PARAMETERS.items() if not spec.read_only)

    @given(changes=strategies.dictionaries(strategies.sampled_from(writable),
                                           parameter_values(), min_size=1, max_size=4))
    def set_any_parameters(changes):
        results = harness.set_parameters(*(Parameter(name, value=value)
                                           for name, value in changes.items()))
        assert all(result.successful or result.reason for result in results)
        values = {name: harness.follower.get_parameter(name).value
                  for name in FOLLOWER_PARAMETERS}
        # Whatever was accepted still makes settings the follower can work with.
        assert FollowerSettings.from_parameters(values) == harness.follower._settings
        assert_safe(harness.send(camera_frame(CENTRE_PX)), harness.follower._settings)

    try:
        set_any_parameters()
        defaults = ControllerConfig()
        harness.set_parameters(*(Parameter(name, value=getattr(defaults, name))
                                 for name in ('steering_law', 'linear_speed_mps',
                                              'min_linear_speed_mps')))
    finally:
        harness.close()


def twists():
    """Draw a Twist with any six numbers: NaN, infinities and huge values included."""
    vectors = strategies.builds(Vector3, x=ANY_FLOAT, y=ANY_FLOAT, z=ANY_FLOAT)
    return strategies.builds(Twist, linear=vectors, angular=vectors)


def check_simulator_takes_any_command(harness, wrap) -> None:
    """Send generated commands to a simulator; its robot stays within the Kobuki's limits."""

    @given(twist=twists())
    def send_any_command(twist):
        harness.cmd_vel.publish(wrap(twist))
        start_s = harness.world.time_s
        harness.run_until(start_s + COMMAND_SETTLE_S)
        linear_mps, angular_radps = harness.world.robot_twist()
        assert math.isfinite(linear_mps) and math.isfinite(angular_radps)
        assert abs(linear_mps) <= KOBUKI_MAX_LINEAR_SPEED_MPS * SPEED_MARGIN
        assert abs(angular_radps) <= KOBUKI_MAX_ANGULAR_SPEED_RADPS * SPEED_MARGIN
        assert all(math.isfinite(value) for value in harness.world.robot_pose())

    send_any_command()
    # Good commands still drive it.
    harness.command(0.3)
    harness.run_until(harness.world.time_s + GOOD_COMMAND_S)
    assert harness.world.robot_twist()[0] > 0.25


def test_simulator_survives_any_twist(sim):
    check_simulator_takes_any_command(sim, lambda twist: twist)


def test_simulator_survives_any_twist_stamped(ros_context):
    harness = SimHarness(ros_context, Parameter('cmd_vel_stamped', value=True),
                         command_type=TwistStamped)
    try:
        check_simulator_takes_any_command(harness, lambda twist: TwistStamped(twist=twist))
    finally:
        harness.close()


def test_simulator_survives_any_parameter_change(sim):
    writable = sorted(name for name, spec in SIMULATOR_PARAMETERS.items()
                      if not spec.read_only and name != 'run_duration_s')
    parameters = AsyncParameterClient(sim.client, 'followbot_sim')
    sim.spin_until(parameters.services_are_ready)

    def set_parameters(changes: dict) -> list:
        future = parameters.set_parameters([Parameter(name, value=value)
                                            for name, value in changes.items()])
        sim.spin_until(future.done)
        return future.result().results

    @given(changes=strategies.dictionaries(strategies.sampled_from(writable),
                                           parameter_values(), min_size=1, max_size=3))
    def set_any_parameters(changes):
        results = set_parameters(changes)
        assert all(result.successful or result.reason for result in results)
        assert sim.world.time_s >= 0.0

    set_any_parameters()
    # As fast as possible again, to drive it within the test's time.
    assert set_parameters({'real_time_factor': 0.0})[0].successful
    sim.command(0.3)
    sim.run_until(sim.world.time_s + GOOD_COMMAND_S)
    assert sim.world.robot_twist()[0] > 0.25
