"""
The ``benchmark`` command: how fast followbot sees, answers and simulates, on this machine.

Three measurements, each printed as a table with the comparison side by side:

* **Perception**: time per 640x480 frame from the Image message to the line's position, for
  the follower's detector and for the book's pipeline (cv_bridge's copy of the frame, the whole
  frame converted to HSV and thresholded, rows outside the band zeroed, image moments; also
  without the copy), on the same frames rendered by the simulator along a course.
* **Camera to cmd_vel** between two processes: a stand-in camera
  (:mod:`followbot_sim.latency_probe`) sends those frames to the real follower process at 20 and
  30 Hz and times each command against the stamp of the image it answers; with nothing
  exported (each node applies the package's Fast DDS profile itself) and with Fast DDS's
  defaults.
* **Simulator speed** with the follower in the loop: the simulator and the follower as two
  processes, headless, in lockstep, as fast as possible.

Every process's peak memory (its largest resident set) is reported. Figures are medians and
99th percentiles over many frames; nothing is asserted, the figures are the output.
"""

import argparse
import dataclasses
import json
import math
import os
from pathlib import Path
import platform
import resource
import signal
import subprocess
import sys
import tempfile
import time

import cv2
from diagnostic_msgs.msg import DiagnosticArray
from followbot.compressed_image import array_to_compressed, compressed_to_array
from followbot.follower_node import FOLLOWER_PARAMETERS
from followbot.ground_projection import CameraGeometry
from followbot.image_conversion import (array_to_image, dtype_of, expected_shape, from_rgb,
                                        image_to_array)
from followbot.line_detector import DetectorConfig, hsv_bounds, LineDetector
from followbot.node_runner import die_with_parent, refuse_ros_arguments, StopSignals
from followbot.number_options import number_in
from followbot.output_files import output_file_option, output_folder_option
from followbot.transport import (environment_without_profile, keep_large_buffers,
                                 USER_CONFIGURATION_VARIABLES)
from followbot_sim import real_frames
from followbot_sim.answered_requests import SimulatorPause
from followbot_sim.course_file import load_course
from followbot_sim.domains import domain_id_option, reserve_default_domains
from followbot_sim.perception_score import PerceptionTally, RIGHT
from followbot_sim.realism import CLEAN, PRESET_NAMES, realise, Realism
from followbot_sim.score import score_values
from followbot_sim.score import SIMULATOR_NODE
from followbot_sim.scorecard import LOCKSTEP_IMAGE_TIMEOUT_S, markdown_table, number_cell
from followbot_sim.world import FollowbotWorld
import mujoco
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

SECTIONS = ('perception', 'real_frames', 'latency', 'simulation')
# The realism presets whose simulator speed is measured side by side (issue 14's targets: lab
# and home at 3x real time or more), the preset of the realistic perception row, and the seed.
SIMULATION_REALISM = (CLEAN, 'lab', 'home')
PERCEPTION_REALISM = 'home'
REALISM_SEED = 1
# Encodings of real cameras timed besides bgr8 and JPEG: a USB webcam's and a raw sensor's.
CAMERA_ENCODINGS = ('yuv422_yuy2', 'bayer_rggb8')
COURSE = 'book_loop'
IMAGE_WIDTH_PX = 640
IMAGE_HEIGHT_PX = 480
CAMERA_RATE_HZ = 20.0
# What each of --rates takes.
RATE_OPTION = number_in(0.0, above=True)
# The frames: poses around the whole course, swaying across the line and turning a little
# as a following robot does, so the detector meets straights, bends and offsets.
SWAY_AMPLITUDE_M = 0.03
SWAY_WAVELENGTH_M = 1.7
YAW_SWAY_RAD = 0.05
# The book's band: rows 3h/4 to 3h/4 + 20 (chapter 12's follower).
BOOK_BAND_ROWS_PX = 20
US_PER_S = 1e6
KIB_PER_MIB = 1024
# How long a run may take before the benchmark gives up on it, beyond its own length.
PROCESS_GRACE_S = 60.0
STOP_GRACE_S = 5.0
POLL_S = 0.05
# Default domain of the runs: a free one in this range, reserved apart from every other
# benchmark, scorecard and test run on the machine.
FIRST_DOMAIN_ID = 100
DOMAIN_ID_SPREAD = 20
# How long the score the simulator publishes as it ends may take to arrive.
LAST_SCORE_WAIT_S = 0.5


def _percentiles(values) -> dict:
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return {'median': None, 'p99': None, 'max': None}
    return {'median': float(np.median(values)), 'p99': float(np.percentile(values, 99)),
            'max': float(values.max())}


def render_course_frames(frame_count: int, course_name: str = COURSE,
                         realism: Realism | None = None) -> tuple:
    """
    Render the robot's camera at poses spread evenly around a course, in driving order.

    :param frame_count: how many frames.
    :param course_name: a built-in course or a course file.
    :param realism: the realistic world and camera to render, None for the clean scene.
    :return: ((N, H, W, 3) uint8 BGR frames, (fx, fy, cx, cy) intrinsics).
    """
    course = load_course(course_name)
    world = FollowbotWorld(course, IMAGE_WIDTH_PX, IMAGE_HEIGHT_PX, realism=realism)
    try:
        frames_bgr = np.empty((frame_count, IMAGE_HEIGHT_PX, IMAGE_WIDTH_PX, 3), np.uint8)
        for index in range(frame_count):
            arc_m = course.length_m * index / frame_count
            phase = 2.0 * np.pi * arc_m / SWAY_WAVELENGTH_M
            x_m, y_m, heading_rad = course.point_at(arc_m, SWAY_AMPLITUDE_M * np.sin(phase))
            world.reset_robot((x_m, y_m, heading_rad + YAW_SWAY_RAD * np.cos(phase)))
            cv2.cvtColor(world.render_camera(), cv2.COLOR_RGB2BGR, dst=frames_bgr[index])
        return frames_bgr, world.camera_intrinsics()
    finally:
        world.close()


class BookPipeline:
    """
    The book's line finder (chapter 12), with OpenCV's hue scale and integer row indices.

    Per frame: the whole image to HSV, thresholded, every row outside the band zeroed, and the
    centroid from the mask's moments; new images each time, as in the book.
    """

    def __init__(self, config: DetectorConfig):
        """
        Take the colour bounds of a detector configuration.

        :param config: its hue, saturation and value bounds are used.
        """
        self._lower_hsv, self._upper_hsv = hsv_bounds(config)

    def detect(self, image_bgr: np.ndarray):
        """
        Find the line's centroid column in the book's band.

        :param image_bgr: an (H, W, 3) uint8 BGR image.
        :return: the centroid's column in pixels, or None when the band has no line pixel.
        """
        hsv = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)
        mask = cv2.inRange(hsv, self._lower_hsv, self._upper_hsv)
        height = image_bgr.shape[0]
        search_top = 3 * height // 4
        search_bottom = search_top + BOOK_BAND_ROWS_PX
        mask[0:search_top] = 0
        mask[search_bottom:height] = 0
        moments = cv2.moments(mask)
        if moments['m00'] <= 0:
            return None
        return moments['m10'] / moments['m00']


def _time_per_frame_us(function, image_messages, repeats: int) -> np.ndarray:
    """Call ``function(msg)`` on every message, ``repeats`` times over, and time each call."""
    times_us = np.empty(len(image_messages) * repeats)
    index = 0
    for _ in range(repeats):
        for msg in image_messages:
            start_s = time.perf_counter()
            function(msg)
            times_us[index] = (time.perf_counter() - start_s) * US_PER_S
            index += 1
    return times_us


def follower_geometry(intrinsics: tuple) -> CameraGeometry:
    """
    Return the camera geometry the follower knows with its default mounting parameters.

    :param intrinsics: (fx, fy, cx, cy) of the frames, as their camera_info says.
    :return: the CameraGeometry the follower projects with.
    """
    fx_px, fy_px, cx_px, cy_px = intrinsics
    camera_matrix = (fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0)
    return CameraGeometry.from_camera_matrix(
        camera_matrix, FOLLOWER_PARAMETERS['camera_height_m'].default,
        math.radians(FOLLOWER_PARAMETERS['camera_pitch_deg'].default),
        FOLLOWER_PARAMETERS['camera_forward_m'].default)


def _in_encoding(frame_bgr: np.ndarray, encoding: str):
    """Return an Image message of a BGR frame as a camera of that encoding would send it."""
    out = np.empty(expected_shape(*frame_bgr.shape[:2], encoding), dtype_of(encoding))
    return array_to_image(from_rgb(cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2RGB), encoding, out),
                          encoding)


def measure_perception(frames_bgr: np.ndarray, repeats: int, intrinsics: tuple,
                       realistic_bgr: np.ndarray | None = None) -> dict:
    """
    Time the follower's detector and the book's pipeline on the same frames.

    Both start from the same sensor_msgs/Image and use the same colour bounds.

    :param frames_bgr: (N, H, W, 3) uint8 BGR frames, in driving order.
    :param repeats: times each frame is processed (in order, so the follower's detector keeps
        its expectations from frame to frame as in a run).
    :param intrinsics: (fx, fy, cx, cy) of the frames, for the follower's camera geometry.
    :param realistic_bgr: the same poses rendered under a realism preset, or None.
    :return: per pipeline: ``median_us``, ``p99_us``, ``calls``; and ``frames``.
    """
    image_messages = [array_to_image(frame, 'bgr8') for frame in frames_bgr]
    realistic = ([] if realistic_bgr is None
                 else [array_to_image(frame, 'bgr8') for frame in realistic_bgr])
    # What other cameras send of the same frames: each pipeline starts from its own messages.
    messages_by_input = {
        'bgr8': image_messages,
        'jpeg': [array_to_compressed(frame, 'bgr8') for frame in frames_bgr],
        'realistic': realistic,
        **{encoding: [_in_encoding(frame, encoding) for frame in frames_bgr]
           for encoding in CAMERA_ENCODINGS},
    }
    geometry = follower_geometry(intrinsics)
    config = DetectorConfig()
    followbot = LineDetector(config)
    # As in the follower node: each input decoded, then detected with the camera's geometry.
    with_geometry = LineDetector(config)

    def follow(pixels_and_encoding):
        image, encoding = pixels_and_encoding
        return with_geometry.detect(image, encoding, geometry)

    book_band = LineDetector(DetectorConfig(
        band_count=1, band_center_fraction=(3 * IMAGE_HEIGHT_PX // 4 + BOOK_BAND_ROWS_PX / 2)
        / IMAGE_HEIGHT_PX, band_height_px=BOOK_BAND_ROWS_PX, min_area_px=1))
    book = BookPipeline(config)
    pipelines = {
        'followbot': lambda msg: followbot.detect(image_to_array(msg), msg.encoding),
        'followbot_book_band': lambda msg: book_band.detect(image_to_array(msg),
                                                            msg.encoding),
        # As chapter 12 writes it: cv_bridge's imgmsg_to_cv2(msg, 'bgr8') returns a copy.
        'book_full_frame': lambda msg: book.detect(np.array(image_to_array(msg))),
        # Its OpenCV steps alone, on a view of the message as this package reads it.
        'book_opencv_only': lambda msg: book.detect(image_to_array(msg)),
        'follower_bgr8': lambda msg: follow((image_to_array(msg), msg.encoding)),
        'follower_jpeg': lambda msg: follow(compressed_to_array(msg)),
        **{f'follower_{encoding}': lambda msg: follow((image_to_array(msg), msg.encoding))
           for encoding in CAMERA_ENCODINGS},
    }
    if realistic:
        pipelines['follower_realistic'] = (
            lambda msg: follow((image_to_array(msg), msg.encoding)))
    results = {'frames': len(image_messages)}
    for name, pipeline in pipelines.items():
        kind = name.removeprefix('follower_') if name.startswith('follower_') else 'bgr8'
        inputs = messages_by_input[kind]
        with_geometry.reset()
        pipeline(inputs[0])  # First call: buffers and OpenCV's dispatch.
        times_us = _time_per_frame_us(pipeline, inputs, repeats)
        figures = _percentiles(times_us)
        results[name] = {'median_us': figures['median'], 'p99_us': figures['p99'],
                         'calls': len(times_us)}
    return results


def format_perception(results: dict) -> str:
    """
    Make the perception table.

    :param results: from :func:`measure_perception`.
    :return: Markdown.
    """
    book_us = results['book_full_frame']['median_us']
    config = DetectorConfig()
    names = {
        'followbot': f"followbot's detector ({config.band_count} bands of "
                     f'{config.band_height_px} rows)',
        'followbot_book_band': "followbot's detector on the book's band (1 band, 20 rows)",
        'book_full_frame': "the book's pipeline (cv_bridge's copy, whole frame to HSV, 1 band)",
        'book_opencv_only': "the book's OpenCV steps alone (no copy)",
        'follower_bgr8': 'the follower: bgr8 Image, with the camera geometry',
        'follower_jpeg': 'the follower: JPEG CompressedImage (decode + detect)',
        'follower_realistic': f'the follower: bgr8 Image of the {PERCEPTION_REALISM} preset '
                              f'(seed {REALISM_SEED}), with the camera geometry',
        **{f'follower_{encoding}': f'the follower: {encoding} Image (convert + detect)'
           for encoding in CAMERA_ENCODINGS},
    }
    rows = [(label, number_cell(results[key]['median_us']), number_cell(results[key]['p99_us']),
             f"{book_us / results[key]['median_us']:.1f}×")
            for key, label in names.items() if key in results]
    return markdown_table(['pipeline, Image message to line position', 'median µs',
                           'p99 µs', 'book ÷ this (median)'], rows)


def measure_real_frames(pictures_dir: Path | None = None) -> dict:
    """
    Score the default follower's detector on the labelled real camera frames, per source.

    :param pictures_dir: the folder (made as --real-frame-pictures is read) where to save a
        schematic (labels and verdicts, none of the frame's pixels) of every frame with a band
        not right, or None.
    :return: ``folder`` and ``rows`` (source, colour, size: the share of the frames' size
        they were scored at, PerceptionTally fields), or ``error`` saying why there are no
        frames. Every source and colour is scored as taken, then at half size.
    """
    folder, reason = real_frames.frames_folder()
    if folder is None:
        return {'error': reason}
    sources = real_frames.load_labels()
    rows = []
    for size_factor in (1.0, real_frames.HALF_SIZE):
        for source in sources:
            for colour in real_frames.LABELLED_COLOURS:
                frames = [frame for frame in source.frames if frame.polylines(colour)]
                if not frames:
                    continue
                tally, results = real_frames.score_source(source, folder, colour, frames,
                                                          size_factor=size_factor)
                for result in results:
                    if (pictures_dir is not None and size_factor == 1.0
                            and set(result.verdicts) != {RIGHT}):
                        name = f'{Path(result.frame.name).stem}_{colour}.png'
                        cv2.imwrite(str(pictures_dir / name), real_frames.draw_schematic(result))
                rows.append({'source': source.name, 'colour': colour, 'size': size_factor,
                             **dataclasses.asdict(tally)})
    return {'folder': str(folder), 'rows': rows}


def format_real_frames(results: dict) -> str:
    """
    Make the real-frame table.

    :param results: from :func:`measure_real_frames`.
    :return: Markdown, or the reason there is no table.
    """
    if 'error' in results:
        return f"No table: {results['error']}"
    rows = []
    for row in results['rows']:
        tally = PerceptionTally(**{key: row[key] for key in row
                                   if key not in ('source', 'colour', 'size')})
        size = 'as taken' if row['size'] == 1.0 else f"× {row['size']:g}"
        rows.append((row['source'], row['colour'], size, tally.frames, tally.bands,
                     f'{100 * tally.right_share:.1f}', f'{100 * tally.false_share:.1f}',
                     f'{100 * tally.share(tally.missed):.1f}', tally.confident_false_frames))
    return markdown_table(['source', 'line colour (preset)', 'frame size', 'frames', 'bands',
                           'right %', 'false %', 'missed %', 'frames confidently false'], rows)


class ChildProcess:
    """
    A node process, and the peak of its resident memory while it ran.

    The peak is the kernel's VmHWM of the process, read while it runs: ``wait4``'s
    ``ru_maxrss`` would not do, as a child starts with its parent's peak.
    """

    def __init__(self, module: str, arguments: list, environment: dict, log_path: Path):
        """
        Start ``python -m module arguments...`` with its output in a log file.

        :param module: the module to run.
        :param arguments: its command-line arguments.
        :param environment: its environment.
        :param log_path: file for its output.
        """
        self.log_path = log_path
        self._log = open(log_path, 'w')
        self.process = subprocess.Popen(
            [sys.executable, '-m', module, *arguments], env=environment,
            stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            preexec_fn=die_with_parent)
        self.peak_memory_mib = None

    def sample_memory(self) -> None:
        """Read the process's peak resident memory so far, while it runs."""
        try:
            status = Path(f'/proc/{self.process.pid}/status').read_text()
        except OSError:
            return  # Ended already: the last reading stands.
        for line in status.splitlines():
            if line.startswith('VmHWM:'):
                # The kernel reports it in kB (KiB).
                self.peak_memory_mib = int(line.split()[1]) / KIB_PER_MIB

    def running(self) -> bool:
        """Return whether the process still runs, reading its memory if it does."""
        if self.process.poll() is not None:
            return False
        self.sample_memory()
        return True

    def wait(self, timeout_s: float) -> bool:
        """
        Wait for the process to end, reading its memory meanwhile.

        :param timeout_s: longest wait.
        :return: whether it ended.
        """
        deadline_s = time.monotonic() + timeout_s
        while self.running():
            if time.monotonic() > deadline_s:
                return False
            time.sleep(POLL_S)
        self._log.close()
        return True

    def stop(self) -> None:
        """Stop it as Ctrl-C would, then harder if it does not end."""
        for stop_signal in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not self.running():
                break
            self.process.send_signal(stop_signal)
            if self.wait(STOP_GRACE_S):
                break
        self._log.close()

    def log_tail(self, lines: int = 15) -> str:
        """Return the last lines of its log, to explain a failure."""
        return '\n'.join(self.log_path.read_text(errors='replace').splitlines()[-lines:])


# The Fast DDS configurations the latency is measured with: what a user gets running the nodes
# with nothing exported (each node applies the package's profile itself), and Fast DDS's own
# defaults (as a user who asks for them with FASTDDS_BUILTIN_TRANSPORTS=DEFAULT).
NOTHING_EXPORTED = 'nothing exported'
FASTDDS_DEFAULTS = "Fast DDS's defaults"
DDS_CONFIGURATIONS = (NOTHING_EXPORTED, FASTDDS_DEFAULTS)


def _node_environment(domain_id: int, configuration: str) -> dict:
    environment = dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
                       ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', RCUTILS_COLORIZED_OUTPUT='0')
    if configuration == NOTHING_EXPORTED:
        return {name: value for name, value in environment.items()
                if name not in USER_CONFIGURATION_VARIABLES}
    return environment_without_profile(environment)


def measure_latency(frames_file: Path, intrinsics: tuple, rate_hz: float, frame_count: int,
                    configuration: str, domain_id: int, log_folder: Path) -> dict:
    """
    Run the follower and the latency probe as two processes and collect the probe's figures.

    :param frames_file: the .npy file of BGR frames the probe sends.
    :param intrinsics: (fx, fy, cx, cy) of those frames.
    :param rate_hz: frames per second.
    :param frame_count: frames measured.
    :param configuration: the Fast DDS configuration of both processes, from
        DDS_CONFIGURATIONS.
    :param domain_id: a ROS domain no one else uses while this runs.
    :param log_folder: where the processes' logs go.
    :return: ``p50_ms``, ``p99_ms``, ``max_ms``, ``answered``, ``dropped``, ``frames``,
        ``profile``, peak memories (MiB), or ``error``.
    """
    environment = _node_environment(domain_id, configuration)
    tag = f'{rate_hz:g}hz_{DDS_CONFIGURATIONS.index(configuration)}'
    follower = ChildProcess('followbot.follower_node', [
        '--ros-args', '-p', 'cmd_vel_stamped:=true', '--log-level', 'warn'],
        environment, log_folder / f'follower_{tag}.log')
    figures_file = log_folder / f'probe_{tag}.json'
    probe = ChildProcess('followbot_sim.latency_probe', [
        '--frames-file', str(frames_file), '--intrinsics', *map(str, intrinsics),
        '--rate-hz', str(rate_hz), '--frames', str(frame_count),
        '--json-out', str(figures_file)], environment, log_folder / f'probe_{tag}.log')
    result = {'rate_hz': rate_hz, 'profile': configuration, 'frames': frame_count}
    try:
        if not probe.wait(frame_count / rate_hz + PROCESS_GRACE_S):
            probe.stop()
    finally:
        follower.stop()
    result['peak_memory_follower_mib'] = follower.peak_memory_mib
    result['peak_memory_probe_mib'] = probe.peak_memory_mib
    try:
        figures = json.loads(figures_file.read_text())
    except (OSError, json.JSONDecodeError):
        result['error'] = f'the probe gave no figures:\n{probe.log_tail()}'
        return result
    if not figures['follower_found']:
        result['error'] = f'the follower did not connect:\n{follower.log_tail()}'
        return result
    latencies_ms = figures['latencies_ms']
    stats = _percentiles(latencies_ms)
    result.update(p50_ms=stats['median'], p99_ms=stats['p99'], max_ms=stats['max'],
                  answered=len(latencies_ms), dropped=frame_count - len(latencies_ms))
    return result


def format_latency(results: list) -> str:
    """
    Make the latency table.

    :param results: from :func:`measure_latency`, one per rate and configuration.
    :return: Markdown.
    """
    rows = []
    for result in results:
        profile = result['profile']
        if profile == NOTHING_EXPORTED:
            profile = "nothing exported (the nodes apply the package's profile)"
        if 'error' in result:
            rows.append((f"{result['rate_hz']:g} Hz", profile, 'failed', '', '', '', '', ''))
            continue
        rows.append((
            f"{result['rate_hz']:g} Hz", profile, number_cell(result['p50_ms'], 2),
            number_cell(result['p99_ms'], 2), number_cell(result['max_ms'], 2),
            f"{result['dropped']} of {result['frames']}",
            number_cell(result['peak_memory_follower_mib'], 0),
            number_cell(result['peak_memory_probe_mib'], 0)))
    return markdown_table(['rate', 'DDS configuration', 'p50 ms', 'p99 ms', 'max ms',
                           'frames dropped', 'follower peak MiB', 'camera peak MiB'], rows)


class _ScoreListener(Node):
    """Record when each of the simulator's score messages arrives (wall time)."""

    def __init__(self, **kwargs):
        super().__init__('benchmark_score_listener', **kwargs)
        self.samples = []  # (wall s, simulated s)
        self.summary = {}
        self.subscription = self.create_subscription(
            DiagnosticArray, '/diagnostics', self.callback, 10)
        self.pause = SimulatorPause(self, f'/{SIMULATOR_NODE}')

    def callback(self, msg: DiagnosticArray) -> None:
        summary = score_values(msg)
        if summary is not None:
            self.summary = summary
            self.samples.append((time.monotonic(), float(summary['time_s'])))


def measure_simulation(simulated_s: float, domain_id: int, log_folder: Path,
                       stop: StopSignals, realism: str = CLEAN) -> dict:
    """
    Run the simulator and the follower as two processes in lockstep, as fast as possible.

    :param simulated_s: simulated seconds to run.
    :param domain_id: a ROS domain no one else uses while this runs.
    :param log_folder: where the processes' logs go.
    :param stop: ends the run early when set.
    :param realism: the realism preset of the world (seed REALISM_SEED).
    :return: ``simulated_per_wall`` (from the score messages' arrival times), ``simulated_s``,
        ``wall_s``, ``laps``, ``rms_cm``, peak memories (MiB), or ``error``.
    """
    environment = _node_environment(domain_id, NOTHING_EXPORTED)
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    listener = _ScoreListener(context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener)
    follower = ChildProcess('followbot.follower_node', [
        '--ros-args', '-p', 'use_sim_time:=true', '-p',
        f'image_timeout_s:={LOCKSTEP_IMAGE_TIMEOUT_S}', '--log-level', 'warn'],
        environment, log_folder / f'follower_simulation_{realism}.log')
    # Started paused, and let go once this process hears its score: a fast run could
    # otherwise be over before discovery has connected the listener.
    simulator = ChildProcess('followbot_sim.sim_node', [
        '--ros-args', '-p', 'lockstep:=true', '-p', 'real_time_factor:=0.0',
        '-p', 'start_paused:=true',
        '-p', f'run_duration_s:={float(simulated_s)}', '-p', f'course:={COURSE}',
        '-p', f'image_width_px:={IMAGE_WIDTH_PX}', '-p', f'image_height_px:={IMAGE_HEIGHT_PX}',
        '-p', f'camera_rate_hz:={CAMERA_RATE_HZ}', '-p', 'score_period_s:=1.0',
        '-p', f'realism:={realism}', '-p', f'realism_seed:={REALISM_SEED}'],
        environment, log_folder / f'sim_simulation_{realism}.log')
    result = {'simulated_s': simulated_s, 'profile': NOTHING_EXPORTED, 'realism': realism}
    try:
        deadline_s = time.monotonic() + PROCESS_GRACE_S
        while not (listener.subscription.get_publisher_count() > 0 and listener.pause.ready):
            if stop.is_set() or time.monotonic() > deadline_s or not simulator.running():
                break
            executor.spin_once(timeout_sec=POLL_S)
        listener.pause.ask_paused(False)
        deadline_s = time.monotonic() + simulated_s + PROCESS_GRACE_S
        while simulator.running() and not stop.is_set():
            if time.monotonic() > deadline_s:
                result['error'] = 'the simulator did not finish in time'
                break
            executor.spin_once(timeout_sec=POLL_S)
            listener.pause.poll()
        # The last score is published as the run ends: take what is still on its way.
        end_s = time.monotonic() + LAST_SCORE_WAIT_S
        while time.monotonic() < end_s:
            executor.spin_once(timeout_sec=POLL_S)
    finally:
        simulator.stop()
        follower.stop()
        executor.shutdown()
        listener.destroy_node()
        rclpy.try_shutdown(context=context)
    result['peak_memory_simulator_mib'] = simulator.peak_memory_mib
    result['peak_memory_follower_mib'] = follower.peak_memory_mib
    samples = listener.samples
    if len(samples) < 2:
        result.setdefault('error', f'no progress from the simulator:\n{simulator.log_tail()}')
        return result
    (first_wall_s, first_sim_s), (last_wall_s, last_sim_s) = samples[0], samples[-1]
    summary = listener.summary
    result.update(
        simulated_per_wall=(last_sim_s - first_sim_s) / (last_wall_s - first_wall_s),
        measured_simulated_s=last_sim_s - first_sim_s, wall_s=last_wall_s - first_wall_s,
        laps=int(summary['laps_completed']),
        rms_cm=100.0 * float(summary['rms_distance_from_line_m']),
        max_cm=100.0 * float(summary['max_distance_from_line_m']))
    return result


def format_simulation(results: list) -> str:
    """
    Make the simulator-speed table, one row per realism preset.

    :param results: from :func:`measure_simulation`, one per preset.
    :return: Markdown.
    """
    rows = []
    for result in results:
        if 'error' in result:
            rows.append((result['realism'], 'failed', '', '', '', '', '', ''))
            continue
        rows.append((result['realism'], f"{result['measured_simulated_s']:.0f}",
                     f"{result['wall_s']:.1f}", f"{result['simulated_per_wall']:.2f}×",
                     result['laps'], f"{result['rms_cm']:.1f} / {result['max_cm']:.1f}",
                     number_cell(result['peak_memory_simulator_mib'], 0),
                     number_cell(result['peak_memory_follower_mib'], 0)))
    return markdown_table(['realism (seed 1)', 'simulated s', 'wall s', 'real time ×', 'laps',
                           'RMS / max cm', 'simulator peak MiB', 'follower peak MiB'], rows)


def machine_description() -> str:
    """Describe what the figures were measured on."""
    return (f'{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs, Python '
            f'{platform.python_version()}, rclpy with '
            f'{rclpy.get_rmw_implementation_identifier()}, MuJoCo {mujoco.__version__}, '
            f'OpenCV {cv2.__version__}, NumPy {np.__version__}')


def parse_arguments(argv=None) -> argparse.Namespace:
    """
    Read the command line.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the parsed options.
    """
    parser = argparse.ArgumentParser(
        prog='benchmark', description='Measure perception time, camera-to-cmd_vel latency '
        'between processes and simulator speed, and print them side by side.')
    parser.add_argument('--sections', default=','.join(SECTIONS),
                        help=f'comma-separated, from {", ".join(SECTIONS)} (default: all)')
    parser.add_argument('--frames', type=number_in(1, whole=True), default=160,
                        help='frames rendered around the course (default: 160)')
    parser.add_argument('--repeats', type=number_in(1, whole=True), default=10,
                        help='perception: times each frame is processed (default: 10)')
    parser.add_argument('--latency-frames', type=number_in(1, whole=True), default=600,
                        help='latency: frames measured per rate and configuration '
                             '(default: 600)')
    parser.add_argument('--rates', default='20,30',
                        help='latency: comma-separated frame rates in Hz (default: 20,30)')
    parser.add_argument('--simulated-seconds', type=number_in(3.0), default=60.0,
                        help='simulation: simulated seconds to run (default: 60)')
    parser.add_argument('--realism', default=','.join(SIMULATION_REALISM),
                        help='simulation: comma-separated realism presets to run, side by side '
                             f"(default: {','.join(SIMULATION_REALISM)})")
    parser.add_argument('--domain-id', type=domain_id_option, default=None, metavar='ID',
                        help='ROS domain of the runs, which take turns in it (default: a free '
                             f'one in {FIRST_DOMAIN_ID}-{FIRST_DOMAIN_ID + DOMAIN_ID_SPREAD - 1}, '
                             'which no other benchmark, scorecard or test run then takes)')
    parser.add_argument('--real-frame-pictures', type=output_folder_option('the pictures'),
                        default=None, metavar='DIR',
                        help='real_frames: save a schematic of every frame not all right '
                             "(labels and verdicts, none of the frame's pixels) in DIR")
    parser.add_argument('--json', type=output_file_option('the figures'), default=None,
                        metavar='FILE',
                        help='also write the figures to this JSON file')
    refuse_ros_arguments(parser, argv, 'it starts its own nodes with the settings it measures.')
    options = parser.parse_args(argv)
    options.sections = [name.strip() for name in options.sections.split(',') if name.strip()]
    unknown = sorted(set(options.sections) - set(SECTIONS))
    if unknown or not options.sections:
        parser.error(f'--sections takes {", ".join(SECTIONS)}; got {options.sections}')
    options.realism = [name.strip() for name in options.realism.split(',') if name.strip()]
    if not options.realism or set(options.realism) - set(PRESET_NAMES):
        parser.error(f'--realism takes {", ".join(PRESET_NAMES)}; got {options.realism}')
    try:
        options.rates = [RATE_OPTION(rate) for rate in options.rates.split(',')]
    except argparse.ArgumentTypeError as error:
        parser.error(f'argument --rates: each rate {error}')
    options.domain_reservation = None
    if options.domain_id is None:
        options.domain_reservation = reserve_default_domains(parser, 1, FIRST_DOMAIN_ID,
                                                             DOMAIN_ID_SPREAD)
        options.domain_id = options.domain_reservation.first
    return options


def main(argv=None) -> int:
    """
    Run the chosen measurements and print their tables.

    :param argv: command-line arguments without the program name.
    :return: 0 when every measurement produced figures, 1 otherwise, 130 on Ctrl-C.
    """
    options = parse_arguments(argv)
    keep_large_buffers()
    stop = StopSignals().install()
    report = {'machine': machine_description()}
    print(f'# followbot benchmark\n\n{report["machine"]}\n', flush=True)
    failed = False
    with tempfile.TemporaryDirectory(prefix='followbot-benchmark-') as folder:
        folder = Path(folder)
        needs_frames = {'perception', 'latency'} & set(options.sections)
        if needs_frames:
            frames_bgr, intrinsics = render_course_frames(options.frames)
        realistic_bgr = None
        if 'perception' in options.sections:
            realistic_bgr, _ = render_course_frames(
                options.frames, realism=realise(PERCEPTION_REALISM, REALISM_SEED))
        if 'perception' in options.sections and not stop.is_set():
            perception = measure_perception(frames_bgr, options.repeats, intrinsics,
                                            realistic_bgr)
            report['perception'] = perception
            print(f'## Perception per {IMAGE_WIDTH_PX}x{IMAGE_HEIGHT_PX} frame '
                  f"({perception['frames']} frames rendered around {COURSE}, each "
                  f'{options.repeats} times)\n\n{format_perception(perception)}\n', flush=True)
        if 'real_frames' in options.sections and not stop.is_set():
            real = measure_real_frames(options.real_frame_pictures)
            report['real_frames'] = real
            print('## The default follower on real camera frames (per band, against labels made '
                  'by looking; as taken, then reduced to half size with the camera calibration '
                  f'scaled)\n\n{format_real_frames(real)}\n', flush=True)
        if 'latency' in options.sections and not stop.is_set():
            frames_file = folder / 'frames.npy'
            np.save(frames_file, frames_bgr)
            latency = []
            for rate_hz in options.rates:
                for configuration in DDS_CONFIGURATIONS:
                    if stop.is_set():
                        break
                    latency.append(measure_latency(
                        frames_file, intrinsics, rate_hz, options.latency_frames,
                        configuration, options.domain_id, folder))
            report['latency'] = latency
            failed |= any('error' in result for result in latency)
            print('## Camera image to the cmd_vel it causes, between two processes '
                  f'({options.latency_frames} frames per row)\n\n{format_latency(latency)}\n',
                  flush=True)
            for result in latency:
                if 'error' in result:
                    print(f"{result['rate_hz']:g} Hz, {result['profile']}: {result['error']}")
        if 'simulation' in options.sections and not stop.is_set():
            simulation = [measure_simulation(options.simulated_seconds, options.domain_id,
                                             folder, stop, preset)
                          for preset in options.realism if not stop.is_set()]
            report['simulation'] = simulation
            failed |= any('error' in result for result in simulation)
            print('## Simulator with the follower in the loop (two processes, headless, '
                  f'lockstep, as fast as possible, {IMAGE_WIDTH_PX}x{IMAGE_HEIGHT_PX} at '
                  f'{CAMERA_RATE_HZ:g} Hz)\n\n{format_simulation(simulation)}\n', flush=True)
            for result in simulation:
                if 'error' in result:
                    print(f"{result['realism']}: {result['error']}")
    report['peak_memory_benchmark_mib'] = (
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / KIB_PER_MIB)
    if options.json is not None:
        try:
            options.json.write_text(json.dumps(report, indent=2) + '\n')
        except OSError as error:
            # The tables above hold the figures: say why there is no JSON, and fail.
            print(f'cannot write the figures to {options.json}: {error.strerror or error}.',
                  file=sys.stderr, flush=True)
            failed = True
    if stop.is_set():
        return 130
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
