"""Tests of the line-following controller: steering law, saturation and lost-line behaviour."""

import math

from followbot.controller import ControllerConfig
from followbot.controller import LineFollowingController
from followbot.controller import LOST_LINE_BEHAVIOURS
from followbot.controller import VelocityCommand
from followbot.line_detector import Detection
import pytest

IMAGE_WIDTH_PX = 640
# A gain of 3.2 with no effective angular limit reproduces the book's law exactly.
BOOK_CONFIG = ControllerConfig(angular_gain_radps=3.2, max_angular_speed_radps=100.0)


def seen(error):
    """Return a Detection of a line at a normalised error."""
    centroid_x_px = IMAGE_WIDTH_PX / 2 * (1.0 + error)
    return Detection(
        found=True, centroid_x_px=centroid_x_px, centroid_y_px=360.0, error=error,
        area_px=300, band_top_px=350, band_bottom_px=370, image_width_px=IMAGE_WIDTH_PX)


def lost():
    """Return a Detection of no line."""
    return Detection(
        found=False, centroid_x_px=math.nan, centroid_y_px=math.nan, error=0.0, area_px=0,
        band_top_px=350, band_bottom_px=370, image_width_px=IMAGE_WIDTH_PX)


@pytest.mark.parametrize('error, angular_radps', (
    (0.0, 0.0),
    (0.1, -0.32),
    (-0.1, 0.32),
    (0.25, -0.8),
    (-0.4, 1.28),
    # Saturation at the default 1.5 rad/s limit.
    (0.5, -1.5),
    (-0.5, 1.5),
    (1.0, -1.5),
    (-1.0, 1.5),
))
def test_steering_law(error, angular_radps):
    command = LineFollowingController().update(seen(error))
    assert command.linear_mps == pytest.approx(0.2)
    assert command.angular_radps == pytest.approx(angular_radps)


def test_line_right_of_centre_turns_right_with_negative_yaw_rate():
    # REP-103: positive angular.z is counter-clockwise (left); the line on the right needs a
    # clockwise turn.
    assert LineFollowingController().update(seen(0.3)).angular_radps < 0.0
    assert LineFollowingController().update(seen(-0.3)).angular_radps > 0.0


@pytest.mark.parametrize('centroid_x_px, angular_radps', (
    (420.0, -1.0),
    (220.0, 1.0),
    (320.0, 0.0),
    (640.0, -3.2),
))
def test_matches_the_books_law(centroid_x_px, angular_radps):
    # The book: angular = -(cx - w/2) / 100 rad/s.
    error = (centroid_x_px - IMAGE_WIDTH_PX / 2) / (IMAGE_WIDTH_PX / 2)
    command = LineFollowingController(BOOK_CONFIG).update(seen(error))
    assert command.angular_radps == pytest.approx(-(centroid_x_px - IMAGE_WIDTH_PX / 2) / 100)
    assert command.angular_radps == pytest.approx(angular_radps)
    assert command.linear_mps == pytest.approx(0.2)


@pytest.mark.parametrize('max_angular_speed_radps', (0.0, 0.5, 2.0))
@pytest.mark.parametrize('error', (-1.0, -0.7, 0.7, 1.0))
def test_angular_speed_is_limited(max_angular_speed_radps, error):
    controller = LineFollowingController(
        ControllerConfig(max_angular_speed_radps=max_angular_speed_radps))
    command = controller.update(seen(error))
    assert abs(command.angular_radps) == pytest.approx(max_angular_speed_radps)


@pytest.mark.parametrize('last_error', (None, -0.5, 0.0, 0.5))
def test_stop_behaviour_stops_when_the_line_is_lost(last_error):
    controller = LineFollowingController(ControllerConfig(lost_line_behaviour='stop'))
    if last_error is not None:
        controller.update(seen(last_error))
    assert controller.update(lost()) == VelocityCommand(linear_mps=0.0, angular_radps=0.0)


@pytest.mark.parametrize('last_errors, angular_radps', (
    # Line last seen right of centre: turn right (clockwise, negative).
    ((0.4,), -0.5),
    ((-0.2, 0.1), -0.5),
    # Line last seen left of centre: turn left (counter-clockwise, positive).
    ((-0.4,), 0.5),
    ((0.3, -0.05), 0.5),
    # Never seen, or last seen dead centre: no side preference, turn left by convention.
    ((), 0.5),
    ((0.6, 0.0), 0.5),
))
def test_search_turns_in_place_towards_the_side_last_seen(last_errors, angular_radps):
    controller = LineFollowingController(ControllerConfig(lost_line_behaviour='search'))
    for error in last_errors:
        controller.update(seen(error))
    for _ in range(3):
        assert controller.update(lost()) == VelocityCommand(
            linear_mps=0.0, angular_radps=angular_radps)


def test_search_speed_follows_the_config():
    controller = LineFollowingController(ControllerConfig(search_angular_speed_radps=1.25))
    controller.update(seen(0.9))
    assert controller.update(lost()).angular_radps == pytest.approx(-1.25)


def test_drives_again_after_reacquiring_the_line():
    controller = LineFollowingController()
    controller.update(seen(0.5))
    assert controller.update(lost()).linear_mps == 0.0
    command = controller.update(seen(-0.1))
    assert command == VelocityCommand(linear_mps=0.2, angular_radps=pytest.approx(0.32))
    assert controller.update(lost()).angular_radps > 0.0


@pytest.mark.parametrize('behaviour', LOST_LINE_BEHAVIOURS)
def test_never_drives_forward_while_the_line_is_lost(behaviour):
    controller = LineFollowingController(
        ControllerConfig(lost_line_behaviour=behaviour, linear_speed_mps=0.7))
    for error in (0.9, -0.9, 0.0, 0.2, -0.3):
        controller.update(seen(error))
        for _ in range(2):
            assert controller.update(lost()).linear_mps == 0.0


@pytest.mark.parametrize('error', (math.nan, math.inf, -math.inf))
def test_found_detection_with_non_finite_error_counts_as_lost(error):
    controller = LineFollowingController()
    controller.update(seen(-0.5))
    assert controller.update(seen(error)) == VelocityCommand(
        linear_mps=0.0, angular_radps=0.5)


def test_reset_forgets_the_side_last_seen():
    controller = LineFollowingController()
    controller.update(seen(0.8))
    controller.reset()
    assert controller.update(lost()).angular_radps == pytest.approx(0.5)


def test_stop_command_is_zero():
    assert LineFollowingController.stop_command() == VelocityCommand(0.0, 0.0)


def test_controller_keeps_its_config():
    config = ControllerConfig(linear_speed_mps=0.1)
    assert LineFollowingController(config).config is config


def test_config_defaults_are_the_books():
    assert ControllerConfig() == ControllerConfig(
        linear_speed_mps=0.2, angular_gain_radps=3.2, max_angular_speed_radps=1.5,
        lost_line_behaviour='search', search_angular_speed_radps=0.5)


@pytest.mark.parametrize('fields, error_type, message_part', (
    ({'linear_speed_mps': -0.1}, ValueError, 'linear_speed_mps must be finite and non-neg'),
    ({'angular_gain_radps': -3.2}, ValueError, 'angular_gain_radps must be finite'),
    ({'max_angular_speed_radps': -1.0}, ValueError, 'max_angular_speed_radps must be'),
    ({'search_angular_speed_radps': -0.5}, ValueError, 'search_angular_speed_radps must'),
    ({'linear_speed_mps': math.nan}, ValueError, 'linear_speed_mps must be finite'),
    ({'max_angular_speed_radps': math.inf}, ValueError, 'must be finite'),
    ({'lost_line_behaviour': 'spin'}, ValueError, "one of search, stop, got 'spin'"),
    ({'lost_line_behaviour': 'STOP'}, ValueError, 'lost_line_behaviour must be one of'),
    ({'linear_speed_mps': '0.2'}, TypeError, 'linear_speed_mps must be a number'),
    ({'angular_gain_radps': None}, TypeError, 'angular_gain_radps must be a number'),
))
def test_config_rejects_invalid_values(fields, error_type, message_part):
    with pytest.raises(error_type, match=message_part):
        ControllerConfig(**fields)


def test_config_accepts_integer_values():
    assert ControllerConfig(linear_speed_mps=0, max_angular_speed_radps=2).linear_speed_mps == 0
