"""
Decide exactly which colours OpenCV's HSV bounds take, without converting pixels to HSV.

A pixel is the line's exactly when ``cv2.inRange`` takes its ``cv2.cvtColor`` BGR-to-HSV
colour to be within the configured bounds. Converting every band pixel to HSV would cost more
than all the rest of the detector, so for bounds shaped like yellow's (a hue range centred on
yellow, no upper saturation or value bound) a few whole-array operations on the blue, green and
red planes decide instead: with g_r = max(red, green), the saturation and value bounds become
g_r > floor(c * blue) and g_r >= value_min, and the hue bound |red - green| <= k * (g_r -
blue). This rule is checked against cvtColor and inRange on all 16.7 million 8-bit colours
the first time a set of bounds is used (a tenth of a second; the verdict is cached), and is
used only if it never contradicts them. OpenCV's fixed-point hue rounds a few colours right at
the hue bound either way, so the rule leaves colours within a fraction of a level of that
bound undecided; the detector settles those pixels with cvtColor itself.
"""

from dataclasses import dataclass
import functools

import cv2
import numpy as np

# Saturation and value of 8-bit HSV images range over 0..255.
HSV_CHANNEL_MAX = 255

# Pure yellow in OpenCV hue units; the fast rule needs a hue range centred on it.
_YELLOW_HUE = 30
# OpenCV hue units per hue sector (60 degrees) between two primary colours.
_HUE_SECTOR = 30
# Widths, in levels of |red - green|, of the band the fast rule leaves undecided about its
# hue bound, narrowest first: OpenCV's fixed-point hue strays from the exact bound by up to a
# quarter level for the default bounds, a little more for others.
_HUE_UNDECIDED_LEVELS = (0.26, 0.5, 1.0)
# The rule's three verdicts in its 8-bit output: no, undecided (anything between), yes.
RULE_NO = 0
RULE_YES = 255
# Half an 8-bit level: cv2 rounds to the nearest integer when it saturates to uint8.
_HALF_LEVEL = 0.5
# Colours are checked against cvtColor in blocks of this many blue levels (16 MB of scratch).
_CHECK_BLUE_LEVELS_PER_BLOCK = 16
# Levels of an 8-bit channel.
_LEVELS = 256


@dataclass(frozen=True)
class ColourRule:
    """
    Decide whether colours are the line's from their blue, green and red planes.

    With g_r = max(red, green), a colour is the line's when g_r >= ``value_min``, g_r >
    floor(``value_per_blue`` * blue) (the saturation bound, blue being the smallest channel)
    and |red - green| <= ``hue_slope`` * (g_r - blue) (the hue bound, symmetric about yellow).
    The hue comparison answers yes or no only ``hue_undecided_levels`` or more away from its
    bound, and leaves the colour undecided nearer.
    """

    value_per_blue: float
    hue_slope: float
    value_min: int
    hue_undecided_levels: float

    def classify(self, blue, green, red, spare, out):
        """
        Write the verdict on each pixel of three equal uint8 planes, overwriting them.

        :param blue: the blue plane; green and red likewise. All three are overwritten.
        :param spare: a uint8 scratch array of the planes' shape.
        :param out: where the verdicts go: any uint8 array or view the planes reshape to.
            Each is RULE_NO, RULE_YES or, undecided, anything between.
        """
        np.maximum(red, green, out=spare)
        cv2.absdiff(red, green, dst=red)
        cv2.subtract(spare, blue, dst=green)
        # slope * chroma - |red - green|, scaled so that the undecided margin or more gives
        # RULE_YES, and minus the margin or less RULE_NO.
        gain = (RULE_YES - _HALF_LEVEL) / (2 * self.hue_undecided_levels)
        cv2.addWeighted(green, gain * self.hue_slope, red, -gain, RULE_YES / 2.0, dst=green)
        # floor(value_per_blue * blue): the largest max(red, green) still too unsaturated.
        cv2.convertScaleAbs(blue, dst=blue, alpha=self.value_per_blue, beta=-_HALF_LEVEL)
        cv2.threshold(spare, self.value_min - 1, RULE_YES, cv2.THRESH_TOZERO, dst=spare)
        cv2.compare(spare, blue, cv2.CMP_GT, dst=blue)
        np.minimum(green.reshape(out.shape), blue.reshape(out.shape), out=out)


@functools.lru_cache(maxsize=None)
def colour_rule(hue_min, hue_max, saturation_min, saturation_max, value_min, value_max):
    """
    Return the ColourRule equal to cvtColor and inRange for these bounds, or None.

    :return: None when the bounds are not shaped like the rule (a hue range centred on yellow
        within the red-green sector, no upper saturation or value bound, a lower saturation
        bound) or no rule with an undecided margin of at most a level agrees with OpenCV on
        every colour.
    """
    centred_hue = hue_min + hue_max == 2 * _YELLOW_HUE and 0 < hue_min <= _YELLOW_HUE
    if not (centred_hue and saturation_min > 0 and saturation_max == HSV_CHANNEL_MAX
            and value_max == HSV_CHANNEL_MAX):
        return None
    ratio = _saturation_ratio(saturation_min, value_min)
    if ratio is None:
        return None
    lower = np.array((hue_min, saturation_min, value_min), np.uint8)
    upper = np.array((hue_max, saturation_max, value_max), np.uint8)
    for undecided_levels in _HUE_UNDECIDED_LEVELS:
        rule = ColourRule(value_per_blue=1.0 / (1.0 - ratio),
                          hue_slope=(_HUE_SECTOR + _HALF_LEVEL - hue_min) / _HUE_SECTOR,
                          value_min=value_min, hue_undecided_levels=undecided_levels)
        if _rule_matches_opencv(rule, lower, upper):
            return rule
    return None


def _saturation_ratio(saturation_min, value_min):
    """
    Return c such that OpenCV's saturation >= saturation_min exactly when chroma >= c * value.

    :return: c, strictly inside the interval every value from value_min up allows, or None
        when no single ratio describes the bound.
    """
    levels = np.arange(_LEVELS)
    value, chroma = np.meshgrid(levels, levels, indexing='ij')
    value, chroma = value[chroma <= value], chroma[chroma <= value]
    # A grey-to-red ramp: blue = green = value - chroma, red = value.
    ramp = np.stack((value - chroma, value - chroma, value), axis=-1).astype(np.uint8)
    saturation = cv2.cvtColor(ramp[np.newaxis], cv2.COLOR_BGR2HSV)[0, :, 1]
    passes = saturation >= saturation_min
    above = value >= max(value_min, 1)
    low = max((chroma[~passes & above] / value[~passes & above]).max(initial=0.0), 0.0)
    high = (chroma[passes & above] / value[passes & above]).min(initial=1.0)
    if not low < high:
        return None
    return (low + high) / 2.0


def _rule_matches_opencv(rule, lower, upper):
    """Return whether the rule never contradicts cvtColor and inRange on any 8-bit colour."""
    levels = np.arange(_LEVELS, dtype=np.uint8)
    bgr = np.empty((1, _CHECK_BLUE_LEVELS_PER_BLOCK * _LEVELS * _LEVELS, 3), np.uint8)
    bgr[0, :, 1] = np.tile(np.repeat(levels, _LEVELS), _CHECK_BLUE_LEVELS_PER_BLOCK)
    bgr[0, :, 2] = np.tile(levels, _LEVELS * _CHECK_BLUE_LEVELS_PER_BLOCK)
    planes = [np.empty(bgr.shape[:2], np.uint8) for _ in range(5)]
    verdict = planes[4]
    expected = np.empty(bgr.shape[:2], np.uint8)
    for first_blue in range(0, _LEVELS, _CHECK_BLUE_LEVELS_PER_BLOCK):
        bgr[0, :, 0] = np.repeat(levels[first_blue:first_blue + _CHECK_BLUE_LEVELS_PER_BLOCK],
                                 _LEVELS * _LEVELS)
        cv2.split(bgr, planes[:3])
        rule.classify(*planes)
        cv2.inRange(cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV), lower, upper, dst=expected)
        wrong_yes = (verdict == RULE_YES) & (expected == 0)
        wrong_no = (verdict == RULE_NO) & (expected != 0)
        if wrong_yes.any() or wrong_no.any():
            return False
    return True
