"""
Wheel odometry of a differential-drive base from its wheel encoder angles.

A pure module (no ROS, no MuJoCo): the simulator node feeds it the wheel joint angles and
publishes the pose in the ``odom`` frame, which starts where the robot was at the first update.
"""

import math

from followbot.frames import quaternion_from_yaw

# Below this heading change in one update the arc formula's division by it loses precision; the
# midpoint formula used instead differs from the arc by distance * O(dyaw^2): nothing.
STRAIGHT_STEP_YAW_RAD = 1e-9


class WheelOdometry:
    """
    Integrate wheel angles into a planar pose, as a Kobuki's encoders would.

    Between two updates each wheel is taken to turn at a constant rate, so the base moves along
    a circular arc (a straight line when both wheels turn alike) and the integration is exact for
    such motion. The first update only sets the reference angles: the pose starts at (0, 0, 0).
    """

    def __init__(self, wheel_radius_m: float, wheel_separation_m: float):
        """
        Start an odometry with no updates.

        :param wheel_radius_m: wheel radius in metres.
        :param wheel_separation_m: distance between the wheels' contact points in metres.
        :raises ValueError: if a dimension is not positive and finite.
        """
        for name, value in (('wheel_radius_m', wheel_radius_m),
                            ('wheel_separation_m', wheel_separation_m)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be a positive finite number, got {value!r}.')
        self._wheel_radius_m = float(wheel_radius_m)
        self._wheel_separation_m = float(wheel_separation_m)
        self.reset()

    def reset(self) -> None:
        """Forget all updates: the next update sets new reference angles at pose (0, 0, 0)."""
        self._previous = None
        self._x_m = 0.0
        self._y_m = 0.0
        self._yaw_rad = 0.0
        self._linear_mps = 0.0
        self._angular_radps = 0.0

    def update(self, left_rad: float, right_rad: float,
               time_s: float) -> tuple[float, float, float]:
        """
        Advance the pose to new wheel angles.

        An update at the same time as the previous one moves the pose but keeps the last twist
        (no time passed to measure a rate over).

        :param left_rad: left wheel angle in radians, increasing when rolling forward.
        :param right_rad: right wheel angle in radians, increasing when rolling forward.
        :param time_s: time of the reading in seconds, not earlier than the previous one.
        :return: the pose (x m, y m, yaw rad) in the odom frame, yaw in [-pi, pi].
        :raises ValueError: if a value is not finite or time runs backwards.
        """
        if not (math.isfinite(left_rad) and math.isfinite(right_rad) and math.isfinite(time_s)):
            raise ValueError('Wheel angles and time must be finite, got '
                             f'({left_rad}, {right_rad}, {time_s}).')
        if self._previous is None:
            self._previous = (left_rad, right_rad, time_s)
            return self.pose
        previous_left_rad, previous_right_rad, previous_time_s = self._previous
        if time_s < previous_time_s:
            raise ValueError(f'Time ran backwards from {previous_time_s} s to {time_s} s; call '
                             'reset() to start again.')
        left_m = (left_rad - previous_left_rad) * self._wheel_radius_m
        right_m = (right_rad - previous_right_rad) * self._wheel_radius_m
        distance_m = (left_m + right_m) / 2.0
        yaw_change_rad = (right_m - left_m) / self._wheel_separation_m
        self._advance(distance_m, yaw_change_rad)
        elapsed_s = time_s - previous_time_s
        if elapsed_s > 0.0:
            self._linear_mps = distance_m / elapsed_s
            self._angular_radps = yaw_change_rad / elapsed_s
        self._previous = (left_rad, right_rad, time_s)
        return self.pose

    def _advance(self, distance_m: float, yaw_change_rad: float) -> None:
        """
        Move the pose along an arc of a given length and heading change.

        :param distance_m: arc length travelled by the base centre in metres.
        :param yaw_change_rad: heading change over the arc in radians.
        """
        if abs(yaw_change_rad) < STRAIGHT_STEP_YAW_RAD:
            mid_yaw_rad = self._yaw_rad + yaw_change_rad / 2.0
            self._x_m += distance_m * math.cos(mid_yaw_rad)
            self._y_m += distance_m * math.sin(mid_yaw_rad)
        else:
            radius_m = distance_m / yaw_change_rad
            new_yaw_rad = self._yaw_rad + yaw_change_rad
            self._x_m += radius_m * (math.sin(new_yaw_rad) - math.sin(self._yaw_rad))
            self._y_m -= radius_m * (math.cos(new_yaw_rad) - math.cos(self._yaw_rad))
        self._yaw_rad = math.remainder(self._yaw_rad + yaw_change_rad, 2.0 * math.pi)

    @property
    def pose(self) -> tuple[float, float, float]:
        """Return where the base is in the odom frame: (x m, y m, yaw rad), yaw in [-pi, pi]."""
        return self._x_m, self._y_m, self._yaw_rad

    @property
    def orientation_xyzw(self) -> tuple[float, float, float, float]:
        """Return the heading as a quaternion (x, y, z, w), for an Odometry message."""
        return quaternion_from_yaw(self._yaw_rad)

    @property
    def twist(self) -> tuple[float, float]:
        """Return the body twist over the last update: (linear m/s, angular rad/s)."""
        return self._linear_mps, self._angular_radps

    @property
    def wheel_radius_m(self) -> float:
        """Return the wheel radius in metres."""
        return self._wheel_radius_m

    @property
    def wheel_separation_m(self) -> float:
        """Return the distance between the wheels in metres."""
        return self._wheel_separation_m
