"""How a detection's bands are judged against where the line truly is."""

import math

from followbot.line_detector import BandDetection, Detection
from followbot_sim import perception_score as score
import pytest

# A line straight up the image at column 300, 20 px wide, from row 470 to row 100.
STRAIGHT = [(300.0, 470.0, 20.0), (300.0, 100.0, 20.0)]
# A dash of it, rows 400-350.
DASH = [(300.0, 400.0, 20.0), (300.0, 350.0, 20.0)]


def band(found, x_px=math.nan, top_px=360):
    """Return a band of rows top..top+4 that saw the line at a column, or nothing."""
    return BandDetection(found, x_px if found else math.nan, top_px + 1.5 if found else math.nan,
                         80 if found else 0, top_px, top_px + 4)


@pytest.mark.parametrize('top, bottom, state', (
    (360, 364, score.PRESENT),
    (480, 484, score.ABSENT),
    (399, 403, score.EITHER),       # the dash ends in the band's upper rows
    (402, 406, score.EITHER),       # ... or just below it
    (410, 414, score.ABSENT),
))
def test_a_band_is_present_absent_or_either(top, bottom, state):
    assert score.band_truth([DASH], top, bottom).state == state


def test_ignored_rows_make_a_band_either():
    assert score.band_truth([STRAIGHT], 200, 204, ignored_rows=((190, 210),)).state == (
        score.EITHER)


def test_a_marking_thinner_than_the_tape_is_not_required():
    thin = [(300.0, 470.0, 3.0), (300.0, 100.0, 3.0)]
    assert score.band_truth([thin], 200, 204, min_width_px=10.0).state == score.EITHER
    assert score.band_truth([thin], 200, 204, min_width_px=2.0).state == score.PRESENT


@pytest.mark.parametrize('found, x_px, state, verdict', (
    (True, 300.0, score.PRESENT, score.RIGHT),
    (True, 313.0, score.PRESENT, score.RIGHT),     # within half a width and the tolerance
    (True, 320.0, score.PRESENT, score.FALSE),
    (False, math.nan, score.PRESENT, score.MISSED),
    (False, math.nan, score.ABSENT, score.RIGHT),
    (True, 300.0, score.ABSENT, score.FALSE),
    (False, math.nan, score.EITHER, score.RIGHT),
))
def test_band_verdicts(found, x_px, state, verdict):
    line = [STRAIGHT] if state != score.ABSENT else []
    truth = score.band_truth(line, 360, 364) if state != score.EITHER else (
        score.band_truth([DASH], 399, 403))
    assert truth.state == state
    assert score.band_verdict(truth, found, x_px) == verdict


def test_dashes_of_one_line_are_grouped_and_a_parallel_line_is_not():
    dashes = [[(300.0, 470.0 - 60 * k, 20.0), (300.0, 440.0 - 60 * k, 20.0)] for k in range(4)]
    other = [(500.0, 470.0, 20.0), (520.0, 200.0, 20.0)]
    groups = score.group_lines(dashes + [other])
    assert sorted(len(group) for group in groups) == [1, 4]


def test_a_band_only_another_line_crosses_is_not_missed():
    near_line = [(300.0, 479.0, 20.0), (300.0, 380.0, 20.0)]
    far_line = [(100.0, 300.0, 20.0), (120.0, 200.0, 20.0)]
    bands = (band(True, 300.0, 450), band(False, top_px=250))
    truths = [[score.band_truth([line], item.top_px, item.bottom_px) for item in bands]
              for line in (near_line, far_line)]
    detection = Detection(bands, 640, 480, 0.5)
    verdicts, _ = score.frame_verdicts(truths, detection)
    assert verdicts == [score.RIGHT, score.RIGHT]


def test_a_detection_of_nothing_misses_every_line():
    line = [(100.0, 300.0, 20.0), (120.0, 200.0, 20.0)]
    bands = (band(False, top_px=250),)
    truths = [[score.band_truth([line], 250, 254)]]
    verdicts, _ = score.frame_verdicts(truths, Detection(bands, 640, 480, 0.0))
    assert verdicts == [score.MISSED]


def test_the_tally_counts_bands_and_confidently_false_frames():
    tally = score.PerceptionTally()
    bands = (band(True, 450.0), band(False, top_px=300))
    truths = [[score.band_truth([STRAIGHT], item.top_px, item.bottom_px) for item in bands]]
    verdicts = tally.add_frame(truths, Detection(bands, 640, 480, 0.7))
    assert verdicts == [score.FALSE, score.MISSED]
    assert (tally.bands, tally.false, tally.missed, tally.confident_false_frames) == (2, 1, 1, 1)
    other = score.PerceptionTally()
    other.add_frame(truths, Detection(bands, 640, 480, 0.2))
    tally.merge(other)
    assert tally.frames == 2 and tally.confident_false_frames == 1
    assert tally.right_share == 0.0 and tally.false_share == 0.5
