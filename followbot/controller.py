"""
Turn line detections into velocity commands.

Two steering laws, chosen by ``ControllerConfig.steering_law``:

- ``'path'`` (the default): the stripes the detector saw in several bands, projected onto the
  floor, form a polyline ahead of the robot. The robot steers along the arc that reaches its
  point ``look_ahead_m`` away (pure pursuit: exact on steady bends, no offset needed to
  turn), turns sharply towards a point far to the side (a sharp corner), and plans its
  speed on the sharpest arc to any of the points (a lateral acceleration bound, so it slows
  before a bend, not in it) and on how many bands see the line, within acceleration limits
  matched to the robot.
- ``'proportional'``: the book's law ("Programming Robots with ROS", ch. 12): a constant speed
  and w = -gain * error of the nearest band's normalised offset.

With either law, a line lost for a moment (a gap in a dashed line) is driven through on the last
command for ``line_memory_s``; a line lost for longer makes the robot stop, or rotate in place
towards the side where it was last seen. Searching (``lost_line_behaviour`` ``'search'``) with
the path law, a line that vanished from every band at once where it was last seen running on out
of the top of the view (glare, worn paint) is first driven along as far as it was seen, like a
line end seen ahead (below), and searched for from there. The side searched first is the side
the line turned away to (the farthest band saw it ``turn_side_offset_m`` or more aside within
``turn_side_memory_s`` of the loss, path law), else the side last steered to. A line the robot
saw end ahead of it (the bands beyond the farthest that saw it held no line-coloured pixel at
all) is not searched for when it is lost: with ``stop_at_line_end`` the robot stops there, on
the end of the line, until the line comes back into view. Where the line ended inside the view
(not at the image's side, where it may go on out of view), the robot first drives on to where it
saw the end (path law): the camera sees the floor only from some way ahead, so the last frame
that saw the line showed its end still that far off. It follows the line's floor points of that
frame, kept where they lay on the floor by dead reckoning (odometry, else its own commands),
and stops ``line_end_stop_short_m`` before their end. A line that turned away to a side just
before it ended may go on round a corner too sharp for the camera (a hairpin whose turn leaves
the view at its bottom edge, a 120-degree corner), so the searching robot first turns up to
``corner_search_angle_deg`` towards that side (at ``corner_search_angular_speed_radps``: the
corner was seen, so faster than a search for a line lost anywhere), turns back to face where
the line ended, and stops there. A line found while searching that lies where the robot has just
driven (most of its points within ``trail_tolerance_m`` of the robot's dead-reckoned path over
the last ``trail_length_m``) is the way back, not taken: a robot that lost its line, or saw it
end where something stands on it, must not follow it back the way it came. A line found
again is trusted after ``frames_to_trust`` frames in a row. The robot never drives forward
without a line, but for coasting on the line memory or along the line it last saw.

Angular velocities follow ROS REP-103: positive is counter-clockwise, i.e. a left turn.
"""

import collections
from dataclasses import dataclass
import math

import numpy as np

# The robot's dead-reckoned path is kept as points this far apart, this many at most (8 m).
TRAIL_SPACING_M = 0.02
MAX_TRAIL_POINTS = 400
# A line found while searching is the way back when at least this share of its points lie on
# the robot's path.
WAY_BACK_SHARE = 0.5

# An odometry move faster than this between two frames is no move of a line-following base but
# a jump (odometry reset, a glitch): that step is driven by the command instead.
ODOMETRY_JUMP_MPS = 5.0
ODOMETRY_JUMP_RADPS = 20.0

# Turned back to within this of facing where the line ended is facing it.
FACING_TOLERANCE_RAD = 1e-3

STEERING_LAWS = ('path', 'proportional')
LOST_LINE_BEHAVIOURS = ('search', 'stop')
# What the controller is doing, as reported on the follower's status topic.
STATE_WAITING = 'waiting'
STATE_TRACKING = 'tracking'
STATE_COASTING = 'coasting'
STATE_ACQUIRING = 'acquiring'
STATE_LOST = 'lost'
STATE_LINE_END = 'line end'
# Where a coasting robot drives: along the line it saw end ahead, or saw run on and vanish.
TO_LINE_END = 'to line end'
ALONG_VANISHED_LINE = 'along vanished line'
# Longest time step between frames that the acceleration limits honour; a longer pause (a
# paused simulation, a camera hiccup) starts again from the limits, not from a huge step.
MAX_TIME_STEP_S = 0.2


@dataclass(frozen=True)
class VelocityCommand:
    """A planar velocity command: forward speed and yaw rate (REP-103, positive = left)."""

    linear_mps: float
    angular_radps: float


@dataclass(frozen=True)
class PathEstimate:
    """
    The line ahead of the robot, in the robot's frame (x forward, y left), from floor points.

    ``look_ahead_x_m`` and ``look_ahead_y_m`` are the point steered for; ``heading_rad`` is
    the direction of the line through the points (positive: to the left of the robot's
    heading); ``sharpest_curvature_per_m`` is the largest curvature of an arc from the robot
    to any of the points (positive: bending left), what the speed is planned for.
    """

    look_ahead_x_m: float
    look_ahead_y_m: float
    heading_rad: float
    sharpest_curvature_per_m: float

    @property
    def bearing_rad(self):
        """Return the direction of the look-ahead point from the robot's heading."""
        return math.atan2(self.look_ahead_y_m, self.look_ahead_x_m)

    @property
    def pursuit_curvature_per_m(self):
        """Return the curvature of the arc from the robot, tangent to it, to the point."""
        return pursuit_curvature(self.look_ahead_x_m, self.look_ahead_y_m)


def pursuit_curvature(x_m, y_m):
    """
    Return the curvature of the arc that leaves the robot straight ahead and reaches a point.

    This is pure pursuit: steering along it brings the robot onto a line through the point.
    On a circle of any radius that the robot already drives, the point ahead on the circle
    gives exactly the circle's curvature, so steady bends are followed without offset.

    :param x_m: forward coordinate of the point (array-like).
    :param y_m: leftward coordinate of the point (array-like).
    :return: curvature in 1/m, positive to the left.
    """
    return 2.0 * y_m / (x_m * x_m + y_m * y_m)


def _segment_point_at_distance(near, far, distance_m):
    """Return the point of the segment near-far at a distance from the origin between theirs."""
    step = far - near
    # |near + t * step| = distance: a quadratic in t with one root in [0, 1].
    a = float(step @ step)
    b = 2.0 * float(near @ step)
    c = float(near @ near) - distance_m * distance_m
    t = (-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)
    return near + min(max(t, 0.0), 1.0) * step


def estimate_path(floor_xy_m, look_ahead_m):
    """
    Find the point to steer for, and what lies ahead, from the floor points the bands saw.

    The look-ahead point is where the polyline through the points, nearest first, is
    ``look_ahead_m`` from the robot: the nearest point if all are farther, the farthest if
    all are nearer.

    :param floor_xy_m: (n, 2) array of floor points (x forward, y left, metres), nearest
        first, n >= 1, at distinct places.
    :param look_ahead_m: the distance from the robot of the point to steer for.
    :return: the PathEstimate.
    """
    points = np.asarray(floor_xy_m, dtype=float).reshape(-1, 2)
    distances_m = np.hypot(points[:, 0], points[:, 1])
    beyond = np.flatnonzero(distances_m >= look_ahead_m)
    if len(beyond) == 0:
        look_ahead = points[-1]
    elif beyond[0] == 0:
        look_ahead = points[0]
    else:
        look_ahead = _segment_point_at_distance(points[beyond[0] - 1], points[beyond[0]],
                                                look_ahead_m)
    if len(points) >= 2:
        # The principal direction of the points, pointing from the nearest to the farthest.
        centred = points - points.mean(axis=0)
        direction = np.linalg.svd(centred, full_matrices=False)[2][0]
        if np.dot(direction, points[-1] - points[0]) < 0.0:
            direction = -direction
        heading_rad = math.atan2(direction[1], direction[0])
    else:
        heading_rad = math.atan2(points[0, 1], points[0, 0])
    curvatures = pursuit_curvature(points[:, 0], points[:, 1])
    sharpest = float(curvatures[np.argmax(np.abs(curvatures))])
    return PathEstimate(float(look_ahead[0]), float(look_ahead[1]), heading_rad, sharpest)


def _check_number(name, value, minimum=0.0):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f'{name} must be a number, got {value!r}.')
    if not math.isfinite(value) or value < minimum:
        raise ValueError(f'{name} must be finite and at least {minimum:g}, got {value}.')


@dataclass(frozen=True)
class ControllerConfig:
    """
    Gains, limits and lost-line behaviour of the line-following controller.

    The defaults are followbot's path law, tuned on the scorecard. The book's law is
    ``steering_law='proportional'``, ``linear_speed_mps=0.2`` and ``angular_gain_radps=3.2``:
    w = -(cx - w/2) / 100 at a 640-pixel-wide image is 3.2 rad/s per unit of normalised error.
    """

    steering_law: str = 'path'
    linear_speed_mps: float = 0.7
    min_linear_speed_mps: float = 0.05
    angular_gain_radps: float = 3.2
    look_ahead_m: float = 0.4
    bearing_gain_radps: float = 3.0
    confidence_for_full_speed: float = 0.5
    max_lateral_acceleration_mps2: float = 0.6
    max_linear_acceleration_mps2: float = 1.0
    max_angular_acceleration_radps2: float = 8.0
    max_angular_speed_radps: float = 3.0
    frames_to_trust: int = 2
    line_memory_s: float = 0.3
    lost_line_behaviour: str = 'search'
    search_angular_speed_radps: float = 1.0
    stop_at_line_end: bool = True
    turn_side_offset_m: float = 0.1
    turn_side_memory_s: float = 1.5
    corner_search_angle_deg: float = 150.0
    corner_search_angular_speed_radps: float = 3.0
    line_end_stop_short_m: float = 0.1
    trail_length_m: float = 2.0
    trail_tolerance_m: float = 0.1

    def __post_init__(self):
        """Reject negative or non-finite numbers and unknown laws and behaviours."""
        for name in ('linear_speed_mps', 'min_linear_speed_mps', 'angular_gain_radps',
                     'look_ahead_m', 'bearing_gain_radps', 'max_angular_speed_radps',
                     'line_memory_s', 'search_angular_speed_radps', 'turn_side_offset_m',
                     'turn_side_memory_s', 'corner_search_angle_deg',
                     'corner_search_angular_speed_radps',
                     'line_end_stop_short_m', 'trail_length_m', 'trail_tolerance_m'):
            _check_number(name, getattr(self, name))
        for name in ('confidence_for_full_speed', 'max_lateral_acceleration_mps2',
                     'max_linear_acceleration_mps2',
                     'max_angular_acceleration_radps2'):
            _check_number(name, getattr(self, name), minimum=1e-3)
        if isinstance(self.frames_to_trust, bool) or not isinstance(self.frames_to_trust, int):
            raise TypeError(f'frames_to_trust must be an integer, got {self.frames_to_trust!r}.')
        if not isinstance(self.stop_at_line_end, bool):
            raise TypeError(f'stop_at_line_end must be a boolean, got {self.stop_at_line_end!r}.')
        if self.frames_to_trust < 1:
            raise ValueError(f'frames_to_trust must be at least 1, got {self.frames_to_trust}.')
        if self.min_linear_speed_mps > self.linear_speed_mps:
            raise ValueError(
                f'min_linear_speed_mps {self.min_linear_speed_mps} must not exceed '
                f'linear_speed_mps {self.linear_speed_mps}.')
        for name, value, allowed in (
                ('steering_law', self.steering_law, STEERING_LAWS),
                ('lost_line_behaviour', self.lost_line_behaviour, LOST_LINE_BEHAVIOURS)):
            if value not in allowed:
                raise ValueError(f'{name} must be one of {", ".join(allowed)}, got {value!r}.')


def _sign(value):
    """Return 1, -1 or 0, the sign of a number."""
    return (value > 0) - (value < 0)


def _clamp(value, low, high):
    return min(max(value, low), high)


def line_ends_in_view(detection):
    """
    Tell whether a detection shows the line ending ahead of the robot, in the camera's view.

    The line ends in view when some band saw it and every searched band beyond the farthest
    of those held no line-coloured pixel at all: bare floor where the line would go on. (A
    band that did not see the line reports all its line-coloured pixels as its area.) A line
    that runs out of the top of the view, or turns out of its side while its other part still
    shows in a band beyond, does not end in view.

    :param detection: a line_detector.Detection, its bands nearest first.
    :return: True when the line ends in view.
    """
    bands = detection.bands
    farthest_seen = max((index for index, band in enumerate(bands) if band.found), default=None)
    if farthest_seen is None:
        return False
    beyond = [band for band in bands[farthest_seen + 1:] if band.searched]
    return bool(beyond) and all(band.area_px == 0 for band in beyond)


def arc_pose(pose, linear_mps, angular_radps, dt_s):
    """
    Return where a planar pose ends after driving a twist for a while (an arc, or a line).

    :param pose: ``(x_m, y_m, yaw_rad)`` at the start.
    :param linear_mps: forward speed, held.
    :param angular_radps: yaw rate, held.
    :param dt_s: how long, in seconds (negative goes back along the same arc).
    :return: ``(x_m, y_m, yaw_rad)``, yaw in [-pi, pi].
    """
    x_m, y_m, yaw_rad = pose
    distance_m = linear_mps * dt_s
    turn_rad = angular_radps * dt_s
    if abs(turn_rad) < 1e-9:
        x_m += distance_m * math.cos(yaw_rad)
        y_m += distance_m * math.sin(yaw_rad)
    else:
        radius_m = distance_m / turn_rad
        x_m += radius_m * (math.sin(yaw_rad + turn_rad) - math.sin(yaw_rad))
        y_m -= radius_m * (math.cos(yaw_rad + turn_rad) - math.cos(yaw_rad))
    yaw_rad += turn_rad
    # An infinite turn (from absurd odometry) gives NaN, as the other figures do, not an error.
    return (x_m, y_m, math.remainder(yaw_rad, math.tau) if math.isfinite(yaw_rad) else math.nan)


def relative_pose(start, end):
    """
    Return a planar pose as seen from another: the move from ``start`` to ``end``.

    :param start: ``(x_m, y_m, yaw_rad)``.
    :param end: ``(x_m, y_m, yaw_rad)`` in the same frame.
    :return: ``(x_m, y_m, yaw_rad)`` of ``end`` in the frame of ``start``.
    """
    dx_m, dy_m = end[0] - start[0], end[1] - start[1]
    cos_yaw, sin_yaw = math.cos(start[2]), math.sin(start[2])
    return (cos_yaw * dx_m + sin_yaw * dy_m, -sin_yaw * dx_m + cos_yaw * dy_m,
            math.remainder(end[2] - start[2], math.tau))


def floor_points(pose, points_m):
    """
    Return points given in a robot's frame in the frame its pose is given in.

    :param pose: the robot's ``(x_m, y_m, yaw_rad)``.
    :param points_m: an (n, 2) array of (x forward, y left) points in the robot's frame.
    :return: an (n, 2) array.
    """
    x_m, y_m, yaw_rad = pose
    cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.stack((x_m + cos_yaw * points_m[:, 0] - sin_yaw * points_m[:, 1],
                     y_m + sin_yaw * points_m[:, 0] + cos_yaw * points_m[:, 1]), axis=1)


def compose_poses(pose, move):
    """
    Return where a planar pose ends after a move given in its own frame.

    :param pose: ``(x_m, y_m, yaw_rad)``.
    :param move: ``(x_m, y_m, yaw_rad)`` relative to ``pose``.
    :return: ``(x_m, y_m, yaw_rad)``, yaw in [-pi, pi].
    """
    cos_yaw, sin_yaw = math.cos(pose[2]), math.sin(pose[2])
    return (pose[0] + cos_yaw * move[0] - sin_yaw * move[1],
            pose[1] + sin_yaw * move[0] + cos_yaw * move[1],
            math.remainder(pose[2] + move[2], math.tau))


class RememberedRoute:
    """
    The floor points of the line last seen, kept where they lie as the robot moves on.

    The robot's pose is dead-reckoned, in a frame fixed to the floor where the controller
    started, from the change of a measured pose (wheel odometry) where one is given at two
    steps in a row, and otherwise from the commands it was given (each held until the next
    frame), which a real base follows only after a lag; the points are kept in that frame and
    given back in the robot's. A sighting is put on the floor only when the route is asked
    for: every frame that sees the line replaces it, and few are ever driven. The robot's own
    path (its trail) is kept too.
    """

    def __init__(self):
        """Make a route with no points, the robot at the origin."""
        self._pose = (0.0, 0.0, 0.0)
        # The pose measured at the last step (in the measuring frame), or None.
        self._measured_pose = None
        # Where the robot has been, oldest first, TRAIL_SPACING_M apart.
        self._trail = collections.deque([(0.0, 0.0)], maxlen=MAX_TRAIL_POINTS)
        # The last sighting as (pose, points in the robot's frame), until put on the floor.
        self._sighting = None
        self._points = np.empty((0, 2))

    def advance(self, command, dt_s, measured_pose=None):
        """
        Move the robot on: as measured, else by a command held for a while.

        :param command: the VelocityCommand the robot drove.
        :param dt_s: how long it drove it, in seconds.
        :param measured_pose: the robot's ``(x_m, y_m, yaw_rad)`` now in a frame of its own
            (odometry's), or None. The robot moves by the change since the last measured pose
            when there was one at the last step and the change is one a base can make in the
            time (ODOMETRY_JUMP_MPS, ODOMETRY_JUMP_RADPS); otherwise by the command, as an arc.
        """
        move = (relative_pose(self._measured_pose, measured_pose)
                if measured_pose is not None and self._measured_pose is not None else None)
        # Written so that a NaN fails it too.
        if move is not None and (math.hypot(move[0], move[1]) <= ODOMETRY_JUMP_MPS * dt_s
                                 and abs(move[2]) <= ODOMETRY_JUMP_RADPS * dt_s):
            self._pose = compose_poses(self._pose, move)
        else:
            self._pose = arc_pose(self._pose, command.linear_mps, command.angular_radps, dt_s)
        self._measured_pose = measured_pose
        last_x_m, last_y_m = self._trail[-1]
        if math.hypot(self._pose[0] - last_x_m, self._pose[1] - last_y_m) >= TRAIL_SPACING_M:
            self._trail.append(self._pose[:2])

    def on_trail(self, floor_xy_m, length_m, tolerance_m):
        """
        Tell whether a line lies where the robot has just been: the way it came.

        :param floor_xy_m: (n, 2) floor points of the line in the robot's frame.
        :param length_m: how much of the robot's latest path counts.
        :param tolerance_m: how near a point must be to that path to lie on it.
        :return: True when at least WAY_BACK_SHARE of the points lie on it.
        """
        count = min(len(self._trail), int(length_m / TRAIL_SPACING_M) + 1)
        points = np.asarray(floor_xy_m, dtype=float).reshape(-1, 2)
        if count < 2 or len(points) == 0 or tolerance_m <= 0.0:
            return False
        trail = np.array(self._trail)[-count:]
        on_floor = floor_points(self._pose, points)
        distances = np.hypot(on_floor[:, None, 0] - trail[None, :, 0],
                             on_floor[:, None, 1] - trail[None, :, 1]).min(axis=1)
        return bool(np.mean(distances <= tolerance_m) >= WAY_BACK_SHARE)

    def remember(self, floor_xy_m):
        """
        Keep these points as the route, in place of any before.

        :param floor_xy_m: (n, 2) floor points in the robot's frame (x forward, y left), in
            the order the line runs.
        """
        self._sighting = (self._pose, np.array(floor_xy_m, dtype=float).reshape(-1, 2))

    def forget(self):
        """Drop the route's points."""
        self._sighting = None
        self._points = np.empty((0, 2))

    def _floor_points(self):
        """Return the route's points in the floor frame, putting a new sighting there first."""
        if self._sighting is not None:
            self._points = floor_points(*self._sighting)
            self._sighting = None
        return self._points

    def ahead(self, stop_short_m):
        """
        Return the route's points still ahead, in the robot's frame, nearest first.

        Points the robot has come within ``stop_short_m`` of, or left behind it (in its own
        frame), and those before them, are dropped for good. So is the whole route once its
        end is within ``stop_short_m``.

        :param stop_short_m: how close counts as there.
        :return: an (n, 2) array, n >= 0.
        """
        points = self._floor_points()
        x_m, y_m, yaw_rad = self._pose
        cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
        dx_m, dy_m = points[:, 0] - x_m, points[:, 1] - y_m
        local = np.stack((cos_yaw * dx_m + sin_yaw * dy_m, -sin_yaw * dx_m + cos_yaw * dy_m),
                         axis=1)
        passed = (np.hypot(local[:, 0], local[:, 1]) <= stop_short_m) | (local[:, 0] <= 0.0)
        if len(local) and passed[-1]:
            self.forget()
            return self._points
        keep = np.flatnonzero(passed)[-1] + 1 if passed.any() else 0
        self._points = points[keep:]
        return local[keep:]


class LineFollowingController:
    """
    Steer along the detected line; coast through short gaps; stop or search when it is lost.

    Call :meth:`update` once per camera frame with the frame's time. The controller keeps
    its last command (for the acceleration limits and for coasting), the side on which the
    line was last seen (for searching), and the last PathEstimate (for the status topic).
    """

    def __init__(self, config=ControllerConfig()):
        """
        Make a controller that has not yet seen the line.

        :param config: gains, limits and lost-line behaviour.
        """
        self._config = config
        self.reset()

    @property
    def config(self):
        """Return the ControllerConfig this controller uses."""
        return self._config

    @config.setter
    def config(self, config):
        """Use new gains and limits from the next frame on, keeping what was seen."""
        self._config = config

    @property
    def state(self):
        """Return what it is doing: waiting, tracking, coasting, acquiring, lost, line end."""
        return self._state

    @property
    def coasting_along(self):
        """Return TO_LINE_END or ALONG_VANISHED_LINE while coasting along a route, else None."""
        return self._coasting_along

    @property
    def path_estimate(self):
        """Return the PathEstimate of the last frame that had one, or None."""
        return self._path_estimate

    @property
    def last_command(self):
        """Return the last command returned by :meth:`update`."""
        return self._command

    @staticmethod
    def stop_command():
        """Return the command that stops the robot: zero linear and angular velocity."""
        return VelocityCommand(linear_mps=0.0, angular_radps=0.0)

    def reset(self):
        """Forget everything seen and commanded, as if just started."""
        self._state = STATE_WAITING
        self._last_side = 0
        self._turn_side = 0
        self._turn_seen_s = -math.inf
        self._corner_search_turned_rad = self._corner_search_net_rad = 0.0
        self._seen_streak = 0
        self._last_seen_s = -math.inf
        self._end_in_view = False
        self._left_at_side = False
        self._coasting_along = None
        self._time_s = None
        self._command = self.stop_command()
        self._path_estimate = None
        self._route = RememberedRoute()

    def update(self, detection, time_s, floor_xy_m=None, odometry_pose=None):
        """
        Return the velocity command for one camera frame.

        :param detection: a line_detector.Detection of the frame.
        :param time_s: the frame's time in seconds (its stamp), for the acceleration limits
            and the line memory.
        :param floor_xy_m: for the 'path' law, an (n, 2) array of the floor points (x forward,
            y left, metres) of the n bands that saw the line, nearest first; None when the
            camera geometry is not known yet; the 'path' law treats None or no points as no
            line.
        :param odometry_pose: the robot's ``(x_m, y_m, yaw_rad)`` at the frame's time in the
            frame of its wheel odometry, or None: where it is given for this frame and the
            last, the route last seen is driven by it rather than by the commands.
        :return: a VelocityCommand. Without a trusted line the linear speed is never
            positive except while coasting through a short gap on the last command.
        """
        config = self._config
        dt_s = (0.0 if self._time_s is None
                else _clamp(time_s - self._time_s, 0.0, MAX_TIME_STEP_S))
        if self._time_s is not None and time_s < self._time_s:
            # Time went backwards (a restarted simulation, a looped bag): what was seen
            # before is not recent, nor where it was.
            self._last_seen_s = -math.inf
            self._route = RememberedRoute()
        self._route.advance(self._command, dt_s, odometry_pose)
        self._time_s = time_s
        self._coasting_along = None
        target = None
        seen = detection.found and (config.steering_law == 'proportional'
                                    or (floor_xy_m is not None and len(floor_xy_m) > 0))
        if seen and config.steering_law == 'path' and self._state in (
                STATE_ACQUIRING, STATE_LOST, STATE_LINE_END):
            # Searching, a line along the robot's own path is the way back: not taken.
            seen = not self._route.on_trail(floor_xy_m, config.trail_length_m,
                                            config.trail_tolerance_m)
        if seen:
            self._seen_streak += 1
            trusted = (self._state in (STATE_TRACKING, STATE_COASTING)
                       or self._seen_streak >= config.frames_to_trust)
            if trusted:
                target = (self._proportional_target(detection)
                          if config.steering_law == 'proportional'
                          else self._path_target(floor_xy_m, detection.confidence))
                self._state = STATE_TRACKING
                self._last_seen_s = time_s
                self._end_in_view = line_ends_in_view(detection)
                self._left_at_side = detection.seen_bands[-1].at_side
                if config.steering_law == 'path':
                    self._route.remember(floor_xy_m)
                self._last_side = _sign(target.angular_radps) or self._last_side
                self._remember_turn_side(floor_xy_m, time_s)
                self._corner_search_turned_rad = self._corner_search_net_rad = 0.0
            else:
                self._state = STATE_ACQUIRING
        else:
            self._seen_streak = 0
            following = self._state in (STATE_TRACKING, STATE_COASTING)
            # The line is where it was last seen unless it left at the image's side (a square
            # corner seen from before it): it ended there inside the view, or ran on out of
            # the view's top and then vanished at once (glare, worn paint).
            on_route = (following and config.steering_law == 'path'
                        and not self._left_at_side)
            to_end = on_route and config.stop_at_line_end and self._end_in_view
            runs_on = (on_route and not self._end_in_view
                       and config.lost_line_behaviour == 'search')
            route = (self._route.ahead(config.line_end_stop_short_m) if to_end or runs_on
                     else ())
            if len(route):
                # Seen ending ahead, or running on: on along the points seen last.
                self._state = STATE_COASTING
                self._coasting_along = TO_LINE_END if to_end else ALONG_VANISHED_LINE
                target = self._path_target(route, 1.0, route_end=True)
            elif (following and not to_end
                    and time_s - self._last_seen_s <= config.line_memory_s):
                self._state = STATE_COASTING
                target = self._command
            elif config.stop_at_line_end and (
                    self._state == STATE_LINE_END
                    or (self._state in (STATE_TRACKING, STATE_COASTING) and self._end_in_view)):
                # It ended where the robot saw it end: driving on or turning to search would
                # leave the line's end.
                self._state = STATE_LINE_END
            elif self._state != STATE_WAITING or detection.bands:
                self._state = STATE_LOST
        if target is None:
            target = self._lost_line_target(dt_s)
        self._command = self._limit(target, dt_s)
        return self._command

    def _proportional_target(self, detection):
        config = self._config
        self._path_estimate = None
        return VelocityCommand(config.linear_speed_mps,
                               -config.angular_gain_radps * detection.error)

    def _path_target(self, floor_xy_m, confidence, route_end=False):
        config = self._config
        estimate = estimate_path(floor_xy_m, config.look_ahead_m)
        self._path_estimate = estimate
        steering_per_m = estimate.pursuit_curvature_per_m
        # Full speed while enough of the bands see the line; slower as fewer do.
        speed_mps = config.linear_speed_mps * min(
            1.0, confidence / config.confidence_for_full_speed)
        if route_end:
            # No faster than when the line was last seen, and slow enough to stop at the
            # route's end within the acceleration limit.
            remaining_m = max(float(np.hypot(*floor_xy_m[-1])) - config.line_end_stop_short_m,
                              0.0)
            speed_mps = min(speed_mps, self._command.linear_mps, math.sqrt(
                2.0 * config.max_linear_acceleration_mps2 * remaining_m))
        bend_per_m = max(abs(estimate.sharpest_curvature_per_m), abs(steering_per_m))
        if bend_per_m > 0.0:
            speed_mps = min(speed_mps,
                            math.sqrt(config.max_lateral_acceleration_mps2 / bend_per_m),
                            config.max_angular_speed_radps / bend_per_m)
        speed_mps = max(speed_mps, config.min_linear_speed_mps)
        angular_radps = speed_mps * steering_per_m
        # A point far to the side (a sharp corner) is turned to at once, not on a wide arc
        # that would lose it from the camera's view.
        pivot_radps = config.bearing_gain_radps * estimate.bearing_rad
        if abs(pivot_radps) > abs(angular_radps):
            angular_radps = pivot_radps
            speed_mps = max(min(speed_mps,
                                config.max_lateral_acceleration_mps2 / abs(angular_radps)),
                            config.min_linear_speed_mps)
        return VelocityCommand(speed_mps, angular_radps)

    def _remember_turn_side(self, floor_xy_m, time_s):
        """Note the side the line turns away to, where the farthest band sees it aside."""
        if self._config.steering_law != 'path' or floor_xy_m is None or len(floor_xy_m) == 0:
            return
        farthest_y_m = float(floor_xy_m[-1][1])
        if abs(farthest_y_m) >= max(self._config.turn_side_offset_m, 1e-9):
            self._turn_side = _sign(farthest_y_m)
            self._turn_seen_s = time_s

    def _recent_turn_side(self):
        """Return the side the line turned away to just before it was lost, or 0."""
        if self._last_seen_s - self._turn_seen_s <= self._config.turn_side_memory_s:
            return self._turn_side
        return 0

    def _lost_line_target(self, dt_s):
        config = self._config
        turn_side = self._recent_turn_side()
        if config.lost_line_behaviour == 'search' and self._state == STATE_LINE_END and turn_side:
            # The line that ended right after turning away to a side may go on round a corner
            # sharper than the camera can see: look there once, then turn back to face where
            # it ended (something may stand on it there), and stand still.
            self._corner_search_turned_rad += abs(self._command.angular_radps) * dt_s
            self._corner_search_net_rad += turn_side * self._command.angular_radps * dt_s
            speed_radps = config.corner_search_angular_speed_radps
            if self._corner_search_turned_rad < math.radians(config.corner_search_angle_deg):
                return VelocityCommand(0.0, turn_side * speed_radps)
            if self._corner_search_net_rad > FACING_TOLERANCE_RAD:
                # Slowing within the acceleration limit to stop facing where it ended: a
                # frame at this rate, then braking, covers what is left.
                net_rad = self._corner_search_net_rad
                braking = config.max_angular_acceleration_radps2
                return VelocityCommand(0.0, -turn_side * min(speed_radps, braking * (
                    math.sqrt(dt_s * dt_s + 2.0 * net_rad / braking) - dt_s)))
        if (config.lost_line_behaviour == 'stop'
                or self._state in (STATE_WAITING, STATE_LINE_END)):
            return self.stop_command()
        # Towards the side the line turned away to, else the side it was last steered to
        # (which can point back along the line the robot came by); left when it has no side.
        direction = turn_side or self._last_side or 1
        return VelocityCommand(0.0, direction * config.search_angular_speed_radps)

    def _limit(self, target, dt_s):
        config = self._config
        previous = self._command
        linear_step = config.max_linear_acceleration_mps2 * dt_s
        angular_step = config.max_angular_acceleration_radps2 * dt_s
        linear_mps = _clamp(target.linear_mps, previous.linear_mps - linear_step,
                            previous.linear_mps + linear_step)
        if target.linear_mps == 0.0:
            # Stopping for a lost line is not delayed by the acceleration limit: driving on
            # blind is worse than a hard stop.
            linear_mps = 0.0
        angular_radps = _clamp(target.angular_radps, previous.angular_radps - angular_step,
                               previous.angular_radps + angular_step)
        limit = config.max_angular_speed_radps
        return VelocityCommand(linear_mps, _clamp(angular_radps, -limit, limit))
