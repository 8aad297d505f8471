"""
Recordings written by followbot.recording, read back by independent readers.

Messages are serialised by rclpy (the bytes a ``raw=True`` subscription delivers), written, and
read back with the ``rosbags`` library (its own MCAP reader and CDR deserialiser) and with the
``mcap`` library's reader and ROS 2 decoder, comparing field values.
"""

import importlib
import os
from pathlib import Path
import signal
import subprocess
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot import recording
from followbot.recording import (MessageDefinitions, OfferedQos, read_messages,
                                 RecordingError, RecordingWriter)
from geometry_msgs.msg import TransformStamped, Twist
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability
from sensor_msgs.msg import CameraInfo, Image
import yaml

SECOND_NS = 1_000_000_000
CHILD_TIMEOUT_S = 60.0


def image() -> Image:
    """Return a small bgr8 image whose pixels all differ."""
    msg = Image(height=4, width=5, encoding='bgr8', step=15,
                data=np.arange(60, dtype=np.uint8).tobytes())
    msg.header.frame_id = 'camera_rgb_optical_frame'
    msg.header.stamp.sec = 12
    msg.header.stamp.nanosec = 500
    return msg


def camera_info() -> CameraInfo:
    """Return a camera_info with the book's Kinect intrinsics."""
    msg = CameraInfo(width=640, height=480, distortion_model='plumb_bob')
    msg.k = [554.3, 0.0, 320.5, 0.0, 554.3, 240.5, 0.0, 0.0, 1.0]
    msg.d = [0.0] * 5
    return msg


def twist() -> Twist:
    """Return a command turning left while driving."""
    msg = Twist()
    msg.linear.x = 0.2
    msg.angular.z = -0.35
    return msg


def odometry() -> Odometry:
    """Return an odometry message with a pose and a covariance."""
    msg = Odometry(child_frame_id='base_footprint')
    msg.header.frame_id = 'odom'
    msg.pose.pose.position.x = 1.5
    msg.pose.pose.orientation.z = 0.6
    msg.pose.pose.orientation.w = 0.8
    msg.pose.covariance = [float(index) for index in range(36)]
    return msg


def diagnostics() -> DiagnosticArray:
    """Return a score status like the simulator's."""
    status = DiagnosticStatus(level=DiagnosticStatus.OK, name='followbot_sim: course score',
                              hardware_id='followbot_sim', message='1 laps',
                              values=[KeyValue(key='laps_completed', value='1')])
    return DiagnosticArray(status=[status])


def transform(parent: str, child: str, x_m: float) -> TransformStamped:
    """Return a transform; frame names of odd lengths make CDR insert padding."""
    msg = TransformStamped(child_frame_id=child)
    msg.header.frame_id = parent
    msg.header.stamp.sec = 3
    msg.transform.translation.x = x_m
    msg.transform.rotation.w = 1.0
    return msg


# (topic, type, message): what the simulator and the follower publish, one of each.
MESSAGES = [
    ('/camera/rgb/image_raw', 'sensor_msgs/msg/Image', image()),
    ('/camera/rgb/camera_info', 'sensor_msgs/msg/CameraInfo', camera_info()),
    ('/cmd_vel', 'geometry_msgs/msg/Twist', twist()),
    ('/odom', 'nav_msgs/msg/Odometry', odometry()),
    ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', diagnostics()),
]


def write_all(path: Path, **options) -> None:
    """Write MESSAGES one second apart, in reverse time order, and transforms on /tf."""
    with RecordingWriter(path, **options) as writer:
        for index, (topic, type_name, message) in enumerate(MESSAGES):
            writer.add_topic(topic, type_name, [OfferedQos()])
            writer.write(topic, serialize_message(message), (10 - index) * SECOND_NS)
        writer.write_transforms('/tf', [transform('odom', 'base_footprint', 1.0),
                                        transform('a', 'b', 2.0)], 20 * SECOND_NS)


def as_array(value) -> np.ndarray:
    """Return a field value as an array; bytes (uint8[] in some readers) as numbers."""
    if isinstance(value, (bytes, bytearray)):
        return np.frombuffer(value, np.uint8)
    return np.asarray(value)


def assert_fields_equal(read, expected) -> None:
    """Compare a message read by another library with the rclpy message, field by field."""
    for name, field_type in expected.get_fields_and_field_types().items():
        written = getattr(expected, name)
        value = getattr(read, name)
        if field_type == 'octet':  # rclpy holds a byte as bytes, the other readers as an int.
            written = written[0]
        if hasattr(written, 'get_fields_and_field_types'):
            assert_fields_equal(value, written)
        elif isinstance(written, (list, tuple)) and written and hasattr(
                written[0], 'get_fields_and_field_types'):
            assert len(value) == len(written)
            for read_item, written_item in zip(value, written):
                assert_fields_equal(read_item, written_item)
        else:
            assert np.array_equal(as_array(value), as_array(written)), name


@pytest.fixture
def recording_path(tmp_path) -> Path:
    """Return the path of a recording of MESSAGES and two transforms, written in tmp_path."""
    path = tmp_path / 'run.mcap'
    write_all(path)
    return path


def test_rosbags_reads_every_message_with_its_field_values(recording_path):
    expected = {topic: message for topic, _, message in MESSAGES}
    with AnyReader([recording_path]) as reader:
        assert {connection.topic: connection.msgtype for connection in reader.connections} == {
            **{topic: type_name for topic, type_name, _ in MESSAGES},
            '/tf': 'tf2_msgs/msg/TFMessage'}
        read = {connection.topic: reader.deserialize(raw, connection.msgtype)
                for connection, _, raw in reader.messages()}
    for topic, message in expected.items():
        assert_fields_equal(read[topic], message)
    transforms = read['/tf'].transforms
    assert [(item.header.frame_id, item.child_frame_id) for item in transforms] == [
        ('odom', 'base_footprint'), ('a', 'b')]
    assert [item.transform.translation.x for item in transforms] == [1.0, 2.0]


def test_mcap_reader_decodes_every_message_from_the_schemas(recording_path):
    with open(recording_path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        decoded = {channel.topic: (schema, message) for schema, channel, _, message
                   in reader.iter_decoded_messages()}
    for topic, type_name, message in MESSAGES:
        schema, read = decoded[topic]
        assert (schema.name, schema.encoding) == (type_name, 'ros2msg')
        assert_fields_equal(read, message)


def test_channels_carry_rosbag2_qos_and_type_hash(recording_path):
    with AnyReader([recording_path]) as reader:
        qos = {connection.topic: connection.ext.offered_qos_profiles
               for connection in reader.connections}
    assert qos['/camera/rgb/image_raw'][0].reliability == QosReliability.RELIABLE
    assert qos['/camera/rgb/image_raw'][0].durability == QosDurability.VOLATILE
    with open(recording_path, 'rb') as stream:
        channels = make_reader(stream).get_summary().channels.values()
    hashes = {channel.topic: channel.metadata['topic_type_hash'] for channel in channels}
    assert hashes['/cmd_vel'] == MessageDefinitions().type_hash('geometry_msgs/msg/Twist')
    assert hashes['/cmd_vel'].startswith('RIHS01_')


def test_closing_writes_the_rosbag2_metadata_record(recording_path):
    with open(recording_path, 'rb') as stream:
        records = {record.name: record.metadata for record in make_reader(stream).iter_metadata()}
    metadata = yaml.safe_load(records['rosbag2']['serialized_metadata'])
    assert metadata['version'] == 9
    assert metadata['storage_identifier'] == 'mcap'
    assert metadata['message_count'] == len(MESSAGES) + 1
    assert metadata['starting_time']['nanoseconds_since_epoch'] == 6 * SECOND_NS
    assert metadata['duration']['nanoseconds'] == 14 * SECOND_NS
    counts = {entry['topic_metadata']['name']: entry['message_count']
              for entry in metadata['topics_with_message_count']}
    assert counts == {**{topic: 1 for topic, _, _ in MESSAGES}, '/tf': 1}
    assert metadata['relative_file_paths'] == ['run.mcap']


def test_read_messages_yields_serialised_messages_in_log_time_order(recording_path):
    read = list(read_messages(recording_path))
    assert [message.log_time_ns for message in read] == sorted(
        message.log_time_ns for message in read)
    # Written without a publish time: it is the log time.
    assert read[0] == ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', 6 * SECOND_NS,
                       serialize_message(diagnostics()), 6 * SECOND_NS)
    assert [message.topic for message in read_messages(recording_path, ['/cmd_vel', '/tf'])] \
        == ['/cmd_vel', '/tf']


@pytest.mark.parametrize('compression', ['none', 'lz4', 'zstd'])
def test_every_compression_reads_back_the_same(tmp_path, compression):
    path = tmp_path / 'run.mcap'
    write_all(path, compression=compression)
    with AnyReader([path]) as reader:
        assert len(list(reader.messages())) == len(MESSAGES) + 1
    assert [message.data for message in read_messages(path, ['/camera/rgb/image_raw'])] == [
        serialize_message(image())]


def test_rclpy_deserialises_transforms_encoded_from_the_definition(tmp_path):
    try:
        tf_message = importlib.import_module('tf2_msgs.msg').TFMessage
    except ImportError as error:
        pytest.fail(f'tf2_msgs is not importable ({error}): run make setup')
    transforms = [transform('odom', 'base_footprint', 1.0), transform('a', 'bc', -2.5)]
    with RecordingWriter(tmp_path / 'tf.mcap') as writer:
        encoded = writer.encode_transforms(transforms)
    # Not compared byte for byte: CDR leaves the content of alignment padding open (rclpy's
    # serialiser leaves it uninitialised), so equal messages may differ there.
    assert len(encoded) == len(serialize_message(tf_message(transforms=transforms)))
    assert deserialize_message(encoded, tf_message) == tf_message(transforms=transforms)


def test_transforms_accept_mappings_with_the_fields_of_a_transform(tmp_path):
    mapping = {'header': {'stamp': {'sec': 3, 'nanosec': 0}, 'frame_id': 'a'},
               'child_frame_id': 'b',
               'transform': {'translation': {'x': 2.0, 'y': 0.0, 'z': 0.0},
                             'rotation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}}
    with RecordingWriter(tmp_path / 'tf.mcap') as writer:
        assert writer.encode_transforms([mapping]) == writer.encode_transforms(
            [transform('a', 'b', 2.0)])


def share_without_tf2_msgs(tmp_path) -> Path:
    """Return a share folder with the packages TFMessage uses, but not tf2_msgs."""
    share = tmp_path / 'share'
    share.mkdir()
    for package in ('geometry_msgs', 'std_msgs', 'builtin_interfaces'):
        source = next(folder / package for folder in recording.default_share_dirs()
                      if (folder / package / 'msg').is_dir())
        (share / package).symlink_to(source)
    return share


def test_tf_is_written_from_the_built_in_definition_without_tf2_msgs(tmp_path):
    definitions = MessageDefinitions([share_without_tf2_msgs(tmp_path)])
    path = tmp_path / 'tf.mcap'
    with RecordingWriter(path, definitions=definitions) as writer:
        writer.write_transforms('/tf_static', [transform('base_link', 'camera_link', 0.1)], 0)
    assert definitions.full_text('tf2_msgs/msg/TFMessage').startswith(
        recording.BUILT_IN_DEFINITIONS['tf2_msgs/msg/TFMessage'])
    with AnyReader([path]) as reader:
        (connection, _, raw), = reader.messages()
        message = reader.deserialize(raw, connection.msgtype)
        latched = connection.ext.offered_qos_profiles[0].durability
    assert message.transforms[0].child_frame_id == 'camera_link'
    assert message.transforms[0].transform.translation.x == pytest.approx(0.1)
    assert latched == QosDurability.TRANSIENT_LOCAL


def write_msg(share: Path, type_name: str, text: str) -> None:
    """Write a .msg file into a share folder."""
    package, name = type_name.split('/')
    folder = share / package / 'msg'
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f'{name}.msg').write_text(text, encoding='utf-8')


def test_full_text_lists_dependencies_as_rosbag2_does(tmp_path):
    write_msg(tmp_path, 'pkg_a/Top', '# top\nint32 X=1\npkg_b/Middle middle\nLeaf[3] leaves\n')
    write_msg(tmp_path, 'pkg_a/Leaf', 'string<=8 name\n')
    write_msg(tmp_path, 'pkg_b/Middle', 'pkg_a/Leaf leaf  # the same leaf\nfloat64 x\n')
    separator = '\n' + '=' * 80 + '\n'
    # Dependencies sorted, depth first, each once: Middle's Leaf is already there.
    assert MessageDefinitions([tmp_path]).full_text('pkg_a/msg/Top') == (
        '# top\nint32 X=1\npkg_b/Middle middle\nLeaf[3] leaves\n'
        f'{separator}MSG: pkg_a/Leaf\nstring<=8 name\n'
        f'{separator}MSG: pkg_b/Middle\npkg_a/Leaf leaf  # the same leaf\nfloat64 x\n')


def test_qos_profile_is_serialised_as_rosbag2_version_9():
    assert yaml.safe_load(recording.qos_profiles_yaml([recording.STATIC_TF_QOS])) == [{
        'history': 'keep_last', 'depth': 1, 'reliability': 'reliable',
        'durability': 'transient_local',
        'deadline': {'sec': 9223372036, 'nsec': 854775807},
        'lifespan': {'sec': 9223372036, 'nsec': 854775807},
        'liveliness': 'automatic',
        'liveliness_lease_duration': {'sec': 9223372036, 'nsec': 854775807},
        'avoid_ros_namespace_conventions': False}]


KILLED_WRITER = """
import os, signal, sys
from followbot.recording import RecordingWriter
writer = RecordingWriter(sys.argv[1], flush_period_s=0.0)
writer.add_topic('/count', 'std_msgs/msg/UInt32')
for count in range(int(sys.argv[2])):
    writer.write('/count', bytes([0, 1, 0, 0, count, 0, 0, 0]), count + 1)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_a_killed_writer_leaves_the_messages_written_before(tmp_path):
    path = tmp_path / 'killed.mcap'
    written = 25
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(Path(__file__).resolve().parent.parent), os.environ.get('PYTHONPATH', '')]))
    result = subprocess.run([sys.executable, '-c', KILLED_WRITER, str(path), str(written)],
                            env=environment, timeout=CHILD_TIMEOUT_S, capture_output=True)
    assert result.returncode == -signal.SIGKILL, result.stderr
    read = list(read_messages(path))
    assert [message.log_time_ns for message in read] == list(range(1, written + 1))
    assert read[-1].data == bytes([0, 1, 0, 0, written - 1, 0, 0, 0])


@pytest.mark.parametrize('type_name', ['Image', 'sensor_msgs/srv/Image', 'a/b/c/d', '', 7,
                                       'sensor msgs/Image'])
def test_invalid_type_names_are_refused(tmp_path, type_name):
    with RecordingWriter(tmp_path / 'run.mcap') as writer:
        with pytest.raises(RecordingError, match='is not a message type name'):
            writer.add_topic('/topic', type_name)


def test_a_type_without_definition_is_refused_naming_what_was_searched(tmp_path):
    with RecordingWriter(tmp_path / 'run.mcap', MessageDefinitions([tmp_path])) as writer:
        with pytest.raises(RecordingError, match='no_such_msgs/msg/Thing.msg in'):
            writer.add_topic('/thing', 'no_such_msgs/msg/Thing')


@pytest.mark.parametrize(('write', 'error'), [
    (lambda writer: writer.write('/unknown', b'\0\1\0\0', 0), 'was not added'),
    (lambda writer: writer.write('/cmd_vel', 'text', 0), 'must be CDR bytes'),
    (lambda writer: writer.write('/cmd_vel', b'\0\1', 0), 'must be CDR bytes'),
    (lambda writer: writer.write('/cmd_vel', b'\0\1\0\0', -1), 'nanoseconds from 0'),
    (lambda writer: writer.write('/cmd_vel', b'\0\1\0\0', 1.5), 'nanoseconds from 0'),
    (lambda writer: writer.add_topic('/cmd_vel', 'std_msgs/msg/String'), 'is recorded as'),
    (lambda writer: writer.add_topic('cmd_vel', 'geometry_msgs/msg/Twist'), 'full topic name'),
    (lambda writer: writer.write_transforms('/tf', [{'header': {}}], 0), 'needs the fields'),
    (lambda writer: writer.write_transforms('/tf', [twist()], 0), 'needs the fields'),
    (lambda writer: writer.write_transforms('/tf', [{
        'header': {}, 'child_frame_id': 'b', 'transform': {'translation': {'x': 'far'}}}], 0),
     'Cannot encode'),
], ids=['unknown topic', 'text', 'short', 'negative time', 'float time', 'other type',
        'relative name', 'transform lacking fields', 'twist', 'text coordinate'])
def test_bad_writes_are_refused_with_one_clear_error(tmp_path, write, error):
    with RecordingWriter(tmp_path / 'run.mcap') as writer:
        writer.add_topic('/cmd_vel', 'geometry_msgs/msg/Twist')
        with pytest.raises(RecordingError, match=error):
            write(writer)


def test_a_closed_writer_refuses_more_messages(tmp_path):
    writer = RecordingWriter(tmp_path / 'run.mcap')
    writer.add_topic('/cmd_vel', 'geometry_msgs/msg/Twist')
    writer.close()
    writer.close()
    with pytest.raises(RecordingError, match='is closed'):
        writer.write('/cmd_vel', serialize_message(twist()), 0)


@pytest.mark.parametrize(('options', 'error'), [
    ({'compression': 'gzip'}, 'Unknown compression'),
    ({'chunk_size_bytes': 0}, 'must be positive'),
    ({'flush_period_s': -1.0}, 'must be positive'),
])
def test_bad_writer_options_are_refused(tmp_path, options, error):
    with pytest.raises(RecordingError, match=error):
        RecordingWriter(tmp_path / 'run.mcap', **options)


def test_a_recording_in_a_missing_folder_is_refused(tmp_path):
    with pytest.raises(RecordingError, match='Cannot create the recording'):
        RecordingWriter(tmp_path / 'missing' / 'run.mcap')


@pytest.mark.parametrize(('content', 'error'), [
    (None, 'Cannot read the recording'),
    (b'', 'is not an MCAP file'),
    (b'#ROSBAG V2.0\n', 'is not an MCAP file'),
])
def test_reading_what_is_no_recording_is_refused(tmp_path, content, error):
    path = tmp_path / 'run.mcap'
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(RecordingError, match=error):
        list(read_messages(path))


@pytest.mark.parametrize('compression', ['lz4', 'zstd'])
def test_a_damaged_compressed_chunk_is_a_damaged_recording(tmp_path, compression):
    path = tmp_path / 'run.mcap'
    write_all(path, compression=compression)
    with open(path, 'rb') as stream:
        chunk_offset = make_reader(stream).get_summary().chunk_indexes[0].chunk_start_offset
    data = bytearray(path.read_bytes())
    # Chunk record: opcode, length, start and end time, uncompressed size and CRC, then the
    # compression's name (length-prefixed) and the compressed records' length: then the data.
    data_offset = chunk_offset + 1 + 8 + 8 + 8 + 8 + 4 + 4 + len(compression) + 8
    data[data_offset:data_offset + 16] = b'\xff' * 16
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match='is damaged'):
        list(read_messages(path))
