"""The run recorder over real DDS: it holds simulated time while it lags behind the clock."""

from conftest import spin_until
from followbot_sim import run_recording
from followbot_sim.run_recording import HOLD_LAG_S, RESUME_LAG_S, run_topics, RunRecording
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

SIM_TIME_S = 5.0
NANOSECONDS = 1_000_000_000
# (recorded /clock, expected hold) in order: hysteresis between the two thresholds.
LAG_STEPS = [(SIM_TIME_S - HOLD_LAG_S + 0.1, False), (SIM_TIME_S - HOLD_LAG_S - 0.1, True),
             (SIM_TIME_S - RESUME_LAG_S - 0.1, True), (SIM_TIME_S - RESUME_LAG_S + 0.1, False),
             (SIM_TIME_S - HOLD_LAG_S + 0.1, False)]


@pytest.fixture
def recording_at_sim_time(ros_context, tmp_path):
    """
    Yield a RunRecording whose clock reads SIM_TIME_S, from a real /clock publisher.

    The executor that spins it is ``recording.test_executor``.
    """
    clock_node = Node('clock_source', context=ros_context)
    recording = RunRecording(tmp_path / 'run.mcap', None, context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(clock_node)
    executor.add_node(recording.recorder)
    publisher = clock_node.create_publisher(Clock, '/clock', 10)
    sim_time = Clock()
    sim_time.clock.sec = int(SIM_TIME_S)
    assert spin_until(executor, lambda: publisher.publish(sim_time) or (
        recording.recorder.get_clock().now().nanoseconds == SIM_TIME_S * NANOSECONDS))
    recording.test_executor = executor
    yield recording
    executor.shutdown()
    recording.close()
    clock_node.destroy_node()


def test_time_is_held_from_a_lag_of_a_second_until_the_recorder_caught_up(
        recording_at_sim_time):
    recording = recording_at_sim_time
    assert not recording.should_hold()  # Nothing recorded yet: no lag known.
    for recorded_s, expected in LAG_STEPS:
        recording.recorder.progress_ns = int(recorded_s * NANOSECONDS)
        assert recording.should_hold() == expected, recorded_s
    assert recording.holds == 1
    assert 'time held 1 times' in recording.close()


def test_a_simulator_spun_in_this_process_stands_still_while_the_recorder_lags(
        recording_at_sim_time, ros_context):
    # The scorecard's way: no pause service; the simulator node leaves the executor.
    recording, executor = recording_at_sim_time, recording_at_sim_time.test_executor
    simulator = Node('simulator_stand_in', context=ros_context)
    executor.add_node(simulator)
    try:
        for recorded_s, held in LAG_STEPS:
            recording.recorder.progress_ns = int(recorded_s * NANOSECONDS)
            recording.hold_in(executor, simulator)
            assert recording.holding == held, recorded_s
            assert (simulator in executor.get_nodes()) == (not held), recorded_s
        assert recording.holds == 1
    finally:
        executor.remove_node(simulator)
        simulator.destroy_node()


@pytest.mark.parametrize('compressed, camera', [
    (False, ('camera/rgb/image_raw', 'sensor_msgs/msg/Image')),
    (True, ('camera/rgb/image_raw/compressed', 'sensor_msgs/msg/CompressedImage')),
])
def test_run_topics_hold_the_camera_chosen_and_the_robots_clock(compressed, camera):
    topics = run_topics(compressed, '/r1/clock')
    assert topics[0] == camera
    assert topics[-1] == ('/r1/clock', 'rosgraph_msgs/msg/Clock')
    assert {'cmd_vel', 'odom', 'ground_truth/odom', 'follower/status', '/diagnostics', '/tf',
            '/tf_static', 'camera/rgb/camera_info'} <= {topic for topic, _ in topics}


def test_a_held_simulation_is_reported_once_when_its_time_has_come(monkeypatch):
    asked = []

    def missing():
        asked.append(True)
        return 'a publisher of /follower/debug_image'

    report = run_recording.HoldReport('the video')
    # Not yet: what is missing is not even looked at.
    assert report.line(missing) is None
    assert asked == []
    monkeypatch.setattr(run_recording, 'WAIT_REPORT_S', 0.0)
    assert report.line(missing) == ('Simulation held for 0 s: the video still waits for a '
                                    'publisher of /follower/debug_image.')
    assert report.line(missing) is None
    assert len(asked) == 1
