"""The path the robot drove, as the overview draws it: points a centimetre apart, bounded."""

import collections
import math

# A point a centimetre draws the same path as the 100 poses a second the simulator scores.
TRAIL_SPACING_M = 0.01
# The last 200 m driven (a few laps): an endless run keeps constant memory.
TRAIL_MAX_POINTS = 20_000


class Trail:
    """The last ``max_points`` places the robot passed, ``spacing_m`` or more apart."""

    def __init__(self, spacing_m: float = TRAIL_SPACING_M, max_points: int = TRAIL_MAX_POINTS):
        """
        Start an empty trail.

        :param spacing_m: least distance between two kept points.
        :param max_points: most points kept; the oldest go first.
        """
        self._spacing_m = spacing_m
        self._points = collections.deque(maxlen=max_points)

    def add(self, x_m: float, y_m: float) -> None:
        """
        Add the robot's position, unless it is within the spacing of the last point kept.

        :param x_m: x on the floor.
        :param y_m: y on the floor.
        """
        if self._points:
            last_x_m, last_y_m = self._points[-1]
            if math.hypot(x_m - last_x_m, y_m - last_y_m) < self._spacing_m:
                return
        self._points.append((x_m, y_m))

    def clear(self) -> None:
        """Forget every point."""
        self._points.clear()

    @property
    def points(self) -> list:
        """Return the kept points, oldest first, as (x, y) pairs."""
        return list(self._points)

    def __len__(self) -> int:
        """Return how many points are kept."""
        return len(self._points)
