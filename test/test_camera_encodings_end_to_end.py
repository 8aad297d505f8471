"""
Every image a camera sends, followed end to end: the simulator and the follower as processes.

The simulator publishes its camera in one encoding (or compressed, on the image_transport
topic), the follower takes it over DDS and drives; the simulator's ground-truth score says the
robot went along the line. A grey (mono8) camera shows the course's yellow line brighter than
its floor, so the follower takes it with the white preset there.
"""

import subprocess
import sys

from conftest import child_environment, kill_leftovers, spin_until, stop_process
from diagnostic_msgs.msg import DiagnosticArray
from followbot_sim.score import score_values
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

# Each run drives this far along the line, as fast as the machine allows, in lockstep.
DRIVEN_DISTANCE_M = 2.0
MAX_DISTANCE_FROM_LINE_M = 0.05
RUN_TIMEOUT_S = 60.0
# (simulator parameters, follower parameters) per way of sending the camera.
CAMERAS = {
    **{encoding: ([f'image_encoding:={encoding}'], []) for encoding in (
        'bgr8', 'rgb8', 'bgra8', 'rgba8', 'yuv422', 'uyvy', 'yuv422_yuy2', 'yuyv',
        'bayer_rggb8', 'bayer_bggr8', 'bayer_gbrg8', 'bayer_grbg8')},
    'mono8': (['image_encoding:=mono8'], ['line_colour:=white']),
    'compressed_jpeg': (['jpeg_quality:=80'], ['image_transport:=compressed']),
}


def node(module: str, parameters: list) -> list:
    """Return the command line of a node process with parameters."""
    arguments = [argument for parameter in parameters for argument in ('-p', parameter)]
    return [sys.executable, '-m', module, '--ros-args', *arguments]


@pytest.mark.parametrize('camera', CAMERAS)
def test_the_follower_follows_every_camera_encoding(ros_context, camera):
    simulator_parameters, follower_parameters = CAMERAS[camera]
    environment = child_environment()
    simulator = subprocess.Popen(node('followbot_sim.sim_node', [
        'real_time_factor:=0.0', 'lockstep:=true', 'depth_enabled:=false',
        'point_cloud_enabled:=false', *simulator_parameters]), env=environment)
    follower = subprocess.Popen(node('followbot.follower_node', [
        'use_sim_time:=true', *follower_parameters]), env=environment)
    client = Node('encoding_client', context=ros_context)
    scores = []
    client.create_subscription(DiagnosticArray, '/diagnostics',
                               lambda msg: scores.append(score_values(msg)), 10)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert spin_until(executor, lambda: any(
            score and float(score['progress_m']) >= DRIVEN_DISTANCE_M for score in scores),
            RUN_TIMEOUT_S), f'last score {scores[-1:]}'
        assert stop_process(follower) == 0
        assert stop_process(simulator) == 0
    finally:
        kill_leftovers(follower, simulator)
        executor.shutdown()
        client.destroy_node()
    score = [score for score in scores if score][-1]
    assert float(score['max_distance_from_line_m']) < MAX_DISTANCE_FROM_LINE_M
    assert float(score['time_off_line_s']) == 0.0
