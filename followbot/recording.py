"""
Write and read rosbag2-compatible MCAP recordings: ROS 2 CDR messages with their definitions.

A file written here is what ROS 2 Jazzy's ``ros2 bag record -s mcap`` writes for the same
messages, so ``ros2 bag info``/``ros2 bag play``, the ``rosbags`` library and Foxglove open it:

* the MCAP profile ``ros2``;
* one schema per message type, named like ``sensor_msgs/msg/Image``, encoded ``ros2msg``: the
  type's ``.msg`` text followed by every type it uses, each after a line of 80 ``=`` and a
  ``MSG: package/Type`` line (rosbag2's ``LocalMessageDefinitionSource`` order: dependencies
  sorted, depth first, each once);
* one channel per topic, message encoding ``cdr``, with the metadata ``offered_qos_profiles``
  (the publishers' QoS as rosbag2's version-9 YAML) and ``topic_type_hash``;
* messages as the serialised CDR bytes a subscription receives (``raw=True`` in rclpy), with the
  log time and publish time in nanoseconds;
* on close, a ``rosbag2`` metadata record holding the bag's ``serialized_metadata`` YAML.

The ``.msg`` files come from ``share/<package>/msg/`` of the ROS prefixes (``AMENT_PREFIX_PATH``
and this Python's prefix, where the PyPI wheels put them). ``tf2_msgs/msg/TFMessage`` has a
built-in definition, so ``/tf`` and ``/tf_static`` can be written, encoded from that definition,
even where tf2_msgs is not installed. No rclpy here: the ROS side is
``followbot_sim.recorder`` (recording) and ``followbot.replay`` (replaying). It sits on the robot
side because a robot's recordings are replayed there, without the simulator.
"""

import dataclasses
import importlib
import json
import os
from pathlib import Path
import struct
import sys
import time
from typing import Iterable, Iterator, NamedTuple

from mcap import stream_reader
from mcap.exceptions import McapError
from mcap.reader import make_reader, NonSeekingReader
from mcap.writer import CompressionType, Writer
from mcap_ros2 import __version__ as MCAP_ROS2_VERSION
# The encoder mcap-ros2-support's own Writer uses; the pinned version keeps this name.
from mcap_ros2._dynamic import serialize_dynamic
import yaml

PROFILE = 'ros2'
SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'
STORAGE_IDENTIFIER = 'mcap'
LIBRARY = f'followbot recording (mcap-ros2-support {MCAP_ROS2_VERSION})'
QOS_METADATA_KEY = 'offered_qos_profiles'
TYPE_HASH_METADATA_KEY = 'topic_type_hash'
BAG_METADATA_NAME = 'rosbag2'
BAG_METADATA_KEY = 'serialized_metadata'
# rosbag2's metadata version in Jazzy (QoS policies as words, type_description_hash present).
BAG_METADATA_VERSION = 9
# The PyPI wheels of requirements.txt are Jazzy's; ROS_DISTRO, when set, wins.
DEFAULT_ROS_DISTRO = 'jazzy'
DEFINITION_DELIMITER = '=' * 80
MCAP_MAGIC = b'\x89MCAP0\r\n'
# What the mcap library raises on a file that ends early or holds a broken record; a damaged
# compressed chunk makes lz4 raise RuntimeError and zstandard its ZstdError (taken from the
# module mcap decompresses with: zstandard comes with mcap, it is no dependency of ours).
ZSTD_ERRORS = (stream_reader.zstandard.ZstdError,) if stream_reader.zstandard else ()
READ_ERRORS = (McapError, ValueError, EOFError, OSError, RuntimeError, *ZSTD_ERRORS)
PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'))
TF_MESSAGE_TYPE = 'tf2_msgs/msg/TFMessage'
# Definitions for types whose package may be missing: tf2_msgs is not on PyPI.
BUILT_IN_DEFINITIONS = {TF_MESSAGE_TYPE: 'geometry_msgs/TransformStamped[] transforms\n'}
TRANSFORM_FIELDS = ('header', 'child_frame_id', 'transform')
COMPRESSIONS = {'none': CompressionType.NONE, 'lz4': CompressionType.LZ4,
                'zstd': CompressionType.ZSTD}
# lz4 by default: a simulated 640x480 bgr8 frame shrinks ~26x (1.1 GB to 43 MB a minute at
# 20 Hz) for about the time an uncompressed write takes, and rosbag2 and Foxglove read it.
DEFAULT_COMPRESSION = 'lz4'
# MCAP's usual chunk size: a 640x480 bgr8 image fills most of one.
CHUNK_SIZE_BYTES = 1024 * 1024
# Complete the chunk in progress and hand it to the system at least this often, so a recorder
# that is killed loses at most about this much of the recording.
FLUSH_PERIOD_S = 1.0
NANOSECONDS_PER_SECOND = 1_000_000_000
# A CDR message starts with 4 bytes of encapsulation (the second: 0 big, 1 little endian); a
# header stamp follows as int32 seconds and uint32 nanoseconds.
CDR_ENCAPSULATION_BYTES = 4
CDR_HEADER_STAMP_END = CDR_ENCAPSULATION_BYTES + 8
CDR_BYTE_ORDERS = {0: '>', 1: '<'}
# RMW_DURATION_INFINITE: the "infinite" a Jazzy publisher reports for deadline and lifespan.
INFINITE_NS = 9_223_372_036_854_775_807


class RecordingError(ValueError):
    """A recording cannot be written or read as asked; the message says why."""


@dataclasses.dataclass(frozen=True)
class OfferedQos:
    """
    A publisher's QoS profile as a recording keeps it: policies by their rmw names.

    Durations are nanoseconds; ``INFINITE_NS`` is infinite, 0 the middleware's default.
    """

    history: str = 'keep_last'
    depth: int = 10
    reliability: str = 'reliable'
    durability: str = 'volatile'
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: str = 'automatic'
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False


# What /tf_static publishers offer (tf2's static broadcaster): latched for late subscribers.
STATIC_TF_QOS = OfferedQos(depth=1, durability='transient_local')


class RecordedMessage(NamedTuple):
    """One message of a recording, still serialised."""

    topic: str
    type_name: str
    log_time_ns: int
    data: bytes
    # When the publisher sent it (its own clock): orders messages of several publishers as
    # they were sent, also where the log times (simulated time) are equal.
    publish_time_ns: int = 0


def _duration_yaml(nanoseconds: int) -> dict:
    return {'sec': nanoseconds // NANOSECONDS_PER_SECOND,
            'nsec': nanoseconds % NANOSECONDS_PER_SECOND}


def qos_profiles_yaml(profiles: Iterable[OfferedQos]) -> str:
    """
    Serialise publishers' QoS profiles as rosbag2 (metadata version 9) writes them.

    :param profiles: one profile per publisher of the topic.
    :return: a YAML list with one mapping per profile (``history: keep_last``, ...).
    """
    return yaml.safe_dump([_qos_mapping(profile) for profile in profiles], sort_keys=False)


def _qos_mapping(profile: OfferedQos) -> dict:
    return {
        'history': profile.history,
        'depth': profile.depth,
        'reliability': profile.reliability,
        'durability': profile.durability,
        'deadline': _duration_yaml(profile.deadline_ns),
        'lifespan': _duration_yaml(profile.lifespan_ns),
        'liveliness': profile.liveliness,
        'liveliness_lease_duration': _duration_yaml(profile.liveliness_lease_duration_ns),
        'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions,
    }


def split_type_name(type_name: str) -> tuple:
    """
    Split a message type name into its package and type.

    :param type_name: ``package/msg/Type`` or ``package/Type``.
    :return: (package, type).
    :raises RecordingError: if the name has another form or names a service or action.
    """
    parts = type_name.split('/') if isinstance(type_name, str) else []
    if len(parts) == 3 and parts[1] == 'msg':
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not all(part and part.replace('_', '').isalnum() for part in parts):
        raise RecordingError(f'{type_name!r} is not a message type name such as '
                             "'sensor_msgs/msg/Image'.")
    return parts[0], parts[1]


def canonical_type_name(type_name: str) -> str:
    """
    Return a message type's full name, as rosbag2 names schemas.

    :param type_name: ``package/msg/Type`` or ``package/Type``.
    :return: ``package/msg/Type``.
    :raises RecordingError: if the name is not a message type name.
    """
    package, name = split_type_name(type_name)
    return f'{package}/msg/{name}'


def import_message_class(type_name: str):
    """
    Return the Python class of a message type, or None when its package is not importable.

    :param type_name: such as ``sensor_msgs/msg/Image``.
    :return: the class, such as ``sensor_msgs.msg.Image``, or None.
    :raises RecordingError: if the name is not a message type name.
    """
    package, name = split_type_name(type_name)
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        return None


def default_share_dirs() -> list:
    """Return the ``share`` folders of the ROS prefixes: AMENT_PREFIX_PATH's, then sys.prefix's."""
    prefixes = [prefix for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                if prefix]
    return [Path(prefix, 'share') for prefix in [*prefixes, sys.prefix]]


def field_types(definition: str) -> list:
    """
    Return the type of each field and constant a ``.msg`` text declares, in order.

    :param definition: the text of a ``.msg`` file.
    :return: type names as written, without array brackets or string bounds.
    """
    types = []
    for line in definition.splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) >= 2:
            types.append(words[0].split('[', 1)[0].split('<=', 1)[0])
    return types


class MessageDefinitions:
    """Find ``.msg`` definitions and join them into the text a ``ros2msg`` schema holds."""

    def __init__(self, share_dirs=None, built_in: dict | None = None):
        """
        Look for definitions in the given ``share`` folders.

        :param share_dirs: folders holding ``<package>/msg/<Type>.msg``; the ROS prefixes'
            (see :func:`default_share_dirs`) when None.
        :param built_in: {full type name: .msg text} used when no folder has the type;
            :data:`BUILT_IN_DEFINITIONS` when None.
        """
        self._share_dirs = [Path(folder) for folder in (
            default_share_dirs() if share_dirs is None else share_dirs)]
        self._built_in = dict(BUILT_IN_DEFINITIONS if built_in is None else built_in)
        self._texts = {}

    def text(self, type_name: str) -> str:
        """
        Return the ``.msg`` text of one type.

        :param type_name: ``package/msg/Type`` or ``package/Type``.
        :return: the file's text, or the built-in definition.
        :raises RecordingError: if no folder has the type and it has no built-in definition.
        """
        full_name = canonical_type_name(type_name)
        if full_name not in self._texts:
            package, name = split_type_name(full_name)
            for folder in self._share_dirs:
                path = folder / package / 'msg' / f'{name}.msg'
                if path.is_file():
                    self._texts[full_name] = path.read_text(encoding='utf-8')
                    break
            else:
                if full_name not in self._built_in:
                    searched = ', '.join(str(folder) for folder in self._share_dirs)
                    raise RecordingError(f'No definition of {full_name} found: no '
                                         f'{package}/msg/{name}.msg in {searched}.')
                self._texts[full_name] = self._built_in[full_name]
        return self._texts[full_name]

    def full_text(self, type_name: str) -> str:
        """
        Return a type's complete definition: its text, then each type it uses, recursively.

        :param type_name: ``package/msg/Type`` or ``package/Type``.
        :return: the ``ros2msg`` schema text.
        :raises RecordingError: if a definition is missing.
        """
        # Each type is expanded once, so types that use each other cannot recurse forever.
        seen = set()

        def with_dependencies(name: str) -> str:
            package, _ = split_type_name(name)
            text = self.text(name)
            dependencies = sorted({used if '/' in used else f'{package}/{used}'
                                   for used in field_types(text)
                                   if used not in PRIMITIVE_TYPES})
            for dependency in dependencies:
                if dependency not in seen:
                    seen.add(dependency)
                    text += (f'\n{DEFINITION_DELIMITER}\nMSG: {dependency}\n'
                             + with_dependencies(dependency))
            return text

        return with_dependencies(type_name)

    def type_hash(self, type_name: str) -> str:
        """
        Return a type's ROS 2 type hash (``RIHS01_...``) from its installed ``.json``.

        :param type_name: ``package/msg/Type`` or ``package/Type``.
        :return: the hash, or '' when no folder has the type's ``.json`` description.
        """
        full_name = canonical_type_name(type_name)
        package, name = split_type_name(full_name)
        for folder in self._share_dirs:
            path = folder / package / 'msg' / f'{name}.json'
            if path.is_file():
                try:
                    hashes = json.loads(path.read_text(encoding='utf-8'))['type_hashes']
                except (ValueError, KeyError, TypeError):
                    return ''
                return next((entry.get('hash_string', '') for entry in hashes
                             if entry.get('type_name') == full_name), '')
        return ''


class _Topic(NamedTuple):
    channel_id: int
    type_name: str
    offered_qos: tuple
    type_hash: str


class RecordingWriter:
    """Write a rosbag2-compatible MCAP file, message by message; close it to finish it."""

    def __init__(self, path, definitions: MessageDefinitions | None = None,
                 compression: str = DEFAULT_COMPRESSION, chunk_size_bytes: int = CHUNK_SIZE_BYTES,
                 flush_period_s: float = FLUSH_PERIOD_S, ros_distro: str | None = None):
        """
        Create the file and write its header.

        :param path: the ``.mcap`` file to create; an existing file is replaced.
        :param definitions: where message definitions come from; the ROS prefixes when None.
        :param compression: chunk compression: 'lz4', 'zstd' or 'none' (rosbag2's default).
        :param chunk_size_bytes: size at which a chunk of messages is completed.
        :param flush_period_s: wall-clock seconds after which the chunk in progress is completed
            and written out; 0 writes every message out at once.
        :param ros_distro: the ROS distribution the metadata names; ROS_DISTRO or Jazzy when
            None.
        :raises RecordingError: if an option is invalid or the file cannot be created.
        """
        if compression not in COMPRESSIONS:
            raise RecordingError(f'Unknown compression {compression!r}: use one of '
                                 f'{", ".join(COMPRESSIONS)}.')
        if not chunk_size_bytes > 0 or not flush_period_s >= 0:
            raise RecordingError('chunk_size_bytes must be positive and flush_period_s at '
                                 f'least 0, not {chunk_size_bytes!r} and {flush_period_s!r}.')
        self.path = Path(path)
        try:
            self._file = open(self.path, 'wb')
        except OSError as error:
            raise RecordingError(f'Cannot create the recording {self.path}: '
                                 f'{error.strerror or error}.') from None
        self._definitions = MessageDefinitions() if definitions is None else definitions
        self._compression = compression
        self._flush_period_s = flush_period_s
        self._ros_distro = ros_distro or os.environ.get('ROS_DISTRO') or DEFAULT_ROS_DISTRO
        self._writer = Writer(self._file, chunk_size=chunk_size_bytes,
                              compression=COMPRESSIONS[compression])
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._schema_ids = {}
        self._topics = {}
        self._message_counts = {}
        self._first_log_time_ns = None
        self._last_log_time_ns = None
        self._tf_encoder = None
        self._last_flush_s = time.monotonic()
        self._closed = False

    @property
    def message_count(self) -> int:
        """Return how many messages have been written."""
        return sum(self._message_counts.values())

    @property
    def message_counts(self) -> dict:
        """Return {topic: messages written} of the topics added so far."""
        return dict(self._message_counts)

    @property
    def topics(self) -> dict:
        """Return {topic: full type name} of the topics added so far."""
        return {topic: entry.type_name for topic, entry in self._topics.items()}

    def add_topic(self, topic: str, type_name: str, offered_qos: Iterable[OfferedQos] = (),
                  type_hash: str | None = None) -> None:
        """
        Declare a topic before its first message: its type's schema and its channel.

        Adding a topic again with the same type does nothing.

        :param topic: the topic's full name, such as ``/camera/rgb/image_raw``.
        :param type_name: its message type, such as ``sensor_msgs/msg/Image``.
        :param offered_qos: the QoS profile of each of its publishers.
        :param type_hash: the type's hash as its publishers report it; the installed
            definition's when None.
        :raises RecordingError: if the topic has another type already, the names are invalid,
            the definition is missing or the recording is closed.
        """
        self._check_open()
        full_name = canonical_type_name(type_name)
        if not isinstance(topic, str) or not topic.startswith('/'):
            raise RecordingError(f'Topic {topic!r} is not a full topic name such as /tf.')
        if topic in self._topics:
            if self._topics[topic].type_name != full_name:
                raise RecordingError(f'Topic {topic} is recorded as '
                                     f'{self._topics[topic].type_name}, not {full_name}.')
            return
        if full_name not in self._schema_ids:
            definition = self._definitions.full_text(full_name)
            self._schema_ids[full_name] = self._writer.register_schema(
                full_name, SCHEMA_ENCODING, definition.encode('utf-8'))
        offered_qos = tuple(offered_qos)
        if type_hash is None:
            type_hash = self._definitions.type_hash(full_name)
        channel_id = self._writer.register_channel(
            topic, MESSAGE_ENCODING, self._schema_ids[full_name],
            {QOS_METADATA_KEY: qos_profiles_yaml(offered_qos),
             TYPE_HASH_METADATA_KEY: type_hash})
        self._topics[topic] = _Topic(channel_id, full_name, offered_qos, type_hash)
        self._message_counts[topic] = 0

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None,
              sequence: int = 0) -> None:
        """
        Write one serialised message of an added topic.

        :param topic: the topic, added before with :meth:`add_topic`.
        :param data: the CDR bytes, encapsulation header included (what rclpy's ``raw=True``
            subscriptions deliver).
        :param log_time_ns: when the message was received, in nanoseconds.
        :param publish_time_ns: when it was sent; ``log_time_ns`` when None.
        :param sequence: the publisher's sequence number, if known.
        :raises RecordingError: if the topic was not added, the data is no CDR message or a time
            is negative.
        """
        self._check_open()
        if topic not in self._topics:
            raise RecordingError(f'Topic {topic!r} was not added to the recording.')
        if not isinstance(data, (bytes, bytearray, memoryview)) or len(data) < 4:
            raise RecordingError(f'A message on {topic} must be CDR bytes with their 4-byte '
                                 'encapsulation header.')
        publish_time_ns = log_time_ns if publish_time_ns is None else publish_time_ns
        if (not isinstance(log_time_ns, int) or not isinstance(publish_time_ns, int)
                or log_time_ns < 0 or publish_time_ns < 0):
            raise RecordingError(f'Times on {topic} must be nanoseconds from 0 up, not '
                                 f'{log_time_ns!r} and {publish_time_ns!r}.')
        self._writer.add_message(self._topics[topic].channel_id, log_time=log_time_ns,
                                 data=bytes(data), publish_time=publish_time_ns,
                                 sequence=sequence)
        self._message_counts[topic] += 1
        if self._first_log_time_ns is None or log_time_ns < self._first_log_time_ns:
            self._first_log_time_ns = log_time_ns
        if self._last_log_time_ns is None or log_time_ns > self._last_log_time_ns:
            self._last_log_time_ns = log_time_ns
        if time.monotonic() - self._last_flush_s >= self._flush_period_s:
            self.flush()

    def encode_transforms(self, transforms) -> bytes:
        """
        Serialise a ``tf2_msgs/msg/TFMessage`` from its definition, without tf2_msgs.

        The whole message is encoded at once: CDR aligns each field to its size from the start
        of the message, so serialised TransformStamped messages cannot simply be joined.

        :param transforms: ``geometry_msgs/msg/TransformStamped`` messages, or mappings with
            the same fields.
        :return: the CDR bytes, encapsulation header included.
        :raises RecordingError: if a transform lacks a field or holds a value of the wrong type.
        """
        transforms = list(transforms)
        for item in transforms:
            present = item.keys() if isinstance(item, dict) else dir(item)
            if not set(TRANSFORM_FIELDS) <= set(present):
                raise RecordingError('A transform needs the fields ' + ', '.join(TRANSFORM_FIELDS)
                                     + f', not {item!r}.')
        if self._tf_encoder is None:
            encoders = serialize_dynamic(
                TF_MESSAGE_TYPE, self._definitions.full_text(TF_MESSAGE_TYPE))
            self._tf_encoder = encoders[TF_MESSAGE_TYPE]
        try:
            return self._tf_encoder({'transforms': transforms})
        except (AttributeError, TypeError, ValueError, KeyError, struct.error) as error:
            raise RecordingError(f'Cannot encode the transforms as a TFMessage: {error}.') \
                from None

    def write_transforms(self, topic: str, transforms, log_time_ns: int) -> None:
        """
        Write transforms on ``/tf`` or ``/tf_static`` as one TFMessage, added if need be.

        :param topic: the topic, such as ``/tf``; ``/tf_static`` is declared latched.
        :param transforms: ``TransformStamped`` messages or mappings with the same fields.
        :param log_time_ns: the log time in nanoseconds.
        :raises RecordingError: as :meth:`add_topic`, :meth:`encode_transforms` and
            :meth:`write` do.
        """
        if topic not in self._topics:
            static = topic.endswith('/tf_static') if isinstance(topic, str) else False
            self.add_topic(topic, TF_MESSAGE_TYPE,
                           [STATIC_TF_QOS if static else OfferedQos(depth=100)])
        self.write(topic, self.encode_transforms(transforms), log_time_ns)

    def flush(self) -> None:
        """Complete the chunk in progress and hand everything written so far to the system."""
        self._check_open()
        self._writer.flush()
        self._last_flush_s = time.monotonic()

    def close(self) -> None:
        """Write the metadata, the index and the summary, and close the file; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.add_metadata(BAG_METADATA_NAME,
                                      {BAG_METADATA_KEY: self.bag_metadata_yaml()})
            self._writer.finish()
        finally:
            self._file.close()

    def bag_metadata_yaml(self) -> str:
        """Return the ``serialized_metadata`` rosbag2 stores: the body of its metadata.yaml."""
        start_ns = self._first_log_time_ns or 0
        duration_ns = (self._last_log_time_ns or 0) - start_ns
        topics = [{'topic_metadata': {'name': topic, 'type': entry.type_name,
                                      'serialization_format': MESSAGE_ENCODING,
                                      QOS_METADATA_KEY: [_qos_mapping(profile)
                                                         for profile in entry.offered_qos],
                                      'type_description_hash': entry.type_hash},
                   'message_count': self._message_counts[topic]}
                  for topic, entry in self._topics.items()]
        metadata = {
            'version': BAG_METADATA_VERSION,
            'storage_identifier': STORAGE_IDENTIFIER,
            'duration': {'nanoseconds': duration_ns},
            'starting_time': {'nanoseconds_since_epoch': start_ns},
            'message_count': self.message_count,
            'topics_with_message_count': topics,
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.path.name],
            'files': [{'path': self.path.name,
                       'starting_time': {'nanoseconds_since_epoch': start_ns},
                       'duration': {'nanoseconds': duration_ns},
                       'message_count': self.message_count}],
            'custom_data': None,
            'ros_distro': self._ros_distro,
        }
        return yaml.safe_dump(metadata, sort_keys=False)

    def _check_open(self) -> None:
        if self._closed:
            raise RecordingError(f'The recording {self.path} is closed.')

    def __enter__(self):
        """Return the writer, for ``with RecordingWriter(path) as writer:``."""
        return self

    def __exit__(self, *exception_info):
        """Close the recording, also when the block raised."""
        self.close()


def header_stamp_ns(data: bytes) -> int | None:
    """
    Return the header stamp of a serialised message that starts with a ``std_msgs/Header``.

    Images, compressed images and diagnostics start with their header: the stamp is read from
    the CDR bytes without deserialising a whole frame.

    :param data: the CDR bytes, encapsulation header included.
    :return: the stamp in nanoseconds, or None if the bytes are too short or of an unknown
        encapsulation.
    """
    if len(data) < CDR_HEADER_STAMP_END or data[1] not in CDR_BYTE_ORDERS:
        return None
    seconds, nanoseconds = struct.unpack_from(CDR_BYTE_ORDERS[data[1]] + 'iI', data,
                                              CDR_ENCAPSULATION_BYTES)
    return seconds * NANOSECONDS_PER_SECOND + nanoseconds


def read_messages(path, topics: Iterable[str] | None = None) -> Iterator[RecordedMessage]:
    """
    Yield a recording's messages in log-time order, still serialised.

    A file cut short (its recorder was killed before closing it) has no index: it is read from
    the start up to its last complete chunk, in memory.

    :param path: the ``.mcap`` file.
    :param topics: only these topics; all when None.
    :return: an iterator of (topic, type name, log time in ns, CDR bytes).
    :raises RecordingError: if the file cannot be read, is no MCAP file or is damaged inside.
    """
    topics = None if topics is None else list(topics)
    try:
        stream = open(path, 'rb')
    except OSError as error:
        raise RecordingError(f'Cannot read the recording {path}: '
                             f'{error.strerror or error}.') from None
    with stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RecordingError(f'{path} is not an MCAP file.')
        stream.seek(0)
        try:
            reader = make_reader(stream)
            complete = reader.get_summary() is not None
        except READ_ERRORS:
            complete = False
        if not complete:
            yield from _salvage(stream, topics)
            return
        try:
            for schema, channel, message in reader.iter_messages(topics=topics):
                yield RecordedMessage(channel.topic, schema.name if schema else '',
                                      message.log_time, message.data, message.publish_time)
        except READ_ERRORS as error:
            raise RecordingError(f'The recording {path} is damaged: {error}.') from None


def _salvage(stream, topics) -> list:
    """Return the messages of a file without summary up to its first broken record, sorted."""
    stream.seek(0)
    found = []
    records = NonSeekingReader(stream).iter_messages(topics=topics, log_time_order=False)
    try:
        for schema, channel, message in records:
            found.append(RecordedMessage(channel.topic, schema.name if schema else '',
                                         message.log_time, message.data, message.publish_time))
    except READ_ERRORS:
        pass  # The file ends inside a record: everything before it is kept.
    found.sort(key=lambda message: message.log_time_ns)
    return found
