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
