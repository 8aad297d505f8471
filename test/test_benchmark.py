"""The benchmark command: its pipelines, its frames, and a short run of every section."""

import json
import subprocess
import sys

from conftest import child_environment, run_domain_id
from followbot.line_detector import DetectorConfig, LineDetector
from followbot.transport import FASTDDS_PROFILE_VARIABLE
from followbot_sim import real_frames
from followbot_sim.benchmark import (BookPipeline, IMAGE_HEIGHT_PX, IMAGE_WIDTH_PX,
                                     parse_arguments, render_course_frames)
import numpy as np
import pytest

FRAME_COUNT = 12
LATENCY_FRAMES = 60
SIMULATED_S = 6.0
BENCHMARK_TIMEOUT_S = 300.0
# The book's band: 20 rows from 3/4 of the height.
BOOK_BAND = DetectorConfig(band_count=1, band_center_fraction=(360 + 10) / 480,
                           band_height_px=20, min_area_px=1)


@pytest.fixture(scope='module')
def frames():
    return render_course_frames(FRAME_COUNT)


def test_frames_go_around_the_course_with_the_line_in_view(frames):
    frames_bgr, intrinsics = frames
    assert frames_bgr.shape == (FRAME_COUNT, IMAGE_HEIGHT_PX, IMAGE_WIDTH_PX, 3)
    assert len(intrinsics) == 4
    detector = LineDetector()
    for index, frame in enumerate(frames_bgr):
        assert detector.detect(frame).found, f'no line in frame {index}'
    # Different places, different pictures.
    assert len({frame.tobytes() for frame in frames_bgr}) == FRAME_COUNT


def test_book_pipeline_finds_the_centroid_the_detector_finds_in_the_books_band(frames):
    book = BookPipeline(BOOK_BAND)
    detector = LineDetector(BOOK_BAND)
    for frame in frames[0]:
        band = detector.detect(frame).nearest
        assert band is not None
        assert book.detect(frame) == pytest.approx(band.centroid_x_px, abs=1e-6)


def test_book_pipeline_sees_nothing_without_yellow():
    grey = np.full((IMAGE_HEIGHT_PX, IMAGE_WIDTH_PX, 3), 116, np.uint8)
    assert BookPipeline(DetectorConfig()).detect(grey) is None


@pytest.mark.parametrize('arguments', [
    ['--sections', 'perception,speed'],
    ['--sections', ''],
    ['--rates', '20,fast'],
    ['--rates', '0'],
    ['--rates', '20,nan'],
    ['--simulated-seconds', 'nan'],
    ['--json', 'no/such/folder/b.json'],
    ['--frames', '0'],
    ['--simulated-seconds', '1'],
    ['--domain-id', '300'],
    ['--realism', 'clean,sunny'],
    ['--realism', ''],
])
def test_bad_options_are_refused(arguments, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse_arguments(arguments)
    assert exit_info.value.code == 2
    assert 'benchmark: error:' in capsys.readouterr().err


def test_a_short_benchmark_measures_every_section(tmp_path):
    figures_file = tmp_path / 'benchmark.json'
    environment = child_environment()
    environment.pop(FASTDDS_PROFILE_VARIABLE, None)
    completed = subprocess.run(
        [sys.executable, '-m', 'followbot_sim.benchmark', '--frames', str(FRAME_COUNT),
         '--repeats', '2', '--latency-frames', str(LATENCY_FRAMES), '--rates', '30',
         '--simulated-seconds', str(SIMULATED_S), '--realism', 'clean,lab',
         '--domain-id', str(run_domain_id()),
         '--json', str(figures_file)],
        env=environment, capture_output=True, text=True, timeout=BENCHMARK_TIMEOUT_S)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    for heading in ('## Perception', '## The default follower on real camera frames',
                    '## Camera image to the cmd_vel', '## Simulator'):
        assert heading in completed.stdout
    report = json.loads(figures_file.read_text())

    perception = report['perception']
    for pipeline in ('followbot', 'followbot_book_band', 'book_full_frame',
                     'book_opencv_only', 'follower_bgr8', 'follower_jpeg',
                     'follower_yuv422_yuy2', 'follower_bayer_rggb8', 'follower_realistic'):
        assert perception[pipeline]['calls'] == 2 * FRAME_COUNT
        assert 0.0 < perception[pipeline]['median_us'] <= perception[pipeline]['p99_us']

    nothing_exported, with_defaults = report['latency']
    assert nothing_exported['profile'] == 'nothing exported'
    assert with_defaults['profile'] == "Fast DDS's defaults"
    for result in (nothing_exported, with_defaults):
        assert 'error' not in result, result.get('error')
        assert result['rate_hz'] == 30.0
        assert 0.0 < result['p50_ms'] <= result['p99_ms'] <= result['max_ms']
        assert result['answered'] + result['dropped'] == LATENCY_FRAMES
        assert result['peak_memory_follower_mib'] > 0.0
    # With nothing exported the nodes take the package's profile: whole frames through shared
    # memory. Fast DDS's defaults send them as UDP fragments, and a best-effort follower misses
    # some.
    assert nothing_exported['dropped'] == 0
    assert with_defaults['dropped'] > 0

    real = report['real_frames']
    if real_frames.frames_folder()[0] is None:
        assert 'error' in real
    else:
        # One row per source and colour labelled in it, each scoring every band of its frames,
        # as taken and at half size.
        labelled = [(source.name, colour, size) for size in (1.0, real_frames.HALF_SIZE)
                    for source in real_frames.load_labels()
                    for colour in real_frames.LABELLED_COLOURS
                    if any(frame.polylines(colour) for frame in source.frames)]
        assert [(row['source'], row['colour'], row['size']) for row in real['rows']] == labelled
        for row in real['rows']:
            assert row['right'] + row['false'] + row['missed'] == row['bands'] > 0

    assert [result['realism'] for result in report['simulation']] == ['clean', 'lab']
    for simulation in report['simulation']:
        assert 'error' not in simulation, simulation.get('error')
        assert simulation['simulated_per_wall'] > 0.0
        assert simulation['measured_simulated_s'] >= SIMULATED_S - 2.0
        assert simulation['rms_cm'] < 3.0
        assert simulation['peak_memory_simulator_mib'] > simulation['peak_memory_follower_mib'] > 0
