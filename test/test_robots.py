"""
Several robots in one MuJoCo world: names, placement, independent driving and real collisions.

The world is pure (no ROS): these tests drive it directly, as the simulator node does.
"""

import math

from followbot.frames import BASE_LINK_FRAME, CAMERA_RGB_OPTICAL_FRAME
from followbot_sim.course import Course, make_course
from followbot_sim.robots import (DEFAULT_ROBOT_SPACING_M, MAX_ROBOTS, robot_names, robot_prefix,
                                  SINGLE_ROBOT, start_arc_lengths_m)
from followbot_sim.world import FollowbotWorld
import mujoco
import numpy as np
import pytest

# A straight start: the robots stand in a row on the bottom side, heading east.
RECTANGLE_LOOP_XY = [(0.0, -3.0), (4.0, -3.0), (4.0, 3.0), (-4.0, 3.0), (-4.0, -3.0)]
SMALL_IMAGE_PX = (64, 48)
SMALL_TEXTURE_PX = 256
KOBUKI_DIAMETER_M = 0.35
RAM_SPEED_MPS = 0.3
RAM_S = 6.0
CONTROL_PERIOD_S = 0.05
# Steering gain towards the robot ahead (rad/s per rad of bearing error).
PURSUIT_GAIN = 2.0
DRIVE_S = 2.0


@pytest.fixture(scope='module')
def rectangle_course():
    return Course(RECTANGLE_LOOP_XY, name='rectangle')


@pytest.fixture
def two_robots(rectangle_course):
    world = FollowbotWorld(rectangle_course, *SMALL_IMAGE_PX, texture_size_px=SMALL_TEXTURE_PX,
                           robot_names=robot_names(2))
    yield world
    world.close()


@pytest.mark.parametrize('setting, names', [
    (1, (SINGLE_ROBOT,)),
    (2, ('r1', 'r2')),
    (3, ('r1', 'r2', 'r3')),
    (['alpha', 'beta_2'], ('alpha', 'beta_2')),
    (['solo'], ('solo',)),
])
def test_robot_names_from_a_count_or_a_list(setting, names):
    assert robot_names(setting) == names


@pytest.mark.parametrize('setting', [
    0, MAX_ROBOTS + 1, -1, True, [], ['r1', 'r1'], ['2fast'], ['with/slash'], [''], 'r1,r2',
])
def test_bad_robot_settings_are_refused_with_a_sentence(setting):
    with pytest.raises(ValueError, match='(?i)robot'):
        robot_names(setting)


def test_named_robots_are_prefixed_and_the_single_one_is_not():
    assert robot_prefix(SINGLE_ROBOT) == ''
    assert robot_prefix('r2') == 'r2/'


def test_robots_start_one_behind_the_other():
    assert start_arc_lengths_m(3, 1.5) == [0.0, -1.5, -3.0]
    with pytest.raises(ValueError, match='spacing'):
        start_arc_lengths_m(2, 0.2)


def test_too_many_robots_for_the_course_are_refused():
    with pytest.raises(ValueError, match='do not fit'):
        FollowbotWorld(make_course('book_loop'), *SMALL_IMAGE_PX,
                       texture_size_px=SMALL_TEXTURE_PX, robot_names=robot_names(8),
                       robot_spacing_m=3.0)


def test_each_robot_has_its_own_prefixed_model_and_frames(two_robots):
    model = two_robots.model
    assert model.nu == 4
    assert {model.camera(index).name for index in range(model.ncam)} >= {
        'r1/camera_rgb', 'r2/camera_depth'}
    frames_r2 = two_robots.sensor_frames(1)
    assert (frames_r2[0].parent, frames_r2[0].child) == ('r2/base_footprint',
                                                         'r2/' + BASE_LINK_FRAME)
    assert 'r2/' + CAMERA_RGB_OPTICAL_FRAME in {transform.child for transform in frames_r2}


def test_robots_start_on_the_line_a_spacing_apart(two_robots):
    (x1, y1, yaw1), (x2, y2, yaw2) = two_robots.robot_pose(0), two_robots.robot_pose(1)
    assert (x1, y1) == pytest.approx((0.0, -3.0), abs=1e-6)
    assert (x2, y2) == pytest.approx((-DEFAULT_ROBOT_SPACING_M, -3.0), abs=1e-6)
    assert yaw1 == pytest.approx(0.0, abs=1e-6)
    assert yaw2 == pytest.approx(0.0, abs=1e-6)


def test_each_robot_obeys_only_its_own_command(two_robots):
    two_robots.set_twist(RAM_SPEED_MPS, 0.0, robot=1)
    two_robots.step(DRIVE_S)
    assert two_robots.robot_twist(1)[0] == pytest.approx(RAM_SPEED_MPS, rel=0.03)
    assert abs(two_robots.robot_twist(0)[0]) < 0.01
    assert two_robots.wheel_angles(0) == pytest.approx((0.0, 0.0), abs=1e-3)
    assert min(two_robots.wheel_angles(1)) > 1.0


def test_each_robot_sees_from_its_own_camera(two_robots):
    first = two_robots.render_camera(0).copy()
    second = two_robots.render_camera(1)
    assert not np.array_equal(first, second)


def test_a_robot_driven_into_another_cannot_pass_through_it_and_pushes_it(two_robots):
    # The rear robot (r2) steers at the front one (r1, standing still) and drives on: without
    # contact it would pass through it; with contact it stops at its shell and shoves it.
    closest_m = math.inf
    start_x1_m = two_robots.robot_pose(0)[0]
    for _ in range(round(RAM_S / CONTROL_PERIOD_S)):
        x1, y1, _ = two_robots.robot_pose(0)
        x2, y2, yaw2 = two_robots.robot_pose(1)
        bearing_rad = math.atan2(y1 - y2, x1 - x2)
        error_rad = math.atan2(math.sin(bearing_rad - yaw2), math.cos(bearing_rad - yaw2))
        two_robots.set_twist(RAM_SPEED_MPS, PURSUIT_GAIN * error_rad, robot=1)
        two_robots.step(CONTROL_PERIOD_S)
        closest_m = min(closest_m, math.hypot(x1 - x2, y1 - y2))
    assert closest_m > KOBUKI_DIAMETER_M - 0.02
    assert closest_m < KOBUKI_DIAMETER_M + 0.05
    # The only thing that moves r1, whose wheels hold still, is r2 pushing its shell.
    assert two_robots.robot_pose(0)[0] > start_x1_m + 0.05
    contacts = {frozenset((two_robots.model.geom(contact.geom1).name,
                           two_robots.model.geom(contact.geom2).name))
                for contact in two_robots.data.contact[:two_robots.data.ncon]}
    assert frozenset(('r1/kobuki_shell', 'r2/kobuki_shell')) in contacts


def test_two_robot_world_steps_without_warnings(two_robots):
    two_robots.set_twist(0.3, 0.5, robot=0)
    two_robots.set_twist(0.3, -0.5, robot=1)
    two_robots.step(1.0)
    assert all(two_robots.data.warning[index].number == 0
               for index in range(mujoco.mjtWarning.mjNWARNING))
