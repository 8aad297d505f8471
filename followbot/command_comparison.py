"""
Compare the commands a follower gives on replayed camera frames with the recorded ones.

Pure: no rclpy. Which recorded command answered which frame: where the follower's status was
recorded, the follower published the command of a frame just before the status stamped with
that frame's stamp, so the answer is the last command sent before that status (exact, also when
the camera was recorded compressed and so sent a little after the raw frame the follower saw).
Otherwise the answer is the first command sent after the frame and before the next one, by the
messages' publish times; in lockstep the simulator waits for exactly that answer.
"""

import bisect
import dataclasses
import math
from typing import NamedTuple

# The six velocity components a Twist carries, in the order they are compared.
TWIST_COMPONENTS = ('linear_x', 'linear_y', 'linear_z', 'angular_x', 'angular_y', 'angular_z')
# How many differing frames the summary names one by one.
LISTED_DIFFERENCES = 20


class Velocity(NamedTuple):
    """The six components of a Twist: metres per second, then radians per second."""

    linear_x: float = 0.0
    linear_y: float = 0.0
    linear_z: float = 0.0
    angular_x: float = 0.0
    angular_y: float = 0.0
    angular_z: float = 0.0

    @classmethod
    def from_twist(cls, twist) -> 'Velocity':
        """
        Take the components of a ``geometry_msgs/Twist``.

        :param twist: the message (or anything with ``linear`` and ``angular`` vectors).
        :return: the velocity.
        """
        return cls(twist.linear.x, twist.linear.y, twist.linear.z,
                   twist.angular.x, twist.angular.y, twist.angular.z)

    def difference(self, other: 'Velocity') -> float:
        """
        Return the largest difference of one component (NaN differs from everything).

        :param other: the velocity to compare with.
        :return: the largest absolute difference; infinity where one component is NaN.
        """
        largest = 0.0
        for mine, theirs in zip(self, other):
            if mine != theirs:
                gap = abs(mine - theirs)
                largest = max(largest, gap if math.isfinite(gap) else math.inf)
        return largest


def answers_by_order(frame_times_ns, command_times_ns) -> list:
    """
    Pair each frame with the command sent first after it and before the next frame.

    :param frame_times_ns: the frames' publish times, in the order the frames are replayed.
    :param command_times_ns: the commands' publish times, in any order.
    :return: for each frame, the index into ``command_times_ns`` of its answer, or None.
    """
    commands = sorted(range(len(command_times_ns)), key=lambda index: command_times_ns[index])
    sorted_times = [command_times_ns[index] for index in commands]
    frames_sorted = sorted(frame_times_ns)
    answers = []
    for frame_time_ns in frame_times_ns:
        position = bisect.bisect_right(sorted_times, frame_time_ns)
        next_frame = bisect.bisect_right(frames_sorted, frame_time_ns)
        next_frame_ns = frames_sorted[next_frame] if next_frame < len(frames_sorted) \
            else math.inf
        if position < len(sorted_times) and sorted_times[position] < next_frame_ns:
            answers.append(commands[position])
        else:
            answers.append(None)
    return answers


def answers_by_status(frame_stamps_ns, statuses, command_times_ns) -> list:
    """
    Pair each frame with the last command sent before the follower's status for its stamp.

    :param frame_stamps_ns: the frames' header stamps, in the order the frames are replayed.
    :param statuses: (header stamp, publish time) of each follower status, in any order.
    :param command_times_ns: the commands' publish times, in any order.
    :return: for each frame, the index into ``command_times_ns`` of its answer, or None when
        the follower reported nothing for that frame.
    """
    status_times = {}
    for stamp_ns, publish_time_ns in statuses:
        status_times.setdefault(stamp_ns, publish_time_ns)
    commands = sorted(range(len(command_times_ns)), key=lambda index: command_times_ns[index])
    sorted_times = [command_times_ns[index] for index in commands]
    answers = []
    for stamp_ns in frame_stamps_ns:
        status_time_ns = status_times.get(stamp_ns)
        position = None if status_time_ns is None else bisect.bisect_right(
            sorted_times, status_time_ns) - 1
        answers.append(commands[position] if position is not None and position >= 0
                       else None)
    return answers


@dataclasses.dataclass
class FrameResult:
    """One replayed frame: its time, the recorded and the replayed command (None if none)."""

    index: int
    stamp_s: float
    recorded: Velocity | None
    replayed: Velocity | None

    @property
    def compared(self) -> bool:
        """Tell whether the frame has a recorded answer to compare with."""
        return self.recorded is not None

    @property
    def difference(self) -> float:
        """Return the largest component difference; infinity when the replay gave none."""
        if self.recorded is None:
            return 0.0
        if self.replayed is None:
            return math.inf
        return self.recorded.difference(self.replayed)


@dataclasses.dataclass
class Comparison:
    """The outcome of a replay: every frame's result and the tolerance they are judged by."""

    tolerance: float
    frames: list = dataclasses.field(default_factory=list)

    def add(self, result: FrameResult) -> None:
        """Add one frame's result."""
        self.frames.append(result)

    @property
    def compared(self) -> list:
        """Return the results of the frames that have a recorded answer."""
        return [frame for frame in self.frames if frame.compared]

    @property
    def identical(self) -> int:
        """Return how many compared frames got exactly the recorded command."""
        return sum(frame.difference == 0.0 for frame in self.compared)

    @property
    def differing(self) -> list:
        """Return the compared frames whose command differs by more than the tolerance."""
        return [frame for frame in self.compared if not frame.difference <= self.tolerance]

    @property
    def unanswered(self) -> int:
        """Return how many frames the replayed follower did not answer."""
        return sum(frame.replayed is None for frame in self.frames)

    @property
    def max_difference(self) -> float:
        """Return the largest difference of any compared frame (0 when none)."""
        return max((frame.difference for frame in self.compared), default=0.0)

    @property
    def matches(self) -> bool:
        """Tell whether every compared command is within the tolerance."""
        return not self.differing

    def summary_lines(self) -> list:
        """
        Describe the comparison for a person: totals, then the differing frames.

        :return: lines of text, without newlines.
        """
        compared = self.compared
        lines = [f'{len(self.frames)} frames replayed, {len(compared)} with a recorded command: '
                 f'{self.identical} identical, {len(self.differing)} differ by more than '
                 f'{self.tolerance:g}; max difference {self.max_difference:.6g} '
                 '(m/s or rad/s)'
                 + (f'; {self.unanswered} frames got no answer' if self.unanswered else '')]
        for frame in self.differing[:LISTED_DIFFERENCES]:
            lines.append(f'  frame {frame.index} (t={frame.stamp_s:.3f} s): recorded '
                         f'{_velocity_text(frame.recorded)}, replayed '
                         f'{_velocity_text(frame.replayed)}')
        if len(self.differing) > LISTED_DIFFERENCES:
            lines.append(f'  ... and {len(self.differing) - LISTED_DIFFERENCES} more')
        return lines


def _velocity_text(velocity: Velocity | None) -> str:
    if velocity is None:
        return 'nothing'
    text = f'v={velocity.linear_x:.4f} m/s w={velocity.angular_z:.4f} rad/s'
    others = {name: value for name, value in zip(TWIST_COMPONENTS, velocity)
              if name not in ('linear_x', 'angular_z') and value != 0.0}
    return text + ''.join(f' {name}={value:.4f}' for name, value in others.items())
