"""Calibration (line_sample, calibration): a piece of line shown becomes a verified setup."""

import dataclasses
import math

import cv2
from followbot import calibration
from followbot import line_sample
from followbot.line_detector import band_rows, DetectorConfig, LineDetector
from followbot.line_sample import CalibrationError
from followbot_sim.perception_score import PerceptionTally
from followbot_sim.real_frames import frame_line_truths, frames_folder, load_labels
import numpy as np
import pytest
import scenes
import yaml

# A line leaving the robot 5 cm to its left, turning slightly left.
LINE = [scenes.straight_line(0.05, 0.2)]
NARROW_TAPE_M = 0.05
CAMERA_NOISE = 4.0
# The row the user shows the line at: below the middle of the image, where it is near.
SHOWN_ROW = 400
# Tapes and floors: BGR colours, and the line colour calibration must propose.
TAPES = {
    'yellow_on_grey': ((0, 246, 255), (116, 116, 116), 'yellow'),
    'white_on_grey': ((235, 235, 235), (116, 116, 116), 'white'),
    'black_on_concrete': ((25, 25, 25), (180, 180, 180), 'black'),
    'yellow_under_a_warm_cast': ((40, 200, 230), (35, 70, 85), 'yellow'),
    'white_under_a_warm_cast': ((200, 230, 250), (90, 110, 130), 'white'),
    'blue_tape': ((200, 60, 20), (116, 116, 116), 'custom'),
    'green_tape_on_a_green_mat': ((60, 200, 60), (60, 120, 60), 'custom'),
}
# The widths measured on the floor are this close to the tape's.
WIDTH_TOLERANCE = 0.05
# The real frames of white and black tape, and their tape's colour.
REAL_TAPES = {'ev3-whitelane': 'white', 'kejdi-blacktape': 'black'}
# Frames where the detector itself cannot keep to the tape, whatever the configuration.
REAL_FRAME_LIMITS = {
    'kejdi_robot_on_track_1.png': "a bystander's photo: the robot, its cables and two chair "
                                  "legs of the tape's black stand on and across the tape, "
                                  'and the detector chains them',
}


def frame(line_bgr, floor_bgr, width_m=scenes.LINE_WIDTH_M, seed=0):
    """Return a noisy frame of the line seen by the simulated Kinect, and its line mask."""
    image = scenes.scene(LINE, width_m=width_m, line_bgr=line_bgr, floor_bgr=floor_bgr)
    return scenes.add_noise(image, CAMERA_NOISE, seed), scenes.line_mask(LINE, width_m)


def point_on(mask, row=SHOWN_ROW):
    """Return the pixel in the middle of the line on a row."""
    columns = np.flatnonzero(mask[row])
    return int(columns.mean()), row


def found_on_line(detection, mask):
    """Return in how many bands the detection's stripe lies on the line, and off it."""
    on = off = 0
    for band in detection.bands:
        if band.found:
            column = int(round(band.centroid_x_px))
            hit = mask[band.top_px:band.bottom_px, max(column - 2, 0):column + 3].any()
            on, off = on + hit, off + (not hit)
    return on, off


@pytest.mark.parametrize('camera', [None, scenes.KINECT], ids=['no_camera', 'camera'])
@pytest.mark.parametrize('tape', list(TAPES))
def test_a_point_on_the_tape_gives_a_configuration_that_finds_it(tape, camera):
    line_bgr, floor_bgr, colour = TAPES[tape]
    image, mask = frame(line_bgr, floor_bgr)
    sample = line_sample.sample_at_point(image, point_on(mask))
    proposal = calibration.propose(image, 'bgr8', sample, camera)
    assert proposal.passed, proposal.best.verdict.describe()
    assert proposal.config.line_colour == colour
    # Checked apart from the verification: a fresh detector with the configuration.
    detection = LineDetector(proposal.config).detect(image, 'bgr8', camera)
    on, off = found_on_line(detection, mask)
    assert on >= 5 and off == 0


def test_custom_bounds_take_the_tape_and_not_the_floor():
    image, mask = frame((200, 60, 20), (116, 116, 116))
    sample = line_sample.sample_at_point(image, point_on(mask))
    config = calibration.propose(image, 'bgr8', sample).config
    # Blue is hue 120 (240 degrees) in OpenCV units.
    assert config.hue_min <= 120 - 1 and config.hue_max >= 120 - 1
    assert config.hue_max - config.hue_min <= 20
    # The grey floor has no saturation: the bounds exclude it.
    assert config.saturation_min > 0


def test_a_red_tape_gets_the_larger_side_of_its_hue_range():
    # Red's hues straddle 0 and 179; OpenCV bounds cannot wrap, so one side is kept.
    image, mask = frame((30, 30, 200), (116, 116, 116))
    sample = line_sample.sample_at_point(image, point_on(mask))
    proposal = calibration.propose(image, 'bgr8', sample)
    assert proposal.passed
    config = proposal.config
    assert config.line_colour == 'custom'
    assert config.hue_min == 0 or config.hue_max == calibration.OPENCV_HUE_MAX


@pytest.mark.parametrize('width_m', [scenes.LINE_WIDTH_M, NARROW_TAPE_M])
def test_the_tape_width_is_measured_on_the_floor(width_m):
    image, mask = frame((235, 235, 235), (116, 116, 116), width_m)
    sample = line_sample.sample_at_point(image, point_on(mask))
    width = line_sample.measure_line_width_m(sample, scenes.KINECT)
    assert width.metres == pytest.approx(width_m, rel=WIDTH_TOLERANCE)
    assert width.across_px > line_sample.MIN_SHARP_ACROSS_PX


def test_a_line_running_across_the_view_is_measured_across_it():
    across = [[(0.8, 2.0), (0.8, -2.0)]]
    image = scenes.scene(across, width_m=NARROW_TAPE_M, line_bgr=(235, 235, 235))
    mask = scenes.line_mask(across, NARROW_TAPE_M)
    rows = np.flatnonzero(mask[:, 320])
    sample = line_sample.sample_at_point(image, (320, int(rows.mean())))
    width = line_sample.measure_line_width_m(sample, scenes.KINECT)
    assert width.metres == pytest.approx(NARROW_TAPE_M, rel=WIDTH_TOLERANCE)


def test_a_region_around_the_tape_finds_the_same_piece_as_a_point_on_it():
    image, mask = frame((25, 25, 25), (180, 180, 180), NARROW_TAPE_M)
    x_px, y_px = point_on(mask)
    from_point = line_sample.sample_at_point(image, (x_px, y_px))
    from_region = line_sample.sample_in_region(image, (x_px - 60, y_px - 20, 120, 40))
    inside = np.zeros_like(mask)
    inside[y_px - 20:y_px + 20, x_px - 60:x_px + 60] = True
    assert (from_region.piece == (from_point.piece & inside)).mean() > 0.99
    assert not (from_region.piece & ~mask).any()


def test_without_a_piece_shown_the_most_confident_preset_is_proposed():
    image, _ = frame((235, 235, 235), (116, 116, 116))
    proposal = calibration.propose(image, 'bgr8')
    assert proposal.automatic and proposal.passed
    assert proposal.config.line_colour == 'white'
    assert {attempt.config.line_colour for attempt in proposal.attempts} == {
        'yellow', 'white', 'black'}


def test_a_grey_camera_is_offered_white_and_black_only():
    image, mask = frame((235, 235, 235), (116, 116, 116))
    grey = image[..., 1].copy()
    sample = line_sample.sample_at_point(image, point_on(mask))
    proposal = calibration.propose(grey, 'mono8', sample)
    assert proposal.passed and proposal.config.line_colour == 'white'
    assert [attempt.config.line_colour for attempt in proposal.attempts] == ['white', 'black']


def test_a_frame_without_a_line_is_not_verified():
    image, _ = frame((116, 116, 116), (116, 116, 116))
    proposal = calibration.propose(image, 'bgr8')
    assert not proposal.passed
    assert proposal.best.verdict.confidence < calibration.AUTOMATIC_MIN_CONFIDENCE


@pytest.mark.parametrize('point, message', [
    ((640, 10), 'lies outside the 640x480 frame'),
    ((-1, 10), 'lies outside the 640x480 frame'),
    ((600, 100), 'hardly differs from the floor around it'),
])
def test_a_point_not_on_a_line_is_refused(point, message):
    image, _ = frame((235, 235, 235), (116, 116, 116))
    with pytest.raises(CalibrationError, match=message):
        line_sample.sample_at_point(image, point)


@pytest.mark.parametrize('region, message', [
    ((600, 400, 100, 50), 'reaches outside the 640x480 frame'),
    ((10, 10, 0, 5), 'is empty'),
    ((500, 50, 60, 60), 'hardly differs from the floor around it'),
])
def test_a_region_without_a_line_is_refused(region, message):
    image, _ = frame((235, 235, 235), (116, 116, 116))
    with pytest.raises(CalibrationError, match=message):
        line_sample.sample_in_region(image, region)


def test_a_line_above_the_horizon_has_no_width_on_the_floor():
    image, mask = frame((235, 235, 235), (116, 116, 116))
    sample = line_sample.sample_at_point(image, point_on(mask))
    # The same pixels, seen by a camera tilted 40 degrees up: all above its horizon.
    looking_up = dataclasses.replace(scenes.KINECT, pitch_rad=math.radians(-40.0))
    with pytest.raises(CalibrationError, match="above the floor's horizon"):
        line_sample.measure_line_width_m(sample, looking_up)


def test_bands_move_over_a_line_seen_high_in_the_image():
    height = 480
    # The line is seen from row 0 down to row 175 only (a camera looking down at it).
    moved = calibration.bands_over((0, 175), DetectorConfig(), None, height)
    bands = band_rows(height, moved)
    assert len(bands) == DetectorConfig().band_count
    assert all(0 <= top and bottom <= 176 for top, bottom in bands)
    # A line over the default bands' rows keeps them; so does a dash (a short piece).
    assert calibration.bands_over((100, 479), DetectorConfig(), None, height) == (
        DetectorConfig())
    assert calibration.bands_over((300, 330), DetectorConfig(), None, height) == (
        DetectorConfig())


def test_the_parameters_are_a_params_file_for_the_follower():
    config = DetectorConfig(line_colour='custom', hue_min=100, hue_max=130,
                            saturation_min=120, value_min=60, line_width_m=0.05,
                            band_spacing_fraction=0.07)
    parameters = calibration.follower_parameters(config, 0.18, 20)
    text = calibration.parameters_yaml(parameters, ['made by a test'])
    assert text.startswith('# made by a test\n')
    document = yaml.safe_load(text)
    assert list(document) == ['/**/follower']
    values = document['/**/follower']['ros__parameters']
    assert values == {
        'line_colour': 'custom', 'hue_min': 100, 'hue_max': 130, 'saturation_min': 120,
        'value_min': 60, 'band_spacing_fraction': 0.07, 'line_width_m': 0.05,
        'saturation_max': 255, 'value_max': 255, 'camera_height_m': 0.18,
        'camera_pitch_deg': 20.0}
    # ROS parameters are typed: a float parameter given as an integer would be refused.
    assert isinstance(values['camera_pitch_deg'], float)
    assert DetectorConfig(**{name: value for name, value in values.items()
                             if not name.startswith('camera_')}) == config


def test_a_preset_writes_only_what_differs_from_the_defaults():
    parameters = calibration.follower_parameters(DetectorConfig(line_colour='black'))
    assert parameters == {'line_colour': 'black'}


CAMERA_INFO_YAML = """\
image_width: 640
image_height: 480
camera_name: usb_cam
camera_matrix:
  rows: 3
  cols: 3
  data: [520.5, 0.0, 321.2, 0.0, 519.8, 238.9, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.28, 0.07, 0.001, -0.0005, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [450.1, 0.0, 322.0, 0.0, 0.0, 470.2, 237.0, 0.0, 0.0, 0.0, 1.0, 0.0]
"""


def test_a_camera_calibration_file_gives_the_intrinsics():
    intrinsics = calibration.intrinsics_from_yaml(CAMERA_INFO_YAML)
    assert (intrinsics.width_px, intrinsics.height_px) == (640, 480)
    assert (intrinsics.fx_px, intrinsics.fy_px) == (520.5, 519.8)
    assert (intrinsics.cx_px, intrinsics.cy_px) == (321.2, 238.9)
    assert intrinsics.distortion_model == 'plumb_bob'
    assert intrinsics.distortion == (-0.28, 0.07, 0.001, -0.0005, 0.0)


@pytest.mark.parametrize('text, message', [
    ('image_width: [', 'is not YAML'),
    ('image_width: 640\n', 'has no camera_matrix'),
    ('camera_matrix: {data: [1, 2, 3]}\n', 'must hold 9 numbers'),
    ('camera_matrix: {data: [a, 0, 1, 0, 1, 1, 0, 0, 1]}\n', 'cannot be read'),
    ('camera_matrix: {data: [-5, 0, 1, 0, 1, 1, 0, 0, 1]}\n',
     'describes no usable camera: The focal lengths must be positive'),
])
def test_a_broken_camera_calibration_file_is_refused(text, message):
    with pytest.raises(CalibrationError, match=message):
        calibration.intrinsics_from_yaml(text)


def _longest(polylines):
    return max(polylines, key=lambda line: sum(
        math.dist(first[:2], second[:2]) for first, second in zip(line, line[1:])))


def _real_frames():
    """Return (source, frame, colour) of every labelled frame of white or black tape."""
    return [(source, labelled, REAL_TAPES[source.name]) for source in load_labels()
            if source.name in REAL_TAPES for labelled in source.frames]


@pytest.mark.parametrize('camera', [False, True], ids=['no_camera', 'camera'])
@pytest.mark.parametrize('source, labelled, colour', [
    pytest.param(*case, id=case[1].name, marks=[pytest.mark.xfail(
        reason=REAL_FRAME_LIMITS[case[1].name], strict=True)]
        if case[1].name in REAL_FRAME_LIMITS else []) for case in _real_frames()])
def test_a_real_frame_of_tape_gives_a_configuration_that_finds_it(source, labelled, colour,
                                                                  camera):
    folder, reason = frames_folder()
    if folder is None:
        pytest.skip(reason)
    image = cv2.imread(str(folder / source.name / labelled.name))
    # The user shows the middle of the frame's longest piece of tape.
    line = _longest(labelled.polylines(colour))
    x_px, y_px, _ = line[len(line) // 2]
    sample = line_sample.sample_at_point(image, (round(x_px), round(y_px)))
    geometry = source.geometry(labelled) if camera else None
    width_m = None
    if camera:
        width_m = round(line_sample.measure_line_width_m(sample, geometry).metres, 3)
    proposal = calibration.propose(image, 'bgr8', sample, geometry, width_m)
    assert proposal.passed, proposal.best.verdict.describe()
    assert proposal.config.line_colour == colour
    # Judged by the labels, not by the verification: a fresh detector, as on the robot.
    detection = LineDetector(proposal.config).detect(image, 'bgr8', geometry)
    tally = PerceptionTally()
    tally.add_frame(frame_line_truths(labelled, colour, detection, geometry,
                                      proposal.config.line_width_m), detection)
    assert tally.line_bands_right > tally.line_bands / 2
    assert tally.false <= 1
