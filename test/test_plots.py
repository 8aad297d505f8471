"""The scorecard's plots: PNG files made from a real short scorecard run and from run records."""

import json

from conftest import refusal, run_domain_id
import cv2
from followbot_sim.plots import DOTS_PER_INCH, FIGURE_SIZE_IN, plot_lap_times, write_plots
from followbot_sim.scorecard import main, SAMPLE_PERIOD_S
import numpy as np
import pytest

RUN_TIME_LIMIT_S = 4.0
PLOT_SHAPE = (round(FIGURE_SIZE_IN[1] * DOTS_PER_INCH), round(FIGURE_SIZE_IN[0] * DOTS_PER_INCH),
              3)


def read_png(path):
    """Read a PNG back with OpenCV, as an independent reader, and check it is a real picture."""
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    image = cv2.imread(str(path))
    assert image is not None and image.shape == PLOT_SHAPE
    # Something is drawn: not a blank page.
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10
    return image


def coloured_pixels(image) -> int:
    """Count the pixels of the curves and bars: saturated, unlike the axes, text and grid."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    return int(np.count_nonzero(hsv[..., 1] > 100))


def test_scorecard_plots_a_short_run(tmp_path, monkeypatch):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    plots_dir = tmp_path / 'plots'
    json_path = tmp_path / 'scorecard.json'
    exit_code = main(['--scenarios', 'book_loop', '--configs', 'followbot,book',
                      '--time-limit-s', str(RUN_TIME_LIMIT_S), '--jobs', '2',
                      '--domain-id', str(run_domain_id()), '--json', str(json_path),
                      '--plots', str(plots_dir)])
    assert exit_code == 0
    assert sorted(path.name for path in plots_dir.iterdir()) == [
        'distance_book_loop.png', 'lap_times.png', 'speed_book_loop.png']
    for path in plots_dir.iterdir():
        assert coloured_pixels(read_png(path)) > 100, path.name
    # The samples behind the curves are in the JSON too: the run sampled every period.
    for run in json.loads(json_path.read_text())['runs']:
        samples = run['samples']
        assert abs(len(samples['time_s']) - (RUN_TIME_LIMIT_S / SAMPLE_PERIOD_S + 1)) <= 1
        assert samples['progress_m'][-1] == pytest.approx(run['lap_tracker']['progress_m'],
                                                          abs=0.05)
        # Both followers move off at once, and stay on the line at this start.
        assert max(samples['speed_mps']) > 0.1
        assert max(samples['distance_from_line_m']) < 0.05


def record(scenario, configuration, lap_time_s):
    """Return a run record as the scorecard makes it, with the figures the lap plot reads."""
    return {'scenario': scenario, 'configuration': configuration,
            'metrics': {'lap_time_s': lap_time_s}, 'samples': None}


def bar_height_px(image, bgr) -> int:
    """Return the longest unbroken column of a colour: its bar, not its legend patch."""
    mask = (np.abs(image.astype(int) - bgr).max(axis=2) < 10).astype(int)
    longest = run = np.zeros(mask.shape[1], dtype=int)
    for row in mask:
        run = (run + 1) * row
        longest = np.maximum(longest, run)
    return int(longest.max())


def test_lap_time_bars_are_as_tall_as_the_lap_times(tmp_path):
    image = read_png(plot_lap_times([record('book_loop', 'followbot', 200.0),
                                     record('book_loop', 'book', 50.0)], tmp_path / 'laps.png'))
    # matplotlib's first two colours, in configuration order.
    first_bgr, second_bgr = (180, 119, 31), (14, 127, 255)
    ratio = bar_height_px(image, first_bgr) / bar_height_px(image, second_bgr)
    assert ratio == pytest.approx(4.0, rel=0.05)


def test_runs_without_a_lap_or_figures_still_plot(tmp_path):
    runs = [record('book_loop', 'followbot', None),
            {'scenario': 'courses/my course.yaml', 'configuration': 'book', 'metrics': None}]
    paths = write_plots(runs, tmp_path / 'new' / 'folder')
    assert sorted(path.name for path in paths) == [
        'distance_book_loop.png', 'distance_my_course.png', 'lap_times.png',
        'speed_book_loop.png', 'speed_my_course.png']
    for path in paths:
        read_png(path)


def test_scorecard_refuses_a_plots_folder_it_cannot_make(tmp_path, capsys):
    blocker = tmp_path / 'file'
    blocker.write_text('not a folder')
    error = refusal(main, ['--plots', str(blocker / 'plots')], capsys)
    assert (f'argument --plots: cannot write the plots into {blocker}/plots: Not a '
            'directory.') in error
