"""
Differential-drive kinematics and the command watchdog of a Kobuki base.

Pure functions and small classes with no ROS or MuJoCo import: the simulator node turns each
``cmd_vel`` into wheel speeds with them, and the tests check them directly.
"""

from dataclasses import dataclass
import math

KOBUKI_WHEEL_SEPARATION_M = 0.230
KOBUKI_WHEEL_RADIUS_M = 0.035
KOBUKI_MAX_LINEAR_SPEED_MPS = 0.7
KOBUKI_MAX_ANGULAR_SPEED_RADPS = math.pi
KOBUKI_COMMAND_TIMEOUT_S = 0.6
TIME_EPSILON_S = 1e-9


@dataclass(frozen=True)
class DiffDriveLimits:
    """Geometry and speed limits of a differential-drive base (Kobuki defaults)."""

    wheel_separation_m: float = KOBUKI_WHEEL_SEPARATION_M
    wheel_radius_m: float = KOBUKI_WHEEL_RADIUS_M
    max_linear_speed_mps: float = KOBUKI_MAX_LINEAR_SPEED_MPS
    max_angular_speed_radps: float = KOBUKI_MAX_ANGULAR_SPEED_RADPS

    def __post_init__(self):
        for name in ('wheel_separation_m', 'wheel_radius_m',
                     'max_linear_speed_mps', 'max_angular_speed_radps'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be a positive finite number, got {value!r}.')

    @property
    def max_wheel_speed_radps(self) -> float:
        """Wheel speed at which the base reaches its top linear speed."""
        return self.max_linear_speed_mps / self.wheel_radius_m


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


def wheel_speeds_radps(linear_mps: float, angular_radps: float,
                       limits: DiffDriveLimits = DiffDriveLimits()) -> tuple[float, float]:
    """
    Turn a body twist into (left, right) wheel speeds, within the base's limits.

    The twist is first clamped to the linear and angular limits; if a wheel would still spin
    faster than the top speed allows, both wheels are scaled down together so the path keeps
    its curvature (the robot slows down rather than turning less). Non-finite commands give
    zero speeds.

    :param linear_mps: forward speed of the base (m/s, REP-103: +x forward).
    :param angular_radps: yaw rate (rad/s, positive counter-clockwise, i.e. to the left).
    :param limits: geometry and limits of the base.
    :return: (left, right) wheel angular speeds in rad/s, positive rolling forward.
    """
    if not (math.isfinite(linear_mps) and math.isfinite(angular_radps)):
        return 0.0, 0.0
    linear_mps = _clamp(linear_mps, limits.max_linear_speed_mps)
    angular_radps = _clamp(angular_radps, limits.max_angular_speed_radps)
    half_track_speed_mps = angular_radps * limits.wheel_separation_m / 2.0
    left_radps = (linear_mps - half_track_speed_mps) / limits.wheel_radius_m
    right_radps = (linear_mps + half_track_speed_mps) / limits.wheel_radius_m
    fastest_radps = max(abs(left_radps), abs(right_radps))
    if fastest_radps > limits.max_wheel_speed_radps:
        scale = limits.max_wheel_speed_radps / fastest_radps
        left_radps *= scale
        right_radps *= scale
    return left_radps, right_radps


def body_twist(left_radps: float, right_radps: float,
               limits: DiffDriveLimits = DiffDriveLimits()) -> tuple[float, float]:
    """
    Turn (left, right) wheel speeds into the body twist they produce (forward kinematics).

    :param left_radps: left wheel angular speed in rad/s.
    :param right_radps: right wheel angular speed in rad/s.
    :param limits: geometry of the base.
    :return: (linear m/s, angular rad/s).
    """
    radius_m = limits.wheel_radius_m
    linear_mps = radius_m * (left_radps + right_radps) / 2.0
    angular_radps = radius_m * (right_radps - left_radps) / limits.wheel_separation_m
    return linear_mps, angular_radps


class CommandWatchdog:
    """
    Hold the latest velocity command and drop it when it gets too old.

    A Kobuki stops on its own when no command has come for 0.6 s; this reproduces that in
    simulated time so a follower that dies does not leave the robot driving.
    """

    def __init__(self, timeout_s: float = KOBUKI_COMMAND_TIMEOUT_S):
        """
        Start with no command (the robot stands still).

        :param timeout_s: age in seconds after which a command no longer applies.
        :raises ValueError: if the timeout is not positive.
        """
        if not (math.isfinite(timeout_s) and timeout_s > 0.0):
            raise ValueError(f'timeout_s must be a positive finite number, got {timeout_s!r}.')
        self._timeout_s = timeout_s
        self._command = (0.0, 0.0)
        self._received_at_s = None

    def command(self, linear_mps: float, angular_radps: float, time_s: float) -> None:
        """
        Take a new command received at ``time_s``.

        :param linear_mps: forward speed in m/s.
        :param angular_radps: yaw rate in rad/s.
        :param time_s: simulated time of arrival in seconds.
        """
        self._command = (linear_mps, angular_radps)
        self._received_at_s = time_s

    def current(self, time_s: float) -> tuple[float, float]:
        """
        Return the command in force at ``time_s``: the latest one, or zero once it is stale.

        :param time_s: simulated time in seconds.
        :return: (linear m/s, angular rad/s).
        """
        # The epsilon absorbs float drift of accumulated step times, so the stop comes on the
        # step where 0.6 s have passed rather than one step later.
        if (self._received_at_s is None
                or time_s - self._received_at_s >= self._timeout_s - TIME_EPSILON_S):
            return 0.0, 0.0
        return self._command

    def expires_at_s(self) -> float:
        """
        Return when the command in force stops applying, so that physics may run to then.

        :return: simulated time in seconds; infinity when no command is in force.
        """
        if self._received_at_s is None:
            return math.inf
        return self._received_at_s + self._timeout_s

    def reset(self) -> None:
        """Forget the last command."""
        self._command = (0.0, 0.0)
        self._received_at_s = None
