"""
The default follower on issue 14's harder courses, simulator and follower in one executor.

Both nodes run in this process on a private Context over real DDS topics, driven by the
scorecard's runner; the simulator's ground truth (its LapTracker) judges the run. "Leaving the
line" here means the robot's reference point (``base_footprint``, the centre between the
wheels) getting farther from the centre line than half the 0.19 m line width plus 0.05 m.
"""

from followbot.controller import ControllerConfig
from followbot_sim.course import make_course
from followbot_sim.scorecard import END_LAP, END_LINE_END, run_scenario, Scenario

# Room for a lap at the default cruising speed, slower in bends, before the test gives up.
LAP_TIME_MARGIN = 1.6
# How far the robot's centre may stray from the centre line and still be on the painted line:
# half the line's width plus what the robot's footprint over it tolerates.
ROBOT_TOLERANCE_M = 0.05
# A robot that stops at a line end stands still from then on: a few seconds show it.
STUCK_AFTER_S = 5.0
LINE_END_TIME_LIMIT_S = 40.0


def lap(context, name: str) -> dict:
    """Run the default follower on a built-in course until a lap, and return its figures."""
    course = make_course(name)
    time_limit_s = LAP_TIME_MARGIN * course.length_m / ControllerConfig().linear_speed_mps
    run = run_scenario(context, Scenario(name, name), time_limit_s=time_limit_s,
                       stuck_after_s=STUCK_AFTER_S)
    assert run['end_reason'] == END_LAP, run
    return {**run['lap_tracker'], **run['line_statistics']}


def assert_stayed_on_the_line(summary: dict) -> None:
    """Check the robot's centre never left the painted line (see the module docstring)."""
    course = make_course(summary['course'])
    assert summary['laps_completed'] >= 1, summary
    assert summary['max_distance_from_line_m'] <= (
        course.line_width_m / 2.0 + ROBOT_TOLERANCE_M), summary


def test_follower_drives_straight_past_t_junctions(ros_context):
    summary = lap(ros_context, 't_junction')
    assert_stayed_on_the_line(summary)
    # The stubs do not pull the robot off: it stays over the line itself all the way.
    assert summary['time_off_line_s'] == 0.0, summary
    assert summary['arc_jumps'] == 0, summary


def test_follower_stops_at_the_end_of_a_line(ros_context):
    course = make_course('line_end')
    run = run_scenario(ros_context, Scenario('line_end', 'line_end'),
                       time_limit_s=LINE_END_TIME_LIMIT_S, stuck_after_s=STUCK_AFTER_S)
    # Standing still on the paint just before its end, not turning to search nor driving off.
    assert run['end_reason'] == END_LINE_END, run
    summary = run['lap_tracker']
    assert summary['progress_m'] <= course.painted_interval_m[1], summary
    assert summary['max_distance_from_line_m'] <= course.line_width_m / 2.0, summary


def test_follower_laps_hairpins(ros_context):
    assert_stayed_on_the_line(lap(ros_context, 'hairpins'))


def test_follower_laps_sharp_corners(ros_context):
    assert_stayed_on_the_line(lap(ros_context, 'sharp_corners'))
