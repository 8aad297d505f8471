"""
Several robots in one world: their names, the prefix of their names in MuJoCo, ROS and /tf.

No ROS or MuJoCo import. One robot alone has the empty name: its model elements, topics and
frames keep their plain names (``base_footprint``, ``camera/rgb/image_raw``). Named robots are
prefixed: ``r1/base_footprint`` in the model and on /tf, ``r1/camera/rgb/image_raw`` under the
simulator's namespace, the same names a single robot gets under ``-r __ns:=/r1``.
"""

import math
import re

# The one unnamed robot of a single-robot world.
SINGLE_ROBOT = ''
# Names given by a robot count: r1, r2, ...
COUNTED_ROBOT_NAME = 'r{}'
MAX_ROBOTS = 8
# A ROS name token: what may stand between slashes in a topic or namespace.
ROBOT_NAME_PATTERN = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
# Centre to centre along the line: a Kobuki is 0.35 m across, so 1 m leaves 0.65 m between
# bumpers, and the robot behind does not see the one ahead in its band (~0.45 m ahead).
DEFAULT_ROBOT_SPACING_M = 1.0
# Closer than this, two Kobukis (0.35 m across) would start overlapping or touching.
MIN_ROBOT_SPACING_M = 0.4


def robot_names(robots) -> tuple[str, ...]:
    """
    Turn the simulator's ``robots`` setting into robot names.

    :param robots: a count (1 is today's single, unnamed robot; N > 1 gives r1..rN) or a
        sequence of names (each a ROS name token, no two alike).
    :return: the names, in order; ``(SINGLE_ROBOT,)`` for one unnamed robot.
    :raises ValueError: for a count outside 1..MAX_ROBOTS, an empty list, a name that is not a
        ROS name token, or a name given twice.
    """
    if isinstance(robots, bool):
        raise ValueError(f'robots must be a count or a list of names, got {robots!r}.')
    if isinstance(robots, int):
        if not 1 <= robots <= MAX_ROBOTS:
            raise ValueError(f'robots must be a count in 1..{MAX_ROBOTS}, got {robots}.')
        if robots == 1:
            return (SINGLE_ROBOT,)
        return tuple(COUNTED_ROBOT_NAME.format(number) for number in range(1, robots + 1))
    if isinstance(robots, str):
        raise ValueError(f'robots must be a count or a list of names such as [r1,r2], '
                         f'got the text {robots!r}.')
    names = tuple(robots)
    if not 1 <= len(names) <= MAX_ROBOTS:
        raise ValueError(f'robots must name 1..{MAX_ROBOTS} robots, got {len(names)}.')
    for name in names:
        if not isinstance(name, str) or not ROBOT_NAME_PATTERN.fullmatch(name):
            raise ValueError(f'Robot name {name!r} is not a ROS name token (a letter, then '
                             'letters, digits or underscores).')
    if len(set(names)) != len(names):
        raise ValueError(f'Robot names must differ, got {list(names)}.')
    return names


def robot_prefix(name: str) -> str:
    """
    Return the prefix of a robot's model elements, topics and frames.

    :param name: the robot's name; ``SINGLE_ROBOT`` for the unnamed robot.
    :return: ``'<name>/'``, or ``''`` for the unnamed robot.
    """
    return f'{name}/' if name else ''


def start_arc_lengths_m(robot_count: int, spacing_m: float) -> list[float]:
    """
    Return where along the course each robot starts: the first at the start, each next behind.

    :param robot_count: how many robots.
    :param spacing_m: centre-to-centre distance along the line in metres.
    :return: arc lengths in metres (0, -spacing, -2 spacing, ...), taken modulo the course
        length by :meth:`followbot_sim.course.Course.point_at`.
    :raises ValueError: for spacing below ``MIN_ROBOT_SPACING_M`` or not finite.
    """
    if not (math.isfinite(spacing_m) and spacing_m >= MIN_ROBOT_SPACING_M):
        raise ValueError(f'Robot spacing must be at least {MIN_ROBOT_SPACING_M} m (a Kobuki '
                         f'is 0.35 m across), got {spacing_m}.')
    return [-index * spacing_m for index in range(robot_count)]
