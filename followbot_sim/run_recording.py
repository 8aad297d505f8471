"""
Record a simulated run, every frame of it, for ``followbot --record`` and ``scorecard --record``.

The topics are the ones a user looks at again: the camera (raw, or JPEG as image_transport's
compressed plugin sends it), its camera_info, the follower's commands and status, odometry,
ground truth, the score, ``/tf``, ``/tf_static`` and ``/clock``. Log times are simulated time,
so a recording's timeline is the run's, however fast the machine ran it. The simulator starts
paused and is let go only when the recorder has heard every publisher for a moment (so that
the publishers have heard its subscriptions too): no first frame is missed. It is held again
whenever the recorder falls a simulated second behind (a loaded machine leaves it unscheduled),
so its queues never overflow; held time is wall time only, simulated time stands still.
"""

import time

from followbot.output_files import output_file_option, output_folder_option
from followbot_sim.answered_requests import SimulatorPause
from followbot_sim.recorder import Recorder
from followbot_sim.steady_condition import SteadyCondition
from rclpy.parameter import Parameter

CLOCK_TOPIC = '/clock'
RAW_CAMERA_TOPIC = ('camera/rgb/image_raw', 'sensor_msgs/msg/Image')
COMPRESSED_CAMERA_TOPIC = ('camera/rgb/image_raw/compressed', 'sensor_msgs/msg/CompressedImage')
# Everything but the camera image, as (topic relative to the robot's namespace, type).
RUN_TOPICS = (
    ('camera/rgb/camera_info', 'sensor_msgs/msg/CameraInfo'),
    # Twist or TwistStamped, as the follower's cmd_vel_stamped parameter chose.
    ('cmd_vel', None),
    ('odom', 'nav_msgs/msg/Odometry'),
    ('ground_truth/odom', 'nav_msgs/msg/Odometry'),
    ('follower/status', 'diagnostic_msgs/msg/DiagnosticArray'),
    ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray'),
    ('/tf', 'tf2_msgs/msg/TFMessage'),
    ('/tf_static', 'tf2_msgs/msg/TFMessage'),
)
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
RECORDER_ODOMETRY_TOPIC = 'odom'
BYTES_PER_MEGABYTE = 1e6
NANOSECONDS = 1e9
# After a run, the recorder works through what it still holds until nothing has come for this
# long (wall time), for at most DRAIN_LIMIT_S.
DRAIN_QUIET_S = 0.5
DRAIN_LIMIT_S = 30.0
DRAIN_SPIN_S = 0.05
# The simulator is held while the recorder lags this far (simulated seconds of /clock) behind
# its clock, and let go when the lag is back under RESUME_LAG_S: the recorder's queues (5 s of
# camera, 20 s of /clock) never overflow, however loaded the machine.
HOLD_LAG_S = 1.0
RESUME_LAG_S = 0.25
# Wall seconds after which a simulator still held for the recorder is reported, once.
WAIT_REPORT_S = 10.0


def drain(executor, progress) -> None:
    """
    Spin until a consumer has taken everything it received: its progress stands still.

    :param executor: the executor the consumer's node is in.
    :param progress: returns a value that changes while the consumer works through its queue
        (messages written, the newest frame's time); spinning stops once it has not changed
        for DRAIN_QUIET_S of wall time, or after DRAIN_LIMIT_S.
    """
    now_s = time.monotonic()
    deadline_s = now_s + DRAIN_LIMIT_S
    last, last_change_s = progress(), now_s
    while now_s < deadline_s and now_s - last_change_s < DRAIN_QUIET_S:
        executor.spin_once(timeout_sec=DRAIN_SPIN_S)
        now_s = time.monotonic()
        value = progress()
        if value != last:
            last, last_change_s = value, now_s


def run_topics(compressed: bool = False, clock_topic: str = CLOCK_TOPIC) -> list:
    """
    Return the topics a run's recording holds, as (topic, message type) pairs.

    :param compressed: record the camera as JPEG (``.../compressed``) instead of raw.
    :param clock_topic: the simulated clock's topic (a robot under a namespace has its own).
    :return: the pairs; relative names are the robot's, in the recorder's namespace.
    """
    camera = COMPRESSED_CAMERA_TOPIC if compressed else RAW_CAMERA_TOPIC
    return [camera, *RUN_TOPICS, (clock_topic, CLOCK_TYPE)]


class LagHold:
    """Hold from a lag of ``hold_lag_s`` until it is back under ``resume_lag_s``."""

    def __init__(self, hold_lag_s: float = HOLD_LAG_S, resume_lag_s: float = RESUME_LAG_S):
        """
        Start not holding.

        :param hold_lag_s: the lag (simulated seconds) from which to hold.
        :param resume_lag_s: the lag under which to let go again.
        """
        self._hold_lag_s = hold_lag_s
        self._resume_lag_s = resume_lag_s
        self.holding = False
        self.holds = 0

    def update(self, lag_s: float) -> bool:
        """
        Take the present lag.

        :param lag_s: how far behind (simulated seconds) the slow consumer is.
        :return: whether time should stand still until it catches up.
        """
        holding = lag_s > (self._resume_lag_s if self.holding else self._hold_lag_s)
        self.holds += holding and not self.holding
        self.holding = holding
        return holding


class HoldReport:
    """Say once, when a simulator started paused is still held after WAIT_REPORT_S, for what."""

    def __init__(self, waiter: str):
        """
        Start the wait now.

        :param waiter: who holds the simulator, as the report names it (``the video``).
        """
        self._waiter = waiter
        self._created_s = time.monotonic()
        self._reported = False

    def line(self, missing) -> str | None:
        """
        Return the report once its time has come, then never again.

        :param missing: a callable returning what is still missing, as a phrase; called only
            when the report is made.
        :return: the line to print, or None.
        """
        if self._reported or time.monotonic() - self._created_s < WAIT_REPORT_S:
            return None
        self._reported = True
        return (f'Simulation held for {WAIT_REPORT_S:g} s: {self._waiter} still waits for '
                f'{missing()}.')


def add_record_options(parser, one_file_per_run: bool = False) -> None:
    """
    Add ``--record`` and ``--record-compressed`` to a command's argument parser.

    :param parser: an ``argparse.ArgumentParser``.
    :param one_file_per_run: ``--record`` names a folder for one file per run (the
        scorecard), not a file.
    """
    contents = ('camera, camera_info, cmd_vel, odometry, ground truth, score, follower status, '
                '/tf, /tf_static, /clock')
    if one_file_per_run:
        parser.add_argument('--record', metavar='DIR', default=None,
                            type=output_folder_option('the recordings'),
                            help='record each run into DIR/SCENARIO-CONFIGURATION.mcap '
                                 f'(rosbag2-compatible MCAP: {contents})')
    else:
        parser.add_argument('--record', metavar='PATH', default=None,
                            type=output_file_option('the recording'),
                            help='record the run into this rosbag2-compatible MCAP file '
                                 f'({contents}); the simulator starts once the recorder hears '
                                 'every topic')
    parser.add_argument('--record-compressed', action='store_true',
                        help='record the camera as JPEG (sensor_msgs/CompressedImage): about '
                             '13 MB per simulated minute instead of 50 MB raw')


class RunRecording:
    """A Recorder on simulated time that lets a paused simulator go once it hears everything."""

    def __init__(self, path, simulator_name: str, compressed: bool = False,
                 clock_topic: str = CLOCK_TOPIC, **kwargs):
        """
        Create the recorder node; add :attr:`recorder` to an executor and call :meth:`poll`.

        :param path: the ``.mcap`` file to write.
        :param simulator_name: the simulator's fully qualified node name, whose pause service
            is called to start it; None when the caller starts the simulator itself.
        :param compressed: record the camera as JPEG.
        :param clock_topic: the simulated clock's topic.
        :param kwargs: passed to the Recorder and so to ``Node`` (``context=``, ...).
        :raises RecordingError: if the file cannot be created.
        """
        # The recorder's own clock follows the run's clock topic, also under a namespace.
        remap = [] if clock_topic == CLOCK_TOPIC else [
            '--ros-args', '-r', f'{CLOCK_TOPIC}:={clock_topic}']
        self.recorder = Recorder(
            path, run_topics(compressed, clock_topic), tf_odometry_topic=RECORDER_ODOMETRY_TOPIC,
            parameter_overrides=[Parameter('use_sim_time', value=True)], cli_args=remap,
            progress_topic=clock_topic, **kwargs)
        self._pause = SimulatorPause(self.recorder, simulator_name)
        # The recorder subscribes once it sees a publisher, so its side matches first.
        self._connected = SteadyCondition()
        self._lag_hold = LagHold()
        self.started = False
        # Whether the simulator is held now (asked to pause, or left out of the executor).
        self.holding = False
        self._hold_report = HoldReport('the recorder')

    @property
    def holds(self) -> int:
        """Return how many times time was held for the recorder to catch up."""
        return self._lag_hold.holds

    def poll(self, also_hold: bool = False) -> bool:
        """
        Start the simulator once the recorder has heard every topic for a while, then hold it.

        It starts after the recorder has heard every topic for MATCH_SETTLE_S, and is held
        while the recorder lags. Call it after each spin.

        :param also_hold: hold the simulator for another reason too (another consumer lags):
            this object owns the simulator's pause while it records.
        :return: whether the simulator has been asked to start.
        """
        self._pause.poll()
        if not self.started:
            if self._connected.update(self.recorder.matched and self._pause.ready):
                self._pause.ask_paused(False)
                self.started = True
            return self.started
        self.holding = self.should_hold() or also_hold
        self._pause.ask_paused(self.holding)
        return True

    def hold_in(self, executor, simulator) -> None:
        """
        Hold time for a simulator node this process spins, while the recorder lags.

        For a caller with no pause service to ask (the scorecard runs the simulator in its own
        executor): the simulator leaves the executor while the recorder lags, so simulated
        time stands still, and comes back once it caught up. Call it after each spin.

        :param executor: the executor that spins the simulator and the recorder.
        :param simulator: the simulator node.
        """
        holding = self.should_hold()
        if holding != self.holding:
            self.holding = holding
            (executor.remove_node if holding else executor.add_node)(simulator)

    def lag_s(self) -> float:
        """Return how far (simulated seconds) the recorded /clock is behind the recorder's."""
        progress_ns = self.recorder.progress_ns
        if progress_ns is None:
            return 0.0
        return (self.recorder.get_clock().now().nanoseconds - progress_ns) / NANOSECONDS

    def should_hold(self) -> bool:
        """
        Tell whether time should stand still until the recorder catches up.

        :return: True from a lag of HOLD_LAG_S until it is back under RESUME_LAG_S.
        """
        return self._lag_hold.update(self.lag_s())

    def wait_report(self) -> str | None:
        """
        Say once, when the simulator has been held for the recorder for long, what is missing.

        :return: the line to print, or None.
        """
        if self.started:
            return None
        return self._hold_report.line(self._missing)

    def _missing(self) -> str:
        waiting = self.recorder.waiting_topics
        return (f'publishers of {", ".join(waiting)}' if waiting
                else 'a publisher to match its subscriptions (a type or QoS mismatch?)')

    def drain(self, executor) -> None:
        """
        Spin until the recorder has written everything it received (nothing new for a while).

        :param executor: the executor the recorder is in.
        """
        writer = self.recorder.writer
        drain(executor, lambda: writer.message_count)

    def close(self) -> str:
        """
        Finish the file and destroy the recorder node.

        :return: one line saying what was recorded, such as ``run.mcap: 2412 messages on 11
            topics (200 camera frames), 43.1 MB``.
        """
        writer = self.recorder.writer
        camera_frames = sum(count for topic, count in self.message_counts().items()
                            if topic.endswith((RAW_CAMERA_TOPIC[0], COMPRESSED_CAMERA_TOPIC[0])))
        self.recorder.destroy_node()
        try:
            size = f', {writer.path.stat().st_size / BYTES_PER_MEGABYTE:.1f} MB'
        except OSError:
            size = ''
        failures = f'; {len(self.recorder.failures)} not written' \
            if self.recorder.failures else ''
        holds = (f'; time held {self.holds} times for the recorder to catch up' if self.holds
                 else '')
        return (f'{writer.path}: {writer.message_count} messages on {len(writer.topics)} '
                f'topics ({camera_frames} camera frames){size}{failures}{holds}')

    def message_counts(self) -> dict:
        """Return {topic: messages written}."""
        return self.recorder.writer.message_counts
