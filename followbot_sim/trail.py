"""The path the robot drove, as the overview draws it: points a centimetre apart, bounded."""

import math

import numpy as np

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
        # A ring buffer allocated and written once (320 kB for the default): resident memory
        # does not creep up while the trail fills, as a deque of tuples' did by ~2 MB over the
        # first minutes, so a soak sees flat memory from the start.
        self._xy = np.full((max_points, 2), np.nan)
        self._oldest = 0
        self._count = 0

    def add(self, x_m: float, y_m: float) -> None:
        """
        Add the robot's position, unless it is within the spacing of the last point kept.

        :param x_m: x on the floor.
        :param y_m: y on the floor.
        """
        capacity = len(self._xy)
        if self._count:
            last_x_m, last_y_m = self._xy[(self._oldest + self._count - 1) % capacity]
            if math.hypot(x_m - last_x_m, y_m - last_y_m) < self._spacing_m:
                return
        if self._count < capacity:
            self._xy[(self._oldest + self._count) % capacity] = (x_m, y_m)
            self._count += 1
        else:
            self._xy[self._oldest] = (x_m, y_m)
            self._oldest = (self._oldest + 1) % capacity

    def clear(self) -> None:
        """Forget every point."""
        self._oldest = 0
        self._count = 0

    @property
    def points(self) -> list:
        """Return the kept points, oldest first, as (x, y) pairs."""
        order = (self._oldest + np.arange(self._count)) % len(self._xy)
        return [tuple(point) for point in self._xy[order].tolist()]

    def __len__(self) -> int:
        """Return how many points are kept."""
        return self._count
