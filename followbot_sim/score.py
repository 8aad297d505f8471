"""The simulator's node name, and its ground-truth score as it travels on ``/diagnostics``."""

# The simulator node's own name (a namespace or a rename may be added on the command line).
SIMULATOR_NODE = 'followbot_sim'

# A score's status is named '<simulator node>: course score'; its hardware_id is the node.
SCORE_STATUS_SUFFIX = ': course score'


def score_status_name(simulator: str) -> str:
    """
    Return the status name of a simulator's score.

    :param simulator: the simulator node's fully qualified name, such as /r1/followbot_sim.
    :return: the name, such as '/r1/followbot_sim: course score'.
    """
    return simulator + SCORE_STATUS_SUFFIX


def robot_simulator_name(simulator: str, robot: str) -> str:
    """
    Return the name a simulator's robot is scored under: the simulator's, in its namespace.

    A robot named r1 in the simulator /followbot_sim is scored as /r1/followbot_sim: the name
    a single robot gets from a simulator started under ``-r __ns:=/r1``, so a monitor looks
    for the same name however the robots were started.

    :param simulator: the simulator node's fully qualified name, such as /followbot_sim.
    :param robot: the robot's name; empty for a simulator's single, unnamed robot.
    :return: the scored name, such as /r1/followbot_sim (the simulator's own for no name).
    """
    if not robot:
        return simulator
    namespace, _, node_name = simulator.rpartition('/')
    return f'{namespace}/{robot}/{node_name}'


def score_values(diagnostics, simulator: str | None = None) -> dict | None:
    """
    Return a simulator's score in a ``diagnostic_msgs/DiagnosticArray``, if it holds it.

    :param diagnostics: a message from ``/diagnostics``.
    :param simulator: the fully qualified name of the simulator whose score is wanted; any
        simulator's when None.
    :return: the score's key -> text values (``time_s``, ``laps_completed``, ...), or None
        when the message carries no score (of that simulator).
    """
    for status in diagnostics.status:
        if not status.name.endswith(SCORE_STATUS_SUFFIX):
            continue
        if simulator is None or status.hardware_id == simulator:
            return {value.key: value.value for value in status.values}
    return None
