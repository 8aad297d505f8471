"""
TFMessage on the no-ROS route: config/tf2_msgs, built into the venv by ``make setup``.

tf2_msgs is not on PyPI. The set-up builds our stand-in interface package (TFMessage only) with
the Jazzy rosidl generators from PyPI; on a ROS 2 Jazzy system the apt package provides it. Either
way ``from tf2_msgs.msg import TFMessage`` must work and the message must cross Fast DDS.
"""

import importlib
import shutil
import subprocess

from catkin_pkg.package import parse_package
from conftest import PACKAGE_DIR, spin_until
from geometry_msgs.msg import TransformStamped
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from test_colcon_workspace import colcon_executable

INTERFACE_DIR = PACKAGE_DIR / 'config' / 'tf2_msgs'
TF_FIELD_TYPES = {'transforms': 'sequence<geometry_msgs/TransformStamped>'}
MAKE_TIMEOUT_S = 60.0
# The tf2 type hash a ROS 2 Jazzy system reports for tf2_msgs/msg/TFMessage (ros2 topic info -v).
JAZZY_TF_MESSAGE_HASH = 'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'
# Commands of the Makefile's recipes that show which set-up steps would run.
FOLLOWBOT_INSTALL = 'pip install -q -r requirements-test.txt'
TF2_MSGS_INSTALL = 'cmake --install'


def import_tf_message():
    """Return the TFMessage class; fail with the fix when tf2_msgs is not importable."""
    try:
        return importlib.import_module('tf2_msgs.msg').TFMessage
    except ImportError as error:
        pytest.fail(f'tf2_msgs is not importable ({error}): without ROS, `make setup` builds '
                    'config/tf2_msgs into the venv; on ROS 2 Jazzy, install ros-jazzy-tf2-msgs')


def msg_fields(path) -> dict:
    """
    Return the fields a .msg file declares.

    :param path: the .msg file.
    :return: {field name: type as written}, such as {'transforms': 'geometry_msgs/...[]'}.
    """
    fields = {}
    for line in path.read_text(encoding='utf-8').splitlines():
        words = line.split('#', 1)[0].split()
        if words:
            field_type, name = words
            fields[name] = field_type
    return fields


def transform(parent: str, child: str, x_m: float, yaw_z: float) -> TransformStamped:
    """Return a TransformStamped with a translation along x and a quaternion z component."""
    message = TransformStamped()
    message.header.frame_id = parent
    message.header.stamp.sec = 12
    message.header.stamp.nanosec = 345
    message.child_frame_id = child
    message.transform.translation.x = x_m
    message.transform.rotation.z = yaw_z
    return message


def test_interface_package_is_a_format_3_interface_package():
    warnings = []
    package = parse_package(str(INTERFACE_DIR / 'package.xml'), warnings=warnings)
    package.validate(warnings=warnings)
    assert warnings == []
    assert package.name == 'tf2_msgs'
    assert package.get_build_type() == 'ament_cmake'
    assert 'rosidl_interface_packages' in {group.name for group in package.member_of_groups}
    assert 'geometry_msgs' in {dependency.name for dependency in package.build_depends}
    assert 'geometry_msgs' in {dependency.name for dependency in package.exec_depends}


def test_interface_declares_tf_message_as_tf2_does():
    assert sorted(path.name for path in (INTERFACE_DIR / 'msg').iterdir()) == ['TFMessage.msg']
    assert msg_fields(INTERFACE_DIR / 'msg' / 'TFMessage.msg') == {
        'transforms': 'geometry_msgs/TransformStamped[]'}


def test_colcon_finds_followbot_alone_in_the_checkout():
    # colcon stops at followbot's own package.xml: a workspace never builds the stand-in, which
    # would shadow a real tf2_msgs. It is an ament_cmake package when pointed at on purpose.
    def listed(base_path):
        result = subprocess.run([colcon_executable(), 'list', '--base-paths', str(base_path)],
                                capture_output=True, text=True, timeout=MAKE_TIMEOUT_S)
        assert result.returncode == 0, result.stderr
        return [line.split('\t')[::2] for line in result.stdout.splitlines()]

    assert listed(PACKAGE_DIR) == [['followbot', '(ros.ament_python)']]
    assert listed(INTERFACE_DIR) == [['tf2_msgs', '(ros.ament_cmake)']]


def test_tf_message_is_importable_with_tf2s_fields():
    tf_message = import_tf_message()
    assert tf_message.get_fields_and_field_types() == TF_FIELD_TYPES


def test_tf_message_crosses_fast_dds_between_a_publisher_and_a_subscriber(ros_context):
    tf_message = import_tf_message()
    publisher_node = Node('tf_publisher', context=ros_context)
    subscriber_node = Node('tf_subscriber', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(publisher_node)
    executor.add_node(subscriber_node)
    try:
        received = []
        subscriber_node.create_subscription(tf_message, '/tf', received.append, 10)
        publisher = publisher_node.create_publisher(tf_message, '/tf', 10)
        assert spin_until(executor, lambda: publisher.get_subscription_count() > 0)
        sent = tf_message(transforms=[transform('odom', 'base_footprint', 1.5, 0.25),
                                      transform('base_footprint', 'base_link', -0.5, 0.0)])
        publisher.publish(sent)
        assert spin_until(executor, lambda: received)
        assert received[0] == sent
        # The same type as on a Jazzy system: tools there match it by this hash.
        assert str(publisher_node.get_publishers_info_by_topic('/tf')[0].topic_type_hash) == \
            JAZZY_TF_MESSAGE_HASH
        assert [item.child_frame_id for item in received[0].transforms] == [
            'base_footprint', 'base_link']
    finally:
        executor.shutdown()
        publisher_node.destroy_node()
        subscriber_node.destroy_node()


@pytest.fixture
def make_dry_run(tmp_path):
    """
    Return a function that lists the commands ``make setup`` would run on an up-to-date venv.

    The venv is a folder with both set-up stamps, newer than every source; the function's
    argument names a file to treat as just changed.
    """
    make = shutil.which('make')
    if make is None:
        pytest.skip('make is not installed: the Makefile is the no-ROS route')
    venv = tmp_path / 'venv'
    venv.mkdir()
    for stamp in ('.followbot-installed', '.tf2_msgs-installed'):
        (venv / stamp).touch()

    def dry_run(changed_file: str = '') -> str:
        what_if = ['-W', changed_file] if changed_file else []
        result = subprocess.run([make, '-n', *what_if, 'setup', f'VENV={venv}'],
                                cwd=PACKAGE_DIR, capture_output=True, text=True,
                                timeout=MAKE_TIMEOUT_S)
        assert result.returncode == 0, result.stderr
        return result.stdout

    return dry_run


@pytest.mark.parametrize(('changed_file', 'followbot_step', 'tf2_msgs_step'), [
    ('', False, False),
    ('config/tf2_msgs/msg/TFMessage.msg', False, True),
    ('config/tf2_msgs/CMakeLists.txt', False, True),
    ('config/tf2_msgs/package.xml', False, True),
    ('requirements-build.txt', False, True),
    ('requirements.txt', True, True),
])
def test_setup_rebuilds_tf2_msgs_when_its_sources_change(make_dry_run, changed_file,
                                                         followbot_step, tf2_msgs_step):
    commands = make_dry_run(changed_file)
    assert (FOLLOWBOT_INSTALL in commands) == followbot_step
    assert (TF2_MSGS_INSTALL in commands) == tf2_msgs_step
