"""Every numeric command-line option reads a finite number in its range, or says what it takes."""

import argparse
import math

from followbot.follower_node import CAMERA_PARAMETERS
from followbot.number_options import number_in, parameter_option
import pytest


@pytest.mark.parametrize('option, text, value', [
    (number_in(0.0), '0', 0.0),
    (number_in(0.0), '2.5', 2.5),
    (number_in(0.0, above=True), '1e-3', 0.001),
    (number_in(1, 8, whole=True), '8', 8),
    (number_in(-90.0, 90.0), '-90', -90.0),
])
def test_a_number_in_range_is_read(option, text, value):
    assert option(text) == value
    assert type(option(text)) is type(value)


@pytest.mark.parametrize('option, text, message', [
    (number_in(0.0), 'nan', "must be a number >= 0, got 'nan'"),
    (number_in(0.0), 'inf', "must be a number >= 0, got 'inf'"),
    (number_in(0.0), '-0.5', "must be a number >= 0, got '-0.5'"),
    (number_in(0.0), 'fast', "must be a number >= 0, got 'fast'"),
    (number_in(0.0, above=True), '0', "must be a number > 0, got '0'"),
    (number_in(1, 8, whole=True), '9', "must be a whole number in [1, 8], got '9'"),
    (number_in(1, 8, whole=True), '2.5', "must be a whole number in [1, 8], got '2.5'"),
    (number_in(0.0, 1.0, above=True), '0', "must be a number in (0, 1], got '0'"),
])
def test_anything_else_is_refused_saying_what_the_option_takes(option, text, message):
    with pytest.raises(argparse.ArgumentTypeError) as error:
        option(text)
    assert str(error.value) == message


def test_an_option_that_sets_a_parameter_takes_the_parameters_range():
    spec = CAMERA_PARAMETERS['camera_height_m']
    option = parameter_option(spec)
    assert option(str(spec.high)) == spec.high
    with pytest.raises(argparse.ArgumentTypeError, match=r'must be a number in \['):
        option(str(math.nextafter(spec.high, math.inf)))
