"""
The simulator node over real DDS: cmd_vel in, motion and time out, as a ROS user drives it.

A client node publishes Twists; the simulator's own world gives the ground truth of the motion.
"""

import math

from conftest import SimHarness
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from followbot.frames import CAMERA_RGB_OPTICAL_FRAME
from followbot_sim.score import score_status_name, score_values
from followbot_sim.sim_node import LINE_TRUTH_TOPIC, SimulatorNode
from geometry_msgs.msg import PolygonStamped, Twist, Vector3
import pytest
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image

COMMAND_TIMEOUT_S = 0.6
FORWARD_SPEED_MPS = 0.3
SETTLE_S = 0.3


def test_cmd_vel_drives_then_the_watchdog_stops_the_robot(sim):
    sent_at_s = sim.command(FORWARD_SPEED_MPS)
    sim.run_until(sent_at_s + COMMAND_TIMEOUT_S - 0.1)
    speed_mps, _ = sim.world.robot_twist()
    assert speed_mps == pytest.approx(FORWARD_SPEED_MPS, rel=0.02)
    # 0.6 s of simulated time after the only command the wheels stop, and the robot with them.
    sim.run_until(sent_at_s + COMMAND_TIMEOUT_S + SETTLE_S)
    speed_mps, _ = sim.world.robot_twist()
    assert abs(speed_mps) < 0.01
    assert sim.world.data.ctrl == pytest.approx([0.0, 0.0])


def test_commands_beyond_the_kobuki_limits_are_limited(sim):
    sent_at_s = sim.command(2.0)
    sim.run_until(sent_at_s + COMMAND_TIMEOUT_S - 0.1)
    speed_mps, _ = sim.world.robot_twist()
    assert speed_mps == pytest.approx(0.7, rel=0.03)


def test_non_finite_cmd_vel_is_refused_and_reported_once(sim):
    sent_at_s = sim.command(FORWARD_SPEED_MPS)
    for _ in range(5):
        sim.cmd_vel.publish(Twist(linear=Vector3(x=math.nan), angular=Vector3(z=1.0)))
    sim.run_until(sent_at_s + 0.4)
    speed_mps, yaw_rate_radps = sim.world.robot_twist()
    assert speed_mps == pytest.approx(FORWARD_SPEED_MPS, rel=0.02)
    assert abs(yaw_rate_radps) < 0.01
    sim.spin_until(lambda: sim.errors)
    assert len(sim.errors) == 1 and 'non-finite' in sim.errors[0]


def test_run_duration_ends_the_run_at_that_simulated_time(ros_context):
    harness = SimHarness(ros_context, Parameter('run_duration_s', value=1.5))
    try:
        harness.spin_until(lambda: harness.simulator.finished)
        assert harness.world.time_s == pytest.approx(1.5, abs=0.011)
        time_s = harness.world.time_s
        for _ in range(10):
            harness.executor.spin_once(timeout_sec=0.01)
        assert harness.world.time_s == time_s
    finally:
        harness.close()


@pytest.mark.parametrize('name, value', [
    ('real_time_factor', -1.0),
    ('camera_rate_hz', 0.0),
    ('course', 'no_such_course'),
    # A quarter of a metre is more than the line's width beside it.
    ('start_lateral_offset_m', 0.3),
    # One step call may not hold the node for minutes.
    ('step_physics_steps', 1_000_000),
])
def test_bad_parameters_are_refused_at_start(ros_context, name, value):
    with pytest.raises((ParameterException, ValueError)) as raised:
        SimulatorNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])
    assert name in str(raised.value) or str(value) in str(raised.value)


def test_the_score_on_diagnostics_reads_back_with_score_values(sim):
    scores = []

    def keep_score(msg):
        score = score_values(msg)
        if score is not None:
            scores.append(score)

    sim.client.create_subscription(DiagnosticArray, '/diagnostics', keep_score, 10)
    sim.spin_until(lambda: scores)
    assert float(scores[0]['time_s']) == pytest.approx(1.0)
    assert scores[0]['laps_completed'] == '0'
    assert float(scores[0]['course_length_m']) == pytest.approx(sim.world.course.length_m)


def test_score_values_is_none_for_other_statuses():
    other = DiagnosticArray(status=[DiagnosticStatus(name='some driver: temperature')])
    assert score_values(other) is None
    assert score_values(DiagnosticArray()) is None


def test_each_robots_score_is_named_after_its_simulator():
    scores = DiagnosticArray(status=[
        DiagnosticStatus(name=score_status_name(name), hardware_id=name,
                         values=[KeyValue(key='robot', value=name)])
        for name in ('/r1/followbot_sim', '/r2/followbot_sim')])
    assert score_values(scores, '/r2/followbot_sim') == {'robot': '/r2/followbot_sim'}
    assert score_values(scores, '/r3/followbot_sim') is None
    assert score_values(scores) == {'robot': '/r1/followbot_sim'}


def test_line_truth_topic_gives_the_line_under_the_robot_stamped_like_the_image(sim):
    truths = []
    image_stamps = []
    sim.client.create_subscription(PolygonStamped, LINE_TRUTH_TOPIC, truths.append, 10)
    sim.client.create_subscription(
        Image, 'camera/rgb/image_raw', lambda msg: image_stamps.append(msg.header.stamp), 10)
    sim.spin_until(lambda: len(truths) >= 2 and len(image_stamps) >= 2)
    truth = truths[-1]
    assert truth.header.frame_id == CAMERA_RGB_OPTICAL_FRAME
    stamps = [(stamp.sec, stamp.nanosec) for stamp in image_stamps]
    assert (truth.header.stamp.sec, truth.header.stamp.nanosec) in stamps
    rows = sorted({point.y for point in truth.polygon.points})
    # Every 10th row from row 0 (the default step), each listed once at least.
    assert rows == [float(row) for row in range(0, 480, 10)]
    # The robot starts on the line, heading along it: the nearest rows see it mid-image.
    bottom = [point for point in truth.polygon.points if point.y == 470.0]
    assert len(bottom) == 1 and bottom[0].x == pytest.approx(319.5, abs=30.0)
    # ~0.35 m ahead the 0.19 m line is ~300 px wide.
    assert 200.0 < bottom[0].z < 400.0


def test_realism_from_the_course_file_gives_camera_info_the_lens(ros_context, tmp_path):
    course_file = tmp_path / 'lab_square.yaml'
    course_file.write_text(
        'centre_line:\n  start: [-1.0, -1.0, 0]\n  segments:\n'
        + '    - {straight_m: 2.0}\n    - {arc_radius_m: 0.5, arc_angle_deg: 90}\n' * 4
        + 'floor_size_m: 6.0\nrealism: {preset: lab, seed: 4}\n')
    harness = SimHarness(ros_context, Parameter('course', value=str(course_file)),
                         Parameter('depth_enabled', value=False),
                         Parameter('point_cloud_enabled', value=False))
    try:
        infos = []
        harness.client.create_subscription(CameraInfo, 'camera/rgb/camera_info',
                                           infos.append, 10)
        harness.spin_until(lambda: infos)
        assert harness.world.realism.preset == 'lab' and harness.world.realism.seed == 4
        fx_px, _, _, _ = harness.world.published_camera_model()[0]
        assert infos[-1].d[0] == pytest.approx(harness.world.realism.radial_distortion_k1)
        assert infos[-1].d[0] < 0.0 and infos[-1].k[0] == pytest.approx(fx_px)
    finally:
        harness.close()
