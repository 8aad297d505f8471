"""
The simulator node and the follower node lap a course in one executor.

Both nodes run in this process on a private Context, talking over real DDS topics exactly as
they do in two processes, driven by the scorecard's runner. The simulator's ground truth (its
LapTracker) judges the run.
"""

import cv2
from followbot.controller import ControllerConfig
from followbot_sim.course import FLOOR_GREY, LINE_RGB, make_course
from followbot_sim.course_file import load_course
from followbot_sim.scorecard import END_LAP, run_scenario, Scenario
import numpy as np
import pytest

# The robot's centre must stay over the painted line, within half its 0.19 m width of the centre
# line, for the whole lap: what a person watching calls "following the line".
# Room for a lap at the default cruising speed, slower in bends, before the test gives up.
LAP_TIME_MARGIN = 1.6
# Issue 4's targets for the default follower on the book-like course (simulated time).
TARGET_LAP_TIME_S = 35.0
TARGET_RMS_DISTANCE_M = 0.03
TARGET_MAX_DISTANCE_M = 0.10
# The book's course.png: 1024 px for the 10 m floor, two colours, no anti-aliasing.
BOOK_IMAGE_SIZE_PX = 1024
PAINT_THRESHOLD = 0.5


def lap(context, course: str, sim_parameters=()) -> tuple:
    """
    Run the default follower on a course until it completes a lap.

    :param sim_parameters: further (name, value) simulator parameters.
    :return: the score (the simulator's LapTracker summary and the follower's line
        statistics, and the ``camera`` the simulator rendered) and the course.
    """
    course_model = load_course(course)
    time_limit_s = (LAP_TIME_MARGIN * course_model.length_m
                    / ControllerConfig().linear_speed_mps)
    run = run_scenario(context, Scenario(course, course), sim_parameters,
                       time_limit_s=time_limit_s)
    assert run['end_reason'] == END_LAP, run
    return {**run['lap_tracker'], **run['line_statistics'], 'camera': run['camera']}, course_model


def assert_followed_the_line(summary: dict, course) -> None:
    """Check a lap was completed with the robot's centre over the painted line throughout."""
    assert summary['laps_completed'] >= 1, summary
    assert summary['max_distance_from_line_m'] <= course.line_width_m / 2.0, summary
    assert summary['time_off_line_s'] == 0.0, summary


@pytest.mark.parametrize('image_size_px', ((640, 480), (320, 240)), ids=('640x480', '320x240'))
def test_follower_laps_the_default_course(ros_context, image_size_px):
    # Nothing in the follower's configuration depends on the camera's resolution: a 320x240
    # camera (a TurtleBot3's, many USB cameras) needs no other parameters.
    width_px, height_px = image_size_px
    summary, course = lap(ros_context, 'book_loop',
                          (('image_width_px', width_px), ('image_height_px', height_px)))
    assert (summary['camera']['width_px'], summary['camera']['height_px']) == image_size_px
    assert_followed_the_line(summary, course)
    assert summary['lap_times_s'][0] <= TARGET_LAP_TIME_S, summary
    assert summary['rms_distance_from_line_m'] <= TARGET_RMS_DISTANCE_M, summary
    assert summary['max_distance_from_line_m'] <= TARGET_MAX_DISTANCE_M, summary
    assert summary['frames_line_lost'] == 0, summary


def test_follower_laps_a_course_drawn_in_a_png_file(ros_context, tmp_path):
    # A floor image made the way the book's course.png is: RGBA, yellow on grey 116, hard edges.
    reference = make_course('book_loop')
    texture = reference.draw_texture(BOOK_IMAGE_SIZE_PX).astype(float)
    painted = (texture[..., 0] - FLOOR_GREY) / (LINE_RGB[0] - FLOOR_GREY) > PAINT_THRESHOLD
    image_rgba = np.full((BOOK_IMAGE_SIZE_PX, BOOK_IMAGE_SIZE_PX, 4), 255, np.uint8)
    image_rgba[..., :3] = FLOOR_GREY
    image_rgba[painted, :3] = LINE_RGB
    cv2.imwrite(str(tmp_path / 'course.png'), cv2.cvtColor(image_rgba, cv2.COLOR_RGBA2BGRA))
    x_m, y_m, yaw_rad = reference.start_pose()
    (tmp_path / 'course.yaml').write_text(
        'floor_size_m: 10.0\n'
        f'image: {{file: course.png, start: [{x_m}, {y_m}, {np.degrees(yaw_rad)}]}}\n')

    summary, course = lap(ros_context, str(tmp_path / 'course.yaml'))
    # The centre line traced from the paint is the one the image was drawn from.
    assert abs(course.length_m - reference.length_m) < 0.01 * reference.length_m
    assert_followed_the_line(summary, course)
