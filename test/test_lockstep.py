"""Lockstep: the simulator waits for the answer to each camera frame, so runs repeat exactly."""

import subprocess
import sys

from conftest import SimHarness, spin_until
from followbot import messages
from followbot.follower_node import FollowerNode
from followbot_sim.sim_node import SimulatorNode
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

FRAME_PERIOD_S = 0.05
# Spins that would let an unhindered simulator run on by many frames.
OBSERVATION_SPINS = 30
OBSERVATION_SPIN_S = 0.01
RUN_DURATION_S = 10.0
RUN_TIMEOUT_S = 120.0
IMAGE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
# Only the camera matters here: no depth rendering, no point clouds.
CAMERA_ONLY = (Parameter('depth_enabled', value=False),
               Parameter('point_cloud_enabled', value=False))


class LockstepHarness(SimHarness):
    """A simulator in lockstep and a client that can play the follower."""

    def __init__(self, context, *overrides):
        super().__init__(context, Parameter('lockstep', value=True), *CAMERA_ONLY, *overrides)
        self.frames = []

    def take_the_camera(self):
        """Subscribe to the camera as a follower does, keeping every frame's stamp."""
        self.client.create_subscription(
            Image, 'camera/rgb/image_raw',
            lambda msg: self.frames.append(messages.seconds(msg.header.stamp)), IMAGE_QOS)

    def logged(self, text):
        """Return whether the simulator has logged a line containing ``text``."""
        return any(text in msg.msg for msg in self.logs)

    def observe(self):
        """Spin for a while, long enough for a free-running simulator to run on."""
        for _ in range(OBSERVATION_SPINS):
            self.executor.spin_once(timeout_sec=OBSERVATION_SPIN_S)


@pytest.fixture
def lockstep(ros_context):
    harness = LockstepHarness(ros_context)
    yield harness
    harness.close()


def test_time_stands_still_until_a_follower_takes_the_camera(lockstep):
    lockstep.spin_until(lambda: lockstep.logged('Lockstep: holding time at 0.000 s'))
    lockstep.observe()
    assert lockstep.world.time_s == 0.0
    lockstep.take_the_camera()
    lockstep.spin_until(lambda: lockstep.frames)
    assert lockstep.logged('Lockstep: follower connected, time runs.')


def test_each_frame_waits_for_the_command_that_answers_it(lockstep):
    lockstep.take_the_camera()
    for frame in range(1, 4):
        lockstep.spin_until(lambda: len(lockstep.frames) == frame)
        frame_s = lockstep.frames[-1]
        lockstep.observe()
        # Unanswered, the frame holds time at its stamp, and no further frame comes.
        assert lockstep.world.time_s == pytest.approx(frame_s, abs=1e-9)
        assert len(lockstep.frames) == frame
        assert lockstep.command(0.3) == pytest.approx(frame_s, abs=1e-9)
    lockstep.spin_until(lambda: len(lockstep.frames) == 4)
    assert lockstep.frames[-1] - lockstep.frames[-2] == pytest.approx(FRAME_PERIOD_S)
    assert lockstep.simulator.lockstep_timeouts == 0
    assert lockstep.world.robot_twist()[0] == pytest.approx(0.3, abs=0.05)


def test_an_unanswered_frame_waits_no_longer_than_the_timeout(ros_context):
    harness = LockstepHarness(ros_context, Parameter('lockstep_timeout_s', value=0.05))
    try:
        harness.take_the_camera()
        harness.spin_until(lambda: harness.simulator.lockstep_timeouts >= 3)
        assert len(harness.frames) >= 3
        assert harness.world.time_s >= 2 * FRAME_PERIOD_S
        # One warning, not one per frame.
        harness.spin_until(lambda: harness.logged('no cmd_vel answered'))
        timeout_warnings = [text for text in harness.warnings
                            if 'no cmd_vel answered the camera frame' in text]
        assert len(timeout_warnings) == 1
    finally:
        harness.close()


def test_stepping_a_paused_simulator_does_not_wait_for_answers(ros_context):
    harness = LockstepHarness(ros_context, Parameter('start_paused', value=True),
                              Parameter('step_physics_steps', value=100))
    try:
        harness.take_the_camera()
        assert harness.step().success
        assert harness.world.time_s == pytest.approx(0.2)
    finally:
        harness.close()


def run_in_lockstep(context) -> dict:
    """Run the simulator and the follower in process, in lockstep; return where it ended."""
    simulator = SimulatorNode(context=context, parameter_overrides=[
        Parameter('lockstep', value=True), Parameter('real_time_factor', value=0.0),
        Parameter('run_duration_s', value=RUN_DURATION_S), *CAMERA_ONLY])
    follower = FollowerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(simulator)
    executor.add_node(follower)
    try:
        assert spin_until(executor, lambda: simulator.finished, RUN_TIMEOUT_S)
        return {
            'pose': simulator.world.robot_pose(),
            'odometry': simulator.odometry.pose,
            # RMS and max sum over the whole path, sampled at 100 Hz: any difference anywhere
            # along the way shows in them.
            'score': simulator.lap_tracker.summary(),
            'commands': simulator.commands_received,
            'lockstep_timeouts': simulator.lockstep_timeouts,
            'follower': follower.line_statistics,
        }
    finally:
        executor.shutdown()
        follower.destroy_node()
        simulator.destroy_node()


def test_two_runs_drive_the_same_path_even_under_load(ros_context):
    quiet = run_in_lockstep(ros_context)
    # A second run competing with a process that keeps a core busy.
    hog = subprocess.Popen([sys.executable, '-c', 'while True: pass'])
    try:
        loaded = run_in_lockstep(ros_context)
    finally:
        hog.kill()
        hog.wait()
    assert loaded == quiet
    assert quiet['lockstep_timeouts'] == 0
    # Every frame was answered, one command each, the last one too: the run ends once it came.
    assert quiet['commands'] == round(RUN_DURATION_S / FRAME_PERIOD_S)
    assert quiet['score']['progress_m'] > 5.0
