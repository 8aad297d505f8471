"""
The recorder node over real DDS: publishers in this process, the file read back by rosbags.

Each test publishes real messages with rclpy publishers, records them with the Recorder node in
the same executor, closes the recording and reads it with the independent ``rosbags`` library.
"""

import importlib
import sys
import time

from conftest import spin_until
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot.recording import RecordingError
from followbot_sim.recorder import Recorder
from geometry_msgs.msg import TransformStamped, Twist
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image

MESSAGES_PER_TOPIC = 3
WIDTH_PX = 640
HEIGHT_PX = 480
TF_STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
TF_TYPE = 'tf2_msgs/msg/TFMessage'
SIM_TIME_S = 42.5


def tf_message_class():
    """Return TFMessage; fail with the fix when tf2_msgs is not importable."""
    try:
        return importlib.import_module('tf2_msgs.msg').TFMessage
    except ImportError as error:
        pytest.fail(f'tf2_msgs is not importable ({error}): run make setup')


def camera_image(index: int) -> Image:
    """Return a 640x480 bgr8 frame whose pixels depend on its index."""
    pixels = np.full((HEIGHT_PX, WIDTH_PX, 3), index, np.uint8)
    pixels[index, :, 2] = 255
    msg = Image(height=HEIGHT_PX, width=WIDTH_PX, encoding='bgr8', step=3 * WIDTH_PX,
                data=pixels.tobytes())
    msg.header.frame_id = 'camera_rgb_optical_frame'
    msg.header.stamp.sec = index
    return msg


def transform(parent: str, child: str, x_m: float) -> TransformStamped:
    """Return a transform along x."""
    msg = TransformStamped(child_frame_id=child)
    msg.header.frame_id = parent
    msg.transform.translation.x = x_m
    msg.transform.rotation.w = 1.0
    return msg


def odometry(index: int) -> Odometry:
    """Return the odometry of a robot that moved ``index`` decimetres."""
    msg = Odometry(child_frame_id='base_footprint')
    msg.header.frame_id = 'odom'
    msg.header.stamp.sec = index
    msg.pose.pose.position.x = index / 10
    msg.pose.pose.orientation.z = 0.6
    msg.pose.pose.orientation.w = 0.8
    return msg


def type_name(message_class) -> str:
    """Return the full type name of a message class, such as sensor_msgs/msg/Image."""
    return f'{message_class.__module__.split(".")[0]}/msg/{message_class.__name__}'


def message_table(tf_message) -> dict:
    """Return {topic: (class, depth, messages)} of what the simulator and follower publish."""
    def score(index):
        return DiagnosticArray(status=[DiagnosticStatus(
            name='followbot_sim: course score', hardware_id='followbot_sim',
            values=[KeyValue(key='laps_completed', value=str(index))])])

    def command(index):
        msg = Twist()
        msg.linear.x = 0.2
        msg.angular.z = index / 4
        return msg

    indices = range(MESSAGES_PER_TOPIC)
    return {
        'camera/rgb/image_raw': (Image, 10, [camera_image(index) for index in indices]),
        'camera/rgb/camera_info': (CameraInfo, 10,
                                   [CameraInfo(width=WIDTH_PX + index) for index in indices]),
        'cmd_vel': (Twist, 10, [command(index) for index in indices]),
        'odom': (Odometry, 10, [odometry(index) for index in indices]),
        '/diagnostics': (DiagnosticArray, 10, [score(index) for index in indices]),
        '/tf': (tf_message, 100, [tf_message(transforms=[transform(
            'odom', 'base_footprint', float(index))]) for index in indices]),
    }


class Publishers:
    """A node publishing the test's messages, and the recorder, in one executor."""

    def __init__(self, context):
        """Create the publishing node and the executor; :meth:`start` adds the recorder."""
        self.node = Node('recorded_publisher', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.recorder = None

    def start(self, *args, **kwargs) -> Recorder:
        """Start a Recorder in the same context and executor."""
        self.recorder = Recorder(*args, context=self.node.context, **kwargs)
        self.executor.add_node(self.recorder)
        return self.recorder

    def wait_until_recorded(self, publishers, count: int) -> None:
        """Wait for the recorder to subscribe to every publisher, or for ``count`` messages."""
        assert spin_until(self.executor, lambda: all(
            publisher.get_subscription_count() > 0 for publisher in publishers)
            if publishers else self.recorder.writer.message_count >= count)

    def stop_recording(self) -> None:
        """Destroy the recorder, which finishes the file."""
        self.executor.remove_node(self.recorder)
        self.recorder.destroy_node()

    def close(self) -> None:
        """Destroy everything left."""
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def publishers(ros_context):
    """Yield the publishing side, destroyed after the test."""
    harness = Publishers(ros_context)
    yield harness
    harness.close()


def read_back(path) -> dict:
    """Return {topic: [(log time ns, message)]} and {topic: offered QoS} as rosbags reads them."""
    messages = {}
    with AnyReader([path]) as reader:
        qos = {connection.topic: connection.ext.offered_qos_profiles
               for connection in reader.connections}
        for connection, log_time_ns, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (log_time_ns, reader.deserialize(raw, connection.msgtype)))
    return messages, qos


def test_every_topic_is_recorded_with_the_values_published(publishers, tmp_path):
    tf_message = tf_message_class()
    table = message_table(tf_message)
    static_publisher = publishers.node.create_publisher(tf_message, '/tf_static',
                                                        TF_STATIC_QOS)
    # Published before the recorder exists: only a latched subscription still gets it.
    static_publisher.publish(tf_message(transforms=[transform('base_link', 'camera_link',
                                                              0.1)]))
    topic_publishers = {topic: publishers.node.create_publisher(message_class, topic, depth)
                        for topic, (message_class, depth, _) in table.items()}
    path = tmp_path / 'run.mcap'
    recorder = publishers.start(path, [(topic, type_name(message_class)) for topic, (
        message_class, _, _) in table.items()] + [('/tf_static', TF_TYPE)])
    publishers.wait_until_recorded(list(topic_publishers.values()), 0)
    before_ns = time.time_ns()
    for index in range(MESSAGES_PER_TOPIC):
        for topic, (_, _, messages) in table.items():
            topic_publishers[topic].publish(messages[index])
    expected_count = MESSAGES_PER_TOPIC * len(table) + 1
    publishers.wait_until_recorded([], expected_count)
    after_ns = time.time_ns()
    assert recorder.waiting_topics == []
    publishers.stop_recording()

    recorded, qos = read_back(path)
    assert recorded['/tf_static'][0][1].transforms[0].child_frame_id == 'camera_link'
    assert qos['/tf_static'][0].durability == QosDurability.TRANSIENT_LOCAL
    assert qos['/camera/rgb/image_raw'][0].reliability == QosReliability.RELIABLE
    images = [message for _, message in recorded['/camera/rgb/image_raw']]
    for index, image in enumerate(images):
        assert image.header.stamp.sec == index
        assert (image.width, image.height, image.encoding) == (WIDTH_PX, HEIGHT_PX, 'bgr8')
        assert np.array_equal(image.data, np.frombuffer(camera_image(index).data, np.uint8))
    assert [info.width for _, info in recorded['/camera/rgb/camera_info']] == [
        WIDTH_PX + index for index in range(MESSAGES_PER_TOPIC)]
    assert [command.angular.z for _, command in recorded['/cmd_vel']] == [0.0, 0.25, 0.5]
    assert [odom.pose.pose.position.x for _, odom in recorded['/odom']] == [0.0, 0.1, 0.2]
    assert [array.status[0].values[0].value for _, array in recorded['/diagnostics']] == [
        '0', '1', '2']
    assert [tf.transforms[0].transform.translation.x for _, tf in recorded['/tf']] == [
        0.0, 1.0, 2.0]
    # Without simulated time, the log time is the time of reception, as in rosbag2.
    for topic in table:
        name = topic if topic.startswith('/') else '/' + topic
        assert all(before_ns <= log_time_ns <= after_ns for log_time_ns, _ in recorded[name])


def test_a_best_effort_publisher_is_recorded_best_effort(publishers, tmp_path):
    publisher = publishers.node.create_publisher(Twist, 'cmd_vel', qos_profile_sensor_data)
    publishers.start(tmp_path / 'run.mcap', [('cmd_vel', 'geometry_msgs/msg/Twist')])
    publishers.wait_until_recorded([publisher], 0)
    publisher.publish(Twist())
    publishers.wait_until_recorded([], 1)
    publishers.stop_recording()
    recorded, qos = read_back(tmp_path / 'run.mcap')
    assert len(recorded['/cmd_vel']) == 1
    assert qos['/cmd_vel'][0].reliability == QosReliability.BEST_EFFORT


def test_under_simulated_time_the_log_time_is_the_simulated_time(publishers, tmp_path):
    clock_publisher = publishers.node.create_publisher(Clock, '/clock', 10)
    publisher = publishers.node.create_publisher(Twist, 'cmd_vel', 10)
    recorder = publishers.start(tmp_path / 'run.mcap', [('cmd_vel', 'geometry_msgs/msg/Twist')],
                                parameter_overrides=[Parameter('use_sim_time', value=True)])
    publishers.wait_until_recorded([publisher], 0)
    sim_time = Clock()
    sim_time.clock.sec = int(SIM_TIME_S)
    sim_time.clock.nanosec = int((SIM_TIME_S % 1) * 1e9)
    assert spin_until(publishers.executor, lambda: clock_publisher.publish(sim_time) or (
        recorder.get_clock().now().nanoseconds == int(SIM_TIME_S * 1e9)))
    publisher.publish(Twist())
    publishers.wait_until_recorded([], 1)
    publishers.stop_recording()
    recorded, _ = read_back(tmp_path / 'run.mcap')
    assert [log_time_ns for log_time_ns, _ in recorded['/cmd_vel']] == [int(SIM_TIME_S * 1e9)]


def test_without_tf2_msgs_tf_is_recorded_from_odometry(publishers, tmp_path, monkeypatch):
    # As on a machine where tf2_msgs is not installed: importing it fails.
    monkeypatch.setitem(sys.modules, 'tf2_msgs.msg', None)
    publisher = publishers.node.create_publisher(Odometry, 'odom', 10)
    static = [transform('base_footprint', 'base_link', 0.0),
              transform('base_link', 'camera_link', 0.1)]
    publishers.start(tmp_path / 'run.mcap', [('/tf', TF_TYPE), ('/tf_static', TF_TYPE)],
                     tf_odometry_topic='odom', static_transforms=static)
    publishers.wait_until_recorded([publisher], 0)
    for index in range(MESSAGES_PER_TOPIC):
        publisher.publish(odometry(index))
    publishers.wait_until_recorded([], MESSAGES_PER_TOPIC + 1)
    publishers.stop_recording()
    recorded, _ = read_back(tmp_path / 'run.mcap')
    moving = [tf.transforms[0] for _, tf in recorded['/tf']]
    assert [(item.header.frame_id, item.child_frame_id) for item in moving] == [
        ('odom', 'base_footprint')] * MESSAGES_PER_TOPIC
    assert [item.transform.translation.x for item in moving] == [0.0, 0.1, 0.2]
    assert [item.header.stamp.sec for item in moving] == [0, 1, 2]
    assert moving[0].transform.rotation.z == pytest.approx(0.6)
    (static_time_ns, static_tf), = recorded['/tf_static']
    assert [item.child_frame_id for item in static_tf.transforms] == ['base_link', 'camera_link']
    assert static_time_ns == recorded['/tf'][0][0]


def test_a_type_whose_package_is_missing_is_refused(publishers, tmp_path):
    with pytest.raises(RecordingError, match='no_such_msgs/msg/Thing is not importable'):
        publishers.start(tmp_path / 'run.mcap', [('thing', 'no_such_msgs/msg/Thing')])
