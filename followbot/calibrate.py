"""
The ``calibrate`` command: the follower's parameters for a camera and a tape, from one frame.

``ros2 run followbot calibrate`` (or ``followbot calibrate``) takes one camera frame from an
image file, a recording (MCAP, as ``ros2 bag record -s mcap`` writes it) or a live topic, and
the line in it (a pixel on it, a box around a piece of it, or nothing: then every colour
preset is tried). It proposes the line's colour (a preset, or custom HSV bounds), with the
camera's intrinsics and mounting also the tape's width, checks the proposal with the
follower's own detector on the frame (see :mod:`followbot.calibration`), prints the
parameters YAML for ``--params-file`` and saves a picture of what the configuration sees.
"""

import argparse
import math
import os
from pathlib import Path
import sys
import time

import cv2
from followbot import calibration
from followbot import line_sample
from followbot.compressed_image import compressed_to_array
from followbot.follower_node import CAMERA_PARAMETERS, DETECTOR_PARAMETERS, SENSOR_QOS
from followbot.ground_projection import CameraGeometry, CameraInfoError
from followbot.image_conversion import image_to_array, ImageConversionError, to_bgr
from followbot.line_detector import band_rows, DetectorConfig
from followbot.line_sample import CalibrationError
from followbot.node_runner import init_rclpy, RosStartError, split_ros_arguments
from followbot.number_options import number_in, parameter_option
from followbot.output_files import output_file_option
# The recording format's magic bytes and read errors (a damaged lz4/zstd chunk among them).
from followbot.recording import MCAP_MAGIC, READ_ERRORS
from mcap.reader import make_reader, NonSeekingReader
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CompressedImage, Image

PROGRAM = 'calibrate'
NODE_NAME = 'calibrate'
EXIT_OK = 0
EXIT_FAILED = 2
# Ctrl-C: the shell's convention for a command ended by SIGINT.
EXIT_INTERRUPTED = 130
DEFAULT_PICTURE = 'calibration.png'
PICTURE_SUFFIX = '.png'
# The picture types a --picture may name (OpenCV writes them in every build).
PICTURE_SUFFIXES = (PICTURE_SUFFIX, '.jpg', '.jpeg')
RECORDING_SUFFIX = '.mcap'
DEFAULT_TIMEOUT_S = 10.0
SPIN_S = 0.1
# The image message types a frame can come in, by their names in recordings and the graph.
IMAGE_TYPES = {'sensor_msgs/msg/Image': Image, 'sensor_msgs/Image': Image,
               'sensor_msgs/msg/CompressedImage': CompressedImage,
               'sensor_msgs/CompressedImage': CompressedImage}
GREY_ENCODING = 'mono8'
COLOUR_ENCODING = 'bgr8'
CAMERA_OPTIONS = ('camera_info', 'camera_height_m', 'camera_pitch_deg')
POINT_FIELDS = 2
REGION_FIELDS = 4

DESCRIPTION = (
    "Propose the follower's line colour (a preset or a custom HSV range) and, given the "
    "camera, the tape's width, from one camera frame; check the proposal with the follower's "
    'own detector on that frame; print the parameters YAML (for --params-file) and save a '
    'picture of what the configuration sees.')
EPILOG = (
    'SOURCE is an image file (any format OpenCV reads), a recording (.mcap, or the rosbag2 '
    'folder holding one: its Image or CompressedImage topic), or nothing: then --topic is a '
    'live camera topic (sensor_msgs/Image, or CompressedImage such as '
    '/camera/rgb/image_raw/compressed). This OpenCV has no window to click in: read the '
    'pixel coordinates off the frame in any image viewer and give them as --point or '
    '--region; without either, every colour preset is tried and the most confident one is '
    'proposed. The picture shows the frame with the pixels the configuration takes for the '
    "line (magenta) and the piece of line shown (cyan outline), beside the detector's view. "
    'Exit status 0 when the proposal is verified, 2 for bad input or a frame where no line '
    'is found. ROS arguments after --ros-args (remaps, a domain via ROS_DOMAIN_ID) apply to '
    '--topic.')


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every error of this command is."""

    def error(self, message):
        """Print the error in one line and exit with status 2."""
        self.exit(EXIT_FAILED, f'{self.prog}: error: {message} (see --help)\n')


def _numbers(text, count, name):
    """Return ``count`` comma-separated integers, or raise argparse's type error."""
    parts = text.split(',')
    try:
        values = tuple(int(part) for part in parts)
    except ValueError:
        values = ()
    if len(values) != count:
        raise argparse.ArgumentTypeError(
            f'{name} must be {count} whole numbers separated by commas, got {text!r}')
    return values


def _point(text):
    return _numbers(text, POINT_FIELDS, 'a point X,Y')


def _region(text):
    return _numbers(text, REGION_FIELDS, 'a region X,Y,W,H')


def parse_arguments(argv=None, prog=PROGRAM):
    """
    Read the command line.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :param prog: the program's name in messages (``followbot calibrate`` from the launcher).
    :return: the parsed options; ``ros_arguments`` holds the ROS sections.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    own_arguments, ros_arguments = split_ros_arguments(argv)
    parser = _Parser(prog=prog, description=DESCRIPTION, epilog=EPILOG,
                     usage='%(prog)s [SOURCE] [options] [--ros-args ...]')
    parser.add_argument('source', nargs='?', type=Path, metavar='SOURCE',
                        help='an image file or a recording (.mcap or a rosbag2 folder)')
    parser.add_argument('--topic', metavar='TOPIC',
                        help='the image topic: of the recording (needed when it has several),'
                             ' or, without SOURCE, a live topic to take a frame from')
    parser.add_argument('--frame', type=number_in(0, whole=True), default=0, metavar='N',
                        help='take the N-th image message of the recording or topic, '
                             'counting from 0 (default: 0, the first)')
    line = parser.add_mutually_exclusive_group()
    line.add_argument('--point', type=_point, metavar='X,Y',
                      help='a pixel on the line (column, row from the top-left corner)')
    line.add_argument('--region', type=_region, metavar='X,Y,W,H',
                      help='a box around a piece of the line and some floor beside it')
    parser.add_argument('--camera-info', type=Path, metavar='FILE',
                        help="the camera's calibration YAML, as camera_calibration writes "
                             'it; with --camera-height-m and --camera-pitch-deg the '
                             "tape's width is measured and the width checks are verified")
    parser.add_argument('--camera-height-m', metavar='M',
                        type=parameter_option(CAMERA_PARAMETERS['camera_height_m']),
                        help='height of the camera above the floor')
    parser.add_argument('--camera-pitch-deg', metavar='DEG',
                        type=parameter_option(CAMERA_PARAMETERS['camera_pitch_deg']),
                        help='downward tilt of the camera from the horizontal')
    parser.add_argument('--output', type=output_file_option('the parameters'), metavar='FILE',
                        help='write the parameters YAML here instead of to stdout')
    parser.add_argument('--picture', metavar='FILE.png',
                        type=output_file_option('the picture', PICTURE_SUFFIXES),
                        help='where to save the picture (default: beside --output, with '
                             f'the suffix {PICTURE_SUFFIX}, else {DEFAULT_PICTURE})')
    parser.add_argument('--timeout', type=number_in(0.0, above=True), default=DEFAULT_TIMEOUT_S,
                        metavar='S',
                        help='seconds to wait for a frame on a live topic (default: '
                             f'{DEFAULT_TIMEOUT_S:g})')
    options = parser.parse_args(own_arguments)
    options.ros_arguments = ros_arguments
    if options.source is None and options.topic is None:
        parser.error('give an image file or recording, or a live --topic')
    if options.output is not None and _picture_path(options) == options.output:
        parser.error(f'--output {options.output} is where the picture would go: give the '
                     'parameters another name, or the picture its own with --picture')
    given = [getattr(options, name) is not None for name in CAMERA_OPTIONS]
    if any(given) and not all(given):
        missing = ', '.join('--' + name.replace('_', '-')
                            for name, present in zip(CAMERA_OPTIONS, given) if not present)
        parser.error(f'the camera needs --camera-info, --camera-height-m and '
                     f'--camera-pitch-deg together; missing {missing}')
    return options


def read_image_file(path):
    """
    Read a frame from an image file.

    :param path: the file.
    :return: (image, encoding): BGR 'bgr8', or 'mono8' for a file without colour.
    :raises CalibrationError: if it cannot be read as an image.
    """
    if not path.is_file():
        raise CalibrationError(f'No such file: {path}.')
    image = cv2.imread(str(path), cv2.IMREAD_ANYCOLOR)
    if image is None:
        raise CalibrationError(f'{path} is not an image OpenCV can read.')
    return image, GREY_ENCODING if image.ndim == 2 else COLOUR_ENCODING


def frame_from_message(msg):
    """
    Return the frame a camera message holds, for calibration.

    :param msg: a sensor_msgs Image or CompressedImage.
    :return: (image, encoding): 'mono8' for a grey camera, else BGR 'bgr8'.
    :raises CalibrationError: if the message holds no usable picture (a depth image, a
        broken message).
    """
    try:
        if isinstance(msg, CompressedImage):
            return compressed_to_array(msg)
        image = image_to_array(msg)
        if msg.encoding == GREY_ENCODING:
            return image, GREY_ENCODING
        return to_bgr(image, msg.encoding), COLOUR_ENCODING
    except ImageConversionError as error:
        raise CalibrationError(f'The frame cannot be used: {error}') from None


def recording_file(path):
    """
    Return the MCAP file of a recording: the file itself, or the one in a rosbag2 folder.

    :raises CalibrationError: if there is none, or a folder holds several.
    """
    if path.is_dir():
        files = sorted(path.glob('*' + RECORDING_SUFFIX))
        if len(files) != 1:
            raise CalibrationError(
                f'The folder {path} holds {len(files)} {RECORDING_SUFFIX} files: give one.')
        return files[0]
    return path


def read_recording_frame(path, topic=None, index=0):
    """
    Read one image message of a recording.

    :param path: the ``.mcap`` file.
    :param topic: the image topic; when None, the recording's only Image or CompressedImage
        topic.
    :param index: which of the topic's messages, counting from 0.
    :return: (message, topic).
    :raises CalibrationError: if the file is no readable recording, has no such topic or
        several image topics to choose from, or fewer messages.
    """
    try:
        stream = open(path, 'rb')
    except OSError as error:
        raise CalibrationError(f'Cannot read {path}: {error.strerror or error}.') from None
    with stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise CalibrationError(f'{path} is neither an image nor an MCAP recording.')
        stream.seek(0)
        topic = _recording_topic(stream, path, topic)
        stream.seek(0)
        seen = 0
        records = NonSeekingReader(stream).iter_messages(
            topics=None if topic is None else [topic], log_time_order=False)
        try:
            for schema, channel, message in records:
                message_type = IMAGE_TYPES.get(schema.name if schema else '')
                if message_type is None or topic not in (None, channel.topic):
                    continue
                topic = channel.topic
                if seen == index:
                    return deserialize_message(message.data, message_type), topic
                seen += 1
        except READ_ERRORS:
            pass  # A recording cut short: what came before the broken record counts.
    if topic is None:
        raise CalibrationError(f'The recording {path} has no Image or CompressedImage topic.')
    raise CalibrationError(f'The recording {path} has {seen} image message(s) on {topic}; '
                           f'--frame {index} asks for message {index + 1}.')


def _recording_topic(stream, path, topic):
    """Choose the image topic from a recording's summary (None when it has no summary)."""
    try:
        summary = make_reader(stream).get_summary()
    except READ_ERRORS:
        summary = None
    if summary is None:
        return topic
    types = {channel.topic: summary.schemas[channel.schema_id].name
             for channel in summary.channels.values() if channel.schema_id in summary.schemas}
    images = sorted(name for name, type_name in types.items() if type_name in IMAGE_TYPES)
    if topic is not None:
        if topic not in types:
            raise CalibrationError(
                f'The recording {path} has no topic {topic}; its image topics: '
                f'{", ".join(images) or "none"}.')
        if topic not in images:
            raise CalibrationError(f'{topic} in {path} is {types[topic]}, not an image.')
        return topic
    if not images:
        raise CalibrationError(f'The recording {path} has no Image or CompressedImage topic.')
    if len(images) > 1:
        raise CalibrationError(f'The recording {path} has several image topics '
                               f'({", ".join(images)}): choose one with --topic.')
    return images[0]


class FrameGrabber(Node):
    """Take one frame from a live image topic, of whichever image type it carries."""

    def __init__(self, topic, skip=0, **kwargs):
        """
        Make the node; :meth:`subscribe` starts listening once the topic's type is known.

        :param topic: the topic, remaps and namespace applied as for any node.
        :param skip: how many messages to let pass before the one taken.
        :param kwargs: forwarded to :class:`rclpy.node.Node`.
        """
        super().__init__(NODE_NAME, **kwargs)
        self.topic = self.resolve_topic_name(topic)
        self.message = None
        self._skip = skip
        self._subscription = None

    def topic_types(self):
        """Return the message types the graph knows for the topic (empty while unknown)."""
        return dict(self.get_topic_names_and_types()).get(self.topic, [])

    def subscribe(self, message_type):
        """Listen to the topic with sensor-data QoS, which every camera publisher matches."""
        self._subscription = self.create_subscription(message_type, self.topic,
                                                      self.image_callback, SENSOR_QOS)

    def image_callback(self, msg):
        """Keep the first message after the ones to skip."""
        if self._skip > 0:
            self._skip -= 1
        elif self.message is None:
            self.message = msg


def grab_live_frame(topic, index, timeout_s, ros_arguments):
    """
    Take one message from a live image topic.

    :param topic: the topic.
    :param index: how many messages to let pass first.
    :param timeout_s: how long to wait for the topic and the message, in all.
    :param ros_arguments: ROS sections of the command line (remaps and the like).
    :return: the Image or CompressedImage.
    :raises CalibrationError: if the topic does not appear, is no image topic or sends no
        message in time, or ROS cannot start.
    """
    context = Context()
    try:
        init_rclpy([PROGRAM, *ros_arguments], context=context)
    except RosStartError as error:
        raise CalibrationError(str(error)) from None
    executor = SingleThreadedExecutor(context=context)
    node = FrameGrabber(topic, index, context=context)
    executor.add_node(node)
    domain = f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID") or 0}'
    try:
        deadline = time.monotonic() + timeout_s
        types = node.topic_types()
        while not types and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=SPIN_S)
            types = node.topic_types()
        if not types:
            raise CalibrationError(f'No topic {node.topic} appeared within {timeout_s:g} s '
                                   f'({domain}): is the camera running?')
        image_types = [IMAGE_TYPES[name] for name in types if name in IMAGE_TYPES]
        if not image_types:
            raise CalibrationError(f'{node.topic} carries {", ".join(types)}, not '
                                   'sensor_msgs/msg/Image or CompressedImage.')
        node.subscribe(image_types[0])
        while node.message is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=SPIN_S)
        if node.message is None:
            raise CalibrationError(f'No frame came on {node.topic} within {timeout_s:g} s '
                                   f'({domain}).')
        return node.message
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def read_frame(options):
    """
    Read the frame the command line names.

    :param options: the parsed options.
    :return: (image, encoding, a short description of where it came from).
    :raises CalibrationError: as the readers do.
    """
    source = options.source
    if source is None:
        message = grab_live_frame(options.topic, options.frame, options.timeout,
                                  options.ros_arguments)
        return (*frame_from_message(message), f'topic {options.topic}')
    if not source.exists():
        raise CalibrationError(f'No such file or folder: {source}.')
    if source.is_dir() or source.suffix == RECORDING_SUFFIX:
        path = recording_file(source)
        message, topic = read_recording_frame(path, options.topic, options.frame)
        return (*frame_from_message(message), f'{path.name}, {topic} message {options.frame}')
    if options.topic is not None or options.frame:
        raise CalibrationError(f'{source} is an image: --topic and --frame apply to '
                               'recordings and live topics.')
    return (*read_image_file(source), source.name)


def camera_geometry(options, size):
    """
    Return the camera's geometry from the command line, or None when it was not given.

    :param options: the parsed options.
    :param size: (width, height) of the frame.
    :raises CalibrationError: if the camera info cannot be read or does not fit the frame.
    """
    if options.camera_info is None:
        return None
    try:
        text = options.camera_info.read_text()
    except OSError as error:
        raise CalibrationError(f'Cannot read {options.camera_info}: '
                               f'{error.strerror or error}.') from None
    try:
        intrinsics = calibration.intrinsics_from_yaml(text)
        intrinsics.check_image_size(*size)
    except CameraInfoError as error:
        raise CalibrationError(f'{options.camera_info}: {error}') from None
    return CameraGeometry.from_intrinsics(intrinsics, options.camera_height_m,
                                          math.radians(options.camera_pitch_deg))


def _shown(options):
    """Describe the piece of line given on the command line."""
    if options.point is not None:
        return 'the line at ({}, {})'.format(*options.point)
    return 'the line in the region {},{},{},{}'.format(*options.region)


def calibrate(options):
    """
    Run the calibration the options ask for, writing the picture and the YAML.

    :param options: the parsed options.
    :return: the one-line summary.
    :raises CalibrationError: for bad input, or a frame where no configuration finds the line
        (the picture is saved all the same, and named in the message).
    """
    image, encoding, origin = read_frame(options)
    height, width = image.shape[:2]
    bgr = image if encoding == COLOUR_ENCODING else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    geometry = camera_geometry(options, (width, height))
    sample = None
    if options.point is not None:
        sample = line_sample.sample_at_point(bgr, options.point)
    elif options.region is not None:
        sample = line_sample.sample_in_region(bgr, options.region)
    width = line_width_m = None
    if geometry is not None and sample is not None:
        width = line_sample.measure_line_width_m(sample, geometry)
        low, high, _ = DETECTOR_PARAMETERS['line_width_m']
        if not low <= width.metres <= high:
            raise CalibrationError(
                f'The tape measures {width.metres:.3f} m across: not a line the follower '
                f'takes ({low:g}-{high:g} m); check the camera height and pitch.')
        line_width_m = round(width.metres, calibration.WIDTH_DECIMALS)
    proposal = calibration.propose(image, encoding, sample, geometry, line_width_m)
    picture_path = _picture_path(options)
    if not cv2.imwrite(str(picture_path), calibration.picture(image, encoding, proposal.best,
                                                              sample)):
        raise CalibrationError(f'Cannot write the picture {picture_path}.')
    verdict = proposal.best.verdict
    config = proposal.config
    if not proposal.passed:
        if proposal.automatic:
            raise CalibrationError(
                f'No line found in {origin} with any preset: the most confident, '
                f'{config.line_colour}, reaches {verdict.confidence:.2f} (at least '
                f'{calibration.AUTOMATIC_MIN_CONFIDENCE:g} needed); show the line with '
                f'--point or --region (picture: {picture_path}).')
        raise CalibrationError(
            f'No configuration finds {_shown(options)} in {origin}: with the best try, '
            f'{config.line_colour}, {verdict.describe()} (picture: {picture_path}).')
    if proposal.automatic:
        others = ', '.join(f'{attempt.config.line_colour} {attempt.verdict.confidence:.2f}'
                           for attempt in proposal.attempts if attempt is not proposal.best)
        notes = [f'{config.line_colour} line found automatically in {origin}: the most '
                 f'confident preset, {verdict.confidence:.2f} (others: {others})']
    else:
        notes = [f'{config.line_colour} line, verified on {_shown(options)} in {origin}: '
                 f'{verdict.describe()}']
    if width is not None:
        notes.append(f'line_width_m {line_width_m:g} measured on the floor, over '
                     f'{width.across_px:.0f} px')
        if width.across_px < line_sample.MIN_SHARP_ACROSS_PX:
            notes.append('blur widens so thin a line: for a truer width show the line where '
                         'it looks wider, nearer the camera')
    else:
        default_width = DetectorConfig().line_width_m
        notes.append('line_width_m not measured: the width checks need --camera-info, '
                     f'--camera-height-m and --camera-pitch-deg (keeping {default_width:g})')
    bands = band_rows(height, config)
    if (config.band_center_fraction, config.band_spacing_fraction) != (
            DetectorConfig().band_center_fraction, DetectorConfig().band_spacing_fraction):
        notes.append(f'bands moved over rows {bands[-1][0]}-{bands[0][1] - 1}, where the line '
                     'is seen')
    parameters = calibration.follower_parameters(
        config, options.camera_height_m, options.camera_pitch_deg)
    comments = [f'followbot calibrate: {note}.' for note in notes]
    comments.append('Use: ros2 run followbot follower --ros-args --params-file <this file>')
    text = calibration.parameters_yaml(parameters, comments)
    if options.output is None:
        sys.stdout.write(text)
    else:
        try:
            options.output.write_text(text)
        except OSError as error:
            raise CalibrationError(f'Cannot write {options.output}: '
                                   f'{error.strerror or error}.') from None
    return '; '.join(notes) + f'; picture {picture_path}'


def _picture_path(options):
    """Return where the picture goes: as given, beside the output, or the default name."""
    if options.picture is not None:
        return options.picture
    if options.output is not None:
        return options.output.with_suffix(PICTURE_SUFFIX)
    return Path(DEFAULT_PICTURE)


def main(argv=None, prog=PROGRAM):
    """
    Run the command.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :param prog: the program's name in messages.
    :return: the exit status: 0 verified, 2 bad input or no line found, 130 on Ctrl-C.
    """
    options = parse_arguments(argv, prog)
    try:
        summary = calibrate(options)
    except CalibrationError as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    print(f'{prog}: {summary}', file=sys.stderr)
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
