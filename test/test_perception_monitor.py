"""Tests of scoring the detector against the simulator's line truth, and of the realistic table."""

import math
from types import SimpleNamespace

from followbot.line_detector import BandDetection
from followbot_sim.perception_monitor import detection_line_truths
from followbot_sim.perception_monitor import truth_polylines
from followbot_sim.perception_score import PerceptionTally
from followbot_sim.perception_score import PRESENT
from followbot_sim.scorecard import format_realistic_table
from followbot_sim.scorecard import REALISTIC_SCENARIOS
from followbot_sim.scorecard import select_scenarios
import pytest


def point(x, y, z):
    """Return a line-truth point as the PolygonStamped layout has it."""
    return SimpleNamespace(x=x, y=y, z=z)


def band(found, centroid_x_px, top_px, bottom_px):
    """Return a band detection with the fields scoring reads."""
    fields = dict.fromkeys(BandDetection._fields, 0)
    fields.update(found=found, centroid_x_px=centroid_x_px, top_px=top_px,
                  bottom_px=bottom_px, searched=True)
    return BandDetection(**fields)


def detection(*bands):
    """Return a detection-like record of bands."""
    return SimpleNamespace(bands=bands, found=any(b.found for b in bands), confidence=1.0)


def test_rows_where_the_line_is_not_seen_give_no_piece():
    pieces = truth_polylines([point(math.nan, 10.0, 0.0), point(100.0, 20.0, 30.0)])
    assert pieces == [[(100.0, 19.5, 30.0), (100.0, 20.5, 30.0)]]


def test_a_stripe_on_the_true_line_is_right_and_one_beside_it_false():
    truth_points = [point(300.0, float(row), 40.0) for row in range(400, 440)]
    pieces = truth_polylines(truth_points)
    tally = PerceptionTally()
    on_line = detection(band(True, 305.0, 410, 430))
    truths = detection_line_truths(pieces, on_line, None, 0.19)
    assert truths[0][0].state == PRESENT
    assert tally.add_frame(truths, on_line) == ['right']
    beside = detection(band(True, 100.0, 410, 430))
    assert tally.add_frame(detection_line_truths(pieces, beside, None, 0.19), beside) == [
        'false']
    nothing = detection(band(False, math.nan, 410, 430))
    assert tally.add_frame(detection_line_truths(pieces, nothing, None, 0.19), nothing) == [
        'missed']


def test_realistic_group_holds_every_preset_on_three_courses_with_two_seeds():
    scenarios = select_scenarios(['realistic'])
    assert len(scenarios) == len(REALISTIC_SCENARIOS) == 6 * 3 * 2
    chosen = select_scenarios(['book_loop@harsh#2'])[0]
    assert (chosen.course, chosen.realism, chosen.realism_seed) == ('book_loop', 'harsh', 2)


def test_realistic_table_has_one_row_per_scored_run():
    run = {'scenario': 'book_loop@lab#1', 'course': 'book_loop', 'configuration': 'followbot',
           'end_reason': 'lap completed', 'simulated_per_wall': 1.5,
           'metrics': {'lap_time_s': 40.0, 'rms_distance_from_line_m': 0.005,
                       'max_distance_from_line_m': 0.013, 'line_lost_percent': 0.0},
           'perception': {'right_percent': 99.5, 'false_percent': 0.3, 'missed_percent': 0.2}}
    table = format_realistic_table([run, {'scenario': 'book_loop', 'perception': None}])
    lines = table.splitlines()
    assert len(lines) == 3
    assert lines[2] == ('| lab | book_loop | 1 | followbot | lap completed | 40.0 | 0.5 | 1.3 | '
                        '0.00 | 99.5 | 0.3 | 0.2 | 1.50 |')


def test_unknown_realistic_name_is_refused():
    with pytest.raises(ValueError, match='realistic'):
        select_scenarios(['book_loop@foggy#1'])
