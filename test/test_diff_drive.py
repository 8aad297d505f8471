"""Tests of the Kobuki differential-drive kinematics and the command watchdog."""

import math

from followbot_sim.diff_drive import body_twist
from followbot_sim.diff_drive import CommandWatchdog
from followbot_sim.diff_drive import DiffDriveLimits
from followbot_sim.diff_drive import KOBUKI_COMMAND_TIMEOUT_S
from followbot_sim.diff_drive import KOBUKI_MAX_ANGULAR_SPEED_RADPS
from followbot_sim.diff_drive import KOBUKI_MAX_LINEAR_SPEED_MPS
from followbot_sim.diff_drive import KOBUKI_WHEEL_RADIUS_M
from followbot_sim.diff_drive import KOBUKI_WHEEL_SEPARATION_M
from followbot_sim.diff_drive import wheel_speeds_radps
import pytest

KOBUKI = DiffDriveLimits()
RADIUS_M = KOBUKI_WHEEL_RADIUS_M
HALF_TRACK_M = KOBUKI_WHEEL_SEPARATION_M / 2.0
# 0.7 m/s on 0.035 m wheels.
MAX_WHEEL_RADPS = 20.0
TOLERANCE = 1e-9


@pytest.mark.parametrize('linear_mps, angular_radps, expected_radps', [
    (0.0, 0.0, (0.0, 0.0)),
    (0.35, 0.0, (10.0, 10.0)),
    (-0.35, 0.0, (-10.0, -10.0)),
    # REP-103: positive yaw rate turns left, so the right wheel rolls forward.
    (0.0, 1.0, (-HALF_TRACK_M / RADIUS_M, HALF_TRACK_M / RADIUS_M)),
    (0.0, -1.0, (HALF_TRACK_M / RADIUS_M, -HALF_TRACK_M / RADIUS_M)),
    (0.2, 0.5, ((0.2 - 0.5 * HALF_TRACK_M) / RADIUS_M, (0.2 + 0.5 * HALF_TRACK_M) / RADIUS_M)),
    (0.2, -0.5, ((0.2 + 0.5 * HALF_TRACK_M) / RADIUS_M, (0.2 - 0.5 * HALF_TRACK_M) / RADIUS_M)),
])
def test_wheel_speeds_within_limits(linear_mps, angular_radps, expected_radps):
    assert wheel_speeds_radps(linear_mps, angular_radps) == pytest.approx(expected_radps)


@pytest.mark.parametrize('angular_radps', [0.5, 1.0, 2.0])
def test_left_turn_spins_right_wheel_faster(angular_radps):
    left_radps, right_radps = wheel_speeds_radps(0.2, angular_radps)
    assert right_radps > left_radps


@pytest.mark.parametrize('linear_mps, angular_radps, expected_radps', [
    (2.0, 0.0, (MAX_WHEEL_RADPS, MAX_WHEEL_RADPS)),
    (-2.0, 0.0, (-MAX_WHEEL_RADPS, -MAX_WHEEL_RADPS)),
    (1e6, 0.0, (MAX_WHEEL_RADPS, MAX_WHEEL_RADPS)),
    (0.0, 10.0, (-math.pi * HALF_TRACK_M / RADIUS_M, math.pi * HALF_TRACK_M / RADIUS_M)),
    (0.0, -10.0, (math.pi * HALF_TRACK_M / RADIUS_M, -math.pi * HALF_TRACK_M / RADIUS_M)),
])
def test_twist_is_clamped_to_kobuki_limits(linear_mps, angular_radps, expected_radps):
    assert wheel_speeds_radps(linear_mps, angular_radps) == pytest.approx(expected_radps)


@pytest.mark.parametrize('linear_mps, angular_radps', [
    (0.7, 1.0),
    (0.6, -2.0),
    (-0.7, 1.5),
    (0.5, math.pi),
])
def test_fast_wheel_is_scaled_to_top_speed_keeping_curvature(linear_mps, angular_radps):
    left_radps, right_radps = wheel_speeds_radps(linear_mps, angular_radps)
    driven_linear_mps, driven_angular_radps = body_twist(left_radps, right_radps)
    assert max(abs(left_radps), abs(right_radps)) == pytest.approx(MAX_WHEEL_RADPS)
    assert driven_angular_radps / driven_linear_mps == pytest.approx(
        angular_radps / linear_mps)
    assert abs(driven_linear_mps) < abs(linear_mps)


def test_clamped_twist_keeps_curvature_of_clamped_command():
    left_radps, right_radps = wheel_speeds_radps(5.0, 5.0)
    driven_linear_mps, driven_angular_radps = body_twist(left_radps, right_radps)
    assert driven_angular_radps / driven_linear_mps == pytest.approx(
        KOBUKI_MAX_ANGULAR_SPEED_RADPS / KOBUKI_MAX_LINEAR_SPEED_MPS)


@pytest.mark.parametrize('linear_mps, angular_radps', [
    (math.nan, 0.0),
    (0.0, math.nan),
    (math.inf, 0.0),
    (-math.inf, 0.0),
    (0.3, math.inf),
    (0.3, -math.inf),
])
def test_non_finite_command_gives_zero_wheel_speeds(linear_mps, angular_radps):
    assert wheel_speeds_radps(linear_mps, angular_radps) == (0.0, 0.0)


def test_custom_limits_are_used():
    limits = DiffDriveLimits(wheel_separation_m=0.5, wheel_radius_m=0.1,
                             max_linear_speed_mps=1.0, max_angular_speed_radps=1.0)
    assert wheel_speeds_radps(0.5, 1.0, limits) == pytest.approx((2.5, 7.5))


@pytest.mark.parametrize('linear_mps, angular_radps', [
    (0.0, 0.0),
    (0.3, 0.0),
    (-0.3, 0.0),
    (0.0, 1.0),
    (0.0, -math.pi),
    (0.2, -0.5),
    (-0.1, 0.3),
    (0.5, 1.0),
])
def test_body_twist_inverts_wheel_speeds_within_limits(linear_mps, angular_radps):
    twist = body_twist(*wheel_speeds_radps(linear_mps, angular_radps))
    assert twist == pytest.approx((linear_mps, angular_radps), abs=TOLERANCE)


@pytest.mark.parametrize('left_radps, right_radps, expected_twist', [
    (10.0, 10.0, (0.35, 0.0)),
    (-10.0, 10.0, (0.0, 10.0 * RADIUS_M / HALF_TRACK_M)),
    (0.0, 10.0, (0.175, 0.35 / KOBUKI_WHEEL_SEPARATION_M)),
])
def test_body_twist_of_wheel_speeds(left_radps, right_radps, expected_twist):
    assert body_twist(left_radps, right_radps) == pytest.approx(expected_twist)


def test_kobuki_top_wheel_speed():
    assert KOBUKI.max_wheel_speed_radps == pytest.approx(MAX_WHEEL_RADPS)


@pytest.mark.parametrize('field', [
    'wheel_separation_m', 'wheel_radius_m', 'max_linear_speed_mps', 'max_angular_speed_radps',
])
@pytest.mark.parametrize('value', [0.0, -1.0, math.nan, math.inf])
def test_limits_reject_non_positive_or_non_finite(field, value):
    with pytest.raises(ValueError, match=field):
        DiffDriveLimits(**{field: value})


def test_watchdog_without_command_stands_still():
    watchdog = CommandWatchdog()
    assert watchdog.current(0.0) == (0.0, 0.0)
    assert watchdog.current(100.0) == (0.0, 0.0)


@pytest.mark.parametrize('time_s, expected', [
    (0.0, (0.3, 0.2)),
    (0.3, (0.3, 0.2)),
    (0.599, (0.3, 0.2)),
    (KOBUKI_COMMAND_TIMEOUT_S, (0.0, 0.0)),
    (0.601, (0.0, 0.0)),
    (5.0, (0.0, 0.0)),
])
def test_watchdog_holds_command_until_timeout(time_s, expected):
    watchdog = CommandWatchdog()
    watchdog.command(0.3, 0.2, 0.0)
    assert watchdog.current(time_s) == expected


def test_watchdog_default_timeout_is_kobukis():
    assert KOBUKI_COMMAND_TIMEOUT_S == 0.6


def test_new_command_rearms_watchdog():
    watchdog = CommandWatchdog()
    watchdog.command(0.3, 0.0, 0.0)
    watchdog.command(0.1, -0.4, 0.5)
    assert watchdog.current(1.0) == (0.1, -0.4)
    assert watchdog.current(1.1) == (0.0, 0.0)


def test_command_after_timeout_drives_again():
    watchdog = CommandWatchdog()
    watchdog.command(0.3, 0.0, 0.0)
    assert watchdog.current(1.0) == (0.0, 0.0)
    watchdog.command(0.2, 0.1, 1.0)
    assert watchdog.current(1.0) == (0.2, 0.1)


def test_watchdog_reset_forgets_command():
    watchdog = CommandWatchdog()
    watchdog.command(0.3, 0.2, 0.0)
    watchdog.reset()
    assert watchdog.current(0.0) == (0.0, 0.0)


def test_watchdog_custom_timeout():
    watchdog = CommandWatchdog(timeout_s=0.125)
    watchdog.command(0.3, 0.0, 0.0)
    assert watchdog.current(0.1) == (0.3, 0.0)
    assert watchdog.current(0.125) == (0.0, 0.0)


@pytest.mark.parametrize('timeout_s', [0.0, -0.6, math.nan, math.inf])
def test_watchdog_rejects_invalid_timeout(timeout_s):
    with pytest.raises(ValueError, match='timeout_s'):
        CommandWatchdog(timeout_s)
