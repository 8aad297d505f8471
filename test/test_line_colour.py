"""The line colour presets: the line's pixels judged against the floor around them."""

from followbot import line_colour
import numpy as np
import pytest

BANDS = 6
ROWS = 4
ROW_WIDTH = 320
LINE_COLUMNS = slice(140, 180)


def bands_of(floor_bgr, line_bgr=None, line_columns=LINE_COLUMNS, grey=False):
    """Return band pixels: every band a floor with (optionally) a stripe of the line."""
    pixels = np.empty((BANDS, ROWS, ROW_WIDTH, 3), np.uint8)
    pixels[:] = floor_bgr
    if line_bgr is not None:
        pixels[:, :, line_columns] = line_bgr
    pixels = pixels.reshape(BANDS, ROWS * ROW_WIDTH, 3)
    if grey:
        return pixels[..., 1].copy()
    return pixels


def line_share(mask):
    """Return the share of the stripe's pixels, and of the floor's, that the mask took."""
    per_pixel = mask.reshape(BANDS, ROWS, ROW_WIDTH)
    on_line = per_pixel[:, :, LINE_COLUMNS].mean()
    off = np.ones(ROW_WIDTH, bool)
    off[LINE_COLUMNS] = False
    # Leave the smoothing's reach beside the stripe out of the floor.
    off[LINE_COLUMNS.start - 2:LINE_COLUMNS.stop + 2] = False
    return on_line, per_pixel[:, :, off].mean()


def judge(colour, pixels, **options):
    """Classify band pixels with a preset, white-balanced on all bands."""
    gains = line_colour.white_balance(pixels, range(BANDS), colour)
    mask, _, _ = line_colour.classify(colour, pixels, gains, ROW_WIDTH, range(BANDS), **options)
    return line_share(mask)


@pytest.mark.parametrize('floor_bgr, line_bgr', (
    ((116, 116, 116), (0, 246, 255)),        # the simulator's course
    ((40, 42, 45), (30, 190, 210)),          # a dark rubber mat
    ((35, 70, 85), (40, 200, 230)),          # the mat under a warm cast
    ((60, 90, 60), (50, 210, 200)),          # a green cast
    ((150, 160, 165), (110, 200, 215)),      # pale tape (saturation ~0.5) on light concrete
    ((120, 125, 125), (95, 135, 140)),       # faded tape (saturation ~0.32)
    # A magenta carpet pulls the balance so far that the tape would turn lime (home preset).
    ((32, 30, 45), (32, 122, 117)),
    # Worn tape on a carpet, a cold lamp and no white balance: the camera shows it cyan-grey.
    ((106, 83, 65), (140, 142, 113)),
), ids=('course', 'dark_mat', 'warm_cast', 'green_cast', 'pale_tape', 'faded_tape',
        'magenta_carpet', 'cold_cast_no_white_balance'))
def test_yellow_tape_is_found_and_its_floor_is_not(floor_bgr, line_bgr):
    on_line, on_floor = judge('yellow', bands_of(floor_bgr, line_bgr))
    assert on_line == 1.0
    assert on_floor == 0.0


def test_under_a_warm_cast_the_bare_floor_is_not_yellow():
    # The fixed HSV bounds take this floor for yellow (hue ~33, saturation ~150).
    on_line, on_floor = judge('yellow', bands_of((35, 70, 85)))
    assert on_floor == 0.0


@pytest.mark.parametrize('line_bgr', (
    (230, 235, 235),     # white tape
    (200, 220, 240),     # a warm-tinted white line
    (40, 140, 250),      # orange
    (60, 200, 60),       # green
), ids=('white', 'warm_white', 'orange', 'green'))
def test_what_is_not_yellow_is_not_taken_for_yellow(line_bgr):
    on_line, _ = judge('yellow', bands_of((60, 62, 64), line_bgr))
    assert on_line == 0.0


@pytest.mark.parametrize('floor_bgr, line_bgr', (
    ((120, 120, 120), (235, 235, 235)),
    ((40, 42, 45), (180, 185, 185)),
    ((100, 110, 120), (200, 215, 230)),      # under a warm cast
), ids=('grey_carpet', 'dark_mat', 'warm_cast'))
def test_white_tape_is_brighter_than_its_floor_and_colourless(floor_bgr, line_bgr):
    on_line, on_floor = judge('white', bands_of(floor_bgr, line_bgr))
    assert on_line == 1.0 and on_floor == 0.0
    assert judge('white', bands_of(floor_bgr, (0, 220, 240)))[0] == 0.0, 'yellow is not white'


@pytest.mark.parametrize('floor_bgr, line_bgr', (
    ((190, 195, 195), (30, 30, 32)),
    ((120, 120, 120), (45, 45, 45)),
), ids=('light_vinyl', 'grey_carpet'))
def test_black_tape_is_darker_than_its_floor(floor_bgr, line_bgr):
    on_line, on_floor = judge('black', bands_of(floor_bgr, line_bgr))
    assert on_line == 1.0 and on_floor == 0.0


def test_black_tape_stands_out_within_a_shadow_and_the_shadow_does_not():
    pixels = bands_of((150, 150, 150), (45, 45, 45), line_columns=slice(0, 200))
    pixels.reshape(BANDS, ROWS, ROW_WIDTH, 3)[:, :, 90:100] = 12
    gains = line_colour.white_balance(pixels, range(BANDS), 'black')
    mask, _, model = line_colour.classify('black', pixels, gains, ROW_WIDTH, range(BANDS))
    # Against the band's floor the whole shadow is the line's colour ...
    assert mask.reshape(BANDS, ROWS, ROW_WIDTH)[:, :, 10:190].all()
    # ... against the shadow itself only the tape is.
    stretch = pixels.reshape(BANDS, ROWS, ROW_WIDTH, 3)[2, :, :200].astype(np.float32)
    strength = line_colour.strength_within(model, stretch, 2)
    assert (strength[:, 90:100] >= 1.0).all()
    assert (strength[:, :85] < 1.0).all() and (strength[:, 105:] < 1.0).all()


@pytest.mark.parametrize('preset', ('yellow', 'white'))
def test_only_black_tape_is_looked_for_within_a_stretch(preset):
    pixels = bands_of((120, 120, 120), (230, 230, 230))
    gains = line_colour.white_balance(pixels, range(BANDS), preset)
    _, _, model = line_colour.classify(preset, pixels, gains, ROW_WIDTH, range(BANDS))
    stretch = pixels.reshape(BANDS, ROWS, ROW_WIDTH, 3)[0].astype(np.float32)
    assert line_colour.strength_within(model, stretch, 0) is None


@pytest.mark.parametrize('preset, line_grey', (('white', 230), ('black', 25)))
def test_grey_images_show_white_and_black_tape(preset, line_grey):
    pixels = bands_of((120, 120, 120), (line_grey,) * 3, grey=True)
    on_line, on_floor = judge(preset, pixels)
    assert on_line == 1.0 and on_floor == 0.0


@pytest.mark.parametrize('preset', ('yellow', 'custom'))
def test_a_grey_image_cannot_show_a_coloured_line(preset):
    pixels = bands_of((120, 120, 120), grey=True)
    with pytest.raises(ValueError, match='white or black'):
        line_colour.classify(preset, pixels, np.ones(1, np.float32), ROW_WIDTH)


def test_an_unknown_preset_is_refused():
    with pytest.raises(ValueError, match='line_colour must be one of'):
        line_colour.classify('purple', bands_of((1, 2, 3)), np.ones(3, np.float32), ROW_WIDTH)


def test_camera_noise_on_the_floor_is_not_the_line():
    pixels = bands_of((116, 116, 116), (0, 246, 255)).astype(float)
    pixels += np.random.default_rng(3).normal(0.0, 24.0, pixels.shape)
    on_line, on_floor = judge('yellow', np.clip(pixels, 0, 255).astype(np.uint8))
    assert on_line > 0.99
    # Single pixels: the detector's stripes need most of a band's rows in a column, and the
    # line's width, which such specks never make.
    assert on_floor < 0.02


def test_a_band_the_line_fills_is_judged_by_the_other_bands_floor():
    # The nearest band looks at the line running across it: no floor of its own to compare.
    pixels = bands_of((116, 116, 116), (0, 246, 255)).reshape(BANDS, ROWS, ROW_WIDTH, 3)
    pixels[0, :, 10:310] = (0, 246, 255)
    mask, _, _ = line_colour.classify('yellow', pixels.reshape(BANDS, -1, 3),
                                      np.ones(3, np.float32), ROW_WIDTH, range(BANDS))
    assert mask.reshape(BANDS, ROWS, ROW_WIDTH)[0, :, 10:310].all()


def test_custom_bounds_are_applied_to_white_balanced_colours():
    bounds = ((100, 150, 50), (130, 255, 255))     # blue, in OpenCV HSV
    on_line, on_floor = judge('custom', bands_of((116, 116, 116), (200, 60, 20)),
                              hsv_bounds=bounds)
    assert on_line == 1.0 and on_floor == 0.0


@pytest.mark.parametrize('preset, bound', (
    ('yellow', line_colour.MAX_WHITE_BALANCE_GAIN),
    ('custom', line_colour.MAX_CUSTOM_WHITE_BALANCE_GAIN),
))
def test_the_white_balance_is_bounded_and_neutral_on_grey(preset, bound):
    assert line_colour.white_balance(bands_of((116, 116, 116)), range(BANDS), preset) == (
        pytest.approx([1.0, 1.0, 1.0]))
    gains = line_colour.white_balance(bands_of((20, 120, 200)), range(BANDS), preset)
    assert gains.max() == pytest.approx(bound)
    assert gains.min() == pytest.approx(1.0 / bound)
    assert list(line_colour.white_balance(bands_of((1, 1, 1), grey=True), (), preset)) == [1.0]


def test_pale_tape_filling_most_bands_does_not_sway_the_white_balance():
    # Coming into a corner, pale worn tape runs across the view and fills most of four
    # bands' pixels (the harsh realism preset's colours): balanced on those bands, the tape
    # would turn grey and be lost.
    floor_bgr, tape_bgr = (50, 50, 50), (196, 249, 249)
    pixels = bands_of(floor_bgr, tape_bgr)
    filled = bands_of(floor_bgr, tape_bgr, line_columns=slice(60, 300))
    pixels[:4] = filled[:4]
    gains = line_colour.white_balance(pixels, range(BANDS), 'yellow')
    assert gains == pytest.approx([1.0, 1.0, 1.0])
    mask, _, _ = line_colour.classify('yellow', pixels, gains, ROW_WIDTH, range(BANDS))
    per_pixel = mask.reshape(BANDS, ROWS, ROW_WIDTH)
    assert per_pixel[:4, :, 62:298].all() and per_pixel[4:, :, 142:178].all()
    assert not per_pixel[:, :, :58].any()


def test_pixel_strength_judges_any_pixels_against_their_bands_floor():
    pixels = bands_of((40, 42, 45), (30, 190, 210))
    gains = line_colour.white_balance(pixels, range(BANDS), 'yellow')
    _, _, model = line_colour.classify('yellow', pixels, gains, ROW_WIDTH, range(BANDS))
    samples = np.array([[30, 190, 210], [40, 42, 45]], np.float32)
    strength = line_colour.pixel_strength(model, samples, np.array([0, 5]))
    assert strength[0] >= 1.0 > strength[1]


def test_custom_bounds_judge_a_list_of_pixels_too():
    # The detector judges the pixels between two bands' stripes as a flat list.
    bounds = ((100, 150, 50), (130, 255, 255))
    pixels = bands_of((116, 116, 116), (200, 60, 20))
    gains = line_colour.white_balance(pixels, range(BANDS), 'custom')
    _, _, model = line_colour.classify('custom', pixels, gains, ROW_WIDTH, range(BANDS),
                                       hsv_bounds=bounds)
    samples = np.array([[200, 60, 20], [116, 116, 116]], np.float32)
    strength = line_colour.pixel_strength(model, samples, np.array([0, 5]))
    assert list(strength) == [1.0, 0.0]
