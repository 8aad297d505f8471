"""
Record topics into a rosbag2-compatible MCAP file from a node, as ``ros2 bag record`` would.

Messages are taken serialised (``raw=True``) and written as they came: nothing is deserialised
or serialised again per message. As in Jazzy's rosbag2, a topic is subscribed once a publisher
of it is seen, with a QoS its publishers are all compatible with; the log time is the time of
reception (the node's clock when it uses simulated time); the publish time is the publisher's
send time. Where tf2_msgs is not importable, ``/tf`` can still be recorded from an odometry topic
(the simulator's ``/tf`` is its odometry pose) and ``/tf_static`` from given transforms: both
are then encoded from TFMessage's definition.
"""

from followbot.recording import (canonical_type_name, DEFAULT_COMPRESSION, header_stamp_ns,
                                 import_message_class, OfferedQos, RecordingError,
                                 RecordingWriter, STATIC_TF_QOS, TF_MESSAGE_TYPE)
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

RECORDER_NODE = 'followbot_recorder'
# How often (wall clock) topics still without publisher are looked up again.
DISCOVERY_PERIOD_S = 0.1
# Messages a subscription keeps while the recorder is busy writing: a burst of 5 s of camera at
# 20 Hz. Memory is only used when the recorder falls behind (at most ~90 MB for 640x480 bgr8).
QUEUE_DEPTH = 100
# Small messages come many times more often (/clock at 100 Hz of simulated time, several times
# faster than real time in lockstep): their subscriptions keep 20 s of /clock, a few MB at most,
# so a recorder that the machine leaves unscheduled for a while catches up without a loss.
SMALL_MESSAGE_QUEUE_DEPTH = 2000
# Types whose messages are large, kept QUEUE_DEPTH deep; the others SMALL_MESSAGE_QUEUE_DEPTH.
LARGE_MESSAGE_TYPES = frozenset(('sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage',
                                 'sensor_msgs/msg/PointCloud2'))
TF_TOPIC = '/tf'
# Stands for the class of a topic recorded with whatever type its publishers use.
AS_PUBLISHED = object()
TF_STATIC_TOPIC = '/tf_static'


def offered_qos(profile: QoSProfile) -> OfferedQos:
    """
    Describe a publisher's QoS profile as a recording keeps it.

    :param profile: the profile, as ``get_publishers_info_by_topic`` reports it.
    :return: the policies by their rmw names, durations in nanoseconds.
    """
    return OfferedQos(
        history=profile.history.name.lower(), depth=profile.depth,
        reliability=profile.reliability.name.lower(),
        durability=profile.durability.name.lower(),
        deadline_ns=profile.deadline.nanoseconds, lifespan_ns=profile.lifespan.nanoseconds,
        liveliness=profile.liveliness.name.lower(),
        liveliness_lease_duration_ns=profile.liveliness_lease_duration.nanoseconds,
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions)


def subscription_qos(offers: list, depth: int = QUEUE_DEPTH) -> QoSProfile:
    """
    Return the QoS that receives from every publisher with the best delivery they all offer.

    Reliable if all publishers are reliable (a best-effort subscription would let large images
    be lost between processes even when the machine keeps up); transient local if all are,
    so latched messages such as ``/tf_static`` arrive too. This is rosbag2's rule.

    :param offers: the publishers' QoS profiles.
    :param depth: messages the subscription keeps while the recorder is busy.
    :return: the subscription's profile.
    """
    reliable = bool(offers) and all(
        offer.reliability == ReliabilityPolicy.RELIABLE for offer in offers)
    latched = bool(offers) and all(
        offer.durability == DurabilityPolicy.TRANSIENT_LOCAL for offer in offers)
    return QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def odometry_transform(odometry: Odometry) -> TransformStamped:
    """
    Return the transform an odometry message states: header frame to child frame, its pose.

    :param odometry: the odometry.
    :return: the TransformStamped ``/tf`` carries for it.
    """
    transform = TransformStamped(header=odometry.header,
                                 child_frame_id=odometry.child_frame_id)
    position = odometry.pose.pose.position
    transform.transform.translation.x = position.x
    transform.transform.translation.y = position.y
    transform.transform.translation.z = position.z
    transform.transform.rotation = odometry.pose.pose.orientation
    return transform


class Recorder(Node):
    """A node that records a list of topics into an MCAP file until it is destroyed."""

    def __init__(self, path, topics, compression: str = DEFAULT_COMPRESSION,
                 tf_odometry_topic: str | None = None, static_transforms=(),
                 node_name: str = RECORDER_NODE, progress_topic: str | None = None, **kwargs):
        """
        Create the recording and subscribe to each topic once it has a publisher.

        :param path: the ``.mcap`` file to write; an existing file is replaced.
        :param topics: (topic, message type name) pairs, such as
            ``('camera/rgb/image_raw', 'sensor_msgs/msg/Image')``; relative names are resolved
            in the node's namespace; a type of None records the type the publishers use.
        :param compression: chunk compression: 'lz4', 'zstd' or 'none'.
        :param tf_odometry_topic: where tf2_msgs is not importable, record ``/tf`` from this
            odometry topic (its header frame to its child frame).
        :param static_transforms: where tf2_msgs is not importable, the TransformStamped
            messages to record on ``/tf_static``, once, with the first message recorded.
        :param node_name: the node's name.
        :param progress_topic: a recorded topic whose messages start with a time (``/clock``,
            or a header): :attr:`progress_ns` is the time in the last one written.
        :param kwargs: passed to ``Node`` (``context=``, ``parameter_overrides=``, ...).
        :raises RecordingError: if a type name is invalid or its package is not importable,
            or the file cannot be created.
        """
        classes = []
        for topic, type_name in topics:
            if type_name is None:
                classes.append((topic, None, AS_PUBLISHED))
                continue
            full_type = canonical_type_name(type_name)
            message_class = import_message_class(full_type)
            if message_class is None and full_type != TF_MESSAGE_TYPE:
                raise RecordingError(f'Cannot record {topic}: the Python package of '
                                     f'{full_type} is not importable.')
            classes.append((topic, full_type, message_class))
        super().__init__(node_name, **kwargs)
        self.failures = []
        self.progress_ns = None
        self._progress_topic = None if progress_topic is None else self.resolve_topic_name(
            progress_topic)
        self._pending = {}
        fallback_tf = set()
        for topic, full_type, message_class in classes:
            name = self.resolve_topic_name(topic)
            if message_class is not None:
                self._pending[name] = (message_class, full_type)
            elif name in (TF_TOPIC, TF_STATIC_TOPIC):
                fallback_tf.add(name)
            else:
                self.get_logger().warn(f'tf2_msgs is not importable: {name} is not recorded.')
        self._use_sim_time = self.get_parameter('use_sim_time').value
        self._writer = RecordingWriter(path, compression=compression)
        self._static_transforms = list(static_transforms) if TF_STATIC_TOPIC in fallback_tf \
            else []
        self._warn_about_missing_tf(fallback_tf, tf_odometry_topic)
        if TF_TOPIC in fallback_tf and tf_odometry_topic:
            self._writer.add_topic(TF_TOPIC, TF_MESSAGE_TYPE, [OfferedQos(depth=QUEUE_DEPTH)])
            self.create_subscription(Odometry, tf_odometry_topic, self._odometry_callback,
                                     SMALL_MESSAGE_QUEUE_DEPTH)
        if self._static_transforms:
            self._writer.add_topic(TF_STATIC_TOPIC, TF_MESSAGE_TYPE, [STATIC_TF_QOS])
        # Wall clock: under simulated time a paused /clock must not stop the discovery.
        self._discovery_timer = self.create_timer(
            DISCOVERY_PERIOD_S, self._discovery_callback,
            clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._discovery_callback()

    @property
    def writer(self) -> RecordingWriter:
        """Return the RecordingWriter this node writes with (message counts, topics)."""
        return self._writer

    @property
    def waiting_topics(self) -> list:
        """Return the topics that have no publisher yet, so are not recorded yet."""
        return sorted(self._pending)

    @property
    def matched(self) -> bool:
        """
        Tell whether every topic is subscribed and each subscription hears its publishers.

        A publisher sends only to the subscriptions it has matched: a run that starts before
        this is true may lose its first messages from the recording.
        """
        return not self._pending and all(
            subscription.get_publisher_count() > 0 for subscription in self.subscriptions)

    def _warn_about_missing_tf(self, fallback_tf: set, tf_odometry_topic) -> None:
        if TF_TOPIC in fallback_tf and not tf_odometry_topic:
            self.get_logger().warn('tf2_msgs is not importable and no odometry topic was '
                                   'given: /tf is not recorded.')
        if TF_STATIC_TOPIC in fallback_tf and not self._static_transforms:
            self.get_logger().warn('tf2_msgs is not importable and no static transforms were '
                                   'given: /tf_static is not recorded.')

    def _discovery_callback(self) -> None:
        for name in list(self._pending):
            publishers = self.get_publishers_info_by_topic(name)
            if not publishers:
                continue
            message_class, type_name = self._pending.pop(name)
            if message_class is AS_PUBLISHED:
                type_name = canonical_type_name(publishers[0].topic_type)
                message_class = import_message_class(type_name)
                if message_class is None:
                    reason = f'the Python package of {type_name} is not importable'
                    self.failures.append(f'{name}: {reason}')
                    self.get_logger().error(f'Not recorded: {name}, {reason}.')
                    continue
            offers = [publisher.qos_profile for publisher in publishers]
            type_hash = str(publishers[0].topic_type_hash)
            self._writer.add_topic(name, type_name, [offered_qos(offer) for offer in offers],
                                   type_hash=None if type_hash == 'INVALID' else type_hash)
            self.create_subscription(
                message_class, name,
                lambda data, info, topic=name: self._message_callback(topic, data, info),
                subscription_qos(offers, QUEUE_DEPTH if type_name in LARGE_MESSAGE_TYPES
                                 else SMALL_MESSAGE_QUEUE_DEPTH), raw=True)
        if not self._pending:
            self._discovery_timer.cancel()

    def _log_time_ns(self, info: dict) -> int:
        if self._use_sim_time:
            return self.get_clock().now().nanoseconds
        return info['received_timestamp']

    def _message_callback(self, topic: str, data: bytes, info: dict) -> None:
        log_time_ns = self._log_time_ns(info)
        if topic == self._progress_topic:
            self.progress_ns = header_stamp_ns(data)
        self._write_static_transforms(log_time_ns)
        self._guarded(self._writer.write, topic, data, log_time_ns,
                      publish_time_ns=info['source_timestamp'],
                      sequence=info.get('publication_sequence_number') or 0)

    def _odometry_callback(self, odometry: Odometry, info: dict) -> None:
        log_time_ns = self._log_time_ns(info)
        self._write_static_transforms(log_time_ns)
        self._guarded(self._writer.write_transforms, TF_TOPIC, [odometry_transform(odometry)],
                      log_time_ns)

    def _write_static_transforms(self, log_time_ns: int) -> None:
        if self._static_transforms:
            static, self._static_transforms = self._static_transforms, []
            self._guarded(self._writer.write_transforms, TF_STATIC_TOPIC, static, log_time_ns)

    def _guarded(self, write, *arguments, **keywords) -> None:
        try:
            write(*arguments, **keywords)
        except RecordingError as error:
            self.failures.append(str(error))
            self.get_logger().error(f'Not recorded: {error}', throttle_duration_sec=5.0)

    def destroy_node(self):
        """Finish the recording (index and summary), then destroy the node."""
        self._writer.close()
        return super().destroy_node()
