"""
The executables as users start them: separate processes that talk over DDS only.

An independent rclpy client, like ``ros2 topic echo`` would, checks what the simulator and the
follower publish; the ``followbot`` entry point is run as a person runs the demo.
"""

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

from conftest import (child_environment, kill_leftovers, node_command, run_domain_id, spin_until,
                      stop_process, STOP_TIMEOUT_S)
import cv2
from diagnostic_msgs.msg import DiagnosticArray
from followbot.messages import seconds
from followbot.transport import (fastdds_profile_path, FASTDDS_PROFILE_VARIABLE,
                                 USER_CONFIGURATION_VARIABLES)
from geometry_msgs.msg import Twist
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image


CAMERA_PERIOD_S = 0.05
KINECT_FX_PX = 320.0 / 0.5773502691896257  # 60 degrees across 640 px
DISCOVERY_TIMEOUT_S = 30.0


class TopicRecorder:
    """Collect messages of a few topics with an independent node."""

    def __init__(self, node):
        self.images = []
        self.camera_infos = []
        self.clocks = []
        self.cmd_vels = []
        # Reliable, like the publishers (REP-2003): the test counts every frame published.
        node.create_subscription(Image, 'camera/rgb/image_raw', self.images.append, 50)
        # A reader keeps its last N only: a stall of this test's spinning on a loaded machine
        # drops the oldest unread messages. The small camera_info keeps twenty times as many as
        # the images, so no image it holds has lost its camera_info.
        node.create_subscription(CameraInfo, 'camera/rgb/camera_info',
                                 self.camera_infos.append, 1000)
        node.create_subscription(Clock, '/clock', self.clocks.append, 100)
        node.create_subscription(Twist, 'cmd_vel', self.cmd_vels.append, 10)


def test_sim_and_follower_processes_serve_an_independent_client(ros_context):
    # The tests of a run go one after another: the children share the run's own domain.
    environment = child_environment()
    simulator = subprocess.Popen(
        node_command('followbot_sim.sim_node', '-p', 'real_time_factor:=2.0'),
        env=environment)
    follower = subprocess.Popen(
        node_command('followbot.follower_node', '-p', 'use_sim_time:=true'), env=environment)
    client = Node('independent_client', context=ros_context)
    recorder = TopicRecorder(client)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert spin_until(executor, lambda: len(recorder.images) >= 40
                          and any(abs(msg.angular.z) > 1e-3 for msg in recorder.cmd_vels),
                          DISCOVERY_TIMEOUT_S), (
            f'{len(recorder.images)} images, {len(recorder.cmd_vels)} cmd_vel')
        # What came while everything ran (stopping the children below pauses our spinning).
        images = list(recorder.images)
        clocks = list(recorder.clocks)
        cmd_vels = list(recorder.cmd_vels)
        # DDS orders nothing across topics: a loaded machine may deliver an image before the
        # camera_info published just ahead of it. Every image's camera_info must come, though.
        image_stamps_s = {seconds(msg.header.stamp) for msg in images}
        assert spin_until(executor, lambda: image_stamps_s <= {
            seconds(msg.header.stamp) for msg in recorder.camera_infos}, 5.0)
        camera_infos = list(recorder.camera_infos)
        assert stop_process(follower) == 0
        # The follower's last word is a zero Twist, so the robot does not drive on.
        assert spin_until(executor, lambda: recorder.cmd_vels[-1] == Twist(), 5.0)
        assert stop_process(simulator) == 0
    finally:
        kill_leftovers(follower, simulator)
        executor.shutdown()
        client.destroy_node()

    image = images[-1]
    assert (image.width, image.height, image.encoding) == (640, 480, 'bgr8')
    assert image.step == 640 * 3 and len(image.data) == 640 * 480 * 3
    assert image.header.frame_id == 'camera_rgb_optical_frame'
    stamps_s = [seconds(msg.header.stamp) for msg in images]
    periods_s = [later - earlier for earlier, later in zip(stamps_s, stamps_s[1:])]
    # 20 Hz of simulated time: consecutive stamps 0.05 s apart.
    assert periods_s == pytest.approx([CAMERA_PERIOD_S] * len(periods_s), abs=1e-6)

    info = camera_infos[-1]
    assert (info.width, info.height) == (640, 480)
    assert info.header.frame_id == 'camera_rgb_optical_frame'
    fx, _, cx, _, fy, cy, _, _, _ = info.k
    assert fx == pytest.approx(KINECT_FX_PX) and fy == pytest.approx(KINECT_FX_PX)
    assert (cx, cy) == pytest.approx((319.5, 239.5))
    assert list(info.p[:3]) == pytest.approx([fx, 0.0, cx])

    clock_s = [seconds(msg.clock) for msg in clocks]
    assert clock_s == sorted(clock_s) and clock_s[-1] > clock_s[0]
    assert clock_s[-1] >= stamps_s[-1] - CAMERA_PERIOD_S

    # The follower drives: speeding up from rest, never beyond its cruising speed.
    speeds_mps = [msg.linear.x for msg in cmd_vels]
    assert max(speeds_mps) > 0.0
    assert all(0.0 <= speed_mps <= 0.7 + 1e-9 for speed_mps in speeds_mps)


def frames_processed(statuses: list) -> list:
    """Return (stamp in seconds, frames counted) of the follower's status messages."""
    return [(seconds(msg.header.stamp),
             int({value.key: value.value for value in msg.status[0].values}['frames']))
            for msg in statuses]


def test_ros2_run_sim_and_follower_with_nothing_exported_lose_no_frame(ros_context):
    # A new user's terminals: no Fast DDS configuration at all.
    environment = child_environment()
    for variable in USER_CONFIGURATION_VARIABLES:
        environment.pop(variable, None)
    simulator = subprocess.Popen(node_command('followbot_sim.sim_node'), env=environment,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    follower = subprocess.Popen(node_command('followbot.follower_node', '-p',
                                             'use_sim_time:=true'), env=environment,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    client = Node('independent_client', context=ros_context)
    statuses = []
    images = []
    client.create_subscription(DiagnosticArray, 'follower/status', statuses.append, 100)
    # As `ros2 topic hz` listens: sensor-data QoS.
    client.create_subscription(Image, 'camera/rgb/image_raw', images.append,
                               qos_profile_sensor_data)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert spin_until(executor, lambda: len(statuses) >= 20, DISCOVERY_TIMEOUT_S)
        first = len(statuses)
        first_image = len(images)
        # Eight seconds of real time: 160 frames at 20 Hz.
        assert spin_until(executor, lambda: len(statuses) >= first + 160, 30.0)
        window = frames_processed(statuses[first - 1:])
        camera = [seconds(msg.header.stamp) for msg in images[first_image:]]
    finally:
        for process in (follower, simulator):
            stop_process(process)
        kill_leftovers(follower, simulator)
        executor.shutdown()
        client.destroy_node()
    (first_stamp_s, first_count), (last_stamp_s, last_count) = window[0], window[-1]
    published = round((last_stamp_s - first_stamp_s) / CAMERA_PERIOD_S)
    assert last_count - first_count == published
    assert round((camera[-1] - camera[0]) / CAMERA_PERIOD_S) + 1 == len(camera)
    for process in (follower, simulator):
        output = process.stdout.read()
        assert "Fast DDS configuration: followbot's profile" in output, output


# What a ROS user sees of the simulator alone: topic -> (type, frame_id of its messages).
SIMULATOR_TOPICS = {
    '/camera/rgb/image_raw': ('sensor_msgs/msg/Image', 'camera_rgb_optical_frame'),
    '/camera/rgb/camera_info': ('sensor_msgs/msg/CameraInfo', 'camera_rgb_optical_frame'),
    '/camera/depth/image_raw': ('sensor_msgs/msg/Image', 'camera_depth_optical_frame'),
    '/camera/depth/camera_info': ('sensor_msgs/msg/CameraInfo', 'camera_depth_optical_frame'),
    '/camera/depth/points': ('sensor_msgs/msg/PointCloud2', 'camera_depth_optical_frame'),
    '/odom': ('nav_msgs/msg/Odometry', 'odom'),
    '/ground_truth/odom': ('nav_msgs/msg/Odometry', 'world'),
    '/joint_states': ('sensor_msgs/msg/JointState', ''),
    '/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', 'world'),
    '/clock': ('rosgraph_msgs/msg/Clock', None),
}
SIMULATOR_SERVICES = {
    '/robot1/followbot_sim/pause': 'std_srvs/srv/SetBool',
    '/robot1/followbot_sim/step': 'std_srvs/srv/Trigger',
    '/robot1/followbot_sim/reset': 'std_srvs/srv/Trigger',
}


def message_class(type_name: str):
    """Import a message class from its ROS type name, such as 'nav_msgs/msg/Odometry'."""
    package, _, name = type_name.split('/')
    return getattr(__import__(f'{package}.msg', fromlist=[name]), name)


def test_simulator_serves_its_whole_interface_under_a_namespace(ros_context):
    simulator = subprocess.Popen(
        node_command('followbot_sim.sim_node', '-r', '__ns:=/robot1',
                     '-p', 'real_time_factor:=2.0'), env=child_environment())
    client = Node('independent_client', context=ros_context)
    received = {}
    for topic, (type_name, _) in SIMULATOR_TOPICS.items():
        # /clock stays global; the robot's topics move under the namespace.
        name = topic if topic in ('/clock', '/diagnostics') else '/robot1' + topic
        client.create_subscription(
            message_class(type_name), name,
            lambda msg, topic=topic: received.setdefault(topic, []).append(msg), 10)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert spin_until(executor, lambda: all(
            len(received.get(topic, ())) >= 2 for topic in SIMULATOR_TOPICS),
            DISCOVERY_TIMEOUT_S), sorted(set(SIMULATOR_TOPICS) - set(received))
        topic_types = dict(client.get_topic_names_and_types())
        service_types = dict(client.get_service_names_and_types())
        assert stop_process(simulator) == 0
    finally:
        kill_leftovers(simulator)
        executor.shutdown()
        client.destroy_node()

    for topic, (type_name, frame_id) in SIMULATOR_TOPICS.items():
        name = topic if topic in ('/clock', '/diagnostics') else '/robot1' + topic
        assert topic_types[name] == [type_name]
        if frame_id is not None:
            assert received[topic][-1].header.frame_id == frame_id, topic
    for service, type_name in SIMULATOR_SERVICES.items():
        assert service_types[service] == [type_name]
    clock_s = seconds(received['/clock'][-1].clock)
    # Every stamp is simulated time, at most the newest /clock.
    for topic in set(SIMULATOR_TOPICS) - {'/clock'}:
        assert 0.0 < seconds(received[topic][0].header.stamp) <= clock_s, topic
    # Each image comes with the camera_info of the same instant.
    for image, info in (('/camera/rgb/image_raw', '/camera/rgb/camera_info'),
                        ('/camera/depth/image_raw', '/camera/depth/camera_info')):
        info_stamps = {seconds(msg.header.stamp) for msg in received[info]}
        assert {seconds(msg.header.stamp) for msg in received[image]} & info_stamps
    depth = received['/camera/depth/image_raw'][-1]
    assert (depth.encoding, depth.width, depth.height) == ('32FC1', 640, 480)
    assert received['/odom'][-1].child_frame_id == 'base_footprint'


def run_launcher(domain_id: int, *arguments: str, fastdds_profile: str | None = None,
                 **popen_options) -> subprocess.Popen:
    """Start the followbot entry point as a user would, with Fast DDS profile of their own."""
    environment = child_environment(domain_id)
    environment.pop(FASTDDS_PROFILE_VARIABLE, None)
    if fastdds_profile is not None:
        environment[FASTDDS_PROFILE_VARIABLE] = fastdds_profile
    return subprocess.Popen(
        [sys.executable, '-m', 'followbot_sim.launcher', '--domain-id', str(domain_id),
         *arguments], env=environment, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, **popen_options)


def test_followbot_runs_both_nodes_and_reports_progress(tmp_path):
    pictures_dir = tmp_path / 'pictures'
    # Real time, so that the monitor has discovered the simulator well before the run ends.
    launcher = run_launcher(run_domain_id(), '--duration', '8',
                            '--real-time-factor', '1', '--report-period', '2',
                            '--pictures-dir', str(pictures_dir))
    output, _ = launcher.communicate(timeout=120)
    assert launcher.returncode == 0, output
    assert '[sim] ' in output and '[follower] ' in output
    # The images travel through the package's shared-memory profile unless told otherwise.
    assert f'Fast DDS profile {fastdds_profile_path()}.' in output.splitlines()[0]
    progress = [line for line in output.splitlines() if line.startswith('[followbot] t=')]
    assert len(progress) >= 2, output
    final = [line for line in output.splitlines() if line.startswith('[followbot] final: ')]
    assert final and 't=   8.0 s' in final[0], output
    camera = cv2.imread(str(pictures_dir / 'camera_debug.png'))
    overview = cv2.imread(str(pictures_dir / 'overview.png'))
    assert camera.shape == (480, 640, 3)
    assert overview.shape == (800, 800, 3)


def test_followbot_in_lockstep_with_a_users_fastdds_profile(tmp_path):
    profile = tmp_path / 'my_profile.xml'
    shutil.copy(fastdds_profile_path(), profile)
    launcher = run_launcher(run_domain_id(), '--duration', '5', '--real-time-factor', '0',
                            '--lockstep', fastdds_profile=str(profile))
    output, _ = launcher.communicate(timeout=120)
    assert launcher.returncode == 0, output
    first_line = output.splitlines()[0]
    assert 'as fast as possible, in lockstep' in first_line
    assert f'Fast DDS configuration of yours, FASTRTPS_DEFAULT_PROFILES_FILE={profile}.' in (
        first_line)
    assert 'in lockstep with the follower' in output
    # The monitor may still be discovering the simulator at this speed: its own report counts.
    assert 'Run of 5.0 s simulated time done' in output
    # Every frame answered in time: the simulator never had to drive on without a command.
    assert 'no cmd_vel answered' not in output


def child_pids(parent_pid: int) -> list:
    """Return the process ids whose parent is ``parent_pid`` (Linux /proc)."""
    children = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue  # The process ended while we looked.
        if int(fields[1]) == parent_pid:
            children.append(int(stat.parent.name))
    return children


def start_launcher_and_wait_for_progress() -> tuple:
    """Start followbot with no end and return it with its children once it reports."""
    launcher = run_launcher(run_domain_id(), '--duration', '0')
    lines = []
    for line in launcher.stdout:
        lines.append(line)
        if line.startswith('[followbot] t='):
            break
    children = child_pids(launcher.pid)
    assert len(children) == 2, ''.join(lines)
    return launcher, children, lines


def wait_until_gone(pids: list, timeout_s: float = STOP_TIMEOUT_S) -> list:
    """Wait for processes to end; return those still running after the timeout."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        running = [pid for pid in pids if Path(f'/proc/{pid}').exists()]
        if not running:
            break
        time.sleep(0.1)
    return [pid for pid in pids if Path(f'/proc/{pid}').exists()]


def test_followbot_forwards_ctrl_c_and_leaves_no_orphans():
    launcher, children, lines = start_launcher_and_wait_for_progress()
    launcher.send_signal(signal.SIGINT)
    output, _ = launcher.communicate(timeout=STOP_TIMEOUT_S * 2)
    assert launcher.returncode == 0, ''.join(lines) + output
    assert not wait_until_gone(children)


def test_followbot_killed_outright_takes_its_nodes_with_it():
    launcher, children, _ = start_launcher_and_wait_for_progress()
    launcher.kill()
    launcher.communicate(timeout=STOP_TIMEOUT_S)
    still_running = wait_until_gone(children)
    for pid in still_running:
        os.kill(pid, signal.SIGKILL)
    assert not still_running


def test_followbot_fails_when_a_node_fails():
    # Only the simulator declares camera_rate_hz: it refuses the value as it starts.
    launcher = run_launcher(run_domain_id(), '--duration', '5', '--ros-args', '-p',
                            'camera_rate_hz:=500.0')
    output, _ = launcher.communicate(timeout=60)
    assert launcher.returncode != 0, output
    assert 'Parameter camera_rate_hz out of range' in output
    assert "failed: {'sim': 2}" in output


def test_nodes_stop_on_sigint_even_when_started_with_it_ignored():
    # A shell starts background jobs (`follower &`) with SIGINT ignored; `kill -INT` and
    # launch tools must still stop the node cleanly.
    follower = subprocess.Popen(
        node_command('followbot.follower_node'), env=child_environment(),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    for line in follower.stdout:
        if 'Following the line' in line:
            break
    assert stop_process(follower) == 0


def test_simulator_says_clearly_when_it_cannot_render():
    # An EGL device that does not exist stands in for a machine without a usable GL.
    environment = dict(child_environment(), MUJOCO_GL='egl', MUJOCO_EGL_DEVICE_ID='99')
    result = subprocess.run(node_command('followbot_sim.sim_node'), env=environment,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert 'MuJoCo cannot render off-screen with MUJOCO_GL=egl' in result.stderr
    assert 'Traceback' not in result.stderr


def test_two_launchers_under_their_own_namespaces_share_a_domain(tmp_path):
    # Each robot's simulated clock and score are its own: neither stops for the other's
    # /clock, and each reports the laps of its own robot. Four processes share this machine's
    # cores in real time, and a simulator held up 0.5 s of wall time by the load trips the
    # follower's default camera watchdog (rightly: images did stop). A 2 s watchdog still
    # catches a camera lost for the rest of the run when the other launcher ends (r1 runs
    # about 4 s longer than r2), which is what this test is about.
    domain_id = run_domain_id()
    launchers = [run_launcher(domain_id, '--duration', '8', '--real-time-factor', str(rate),
                              '--report-period', '2', '--ros-args', '-r', f'__ns:=/{name}',
                              '-p', 'image_timeout_s:=2.0')
                 for name, rate in (('r1', 1.0), ('r2', 2.0))]
    outputs = [launcher.communicate(timeout=120)[0] for launcher in launchers]
    for launcher, output in zip(launchers, outputs):
        assert launcher.returncode == 0, output
        # The camera stops only when the simulator's run is over, not for the other robot.
        before_the_end = output.split('simulated time done')[0]
        assert 'No camera image' not in before_the_end, output
        final = [line for line in output.splitlines() if line.startswith('[followbot] final: ')]
        assert final and 't=   8.0 s' in final[0], output
    # Each monitor reported its own robot's clock: the faster one got there first, and never
    # printed the other's times (progress lines go up in steps of its own report period).
    for output in outputs:
        times_s = [float(line.split('t=')[1].split(' s')[0]) for line in output.splitlines()
                   if line.startswith('[followbot] t=')]
        assert times_s == sorted(times_s), output


def test_a_second_launcher_on_the_same_domain_without_a_namespace_refuses_with_the_fix():
    domain_id = run_domain_id()
    first = run_launcher(domain_id, '--duration', '0')
    try:
        for line in first.stdout:
            if line.startswith('[followbot] t='):
                break
        second = run_launcher(domain_id, '--duration', '20')
        output, _ = second.communicate(timeout=60)
        assert second.returncode == 2, output
        refusal = [line for line in output.splitlines() if 'Cannot run' in line]
        assert len(refusal) == 1, output
        assert '/clock' in refusal[0] and '__ns:=' in refusal[0] and '--domain-id' in refusal[0]
        assert '--robots N' in refusal[0]
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=60)
    assert first.returncode == 0


def test_followbot_races_two_configurations_on_one_course_and_scores_each(ros_context):
    # One simulator, two followers under /r1 and /r2 with their configurations, in lockstep:
    # each robot advances along the line at its own configuration's speed, and an independent
    # listener sees each robot's score under its own namespace.
    client = Node('race_listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    score_names = set()
    client.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda msg: score_names.update((status.name, status.hardware_id)
                                       for status in msg.status), 10)
    launcher = run_launcher(run_domain_id(), '--robots', '2', '--configs', 'followbot,book',
                            '--duration', '10', '--real-time-factor', '0', '--lockstep',
                            '--report-period', '5')
    try:
        while launcher.poll() is None:
            executor.spin_once(timeout_sec=0.1)
        output = launcher.stdout.read()
    finally:
        kill_leftovers(launcher)
        executor.shutdown()
        client.destroy_node()
    assert launcher.returncode == 0, output
    assert '2 robots (r1 (followbot), r2 (book))' in output.splitlines()[0]
    assert '[follower r1] ' in output and '[follower r2] ' in output
    assert 'no cmd_vel answered' not in output, output
    finals = {line.split(':')[0]: line for line in output.splitlines()
              if line.startswith('[followbot] final ')}
    assert set(finals) == {'[followbot] final r1 (followbot)', '[followbot] final r2 (book)'}
    progress = {}
    for label, line in finals.items():
        assert 't=  10.0 s' in line, output
        progress[label] = float(line.split('next lap')[1].split('%')[0])
    # The book's follower drives at 0.2 m/s (2 m, 9 % of the 21.4 m loop, in 10 s); followbot's
    # own is faster. Each robot is scored on its own path.
    assert 5 <= progress['[followbot] final r2 (book)'] <= 12, output
    assert progress['[followbot] final r1 (followbot)'] > progress['[followbot] final r2 (book)']
    assert {('/r1/followbot_sim: course score', '/r1/followbot_sim'),
            ('/r2/followbot_sim: course score', '/r2/followbot_sim')} <= score_names
