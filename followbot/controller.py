"""
Turn line detections into velocity commands.

A proportional steering law, as in "Programming Robots with ROS" (ch. 12): drive at a constant
speed and turn against the line's offset. Unlike the book it says what to do when the line is
lost: stop, or rotate in place towards the side where the line was last seen. It never drives
forward blind.

Angular velocities follow ROS REP-103: positive is counter-clockwise, i.e. a left turn.
"""

from dataclasses import dataclass
import math

LOST_LINE_BEHAVIOURS = ('search', 'stop')

# Search turn direction (sign of the angular velocity) for the sign of the last seen error.
# A line last seen right of centre (error > 0) is searched for by turning right (clockwise,
# negative). With no side preference (never seen, or last seen dead centre) turn left.
_SEARCH_DIRECTION_BY_ERROR_SIGN = {
    1: -1.0,
    -1: 1.0,
    0: 1.0,
}


@dataclass(frozen=True)
class VelocityCommand:
    """A planar velocity command: forward speed and yaw rate (REP-103, positive = left)."""

    linear_mps: float
    angular_radps: float


@dataclass(frozen=True)
class ControllerConfig:
    """
    Gains, limits and lost-line behaviour of the line-following controller.

    The book's law w = -(cx - w/2) / 100 at a 640-pixel-wide image is a gain of 3.2 rad/s
    per unit of normalised error.
    """

    linear_speed_mps: float = 0.2
    angular_gain_radps: float = 3.2
    max_angular_speed_radps: float = 1.5
    lost_line_behaviour: str = 'search'
    search_angular_speed_radps: float = 0.5

    def __post_init__(self):
        """Reject negative or non-finite speeds and gains and unknown behaviours."""
        for name in ('linear_speed_mps', 'angular_gain_radps', 'max_angular_speed_radps',
                     'search_angular_speed_radps'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f'{name} must be a number, got {value!r}.')
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f'{name} must be finite and non-negative, got {value}.')
        if self.lost_line_behaviour not in LOST_LINE_BEHAVIOURS:
            raise ValueError(
                f'lost_line_behaviour must be one of {", ".join(LOST_LINE_BEHAVIOURS)}, '
                f'got {self.lost_line_behaviour!r}.')


def _sign(value):
    """Return 1, -1 or 0, the sign of a number."""
    return (value > 0) - (value < 0)


class LineFollowingController:
    """
    Steer towards the detected line; stop or search for it when it is lost.

    While the line is seen the robot drives at ``linear_speed_mps`` and turns at
    ``-angular_gain_radps * error``, clamped to ``max_angular_speed_radps``: a line right of
    centre (error > 0) gives a right turn (negative yaw rate). The controller remembers on
    which side of centre the line was last seen, for the 'search' behaviour.
    """

    def __init__(self, config=ControllerConfig()):
        """
        Make a controller that has not yet seen the line.

        :param config: gains, limits and lost-line behaviour; the defaults are the book's.
        """
        self._config = config
        self._lost_line_commands = {
            'stop': self.stop_command,
            'search': self._search_command,
        }
        self._last_error_sign = 0

    @property
    def config(self):
        """Return the ControllerConfig this controller was made with."""
        return self._config

    @staticmethod
    def stop_command():
        """Return the command that stops the robot: zero linear and angular velocity."""
        return VelocityCommand(linear_mps=0.0, angular_radps=0.0)

    def reset(self):
        """Forget the side where the line was last seen, as if it had never been seen."""
        self._last_error_sign = 0

    def update(self, detection):
        """
        Return the velocity command for one detection.

        :param detection: a line_detector.Detection; only ``found`` and ``error`` are used.
            A found detection with a non-finite error counts as lost.
        :return: a VelocityCommand. While the line is lost the linear speed is always 0:
            'stop' stops, 'search' rotates in place at ``search_angular_speed_radps``
            towards the side where the line was last seen (left if it has no side).
        """
        if not (detection.found and math.isfinite(detection.error)):
            return self._lost_line_commands[self._config.lost_line_behaviour]()
        self._last_error_sign = _sign(detection.error)
        limit = self._config.max_angular_speed_radps
        angular_radps = -self._config.angular_gain_radps * detection.error
        return VelocityCommand(
            linear_mps=self._config.linear_speed_mps,
            angular_radps=min(max(angular_radps, -limit), limit))

    def _search_command(self):
        """Return a rotation in place towards the side where the line was last seen."""
        direction = _SEARCH_DIRECTION_BY_ERROR_SIGN[self._last_error_sign]
        return VelocityCommand(
            linear_mps=0.0,
            angular_radps=direction * self._config.search_angular_speed_radps)
