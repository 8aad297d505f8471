"""
``ros2 run followbot replay run.mcap``: feed a recording's camera to a follower, compare commands.

Offline regression on real or simulated recordings. A real follower node runs in this process;
the recording's camera frames (raw or compressed), their camera_info, the robot's wheel
odometry and its ``/clock`` are published to it as they were recorded, and each command it
answers with is compared with the command recorded for that frame (see
:mod:`followbot.command_comparison`). By default each frame waits for the follower's answer,
so the replay runs as fast as the follower can; ``--rate 1`` sends the frames at their recorded
pace. With ``--params-file`` the follower is a changed one
and the differences are the point: they are printed.

The follower runs under a namespace of its own, with its own clock topic: it never drives a
robot or simulator running on the same ROS domain.

Exit codes: 0 when every recorded command is matched within ``--tolerance``, 1 when some
differ, 2 when the file or the arguments cannot be used.
"""

import argparse
import os
import sys
import time

from followbot.command_comparison import (answers_by_order, answers_by_status, Comparison,
                                          FrameResult, Velocity)
from followbot.follower_node import COMPRESSED_SUFFIX, FollowerNode, LONGEST_IMAGE_TIMEOUT_S
from followbot.node_runner import init_rclpy, RosStartError
from followbot.number_options import number_in
from followbot.parameters_file import check_reaches, ParametersFileError
from followbot.recording import (header_stamp_ns, import_message_class, read_messages,
                                 RecordingError)
from geometry_msgs.msg import Twist, TwistStamped
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

IMAGE_TYPE = 'sensor_msgs/msg/Image'
COMPRESSED_TYPE = 'sensor_msgs/msg/CompressedImage'
CAMERA_INFO_TYPE = 'sensor_msgs/msg/CameraInfo'
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'
# The wheel odometry the follower drives by (see followbot.follower_node): ``.../odom``, not the
# simulator's ``.../ground_truth/odom``.
ODOMETRY_NAME = 'odom'
GROUND_TRUTH_ODOMETRY_SUFFIX = '/ground_truth/odom'
STATUS_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
# The follower's status topic (~/status): the only DiagnosticArray named .../status.
STATUS_SUFFIX = '/status'
COMMAND_TYPES = {'geometry_msgs/msg/Twist': False, 'geometry_msgs/msg/TwistStamped': True}
COMMAND_TOPIC_NAME = 'cmd_vel'
CAMERA_INFO_NAME = 'camera_info'
# The follower's topics, relative to its namespace (see followbot.follower_node).
FOLLOWER_IMAGE_TOPIC = 'camera/rgb/image_raw'
FOLLOWER_CAMERA_INFO_TOPIC = 'camera/rgb/camera_info'
FOLLOWER_ODOMETRY_TOPIC = 'odom'
CLOCK_TOPIC = '/clock'
REPLAY_CLOCK_TOPIC = 'clock'
NAMESPACE_PREFIX = '/followbot_replay_'
# Depth of the replay's publishers and command subscription: one frame is in flight at a time.
QUEUE_DEPTH = 10
SPIN_S = 0.01
# How long (wall) the replay waits for the in-process follower to connect.
CONNECT_TIMEOUT_S = 10.0
DEFAULT_ANSWER_TIMEOUT_S = 1.0
NANOSECONDS_PER_SECOND = 1e9
EXIT_MATCH, EXIT_DIFFER, EXIT_UNUSABLE = 0, 1, 2
# The follower stops when no frame came for image_timeout_s of wall time. A replay's pace is
# not the camera's (the machine may stall it): the replayed follower waits as long as it may.
IMAGE_TIMEOUT_PARAMETER = 'image_timeout_s'


def parse_arguments(argv=None) -> argparse.Namespace:
    """
    Read the command line; argparse exits with code 2 on a bad one.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the options.
    """
    parser = argparse.ArgumentParser(
        prog='replay',
        description="Feed a recording's camera frames to a follower and compare its commands "
                    'with the recorded ones. Exit code 0: all match within --tolerance; 1: '
                    'some differ; 2: the file or the arguments cannot be used.')
    parser.add_argument('recording', help='the .mcap file (e.g. from followbot --record)')
    parser.add_argument('--rate', type=number_in(0.0), default=0.0, metavar='FACTOR',
                        help='recorded seconds per wall second; 0 (default) sends each frame '
                             'as soon as the follower answered the previous one')
    parser.add_argument('--tolerance', type=number_in(0.0), default=0.0, metavar='VALUE',
                        help='largest difference of a velocity component (m/s, rad/s) still '
                             'counted as a match (default: 0, identical)')
    parser.add_argument('--params-file', default=None, metavar='FILE',
                        help="the follower's parameters (as for ros2 run followbot follower "
                             '--ros-args --params-file FILE, but the follower runs under the '
                             "replay's namespace: its section must reach it there, as "
                             "'/**/follower' does); its defaults when absent")
    parser.add_argument('--camera-topic', default=None, metavar='TOPIC',
                        help="the recording's Image or CompressedImage topic (needed only when "
                             'it has several)')
    parser.add_argument('--command-topic', default=None, metavar='TOPIC',
                        help="the recording's Twist or TwistStamped command topic (default: the "
                             'one named .../cmd_vel)')
    parser.add_argument('--answer-timeout', type=number_in(0.0, above=True),
                        default=DEFAULT_ANSWER_TIMEOUT_S, metavar='SECONDS',
                        help='longest wait (wall time) for the answer to one frame (default: '
                             f'{DEFAULT_ANSWER_TIMEOUT_S:g})')
    options = parser.parse_args(argv)
    if options.params_file is not None:
        # The follower runs under the replay's own namespace: a section written for
        # `ros2 run followbot follower` alone (follower:) would not reach it, silently.
        try:
            check_reaches(options.params_file, f'{replay_namespace()}/{FollowerNode.NODE_NAME}')
        except ParametersFileError as error:
            parser.error(f'--params-file: {error}')
    return options


def replay_namespace() -> str:
    """Return the namespace of this process's replay: its follower's and feeder's topics."""
    return f'{NAMESPACE_PREFIX}{os.getpid()}'


class RecordingPlan:
    """What a recording offers for a replay: its topics, frames and recorded commands."""

    def __init__(self, path, camera_topic: str | None = None, command_topic: str | None = None):
        """
        Read the recording once: topics, the frames' and the commands' publish times.

        :param path: the ``.mcap`` file.
        :param camera_topic: the image topic, or None to take the only one.
        :param command_topic: the command topic, or None to take the one named ``cmd_vel``.
        :raises RecordingError: if the file cannot be read or lacks what a replay needs.
        """
        types = {}
        frame_times = {}
        frame_stamps = {}
        statuses = {}
        camera_infos = {}
        odometry = {}
        commands = []
        for message in read_messages(path):
            types.setdefault(message.topic, message.type_name)
            if message.type_name in (IMAGE_TYPE, COMPRESSED_TYPE):
                frame_times.setdefault(message.topic, []).append(message.publish_time_ns)
                frame_stamps.setdefault(message.topic, []).append(
                    header_stamp_ns(message.data))
            elif message.type_name in COMMAND_TYPES:
                commands.append(message)
            elif message.type_name == ODOMETRY_TYPE and is_wheel_odometry(message.topic):
                odometry.setdefault(message.topic, []).append(
                    (header_stamp_ns(message.data) or 0, message.data))
            elif message.type_name == CAMERA_INFO_TYPE:
                camera_infos.setdefault(message.topic, {}).setdefault(
                    header_stamp_ns(message.data), message.data)
            elif message.type_name == STATUS_TYPE and message.topic.endswith(STATUS_SUFFIX):
                statuses.setdefault(message.topic, []).append(
                    (header_stamp_ns(message.data), message.publish_time_ns))
        self.camera_topic = _choose(
            camera_topic, [topic for topic, name in types.items()
                           if name in (IMAGE_TYPE, COMPRESSED_TYPE)], 'camera', path)
        self.camera_type = types[self.camera_topic]
        self.camera_info_topic = camera_info_topic(self.camera_topic)
        # Each frame's camera_info by its stamp: a recording may log the two in either order.
        self.camera_infos = camera_infos.get(self.camera_info_topic, {})
        # /clock, or a robot's own under its namespace: the only one, or none.
        clocks = [topic for topic, name in types.items()
                  if name == CLOCK_TYPE and topic.endswith(CLOCK_TOPIC)]
        self.clock_topic = clocks[0] if len(clocks) == 1 else None
        self.odometry_topic = odometry_topic(self.camera_topic, list(odometry))
        # By stamp: the robot's follower had taken each before the frame of its time (the
        # simulator sends it first), though a recording may log the two in either order.
        self.odometry = sorted(odometry.get(self.odometry_topic, ()), key=lambda item: item[0])
        command_topics = [topic for topic, name in types.items() if name in COMMAND_TYPES]
        named = [topic for topic in command_topics if topic.rsplit('/', 1)[-1] ==
                 COMMAND_TOPIC_NAME]
        self.command_topic = None
        if command_topic is not None or command_topics:
            self.command_topic = _choose(
                command_topic, command_topics if command_topic else named or command_topics,
                'command', path)
        commands = [message for message in commands if message.topic == self.command_topic]
        self.frame_times_ns = frame_times[self.camera_topic]
        self.frame_stamps_ns = frame_stamps[self.camera_topic]
        self.recorded_commands = [_velocity(message) for message in commands]
        command_times_ns = [message.publish_time_ns for message in commands]
        # The follower's status names the frame each command answered; one follower only.
        self.paired_by = 'follower status' if len(statuses) == 1 else 'publish order'
        if len(statuses) == 1:
            answers = answers_by_status(self.frame_stamps_ns, next(iter(statuses.values())),
                                        command_times_ns)
        else:
            answers = answers_by_order(self.frame_times_ns, command_times_ns)
        self.recorded_answers = [None if index is None else self.recorded_commands[index]
                                 for index in answers]

    def describe(self) -> str:
        """Return one line naming the topics the replay uses."""
        commands = (f'{len(self.recorded_commands)} commands on {self.command_topic} (paired '
                    f'with frames by {self.paired_by})'
                    if self.command_topic else 'no recorded commands')
        odometry = f', odometry on {self.odometry_topic}' if self.odometry_topic else ''
        return (f'{len(self.frame_times_ns)} frames on {self.camera_topic} '
                f'({self.camera_type.rsplit("/", 1)[-1]}){odometry}, {commands}')


def camera_info_topic(image_topic: str) -> str:
    """
    Return the camera_info topic that goes with an image topic, as image_transport pairs them.

    :param image_topic: such as ``/camera/rgb/image_raw`` or ``.../image_raw/compressed``.
    :return: such as ``/camera/rgb/camera_info``.
    """
    return _base_topic(image_topic).rsplit('/', 1)[0] + '/' + CAMERA_INFO_NAME


def _base_topic(image_topic: str) -> str:
    """Return an image topic without image_transport's ``/compressed`` suffix."""
    return image_topic[:-len(COMPRESSED_SUFFIX)] if image_topic.endswith(COMPRESSED_SUFFIX) \
        else image_topic


def is_wheel_odometry(topic: str) -> bool:
    """Tell whether an Odometry topic is a robot's wheel odometry (``.../odom``)."""
    return (topic.rsplit('/', 1)[-1] == ODOMETRY_NAME
            and not topic.endswith(GROUND_TRUTH_ODOMETRY_SUFFIX))


def odometry_topic(image_topic: str, topics: list) -> str | None:
    """
    Return the wheel odometry topic of the robot whose camera an image topic is, or None.

    :param image_topic: the camera topic replayed, such as ``/r1/camera/rgb/image_raw``.
    :param topics: the recording's ``nav_msgs/Odometry`` topics.
    :return: the one in the camera's namespace (``/r1/odom``), else the only one, else None.
    """
    wheel = [topic for topic in topics if is_wheel_odometry(topic)]
    base = _base_topic(image_topic)
    if base.endswith('/' + FOLLOWER_IMAGE_TOPIC):
        beside = base[:-len(FOLLOWER_IMAGE_TOPIC)] + ODOMETRY_NAME
        if beside in wheel:
            return beside
    return wheel[0] if len(wheel) == 1 else None


def _choose(wanted: str | None, candidates: list, what: str, path) -> str:
    if wanted is not None:
        if wanted not in candidates:
            raise RecordingError(f'{path} has no {what} topic {wanted}; it has: '
                                 + (', '.join(candidates) or 'none'))
        return wanted
    if len(candidates) != 1:
        raise RecordingError(
            f'{path} has no {what} topic to replay.' if not candidates else
            f'{path} has several {what} topics ({", ".join(candidates)}): choose one with '
            f'--{what}-topic.')
    return candidates[0]


def _velocity(message) -> Velocity:
    message_class = TwistStamped if COMMAND_TYPES[message.type_name] else Twist
    try:
        twist = deserialize_message(message.data, message_class)
    except Exception as error:  # noqa: B902 - rclpy raises several types for broken CDR.
        raise RecordingError(f'A message on {message.topic} is no {message.type_name}: '
                             f'{error}') from None
    return Velocity.from_twist(twist.twist if isinstance(twist, TwistStamped) else twist)


class ReplayFeeder(Node):
    """Publish recorded camera messages to the follower and collect its commands."""

    def __init__(self, compressed: bool, stamped_commands: bool, **kwargs):
        """
        Create the publishers and the command subscription, in the follower's namespace.

        :param compressed: publish CompressedImage on ``.../compressed`` instead of Image.
        :param stamped_commands: the follower publishes TwistStamped.
        :param kwargs: passed to ``Node`` (``context=``, ``namespace=``).
        """
        super().__init__('followbot_replay', **kwargs)
        image_topic = FOLLOWER_IMAGE_TOPIC + (COMPRESSED_SUFFIX if compressed else '')
        self.image_publisher = self.create_publisher(
            CompressedImage if compressed else Image, image_topic, QUEUE_DEPTH)
        self.camera_info_publisher = self.create_publisher(
            CameraInfo, FOLLOWER_CAMERA_INFO_TOPIC, QUEUE_DEPTH)
        self.clock_publisher = self.create_publisher(
            import_message_class(CLOCK_TYPE), REPLAY_CLOCK_TOPIC, QUEUE_DEPTH)
        self.odometry_publisher = self.create_publisher(
            import_message_class(ODOMETRY_TYPE), FOLLOWER_ODOMETRY_TOPIC, QUEUE_DEPTH)
        self.answers = []
        self.command_subscription = self.create_subscription(
            TwistStamped if stamped_commands else Twist, COMMAND_TOPIC_NAME,
            self.command_callback, QUEUE_DEPTH)

    def command_callback(self, msg) -> None:
        """Keep the follower's command."""
        self.answers.append(Velocity.from_twist(msg.twist if isinstance(msg, TwistStamped)
                                                else msg))

    @property
    def connected(self) -> bool:
        """Tell whether the follower hears the camera and this node hears the follower."""
        return (self.image_publisher.get_subscription_count() > 0
                and self.camera_info_publisher.get_subscription_count() > 0
                and self.odometry_publisher.get_subscription_count() > 0
                and self.command_subscription.get_publisher_count() > 0)


def _spin_until(executor, condition, deadline_s: float) -> bool:
    while not condition():
        if time.monotonic() >= deadline_s:
            return False
        executor.spin_once(timeout_sec=SPIN_S)
    return True


def replay(plan: RecordingPlan, path, options, context: Context) -> tuple:
    """
    Replay the recording into a follower on ``context`` and compare its answers.

    :param plan: what the recording holds.
    :param path: the recording.
    :param options: the command line's options (rate, tolerance, answer timeout).
    :param context: an initialised rclpy context, its arguments the follower's.
    :return: (the Comparison, wall seconds spent, recorded seconds the frames span).
    :raises RecordingError: if the file cannot be read on the second pass.
    :raises RuntimeError: if the follower does not connect.
    """
    namespace = replay_namespace()
    compressed = plan.camera_type == COMPRESSED_TYPE
    # The follower's /clock is the replay's own: a simulator on the domain cannot drive it.
    follower = FollowerNode(
        context=context, namespace=namespace,
        cli_args=['--ros-args', '-r', f'{CLOCK_TOPIC}:={namespace}/{REPLAY_CLOCK_TOPIC}'],
        parameter_overrides=[
            Parameter('use_sim_time', value=True),
            Parameter(IMAGE_TIMEOUT_PARAMETER, value=float(LONGEST_IMAGE_TIMEOUT_S)),
            Parameter('image_transport', value='compressed' if compressed else 'raw')])
    feeder = ReplayFeeder(compressed, follower.get_parameter('cmd_vel_stamped').value,
                          context=context, namespace=namespace)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(follower)
    executor.add_node(feeder)
    comparison = Comparison(options.tolerance)
    try:
        if not _spin_until(executor, lambda: feeder.connected,
                           time.monotonic() + CONNECT_TIMEOUT_S):
            raise RuntimeError('The follower did not connect to the replay within '
                               f'{CONNECT_TIMEOUT_S:g} s.')
        topics = [plan.camera_topic] + ([plan.clock_topic] if plan.clock_topic else [])
        odometry = iter(plan.odometry)
        next_odometry = next(odometry, None)
        camera_info = None
        start_wall_s = time.monotonic()
        first_log_ns = last_log_ns = None
        for message in read_messages(path, topics):
            if message.topic == plan.clock_topic:
                feeder.clock_publisher.publish(message.data)
                continue
            first_log_ns = message.log_time_ns if first_log_ns is None else first_log_ns
            last_log_ns = message.log_time_ns
            index = len(comparison.frames)
            if options.rate > 0.0:
                due_s = start_wall_s + (message.log_time_ns - first_log_ns) / (
                    NANOSECONDS_PER_SECOND * options.rate)
                _spin_until(executor, lambda: False, due_s)
            stamp_ns = header_stamp_ns(message.data)
            while next_odometry is not None and next_odometry[0] <= (stamp_ns or 0):
                # Each taken in turn: the follower keeps only the latest.
                taken = follower.odometry_messages
                feeder.odometry_publisher.publish(next_odometry[1])
                _spin_until(executor, lambda: follower.odometry_messages > taken,
                            time.monotonic() + options.answer_timeout)
                next_odometry = next(odometry, None)
            # As the camera does: the intrinsics first, then the frame they describe.
            camera_info = plan.camera_infos.get(stamp_ns, camera_info)
            if camera_info is not None:
                feeder.camera_info_publisher.publish(camera_info)
            answered = len(feeder.answers)
            feeder.image_publisher.publish(message.data)
            _spin_until(executor, lambda: len(feeder.answers) > answered,
                        time.monotonic() + options.answer_timeout)
            comparison.add(FrameResult(
                index, (stamp_ns or message.log_time_ns) / NANOSECONDS_PER_SECOND,
                plan.recorded_answers[index] if index < len(plan.recorded_answers) else None,
                feeder.answers[answered] if len(feeder.answers) > answered else None))
        wall_s = time.monotonic() - start_wall_s
        recorded_s = ((last_log_ns - first_log_ns) / NANOSECONDS_PER_SECOND
                      if first_log_ns is not None else 0.0)
        return comparison, wall_s, recorded_s
    finally:
        executor.shutdown()
        feeder.destroy_node()
        follower.destroy_node()


def main(argv=None) -> int:
    """
    Run the replay and print its summary.

    :param argv: arguments without the program name.
    :return: 0 when all commands match, 1 when some differ, 2 when the input is unusable.
    """
    options = parse_arguments(argv)
    try:
        plan = RecordingPlan(options.recording, options.camera_topic, options.command_topic)
    except RecordingError as error:
        print(f'replay: {error}', file=sys.stderr, flush=True)
        return EXIT_UNUSABLE
    follower_setup = (f'parameters from {options.params_file}' if options.params_file
                      else 'default parameters')
    print(f'replay {options.recording}: {plan.describe()}; follower with {follower_setup}.',
          flush=True)
    arguments = ['replay'] + (['--ros-args', '--params-file', options.params_file]
                              if options.params_file else [])
    context = Context()
    try:
        init_rclpy(arguments, context=context, signal_handler_options=SignalHandlerOptions.NO)
    except RosStartError as error:
        print(f'replay: {error}', file=sys.stderr, flush=True)
        return EXIT_UNUSABLE
    try:
        comparison, wall_s, recorded_s = replay(plan, options.recording, options, context)
    except (RecordingError, RuntimeError) as error:
        print(f'replay: {error}', file=sys.stderr, flush=True)
        return EXIT_UNUSABLE
    except KeyboardInterrupt:
        return EXIT_UNUSABLE
    finally:
        rclpy.try_shutdown(context=context)
    for line in comparison.summary_lines():
        print(line, flush=True)
    speed = f' ({recorded_s / wall_s:.1f}x real time)' if wall_s > 0.0 and recorded_s else ''
    print(f'{wall_s:.1f} s wall for {recorded_s:.1f} s recorded{speed}.', flush=True)
    if not plan.command_topic:
        print('Nothing to compare with: the recording holds no commands.', flush=True)
    return EXIT_MATCH if comparison.matches else EXIT_DIFFER


if __name__ == '__main__':
    sys.exit(main())
