"""The robot side stands alone: the follower runs where no simulator is installed."""

import os
from pathlib import Path
import pkgutil
import subprocess
import sys

from conftest import child_environment
import followbot

TEST_DIR = Path(__file__).resolve().parent
CHILD_TIMEOUT_S = 120.0
# Run in a fresh interpreter where followbot_sim and mujoco cannot be imported (None in
# sys.modules makes an import raise ImportError): every followbot module is imported, then a
# follower node takes a camera frame of a line over DDS and answers with a cmd_vel.
ROBOT_ONLY = """
import sys
sys.modules['followbot_sim'] = None
sys.modules['mujoco'] = None
import importlib
for name in sys.argv[1:]:
    importlib.import_module(name)

import os
from geometry_msgs.msg import Twist
from followbot import messages
from followbot.follower_node import FollowerNode
from followbot.image_conversion import array_to_image
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import CameraInfo, Image
import scenes
import time

context = Context()
rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
follower = FollowerNode(context=context)
camera = rclpy.create_node('camera', context=context)
images = camera.create_publisher(Image, 'camera/rgb/image_raw', 1)
infos = camera.create_publisher(CameraInfo, 'camera/rgb/camera_info', 1)
commands = []
camera.create_subscription(Twist, 'cmd_vel', commands.append, 10)
executor = SingleThreadedExecutor(context=context)
executor.add_node(follower)
executor.add_node(camera)
frame = scenes.scene([scenes.straight_line()])
geometry = scenes.KINECT
info = messages.camera_info((geometry.fx_px, geometry.fy_px, geometry.cx_px, geometry.cy_px),
                            (frame.shape[1], frame.shape[0]), 'camera_rgb_optical_frame')
deadline = time.monotonic() + 60.0
while not any(command.linear.x > 0.0 for command in commands):
    assert time.monotonic() < deadline, 'no command that drives along the line'
    stamp = camera.get_clock().now().to_msg()
    info.header.stamp = stamp
    infos.publish(info)
    image = array_to_image(frame, 'bgr8')
    image.header.stamp = stamp
    image.header.frame_id = 'camera_rgb_optical_frame'
    images.publish(image)
    end = time.monotonic() + 0.05
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)
print('drove along the line:', max(command.linear.x for command in commands))
assert 'followbot_sim' not in sys.modules or sys.modules['followbot_sim'] is None
executor.shutdown()
follower.destroy_node()
camera.destroy_node()
rclpy.try_shutdown(context=context)
"""


def test_the_follower_runs_with_no_simulator_installed(tmp_path):
    modules = sorted(f'followbot.{module.name}'
                     for module in pkgutil.iter_modules(followbot.__path__))
    environment = child_environment()
    environment['PYTHONPATH'] = os.pathsep.join(
        filter(None, [str(TEST_DIR), environment.get('PYTHONPATH')]))
    result = subprocess.run([sys.executable, '-c', ROBOT_ONLY, *modules], cwd=tmp_path,
                            env=environment, capture_output=True, text=True,
                            timeout=CHILD_TIMEOUT_S)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'drove along the line' in result.stdout
