"""
``followbot --record`` and ``replay`` as a user runs them: processes, files, exit codes.

A short lockstep run is recorded once by the launcher; the independent ``rosbags`` library
reads it back, and the replay command feeds it to a fresh follower.
"""

import subprocess
import sys

from conftest import child_environment, run_domain_id
import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader

RUN_S = 10.0
CAMERA_HZ = 20
CLOCK_HZ = 100
ODOM_HZ = 50
RUN_TIMEOUT_S = 240
CAMERA_TOPIC = '/camera/rgb/image_raw'


def run_command(*arguments: str, domain_id: int | None = None) -> subprocess.CompletedProcess:
    """Run a module of the package as a process on this test run's domain; capture its output."""
    return subprocess.run([sys.executable, '-m', *arguments],
                          env=child_environment(domain_id), stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=RUN_TIMEOUT_S)


def record_run(path, *options: str, duration_s: float = RUN_S) -> str:
    """Record a lockstep run as fast as the machine goes; return the launcher's output."""
    done = run_command('followbot_sim.launcher', '--domain-id', str(run_domain_id()),
                       '--lockstep', '--real-time-factor', '0', '--duration', f'{duration_s:g}',
                       '--record', str(path), *options)
    assert done.returncode == 0, done.stdout
    return done.stdout


def read_back(path) -> dict:
    """Return {topic: [message]} in log-time order, as rosbags reads them."""
    messages = {}
    with AnyReader([path]) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(
                reader.deserialize(raw, connection.msgtype))
    return messages


def stamp_s(message) -> float:
    """Return a message's header stamp in seconds."""
    return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9


@pytest.fixture(scope='module')
def lockstep_recording(tmp_path_factory):
    """Record a 10 s lockstep run once for the tests of this module; yield (path, output)."""
    path = tmp_path_factory.mktemp('recording') / 'run.mcap'
    output = record_run(path)
    yield path, output


def test_a_lockstep_run_is_recorded_with_every_camera_frame(lockstep_recording):
    path, output = lockstep_recording
    assert 'Recorder hears every topic: the simulation starts.' in output
    recorded = read_back(path)
    frames = recorded[CAMERA_TOPIC]
    # Every frame the camera took, from the first: 0.05 s, 0.10 s, ... 10.0 s.
    assert [round(stamp_s(frame) * CAMERA_HZ) for frame in frames] == list(
        range(1, int(RUN_S * CAMERA_HZ) + 1))
    assert (frames[0].width, frames[0].height, frames[0].encoding) == (640, 480, 'bgr8')
    assert len(recorded['/camera/rgb/camera_info']) == len(frames)
    # One command answers each frame; the follower's stop after the run may follow.
    assert len(frames) <= len(recorded['/cmd_vel']) <= len(frames) + 2
    assert len(recorded['/follower/status']) == len(frames)
    assert len(recorded['/clock']) == RUN_S * CLOCK_HZ
    for topic in ('/odom', '/ground_truth/odom', '/tf'):
        assert len(recorded[topic]) == RUN_S * ODOM_HZ, topic
    assert recorded['/tf'][0].transforms[0].child_frame_id == 'base_footprint'
    assert {transform.child_frame_id for transform in recorded['/tf_static'][0].transforms}
    score = recorded['/diagnostics'][-1].status[0]
    assert 'laps_completed' in {value.key for value in score.values}
    # The score of the last second: the run ended at the asked duration.
    assert stamp_s(recorded['/diagnostics'][-1]) == pytest.approx(RUN_S)


def test_replaying_a_lockstep_run_reproduces_every_command(lockstep_recording):
    path, _ = lockstep_recording
    done = run_command('followbot.replay', str(path))
    frames = int(RUN_S * CAMERA_HZ)
    assert done.returncode == 0, done.stdout
    assert (f'{frames} frames replayed, {frames} with a recorded command: {frames} identical, '
            '0 differ by more than 0; max difference 0 ') in done.stdout


def test_replay_feeds_the_odometry_a_line_end_was_driven_to_by(tmp_path):
    # At the line_end course's end the follower drives on by odometry: fed the recorded
    # odometry before each frame (by stamp, however the recording logged them), a replay
    # gives the same commands there too. Driven by its commands instead, 12 of them differ.
    path = tmp_path / 'line_end.mcap'
    record_run(path, '--course', 'line_end')
    statuses = read_back(path)['/follower/status']
    used = [{value.key: value.value for value in status.status[0].values}['odometry_used']
            for status in statuses]
    assert set(used) == {'True'}
    done = run_command('followbot.replay', str(path))
    frames = int(RUN_S * CAMERA_HZ)
    assert done.returncode == 0, done.stdout
    assert 'odometry on /odom' in done.stdout
    assert f'{frames} identical, 0 differ by more than 0' in done.stdout


def test_replay_into_a_changed_follower_prints_the_differences(lockstep_recording, tmp_path):
    path, _ = lockstep_recording
    params_file = tmp_path / 'far_sighted.yaml'
    params_file.write_text('/**/follower:\n  ros__parameters:\n    look_ahead_m: 0.6\n')
    done = run_command('followbot.replay', str(path), '--params-file', str(params_file))
    assert done.returncode == 1, done.stdout
    assert f'parameters from {params_file}' in done.stdout
    differences = [line for line in done.stdout.splitlines() if line.startswith('  frame ')]
    assert differences and 'recorded v=' in differences[0] and 'replayed v=' in differences[0]
    # A tolerance larger than any difference of a steering change accepts them all.
    done = run_command('followbot.replay', str(path), '--params-file', str(params_file),
                       '--tolerance', '10')
    assert done.returncode == 0, done.stdout


def damage_middle(data: bytes) -> bytes:
    """Overwrite 5000 bytes in the middle of a file, inside a compressed chunk."""
    middle = len(data) // 2
    return data[:middle] + b'\xff' * 5000 + data[middle + 5000:]


@pytest.mark.parametrize('make_file, expected_text', [
    (lambda data: b'not a recording\n', 'is not an MCAP file'),
    (damage_middle, 'is damaged'),
    (lambda data: data[:1000], 'has no camera topic to replay'),
])
def test_replay_of_an_unusable_file_exits_2_with_one_line(lockstep_recording, tmp_path,
                                                          make_file, expected_text):
    path, _ = lockstep_recording
    broken = tmp_path / 'broken.mcap'
    broken.write_bytes(make_file(path.read_bytes()))
    done = run_command('followbot.replay', str(broken))
    assert done.returncode == 2, done.stdout
    assert expected_text in done.stdout
    assert 'Traceback' not in done.stdout


@pytest.mark.parametrize('arguments', [['no_such.mcap'], ['--rate', '-1', 'x.mcap'], []])
def test_replay_with_a_missing_file_or_bad_arguments_exits_2(arguments, tmp_path):
    done = run_command('followbot.replay', *arguments)
    assert done.returncode == 2, done.stdout
    assert 'Traceback' not in done.stdout


def test_a_compressed_recording_holds_jpeg_frames_that_replay(tmp_path):
    path = tmp_path / 'compressed.mcap'
    duration_s = 3.0
    record_run(path, '--record-compressed', duration_s=duration_s)
    recorded = read_back(path)
    assert CAMERA_TOPIC not in recorded
    frames = recorded[CAMERA_TOPIC + '/compressed']
    assert len(frames) == duration_s * CAMERA_HZ
    assert frames[0].format.startswith('rgb8; jpeg')
    picture = cv2.imdecode(np.asarray(frames[0].data, np.uint8), cv2.IMREAD_COLOR)
    assert picture.shape == (480, 640, 3)
    # The follower drove on raw frames; a replay gives it the JPEG ones: every frame is
    # answered, the commands may differ a little.
    done = run_command('followbot.replay', str(path), '--tolerance', '10')
    assert done.returncode == 0, done.stdout
    assert f'{len(frames)} frames replayed, {len(frames)} with a recorded command' in (
        done.stdout)
    assert 'got no answer' not in done.stdout


def test_scorecard_records_one_file_per_run_with_every_frame(tmp_path):
    time_limit_s = 2.0
    record_dir = tmp_path / 'runs'
    done = run_command('followbot_sim.scorecard', '--scenarios', 'book_loop', '--configs',
                       'followbot,book', '--time-limit-s', f'{time_limit_s:g}', '--jobs', '1',
                       '--domain-id', str(run_domain_id()), '--no-json',
                       '--record', str(record_dir))
    assert done.returncode == 0, done.stdout
    assert sorted(path.name for path in record_dir.iterdir()) == [
        'book_loop-book.mcap', 'book_loop-followbot.mcap']
    for path in record_dir.iterdir():
        recorded = read_back(path)
        frames = recorded[CAMERA_TOPIC]
        # Time started only once the recorder heard everything: the first frame is there.
        assert round(stamp_s(frames[0]) * CAMERA_HZ) == 1, path
        assert [round(stamp_s(frame) * CAMERA_HZ) for frame in frames] == list(
            range(1, len(frames) + 1)), path
        assert len(frames) >= time_limit_s * CAMERA_HZ
        assert f'recorded {path}: ' in done.stdout
