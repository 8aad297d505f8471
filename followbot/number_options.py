"""
Numbers on a command line: each option reads a finite number within its range, or says so.

``type=float`` lets ``nan`` and ``inf`` through every ``<`` check after parsing (``nan < 0``
is false), and a check per command words the same refusal differently. Each command's
numeric options take an argparse ``type`` from :func:`number_in` instead, so a bad value ends
the command with argparse's one line: ``argument --duration: must be a number >= 0, got
'nan'``.
"""

import argparse
import math


def number_in(low: float, high: float = math.inf, *, above: bool = False,
              whole: bool = False):
    """
    Return an argparse ``type`` that reads a finite number within a range.

    :param low: the least value (excluded when ``above``).
    :param high: the greatest value (included); infinite for no upper bound.
    :param above: whether the value must be greater than ``low`` rather than at least it.
    :param whole: whether the value is a whole number (read as an int).
    :return: the function argparse calls with the option's text; it returns the number or
        raises ``argparse.ArgumentTypeError`` saying what the option takes.
    """
    kind = 'a whole number' if whole else 'a number'
    if math.isinf(high):
        wanted = f'{kind} {">" if above else ">="} {low:g}'
    else:
        wanted = f'{kind} in {"(" if above else "["}{low:g}, {high:g}]'

    def read(text: str):
        try:
            value = int(text) if whole else float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and (value > low if above else value >= low)
                and value <= high):
            raise argparse.ArgumentTypeError(f'must be {wanted}, got {text!r}')
        return value

    read.__name__ = wanted
    return read


def parameter_option(spec):
    """
    Return the argparse ``type`` of an option that sets a ROS parameter: the parameter's range.

    :param spec: the parameter's followbot.parameters.ParameterSpec (a number with a range).
    :return: as :func:`number_in`.
    """
    whole = isinstance(spec.default, int) and not isinstance(spec.default, bool)
    return number_in(spec.low, spec.high, whole=whole)
