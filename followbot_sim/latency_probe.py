"""
A stand-in camera that measures how long a follower takes to answer each frame.

It publishes recorded frames and their camera_info on the follower's camera topics at a fixed
rate, each stamped with the system clock as it is handed to DDS, and takes the follower's
``TwistStamped`` commands (``cmd_vel_stamped: true``), which carry the stamp of the image they
answer. Latency is a command's arrival time minus its stamp: the image through DDS, the
follower's callback, and the command back through DDS. Frames no command answered are
dropped frames.

:mod:`followbot_sim.benchmark` runs it as a process of its own; it writes its figures to a JSON
file.
"""

import argparse
import json
import math
from pathlib import Path
import sys
import time

from followbot import frames as frame_names
from followbot import messages
from followbot.image_conversion import array_to_image
from followbot.node_runner import NodeExecutor, StopSignals
from followbot.number_options import number_in
from followbot.transport import keep_large_buffers, use_package_profile
from geometry_msgs.msg import TwistStamped
import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time
from sensor_msgs.msg import CameraInfo, Image

# Frames sent before the measured ones, not counted: the first commands may wait for the
# reliable cmd_vel reader and writer to finish matching.
WARM_UP_FRAMES = 20
# How long to wait for the follower to appear, and for the last answers after the last frame.
CONNECT_TIMEOUT_S = 30.0
LAST_ANSWER_TIMEOUT_S = 1.0
SPIN_S = 0.05


class LatencyProbe(Node):
    """Publish frames at a fixed rate and time the commands that answer them."""

    def __init__(self, frames_bgr: np.ndarray, intrinsics: tuple, rate_hz: float,
                 frame_count: int, **kwargs):
        """
        Prepare the publishers, the command subscription and the frame timer (not started).

        :param frames_bgr: (N, H, W, 3) uint8 BGR frames, sent in order and over again.
        :param intrinsics: (fx, fy, cx, cy) of the camera that took them, in pixels.
        :param rate_hz: frames per second.
        :param frame_count: frames to measure, after :data:`WARM_UP_FRAMES` more.
        :param kwargs: forwarded to :class:`rclpy.node.Node`.
        """
        super().__init__('latency_probe', **kwargs)
        self._frames_bgr = frames_bgr
        height_px, width_px = frames_bgr.shape[1:3]
        # Reliable, as the simulator's camera publishes (REP-2003).
        self._image_publisher = self.create_publisher(Image, 'camera/rgb/image_raw', 10)
        self._info_publisher = self.create_publisher(CameraInfo, 'camera/rgb/camera_info', 10)
        self._info_msg = messages.camera_info(intrinsics, (width_px, height_px),
                                              frame_names.CAMERA_RGB_OPTICAL_FRAME)
        self._image_msg = Image()
        self._image_msg.header.frame_id = frame_names.CAMERA_RGB_OPTICAL_FRAME
        self.create_subscription(TwistStamped, 'cmd_vel', self.cmd_vel_callback, 100)
        self._period_s = 1.0 / rate_hz
        self._frames_to_send = WARM_UP_FRAMES + frame_count
        self._sent = 0
        # Stamp (ns) -> whether it is measured, for frames not answered yet.
        self._unanswered = {}
        self.latencies_ms = []
        self._timer = None

    @property
    def follower_present(self) -> bool:
        """Return whether a node takes the camera and one publishes cmd_vel."""
        return (self._image_publisher.get_subscription_count() > 0
                and self.count_publishers('cmd_vel') > 0)

    @property
    def all_sent(self) -> bool:
        """Return whether every frame has been sent."""
        return self._sent >= self._frames_to_send

    @property
    def unanswered_measured_frames(self) -> int:
        """Return how many measured frames no command answered yet."""
        return sum(self._unanswered.values())

    def start(self) -> None:
        """Start sending frames."""
        self._timer = self.create_timer(self._period_s, self.frame_callback)

    def frame_callback(self) -> None:
        """Send the next frame, with its camera_info first, stamped now."""
        if self.all_sent:
            self._timer.cancel()
            return
        frame = self._frames_bgr[self._sent % len(self._frames_bgr)]
        msg = array_to_image(frame, 'bgr8', self._image_msg)
        now = self.get_clock().now()
        self._info_msg.header.stamp = msg.header.stamp = now.to_msg()
        self._unanswered[now.nanoseconds] = self._sent >= WARM_UP_FRAMES
        self._sent += 1
        self._info_publisher.publish(self._info_msg)
        self._image_publisher.publish(msg)

    def cmd_vel_callback(self, msg: TwistStamped) -> None:
        """Time the command against the frame it answers."""
        arrived_ns = self.get_clock().now().nanoseconds
        stamp_ns = Time.from_msg(msg.header.stamp).nanoseconds
        measured = self._unanswered.pop(stamp_ns, None)
        if measured:
            self.latencies_ms.append((arrived_ns - stamp_ns) / 1e6)


def parse_arguments(argv=None) -> argparse.Namespace:
    """
    Read the command line.

    :param argv: arguments without the program name; ``sys.argv[1:]`` when None.
    :return: the parsed options.
    """
    parser = argparse.ArgumentParser(
        prog='latency_probe', description='Send recorded frames to a follower and time the '
        'commands that answer them; write the figures as JSON.')
    parser.add_argument('--frames-file', required=True,
                        help='.npy file of (N, H, W, 3) uint8 BGR frames')
    parser.add_argument('--intrinsics', type=float, nargs=4, required=True,
                        metavar=('FX', 'FY', 'CX', 'CY'), help='camera intrinsics in pixels')
    parser.add_argument('--rate-hz', type=number_in(0.0, above=True), required=True,
                        help='frames per second')
    parser.add_argument('--frames', type=number_in(1, whole=True), required=True,
                        help='frames to measure')
    parser.add_argument('--json-out', type=Path, required=True,
                        help='file to write the figures to')
    return parser.parse_args(argv)


def _spin_until(executor, condition, timeout_s: float, stop: StopSignals) -> bool:
    deadline_s = time.monotonic() + timeout_s
    while not condition():
        if stop.is_set() or time.monotonic() > deadline_s:
            return False
        executor.spin_once(timeout_sec=SPIN_S)
    return True


def main(argv=None) -> int:
    """
    Measure, write the figures and exit.

    :param argv: command-line arguments without the program name.
    :return: 0 when the follower was found and every frame was sent, else 1.
    """
    options = parse_arguments(argv)
    keep_large_buffers()
    # It stands in for the simulator's camera, so it chooses its Fast DDS configuration as
    # the simulator does (before rclpy makes the participant).
    use_package_profile()
    frames_bgr = np.load(options.frames_file, mmap_mode='r')
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    stop = StopSignals().install()
    probe = LatencyProbe(frames_bgr, tuple(options.intrinsics), options.rate_hz,
                         options.frames)
    # The executor the simulator runs on, so the camera side answers as quickly as it would.
    executor = NodeExecutor()
    executor.add_node(probe)
    try:
        found = _spin_until(executor, lambda: probe.follower_present, CONNECT_TIMEOUT_S, stop)
        if found:
            probe.start()
            _spin_until(executor, lambda: probe.all_sent, math.inf, stop)
            _spin_until(executor, lambda: probe.unanswered_measured_frames == 0,
                        LAST_ANSWER_TIMEOUT_S, stop)
        options.json_out.write_text(json.dumps({
            'follower_found': found, 'frames': options.frames,
            'latencies_ms': probe.latencies_ms}))
    finally:
        executor.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown()
    return 0 if found and probe.all_sent else 1


if __name__ == '__main__':
    sys.exit(main())
