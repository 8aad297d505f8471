"""The calibrate command as a user runs it: image files, recordings, live topics, bad input."""

import math
import subprocess
import sys
import time

from conftest import child_environment, kill_leftovers, run_domain_id, spin_until
import cv2
from diagnostic_msgs.msg import DiagnosticArray
from followbot import calibrate
from followbot.compressed_image import array_to_compressed
from followbot.follower_node import FollowerNode
from followbot.image_conversion import array_to_image
from followbot.recording import RecordingWriter
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message
import scenes
from sensor_msgs.msg import CompressedImage, Image
import yaml

LINE = [scenes.straight_line(0.05, 0.2)]
TAPE_M = 0.05
WHITE_BGR = (235, 235, 235)
SHOWN_ROW = 400
IMAGE_TOPIC = '/camera/rgb/image_raw'
COMPRESSED_TOPIC = IMAGE_TOPIC + '/compressed'
PUBLISH_PERIOD_S = 0.1
COMMAND_TIMEOUT_S = 60
# The simulated Kinect's calibration, as camera_calibration writes it.
KINECT_INFO = {
    'image_width': scenes.WIDTH_PX, 'image_height': scenes.HEIGHT_PX, 'camera_name': 'kinect',
    'camera_matrix': {'rows': 3, 'cols': 3, 'data': [
        scenes.KINECT.fx_px, 0.0, scenes.KINECT.cx_px, 0.0, scenes.KINECT.fy_px,
        scenes.KINECT.cy_px, 0.0, 0.0, 1.0]},
    'distortion_model': 'plumb_bob',
    'distortion_coefficients': {'rows': 1, 'cols': 5, 'data': [0.0] * 5},
}
KINECT_OPTIONS = ['--camera-height-m', str(scenes.KINECT.height_m),
                  '--camera-pitch-deg', str(math.degrees(scenes.KINECT.pitch_rad))]


def tape_frame():
    """Return a frame of white tape on the grey floor, and a pixel on the tape."""
    image = scenes.add_noise(scenes.scene(LINE, width_m=TAPE_M, line_bgr=WHITE_BGR), 4.0)
    columns = np.flatnonzero(scenes.line_mask(LINE, TAPE_M)[SHOWN_ROW])
    return image, f'{int(columns.mean())},{SHOWN_ROW}'


def bare_floor():
    """Return a frame of the floor alone."""
    return scenes.scene((), line_bgr=WHITE_BGR)


def run_command(arguments, cwd, module='followbot.calibrate', environment=None):
    """Run a command as a user would, and return its completed process."""
    return subprocess.run([sys.executable, '-m', module, *map(str, arguments)], cwd=cwd,
                          env=environment or child_environment(), timeout=COMMAND_TIMEOUT_S,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def parameters_of(text):
    """Return the follower's parameters in a parameters YAML."""
    return yaml.safe_load(text)['/**/follower']['ros__parameters']


def test_an_image_file_and_a_point_give_a_verified_yaml_and_a_picture(tmp_path):
    image, point = tape_frame()
    cv2.imwrite(str(tmp_path / 'frame.png'), image)
    result = run_command(['frame.png', '--point', point], tmp_path)
    assert result.returncode == 0, result.stderr
    assert parameters_of(result.stdout) == {'line_colour': 'white'}
    assert result.stdout.startswith('# followbot calibrate: white line, verified on')
    summary = result.stderr.splitlines()
    assert len(summary) == 1 and summary[0].startswith('calibrate: white line, verified')
    assert 'line_width_m not measured' in summary[0]
    picture = cv2.imread(str(tmp_path / calibrate.DEFAULT_PICTURE))
    assert picture.shape == (scenes.HEIGHT_PX, 2 * scenes.WIDTH_PX, 3)


def test_the_camera_gives_the_tape_width_and_the_yaml_starts_the_follower(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    image, point = tape_frame()
    cv2.imwrite(str(tmp_path / 'frame.jpg'), image)
    (tmp_path / 'kinect.yaml').write_text(yaml.safe_dump(KINECT_INFO))
    status = calibrate.main(['frame.jpg', '--point', point, '--camera-info', 'kinect.yaml',
                             *KINECT_OPTIONS, '--output', 'follower.yaml'])
    assert status == 0
    assert (tmp_path / 'follower.png').is_file()
    parameters = parameters_of((tmp_path / 'follower.yaml').read_text())
    assert parameters['line_colour'] == 'white'
    assert parameters['line_width_m'] == pytest.approx(TAPE_M, rel=0.05)
    assert parameters['camera_pitch_deg'] == pytest.approx(30.0)
    # The file is a parameters file the follower takes as it is.
    context = Context()
    rclpy.init(args=['follower', '--ros-args', '--params-file',
                     str(tmp_path / 'follower.yaml')], context=context,
               domain_id=run_domain_id())
    try:
        node = FollowerNode(context=context)
        for name, value in parameters.items():
            assert node.get_parameter(name).value == value
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_followbot_calibrate_is_the_same_command(tmp_path):
    image, point = tape_frame()
    cv2.imwrite(str(tmp_path / 'frame.png'), image)
    result = run_command(['calibrate', 'frame.png', '--point', point, '--picture', 'x.png'],
                         tmp_path, module='followbot_sim.launcher')
    assert result.returncode == 0, result.stderr
    assert result.stderr.startswith('followbot calibrate: white line')
    assert (tmp_path / 'x.png').is_file()


def write_recording(path, frames, topics=(IMAGE_TOPIC, COMPRESSED_TOPIC)):
    """Record frames on a raw and a compressed image topic, 0.1 s apart."""
    with RecordingWriter(path) as writer:
        for topic in topics:
            writer.add_topic(topic, 'sensor_msgs/msg/CompressedImage' if topic.endswith(
                '/compressed') else 'sensor_msgs/msg/Image')
        for index, image in enumerate(frames):
            for topic in topics:
                if topic.endswith('/compressed'):
                    msg = array_to_compressed(image, 'bgr8', msg=CompressedImage())
                else:
                    msg = array_to_image(image, 'bgr8')
                writer.write(topic, serialize_message(msg), (index + 1) * 100_000_000)


@pytest.mark.parametrize('topic', [IMAGE_TOPIC, COMPRESSED_TOPIC], ids=['raw', 'compressed'])
def test_a_recording_gives_the_frame_asked_for(tmp_path, topic, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    image, point = tape_frame()
    write_recording(tmp_path / 'run.mcap', [bare_floor(), image])
    assert calibrate.main(['run.mcap', '--topic', topic, '--frame', '1', '--point', point]) == 0
    captured = capsys.readouterr()
    assert parameters_of(captured.out)['line_colour'] == 'white'
    assert f'run.mcap, {topic} message 1' in captured.err
    # The first frame is the bare floor: nothing to find there.
    assert calibrate.main(['run.mcap', '--topic', topic, '--point', point]) == 2


def test_a_rosbag2_folder_with_one_image_topic_needs_no_topic(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    image, point = tape_frame()
    (tmp_path / 'bag').mkdir()
    write_recording(tmp_path / 'bag' / 'bag_0.mcap', [image], topics=[COMPRESSED_TOPIC])
    assert calibrate.main(['bag', '--point', point]) == 0
    assert f'{COMPRESSED_TOPIC} message 0' in capsys.readouterr().err


class ImagePublisher(Node):
    """Publish the same camera frame every PUBLISH_PERIOD_S, raw or compressed."""

    def __init__(self, image, topic, **kwargs):
        """Make the publisher and its timer."""
        super().__init__('camera', **kwargs)
        compressed = topic.endswith('/compressed')
        if compressed:
            self.msg = array_to_compressed(image, 'bgr8', msg=CompressedImage())
        else:
            self.msg = array_to_image(image, 'bgr8')
        self.publisher = self.create_publisher(CompressedImage if compressed else Image, topic,
                                               10)
        self.timer = self.create_timer(PUBLISH_PERIOD_S, self.timer_callback)

    def timer_callback(self):
        """Send the frame."""
        self.publisher.publish(self.msg)


@pytest.mark.parametrize('topic', [IMAGE_TOPIC, COMPRESSED_TOPIC], ids=['raw', 'compressed'])
def test_a_live_topic_gives_a_frame(ros_context, tmp_path, topic):
    image, point = tape_frame()
    camera = ImagePublisher(image, topic, context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(camera)
    process = subprocess.Popen(
        [sys.executable, '-m', 'followbot.calibrate', '--topic', topic, '--point', point,
         '--timeout', '30'], cwd=tmp_path, env=child_environment(), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    try:
        spin_until(executor, lambda: process.poll() is not None, COMMAND_TIMEOUT_S)
        output, errors = process.communicate(timeout=COMMAND_TIMEOUT_S)
    finally:
        kill_leftovers(process)
        executor.shutdown()
        camera.destroy_node()
    assert process.returncode == 0, errors
    assert parameters_of(output)['line_colour'] == 'white'
    assert f'in topic {topic}' in errors


def test_a_silent_topic_is_one_clear_line(ros_context, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    started = time.monotonic()
    assert calibrate.main(['--topic', '/nobody/image_raw', '--timeout', '0.5']) == 2
    assert time.monotonic() - started < 10
    errors = capsys.readouterr().err.splitlines()
    assert errors == [f'calibrate: No topic /nobody/image_raw appeared within 0.5 s '
                      f'(ROS_DOMAIN_ID={run_domain_id()}): is the camera running?']


def test_a_topic_of_another_type_is_refused(ros_context, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    other = Node('other', context=ros_context)
    other.create_publisher(DiagnosticArray, '/diagnostics_like', 1)
    try:
        assert calibrate.main(['--topic', '/diagnostics_like', '--timeout', '10']) == 2
    finally:
        other.destroy_node()
    assert capsys.readouterr().err.splitlines() == [
        'calibrate: /diagnostics_like carries diagnostic_msgs/msg/DiagnosticArray, not '
        'sensor_msgs/msg/Image or CompressedImage.']


@pytest.mark.parametrize('arguments, message', [
    (['missing.png'], 'No such file or folder: missing.png.'),
    (['notes.txt'], 'notes.txt is not an image OpenCV can read.'),
    (['frame.png', '--point', '700,10'], 'The point (700, 10) lies outside the 640x480 frame.'),
    (['frame.png', '--region', '600,400,100,100'],
     'The region 600,400,100,100 reaches outside the 640x480 frame.'),
    (['frame.png', '--topic', '/x'],
     'frame.png is an image: --topic and --frame apply to recordings and live topics.'),
    (['floor.png'], 'No line found in floor.png with any preset: the most confident, '),
    (['frame.png', '--point', '{point}', '--camera-info', 'small.yaml', *KINECT_OPTIONS],
     'small.yaml: camera_info describes a 320x240 image, but the image is 640x480.'),
    (['odometry.mcap'], 'The recording odometry.mcap has no Image or CompressedImage topic.'),
    (['run.mcap'], 'The recording run.mcap has several image topics (/camera/rgb/image_raw, '
                   '/camera/rgb/image_raw/compressed): choose one with --topic.'),
    (['run.mcap', '--topic', '/camera/rgb/image_raw', '--frame', '3'],
     'The recording run.mcap has 1 image message(s) on /camera/rgb/image_raw; --frame 3 '
     'asks for message 4.'),
    (['run.mcap', '--topic', '/tf'], 'The recording run.mcap has no topic /tf; its image '
                                     'topics: /camera/rgb/image_raw, '
                                     '/camera/rgb/image_raw/compressed.'),
])
def test_bad_input_is_one_line_and_status_2(tmp_path, arguments, message, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    image, point = tape_frame()
    cv2.imwrite(str(tmp_path / 'frame.png'), image)
    cv2.imwrite(str(tmp_path / 'floor.png'), bare_floor())
    (tmp_path / 'notes.txt').write_text('not a picture')
    small = dict(KINECT_INFO, image_width=320, image_height=240)
    (tmp_path / 'small.yaml').write_text(yaml.safe_dump(small))
    write_recording(tmp_path / 'run.mcap', [image])
    with RecordingWriter(tmp_path / 'odometry.mcap') as writer:
        writer.add_topic('/odom', 'nav_msgs/msg/Odometry')
    arguments = [argument.format(point=point) for argument in arguments]
    assert calibrate.main(arguments) == 2
    errors = capsys.readouterr().err.splitlines()
    assert len(errors) == 1 and errors[0].startswith('calibrate: ' + message)


@pytest.mark.parametrize('arguments, message', [
    ([], 'give an image file or recording, or a live --topic'),
    (['frame.png', '--point', '10'], 'a point X,Y must be 2 whole numbers'),
    (['frame.png', '--point', '1,2', '--region', '1,2,3,4'], 'not allowed with argument'),
    (['frame.png', '--camera-info', 'c.yaml'], 'missing --camera-height-m, --camera-pitch-deg'),
    (['frame.png', '--camera-info', 'c.yaml', '--camera-height-m', '0', '--camera-pitch-deg',
      '10'], "argument --camera-height-m: must be a number in [0.01, 10], got '0'"),
    (['frame.png', '--frame', '-1'], "argument --frame: must be a whole number >= 0, got '-1'"),
    (['frame.png', '--picture', 'mask.gif'], 'must end in .png, .jpg or .jpeg'),
    (['frame.png', '--output', 'params.png'], 'is where the picture would go'),
    (['frame.png', '--output', 'same.jpg', '--picture', 'same.jpg'],
     'is where the picture would go'),
    (['frame.png', '--output', 'no/such/folder/p.yaml'], 'folder no/such/folder does not exist'),
])
def test_bad_arguments_are_one_line_and_status_2(arguments, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        calibrate.parse_arguments(arguments)
    assert exit_info.value.code == 2
    errors = capsys.readouterr().err.splitlines()
    assert len(errors) == 1 and message in errors[0]


def test_help_says_how_to_show_the_line_without_a_window(capsys):
    with pytest.raises(SystemExit) as exit_info:
        calibrate.parse_arguments(['--help'])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith('usage: calibrate [SOURCE]')
    assert 'no window to click in' in ' '.join(text.split())


def test_a_grey_picture_is_calibrated_as_a_grey_camera(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    image, point = tape_frame()
    cv2.imwrite('grey.png', 255 - image[..., 1])
    assert calibrate.main(['grey.png', '--point', point]) == 0
    captured = capsys.readouterr()
    assert parameters_of(captured.out) == {'line_colour': 'black'}
    # A grey camera shows no colour: only the white and black presets are tried.
    assert 'the line shown in 6 of the 6 bands' in captured.err


def test_the_command_stands_without_the_simulator(tmp_path):
    # The robot side: calibrate imports nothing of followbot_sim or mujoco.
    code = ("import sys; sys.modules['followbot_sim'] = None; sys.modules['mujoco'] = None; "
            'import followbot.calibrate')
    result = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, env=child_environment(),
                            timeout=COMMAND_TIMEOUT_S, stderr=subprocess.PIPE, text=True)
    assert result.returncode == 0, result.stderr
