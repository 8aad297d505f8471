"""
The line's colour: presets for yellow, white and black tape, and how each finds its pixels.

A camera's colours depend on its white balance and exposure as much as on the tape: under a
warm cast a dark rubber floor has the hue and saturation of a dim yellow, and a white line
turns cream. Fixed HSV bounds then take the whole floor for the line, or lose a pale one. So
the line's pixels are judged relative to the floor around them:

1. The floor's colour in each band of rows is the per-channel median of a sample of its
   pixels (the line covers a small part of a band). Their median over the bands that see the
   floor (but those a yellow line fills, coming into a corner) estimates the light's colour;
   dividing it out (a grey-world white balance, its gains
   kept within ``MAX_WHITE_BALANCE_GAIN``, enough for a camera without white balance under a
   warm or cold lamp, as a coloured floor would otherwise pull the balance far off) makes the
   floor neutral grey.
2. On the balanced colours each preset compares a pixel with its band's floor:

   - ``yellow``: yellowness ``min(red, green) - blue`` at least ``YELLOW_MIN_LEVELS`` above
     the floor's and at least ``YELLOW_MIN_SATURATION`` of the pixel's brightness (pale tape
     has saturation 40-100 of 255), and a hue within ``YELLOW_HUE_TOLERANCE`` of yellow
     (orange-yellow to lime), balanced or as the camera gave it;
   - ``white``: brighter than the floor by ``WHITE_MIN_CONTRAST`` of the way to full
     brightness, and nearly colourless;
   - ``black``: darker than the floor by ``BLACK_MIN_CONTRAST`` of its brightness, and
     nearly colourless;
   - ``custom``: the configured HSV bounds, applied to the balanced colours.

Each also gives a pixel's strength (how far past its threshold it is), from which the detector
judges a stripe's colour evidence. A preset's fixed HSV bounds (``PRESET_HSV_BOUNDS``) are the
first, fast look: on a well-lit clean scene they already find the line exactly, and the
relative judgement is needed only where they leave doubt.
"""

from typing import NamedTuple

import cv2
import numpy as np

LINE_COLOURS = ('yellow', 'white', 'black', 'custom')
# Presets whose line has a colour, which a grey (mono8) image cannot show.
CHROMATIC_COLOURS = ('yellow',)
# Presets whose line a shadow mimics: a deep shadow is as much darker than the floor as black
# tape. (A patch of light passes white too, but on real frames the brighter parts within one
# were glare, not tape.)
SHADOWED_COLOURS = ('black',)
# Fixed OpenCV HSV bounds ((hue, saturation, value) low, high) of each preset's first look.
PRESET_HSV_BOUNDS = {
    'yellow': ((20, 100, 50), (40, 255, 255)),
    'white': ((0, 0, 200), (179, 40, 255)),
    'black': ((0, 0, 0), (179, 255, 50)),
}
# Every how-many-th pixel of a band the floor's median is taken from: a band holds 2560 or
# more pixels, a sample of ~300 gives the same median to a level or two.
FLOOR_SAMPLE_STEP = 8
# The white balance corrects casts, not colours: each channel's gain stays within this factor.
# A camera without white balance under a warm (2700 K) or cold (6500 K) lamp needs about 1.5:
# with 1.2, worn yellow tape under a blue cast stayed cyan-grey and was lost. A floor that is
# itself strongly coloured still cannot pull the balance further.
MAX_WHITE_BALANCE_GAIN = 1.5
# The custom preset's HSV bounds take the line's colours as the camera gives them in the first
# look and balanced in the second: both must hold the line, and a balance far from the camera's
# colours would widen them until they took a coloured floor too.
MAX_CUSTOM_WHITE_BALANCE_GAIN = 1.2
# Darker floors than this (8-bit level) say little about the light's colour.
MIN_FLOOR_LEVEL = 8.0
YELLOW_MIN_LEVELS = 18.0
YELLOW_MIN_SATURATION = 0.14
# |red - green| at most this share of the yellowness: hue 35 to 85 degrees (yellow is 60).
YELLOW_HUE_TOLERANCE = 0.7
WHITE_MIN_CONTRAST = 0.3
BLACK_MIN_CONTRAST = 0.35
# Least contrast in 8-bit levels, whatever the floor: below it camera noise alone passes.
MIN_CONTRAST_LEVELS = 25.0
# Chroma (max - min) over brightness of a colourless pixel.
MAX_GREY_SATURATION = 0.3
MAX_LEVEL = 255.0
# A pixel must stand this many standard deviations of the floor's pixel noise above it, after
# smoothing along its row over SMOOTHING_KERNEL_PX (width, height).
NOISE_SIGMAS = 3.0
SMOOTHING_KERNEL_PX = (5, 1)
# The floor's values are read at these percentiles (outer, inner); for a normal distribution
# they lie QUANTILE_GAP_SIGMAS standard deviations apart, and the inner one QUARTILE_SIGMAS
# below the median.
FLOOR_PERCENTILES = [10, 25]
QUANTILE_GAP_SIGMAS = 0.6071
QUARTILE_SIGMAS = 0.6745
# The median absolute deviation of normally distributed values times this is their sigma.
MAD_TO_SIGMA = 1.4826
# Pixel noise is measured on every this-many-th pair of neighbouring pixels.
NOISE_SAMPLE_STEP = 4
# The common floor's spread is taken as at least this (8-bit levels): a perfectly flat render
# would otherwise make any band whose floor differs by a level look filled by the line.
MIN_COMMON_SIGMA = 4.0


def white_balance(band_pixels: np.ndarray, bands_on_floor, colour: str) -> np.ndarray:
    """
    Return the gains that make the floor grey: a grey-world balance on the floor, bounded.

    :param band_pixels: (bands, pixels, 3) uint8 BGR, or (bands, pixels) grey.
    :param bands_on_floor: indices of the bands that see the floor (below the horizon); the
        balance is estimated from them (from all bands when empty).
    :param colour: the preset, one of LINE_COLOURS: it bounds the gains
        (MAX_CUSTOM_WHITE_BALANCE_GAIN for custom, else MAX_WHITE_BALANCE_GAIN).
    :return: float32 gains per channel (one gain of 1 for a grey image). The floor's colour
        is the median over those bands of each band's per-channel median: a band the line
        fills (the nearest, in the simulator) does not sway it. A coloured line (yellow) that
        fills most of several bands (a corner running across the view) would: a band whose
        median stands out from the floor of all the bands together as the line does (as
        ``classify`` judges a band the line fills) is left out of the balance.
    """
    if band_pixels.ndim == 2:
        return np.ones(1, np.float32)
    chosen = list(bands_on_floor) or list(range(len(band_pixels)))
    sample = band_pixels[chosen, ::FLOOR_SAMPLE_STEP]
    medians = np.median(sample, axis=1)
    if colour in CHROMATIC_COLOURS:
        # White and black tape are colourless: filling a band, they leave its colour the light's.
        common = _floor_value(_feature(colour, sample.astype(np.float32), False), True)
        apart = _feature(colour, medians, False) - common
        on_floor = apart <= NOISE_SIGMAS * MIN_COMMON_SIGMA
        if on_floor.any():
            medians = medians[on_floor]
    floor = np.median(medians, axis=0)
    grey = float(floor.mean())
    if grey < MIN_FLOOR_LEVEL:
        return np.ones(3, np.float32)
    bound = MAX_CUSTOM_WHITE_BALANCE_GAIN if colour == 'custom' else MAX_WHITE_BALANCE_GAIN
    return np.clip(grey / np.maximum(floor, 1.0), 1.0 / bound, bound).astype(np.float32)


class FloorModel(NamedTuple):
    """
    What the floor of each band looks like to a colour preset, to judge any pixel against.

    ``typical`` and ``noise`` are each band's floor value of the preset's feature (yellowness
    for yellow, brightness for white and black) and its pixel noise, shaped (bands, 1).
    """

    colour: str
    grey: bool
    gains: np.ndarray
    typical: np.ndarray
    noise: np.ndarray
    hsv_bounds: tuple | None


def classify(colour: str, band_pixels: np.ndarray, gains: np.ndarray, row_width: int,
             bands_on_floor=(), hsv_bounds=None) -> tuple:
    """
    Judge every band pixel against its band's floor.

    :param colour: one of LINE_COLOURS.
    :param band_pixels: (bands, pixels, 3) uint8 BGR, or (bands, pixels) grey.
    :param gains: the white balance, from :func:`white_balance`.
    :param row_width: pixels in an image row: each band's pixels are its rows one after
        another, smoothed along the rows against camera noise.
    :param bands_on_floor: the indices of the bands below the horizon.
    :param hsv_bounds: for ``custom``, the ((h, s, v), (h, s, v)) OpenCV bounds.
    :return: (mask, strength, model): uint8 (bands, pixels), 1 for the line's pixels; float32
        strength, how many times its threshold a pixel's evidence is (above 1 on the line);
        the FloorModel, to judge other pixels of the image with :func:`pixel_strength`.
    :raises ValueError: for a chromatic colour on a grey image, or an unknown colour.
    """
    if colour not in LINE_COLOURS:
        raise ValueError(f'line_colour must be one of {", ".join(LINE_COLOURS)}, got '
                         f'{colour!r}.')
    if band_pixels.ndim == 2 and colour in CHROMATIC_COLOURS + ('custom',):
        raise ValueError(f'A grey image shows no {colour} line: use line_colour white or '
                         'black.')
    grey = band_pixels.ndim == 2
    pixels = smoothed(band_pixels.astype(np.float32), row_width)
    if colour == 'custom':
        model = FloorModel(colour, grey, gains, None, None, hsv_bounds)
    else:
        feature = _feature(colour, _balanced(pixels, gains, grey), grey)
        typical, noise = _floor_statistics(feature, bands_on_floor, row_width,
                                           floor_below=colour != 'black')
        model = FloorModel(colour, grey, gains, typical, noise, hsv_bounds)
    strength = pixel_strength(model, pixels)
    return (strength >= 1.0).astype(np.uint8), strength, model


def pixel_strength(model: FloorModel, pixels: np.ndarray, bands=None) -> np.ndarray:
    """
    Return how strongly pixels are the line's, against the floor of their bands.

    :param model: the FloorModel of the image.
    :param pixels: float32 pixels, (bands, pixels, 3) BGR or (bands, pixels) grey, already
        smoothed; or, with ``bands``, (n, 3) or (n,).
    :param bands: for a flat list of pixels, the band whose floor judges each (n,) ints.
    :return: float32 strength, of the pixels' shape without channels (>= 1 on the line).
    """
    balanced = _balanced(pixels, model.gains, model.grey)
    if model.colour == 'custom':
        return _hsv_strength(balanced, model.hsv_bounds)
    typical, noise = model.typical, model.noise
    if bands is not None:
        typical, noise = typical[bands, 0], noise[bands, 0]
    if not model.grey:
        blue, green, red = balanced[..., 0], balanced[..., 1], balanced[..., 2]
        level = np.maximum(np.maximum(red, green), blue)
        chroma = level - np.minimum(np.minimum(red, green), blue)
    else:
        level, chroma = balanced, np.zeros_like(balanced)
    if model.colour == 'yellow':
        yellowness = np.minimum(red, green) - blue
        needed = np.maximum(typical + np.maximum(YELLOW_MIN_LEVELS, NOISE_SIGMAS * noise),
                            YELLOW_MIN_SATURATION * level)
        strength = np.where(_yellow_hue(balanced, yellowness) | _yellow_hue(pixels),
                            yellowness / needed, 0.0)
    else:
        if model.colour == 'white':
            contrast = level - typical
            needed = WHITE_MIN_CONTRAST * (MAX_LEVEL - typical)
        else:
            contrast = typical - level
            needed = BLACK_MIN_CONTRAST * typical
        needed = np.maximum(np.maximum(needed, MIN_CONTRAST_LEVELS), NOISE_SIGMAS * noise)
        colourless = chroma <= MAX_GREY_SATURATION * np.maximum(level, typical)
        strength = np.where(colourless, contrast / needed, 0.0)
    return strength.astype(np.float32)


def strength_within(model: FloorModel, pixels: np.ndarray, band: int):
    """
    Return how strongly the pixels of a stretch of a band are the line's, against its own floor.

    A deep shadow is as much darker than the floor as black tape: over a stretch far wider
    than the line the black preset takes it all for the line. The tape in it still stands
    out from the shadow, as it does from the floor outside it. Each row of the stretch is
    judged against its own floor, as a band may hold a shadow's edge.

    :param model: the FloorModel of the image.
    :param pixels: float32 pixels of one band's rows over the stretch, (rows, n, 3) BGR or
        (rows, n) grey, already smoothed.
    :param band: the band's index in the model (top down): its pixel noise is the stretch's.
    :return: float32 strength (rows, n), judged with each row's lightest pixels of the
        stretch as its floor, or None for a preset whose line no shadow mimics (see
        SHADOWED_COLOURS).
    """
    if model.colour not in SHADOWED_COLOURS:
        return None
    feature = _feature(model.colour, _balanced(pixels, model.gains, model.grey), model.grey)
    local = model._replace(typical=_floor_value(feature, floor_below=False, axis=1),
                           noise=np.repeat(model.noise[band:band + 1], len(pixels), axis=0))
    return pixel_strength(local, pixels)


def _yellow_hue(pixels: np.ndarray, yellowness: np.ndarray | None = None) -> np.ndarray:
    """
    Tell which BGR pixels have a hue within YELLOW_HUE_TOLERANCE of yellow.

    ``yellowness`` is the pixels' ``min(red, green) - blue`` when the caller has it already.

    The tape's hue is accepted as balanced or as the camera gave it: a strongly coloured floor
    (a magenta carpet) pulls the grey-world balance, within its bounds, so far that yellow tape
    turns lime, while the camera's own colours still show it yellow. Its contrast with the
    floor is judged on the balanced colours either way, so a cast floor stays floor.
    """
    blue, green, red = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    if yellowness is None:
        yellowness = np.minimum(red, green) - blue
    return np.abs(red - green) <= YELLOW_HUE_TOLERANCE * yellowness


def _balanced(pixels: np.ndarray, gains: np.ndarray, grey: bool) -> np.ndarray:
    """Return colour pixels white-balanced; grey pixels as they are."""
    return pixels if grey else pixels * gains


def _feature(colour: str, balanced: np.ndarray, grey: bool) -> np.ndarray:
    """Return the feature a preset judges by: yellowness, or brightness."""
    if grey:
        return balanced
    blue, green, red = balanced[..., 0], balanced[..., 1], balanced[..., 2]
    if colour == 'yellow':
        return np.minimum(red, green) - blue
    return np.maximum(np.maximum(red, green), blue)


def smoothed(pixels: np.ndarray, row_width: int) -> np.ndarray:
    """
    Return band pixels averaged along their row over SMOOTHING_KERNEL_PX (noise / 2.2).

    Along the row only: the rows above and below a band's are not in it (the next row of
    the buffer is another band's), and a line's end must not spread into a band it misses.
    """
    rows = pixels.reshape((-1, row_width) + pixels.shape[2:])
    return cv2.blur(rows, SMOOTHING_KERNEL_PX).reshape(pixels.shape)


def _floor_statistics(feature: np.ndarray, bands_on_floor, row_width: int,
                      floor_below: bool = True):
    """
    Return each band's typical floor value of a feature, and its noise.

    The line may cover half of a near band (the simulator's 0.19 m line at 0.3 m), so the
    median is not the floor's: the floor is taken from the quarter of the pixels farthest
    from the line's side (lowest yellowness or brightness for yellow and white, highest
    brightness for black). Where the line covers even more of a band (a corner across the
    view), that quarter is the line's: a band whose floor stands out from the floor of all
    the bands together by more than NOISE_SIGMAS of its noise takes the bands' common floor.
    The noise is measured from neighbouring pixels' differences (a robust deviation), so a
    band of several floor materials (a mat, a green verge, white signs) does not count as
    noisy.

    :param feature: (bands, pixels) float32, each band's rows one after another.
    :param bands_on_floor: the indices of the bands below the horizon.
    :param row_width: pixels in an image row.
    :param floor_below: whether the floor lies below the line in this feature.
    :return: (typical floor value, standard deviation of its pixel noise), each (bands, 1).
    """
    sample = feature[:, ::FLOOR_SAMPLE_STEP]
    typical = _floor_value(sample, floor_below, axis=1)
    rows = feature.reshape(len(feature), -1, row_width)
    steps = np.abs(rows[:, :, 1::NOISE_SAMPLE_STEP] - rows[:, :, :-1:NOISE_SAMPLE_STEP])
    noise = (MAD_TO_SIGMA / np.sqrt(2.0)) * np.median(
        steps.reshape(len(feature), -1), axis=1, keepdims=True)
    chosen = list(bands_on_floor) or list(range(len(feature)))
    common_typical = _floor_value(sample[chosen], floor_below)
    common_noise = float(np.median(noise[chosen]))
    apart = (typical - common_typical) if floor_below else (common_typical - typical)
    line_filled = apart > NOISE_SIGMAS * max(common_noise, MIN_COMMON_SIGMA)
    return np.where(line_filled, common_typical, typical), noise


def _floor_value(samples: np.ndarray, floor_below: bool, axis=None):
    """
    Return the floor's typical value among samples of a feature, the line's among them.

    The median of a normal distribution, found from its 10th and 25th percentiles (90th and
    75th when the floor lies above the line), the side the line does not reach.

    :param axis: the axis the samples lie along (kept, of length 1), or None for all.
    """
    percentiles = (FLOOR_PERCENTILES if floor_below
                   else [100 - value for value in FLOOR_PERCENTILES])
    outer, inner = np.percentile(samples, percentiles, axis=axis, keepdims=axis is not None)
    offset = QUARTILE_SIGMAS * np.abs(inner - outer) / QUANTILE_GAP_SIGMAS
    return inner + offset if floor_below else inner - offset


def _hsv_strength(balanced: np.ndarray, hsv_bounds) -> np.ndarray:
    """Return 1 for balanced colours within OpenCV HSV bounds, 0 outside."""
    pixels = np.clip(balanced, 0.0, MAX_LEVEL).astype(np.uint8)
    lower, upper = (np.array(bound, np.uint8) for bound in hsv_bounds)
    hsv = cv2.cvtColor(pixels.reshape(1, -1, 3), cv2.COLOR_BGR2HSV)
    # (bands, pixels, 3) or a flat (n, 3) list of pixels: the verdicts drop the channels.
    inside = cv2.inRange(hsv, lower, upper).reshape(pixels.shape[:-1])
    return (inside > 0).astype(np.float32)
