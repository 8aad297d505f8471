"""
Tests of the realism presets: drawn by seed, rendered without warnings, repeatable bit for bit.

The camera model's lens is checked the way a user meets it: the published K and D, given to the
ground truth, put the line where the distorted frame shows it.
"""

import dataclasses
import math

from followbot_sim.appearance import floor_pattern
from followbot_sim.camera_model import CameraModel
from followbot_sim.camera_model import plumb_bob_distort
from followbot_sim.camera_model import radial_undistortion_factor
from followbot_sim.course import make_course
from followbot_sim.realism import FLOOR_KINDS
from followbot_sim.realism import kelvin_to_rgb
from followbot_sim.realism import PRESET_NAMES
from followbot_sim.realism import realise
from followbot_sim.world import FollowbotWorld
import mujoco
import numpy as np
import pytest

COURSE_NAME = 'book_loop'
DRIVE_S = 1.0
FRAME_INTERVAL_S = 0.05
FRAMES = 3
# Truth and the distorted drawing agree to this.
MAX_ERROR_PX = 1.0
MAX_CHECKED_SLOPE_PX = 0.5
MIN_LINE_WEIGHT = 3.0
EDGE_MARGIN_PX = 2.0
WARNING_NAMES = tuple(name for name in mujoco.mjtWarning.__members__ if name != 'mjNWARNING')


@pytest.fixture(scope='module')
def course():
    """Build the book loop once."""
    return make_course(COURSE_NAME)


def drive_and_render(world):
    """Drive a bend and return copies of the frames taken on the way."""
    world.set_twist(0.4, 0.6)
    world.step(DRIVE_S)
    frames = []
    for _ in range(FRAMES):
        world.step(FRAME_INTERVAL_S)
        frames.append(world.render_camera().copy())
    return frames


def test_the_same_preset_and_seed_draw_the_same_world():
    """A seed fixes every choice; another seed changes some."""
    assert realise('home', 3) == realise('home', 3)
    assert realise('home', 3) != realise('home', 4)


@pytest.mark.parametrize('preset, seed', [('nowhere', 0), ('lab', -1), ('lab', 1.5)])
def test_bad_preset_or_seed_is_refused_with_a_sentence(preset, seed):
    """An unknown preset or a bad seed names itself."""
    with pytest.raises(ValueError, match='realism'):
        realise(preset, seed)


def test_warm_light_is_red_and_daylight_is_near_white():
    """2700 K light is orange; 6500 K is white to a few percent."""
    red, green, blue = kelvin_to_rgb(2700.0)
    assert red == 1.0 and blue < green < 0.75
    np.testing.assert_allclose(kelvin_to_rgb(6500.0), 1.0, atol=0.05)


@pytest.mark.parametrize('yaw_rate_radps', (0.3, 0.5, 3.0))
def test_motion_blur_smears_an_edge_without_brightening_the_frame(yaw_rate_radps):
    # The blur alone: no lens, vignetting, white balance, exposure control, noise or JPEG.
    realism = dataclasses.replace(
        realise('lab', 1), white_balance_error=None, auto_exposure=False, vignetting=0.0,
        radial_distortion_k1=0.0, exposure_time_s=0.01, read_noise_levels=0.0,
        shot_noise_gain=0.0, jpeg_quality=0)
    focal_px = 320.0 / math.tan(math.radians(30.0))
    model = CameraModel(realism, (focal_px, focal_px, 319.5, 239.5), (640, 480))
    image = np.full((480, 640, 3), 40, np.uint8)
    image[:, 320:] = 201
    assert np.array_equal(model.process(image.copy(), 0, 0.0, 0.0), image)
    blurred = model.process(image.copy(), 1, 0.0, yaw_rate_radps).copy()
    # A turn smears across: the edge's columns take rising levels between the two sides, as
    # many as the smear is wide (the rate times the exposure, in pixels), and each side keeps
    # its own level away from the edge. The mean moves only as far as an even smear shifts
    # the edge (half a pixel) and each smeared pixel rounds (half a level): no pixel is
    # rounded up by more.
    smear_px = max(1, round(yaw_rate_radps * realism.exposure_time_s * focal_px))
    row = blurred[240, :, 0].astype(int)
    between = np.flatnonzero((row > 40) & (row < 201))
    assert len(between) == smear_px - 1
    assert (np.diff(row[between]) > 0).all()
    assert (row[:300] == 40).all() and (row[340:] == 201).all()
    half_pixel_shift = 0.5 * (smear_px % 2 == 0) * (201 - 40) / 640
    rounding = 0.5 * (smear_px - 1) / 640
    assert abs(blurred.mean() - image.mean()) <= half_pixel_shift + rounding + 1e-9


def test_radial_undistortion_inverts_plumb_bob():
    """Undistorting a distorted radius gives the radius back."""
    coefficients = (-0.2, 0.0, 0.0, 0.0, 0.0)
    radius = np.linspace(0.0, 0.9, 50)
    distorted, _ = plumb_bob_distort(radius, np.zeros_like(radius), coefficients)
    recovered = distorted * radial_undistortion_factor(distorted, coefficients)
    np.testing.assert_allclose(recovered, radius, atol=1e-9)


def test_every_floor_kind_looks_different():
    """Five floors, five different mean colours and textures."""
    looks = []
    for kind in FLOOR_KINDS:
        floor = floor_pattern(kind, np.random.default_rng(0), 256, 10.0)
        assert floor.shape == (256, 256, 3)
        assert floor.std() > 2.0, f'{kind} is flat'
        looks.append(floor.reshape(-1, 3).mean(axis=0))
    distances = [np.abs(a - b).max() for i, a in enumerate(looks) for b in looks[i + 1:]]
    assert min(distances) > 5.0


def warning_counts(world):
    """Return MuJoCo's warnings that fired, by name."""
    return {name: int(world.data.warning[getattr(mujoco.mjtWarning, name)].number)
            for name in WARNING_NAMES
            if world.data.warning[getattr(mujoco.mjtWarning, name)].number}


@pytest.mark.parametrize('preset', PRESET_NAMES)
def test_every_preset_renders_without_mujoco_warnings(opengl, course, preset):
    """Each preset's world steps and renders cleanly, and shows a frame with contrast."""
    world = FollowbotWorld(course, realism=realise(preset, 1))
    try:
        frames = drive_and_render(world)
        assert warning_counts(world) == {}
        assert frames[-1].std() > 5.0
    finally:
        world.close()


def test_the_same_seed_gives_the_same_frames_bit_for_bit(opengl, course):
    """Two worlds from one preset and seed render identical frames; another seed does not."""
    frames = []
    for seed in (5, 5, 6):
        world = FollowbotWorld(course, realism=realise('harsh', seed))
        try:
            frames.append(drive_and_render(world))
        finally:
            world.close()
    for first, second in zip(frames[0], frames[1]):
        assert np.array_equal(first, second)
    assert not np.array_equal(frames[0][-1], frames[2][-1])


def test_clean_preset_is_the_scene_without_realism(opengl, course):
    """``clean`` changes nothing: the frames are today's."""
    frames = []
    for realism in (None, realise('clean', 9)):
        world = FollowbotWorld(course, realism=realism)
        try:
            frames.append(drive_and_render(world))
        finally:
            world.close()
    for first, second in zip(*frames):
        assert np.array_equal(first, second)


def line_centre_px(image_row):
    """Return the coverage-weighted centre column of saturated yellow in one row."""
    row = image_row.astype(float)
    yellowness = np.minimum(row[:, 0], row[:, 1]) - row[:, 2]
    coverage = np.clip((yellowness - 20.0) / 180.0, 0.0, 1.0)
    weight = coverage.sum()
    if weight < MIN_LINE_WEIGHT:
        return math.nan
    return float((coverage * np.arange(len(coverage))).sum() / weight)


def test_distorted_frames_match_the_published_lens(opengl, course):
    """The ground truth through camera_info's K and D lies on the line in distorted frames."""
    lens_only = dataclasses.replace(
        realise('harsh', 2), floor='concrete', tape_saturation_levels=255.0, tape_wear=0.0,
        light_temperatures_k=(), white_balance_error=None, clutter_count=0, walls=False,
        second_line=False, auto_exposure=False, vignetting=0.0, radial_distortion_k1=-0.25,
        exposure_time_s=0.0, read_noise_levels=0.0, shot_noise_gain=0.0, jpeg_quality=0)
    world = FollowbotWorld(course, realism=lens_only)
    try:
        intrinsics, distortion = world.published_camera_model()
        assert distortion[0] == pytest.approx(-0.25)
        # Barrel distortion zooms the published focal length in to fill the frame.
        assert intrinsics[0] > world.camera_intrinsics()[0]
        image = world.render_camera()
        truth = world.line_truth(row_step_px=1)
        width_px = world.image_size_px[0]
        checked = 0
        for row, crossings, next_crossings in zip(truth.rows_px, truth.crossings,
                                                  truth.crossings[1:]):
            if len(crossings) != 1 or len(next_crossings) != 1:
                continue
            column_px, line_width_px = crossings[0]
            margin_px = EDGE_MARGIN_PX + line_width_px / 2
            if (abs(next_crossings[0][0] - column_px) > MAX_CHECKED_SLOPE_PX
                    or not margin_px <= column_px <= width_px - 1 - margin_px):
                continue
            drawn_px = line_centre_px(image[int(row)])
            assert abs(drawn_px - column_px) <= MAX_ERROR_PX, (
                f'row {row}: truth {column_px:.2f} px, drawn {drawn_px:.2f} px')
            checked += 1
        assert checked >= 50
    finally:
        world.close()
