"""
Realism presets: how far the simulator's world and camera depart from the clean, ideal scene.

A preset names ranges (floors to choose from, colour temperatures, tape saturation, noise
levels...); :func:`realise` draws one concrete :class:`Realism` from a preset and a seed, so the
same preset and seed always give the same world and the same frames. ``clean`` is the scene the
simulator always had: a grey floor, a perfect yellow line, one white light, an ideal camera.

What each setting does is built by :mod:`followbot_sim.appearance` (floor and tape textures,
lights, clutter) and :mod:`followbot_sim.camera_model` (exposure, white balance, vignetting,
motion blur, lens distortion, sensor noise, JPEG). Pure: no ROS, no MuJoCo.
"""

import dataclasses

import numpy as np

CLEAN = 'clean'
FLOOR_KINDS = ('concrete', 'wood', 'vinyl', 'carpet', 'rubber')
SECOND_LINE_COLOURS = {'white': (235, 235, 230), 'blue': (30, 70, 190), 'red': (190, 40, 35)}


@dataclasses.dataclass(frozen=True)
class Preset:
    """
    The ranges one preset draws its world and camera from; (low, high) pairs are uniform.

    Shadows cost ~60 ms a 640x480 frame on a CPU renderer (Mesa llvmpipe), three times the
    rest of the frame: the presets held to >= 3x real time (lab, home) light without them.
    Temperatures in kelvin; saturations in OpenCV levels (0-255); levels in 8-bit intensity;
    distortion coefficients of the plumb_bob model; times in seconds.
    """

    floors: tuple = ()
    tape_saturation_levels: tuple = (255.0, 255.0)
    tape_wear: tuple = (0.0, 0.0)
    light_count: tuple = (0, 0)
    colour_temperature_k: tuple = (6500.0, 6500.0)
    white_balance_error: tuple = (0.0, 0.0)
    shadows: bool = False
    light_level: tuple = (0.6, 0.6)
    clutter_count: tuple = (0, 0)
    yellow_clutter_share: float = 0.0
    walls: bool = False
    second_line: bool = False
    auto_exposure: bool = False
    vignetting: tuple = (0.0, 0.0)
    radial_distortion_k1: tuple = (0.0, 0.0)
    exposure_time_s: tuple = (0.0, 0.0)
    read_noise_levels: tuple = (0.0, 0.0)
    shot_noise_gain: tuple = (0.0, 0.0)
    jpeg_quality: tuple = (0, 0)


PRESETS = {
    CLEAN: Preset(),
    'lab': Preset(
        floors=('concrete', 'vinyl'), tape_saturation_levels=(200.0, 255.0),
        tape_wear=(0.0, 0.15), light_count=(2, 3), colour_temperature_k=(4500.0, 5500.0),
        white_balance_error=(0.0, 0.05), shadows=False, light_level=(0.45, 0.6),
        clutter_count=(4, 6), yellow_clutter_share=0.15, walls=True, auto_exposure=True,
        vignetting=(0.1, 0.2), radial_distortion_k1=(-0.08, -0.03),
        exposure_time_s=(0.004, 0.008), read_noise_levels=(1.0, 2.0),
        shot_noise_gain=(0.05, 0.1)),
    'home': Preset(
        floors=('wood', 'carpet', 'vinyl'), tape_saturation_levels=(140.0, 230.0),
        tape_wear=(0.1, 0.3), light_count=(2, 3), colour_temperature_k=(2700.0, 3500.0),
        white_balance_error=(0.05, 0.2), shadows=False, light_level=(0.35, 0.5),
        clutter_count=(6, 10), yellow_clutter_share=0.2, walls=True, auto_exposure=True,
        vignetting=(0.2, 0.35), radial_distortion_k1=(-0.15, -0.05),
        exposure_time_s=(0.008, 0.015), read_noise_levels=(2.0, 3.0),
        shot_noise_gain=(0.1, 0.2), jpeg_quality=(80, 92)),
    'warehouse': Preset(
        floors=('concrete', 'rubber'), tape_saturation_levels=(100.0, 200.0),
        tape_wear=(0.3, 0.5), light_count=(3, 4), colour_temperature_k=(4000.0, 6500.0),
        white_balance_error=(0.05, 0.15), shadows=True, light_level=(0.4, 0.55),
        clutter_count=(10, 14), yellow_clutter_share=0.3, walls=True, second_line=True,
        auto_exposure=True, vignetting=(0.15, 0.3), radial_distortion_k1=(-0.12, -0.05),
        exposure_time_s=(0.008, 0.015), read_noise_levels=(2.0, 4.0),
        shot_noise_gain=(0.1, 0.25), jpeg_quality=(75, 90)),
    'outdoor': Preset(
        floors=('concrete', 'rubber'), tape_saturation_levels=(120.0, 220.0),
        tape_wear=(0.2, 0.4), light_count=(1, 1), colour_temperature_k=(5500.0, 6500.0),
        white_balance_error=(0.0, 0.1), shadows=True, light_level=(0.7, 0.9),
        clutter_count=(5, 8), yellow_clutter_share=0.2, second_line=True, auto_exposure=True,
        vignetting=(0.1, 0.25), radial_distortion_k1=(-0.1, -0.04),
        exposure_time_s=(0.002, 0.005), read_noise_levels=(1.0, 2.0),
        shot_noise_gain=(0.05, 0.15), jpeg_quality=(80, 92)),
    'harsh': Preset(
        floors=FLOOR_KINDS, tape_saturation_levels=(40.0, 100.0), tape_wear=(0.5, 0.8),
        light_count=(2, 4), colour_temperature_k=(2700.0, 6500.0),
        white_balance_error=(0.2, 0.5), shadows=True, light_level=(0.3, 0.7),
        clutter_count=(10, 16), yellow_clutter_share=0.4, walls=True, second_line=True,
        auto_exposure=True, vignetting=(0.3, 0.5), radial_distortion_k1=(-0.25, -0.12),
        exposure_time_s=(0.015, 0.03), read_noise_levels=(4.0, 8.0),
        shot_noise_gain=(0.3, 0.6), jpeg_quality=(50, 70)),
}
PRESET_NAMES = tuple(PRESETS)


@dataclasses.dataclass(frozen=True)
class Realism:
    """
    One concrete world and camera drawn from a preset by a seed.

    :ivar preset: the preset's name.
    :ivar seed: the seed it was drawn with; textures, clutter and noise derive from it.
    :ivar floor: a :data:`FLOOR_KINDS` entry, or None for the clean grey floor.
    :ivar light_temperatures_k: colour temperature of each added light; empty keeps the
        clean scene's single white light.
    :ivar white_balance_error: how far the camera's white balance misjudges the light's
        temperature (0 = perfect; as a fraction of it); None: no white balance at all.
    """

    preset: str
    seed: int
    floor: str | None
    tape_saturation_levels: float
    tape_wear: float
    light_temperatures_k: tuple
    white_balance_error: float | None
    shadows: bool
    light_level: float
    clutter_count: int
    yellow_clutter_share: float
    walls: bool
    second_line: bool
    auto_exposure: bool
    vignetting: float
    radial_distortion_k1: float
    exposure_time_s: float
    read_noise_levels: float
    shot_noise_gain: float
    jpeg_quality: int

    @property
    def is_clean(self) -> bool:
        """Return whether this is the clean scene (nothing added to world or camera)."""
        return self.preset == CLEAN

    def generator(self, purpose: str) -> np.random.Generator:
        """
        Return a generator for one purpose, independent of the others' draws.

        :param purpose: a short name ('floor', 'clutter', ...); each gives its own stream.
        :return: a PCG64 generator seeded by the seed and the purpose.
        """
        purpose_key = int.from_bytes(purpose.encode('utf-8')[:8].ljust(8, b'\0'), 'little')
        return np.random.Generator(np.random.PCG64([self.seed, purpose_key]))


def realise(preset_name: str, seed: int) -> Realism:
    """
    Draw a concrete world and camera from a preset.

    :param preset_name: one of :data:`PRESET_NAMES`.
    :param seed: a non-negative integer; the same preset and seed give the same Realism.
    :return: the Realism.
    :raises ValueError: for an unknown preset or a negative or non-integer seed.
    """
    if preset_name not in PRESETS:
        raise ValueError(f'unknown realism preset {preset_name!r}: use one of '
                         f'{", ".join(PRESET_NAMES)}.')
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f'realism seed must be a non-negative integer, got {seed!r}.')
    preset = PRESETS[preset_name]
    rng = np.random.Generator(np.random.PCG64([int(seed), PRESET_NAMES.index(preset_name)]))

    def uniform(bounds):
        low, high = bounds
        return float(rng.uniform(low, high)) if high > low else float(low)

    def integer(bounds):
        low, high = bounds
        return int(rng.integers(low, high, endpoint=True))

    floor = str(rng.choice(preset.floors)) if preset.floors else None
    light_count = integer(preset.light_count)
    base_temperature_k = uniform(preset.colour_temperature_k)
    # Mixed sources in one room differ a little; outdoors there is one sun.
    temperatures = tuple(float(np.clip(base_temperature_k * rng.uniform(0.9, 1.1),
                                       *preset.colour_temperature_k))
                         for _ in range(light_count))
    harsh_no_balance = preset_name == 'harsh' and rng.uniform() < 0.5
    return Realism(
        preset=preset_name, seed=int(seed), floor=floor,
        tape_saturation_levels=uniform(preset.tape_saturation_levels),
        tape_wear=uniform(preset.tape_wear), light_temperatures_k=temperatures,
        white_balance_error=None if harsh_no_balance else uniform(preset.white_balance_error),
        shadows=preset.shadows, light_level=uniform(preset.light_level),
        clutter_count=integer(preset.clutter_count),
        yellow_clutter_share=preset.yellow_clutter_share, walls=preset.walls,
        second_line=preset.second_line, auto_exposure=preset.auto_exposure,
        vignetting=uniform(preset.vignetting),
        radial_distortion_k1=uniform(preset.radial_distortion_k1),
        exposure_time_s=uniform(preset.exposure_time_s),
        read_noise_levels=uniform(preset.read_noise_levels),
        shot_noise_gain=uniform(preset.shot_noise_gain),
        jpeg_quality=integer(preset.jpeg_quality))


def kelvin_to_rgb(temperature_k: float) -> np.ndarray:
    """
    Return the colour of a black body at a temperature, normalised to its brightest channel.

    Tanner Helland's fit of the CIE black-body colours (1000-40000 K), good to a few percent,
    which is all a light's tint needs.

    :param temperature_k: colour temperature in kelvin.
    :return: (red, green, blue) in [0, 1], the largest 1.
    """
    t = np.clip(temperature_k, 1000.0, 40000.0) / 100.0
    if t <= 66.0:
        red = 255.0
        green = 99.4708025861 * np.log(t) - 161.1195681661
        blue = 0.0 if t <= 19.0 else 138.5177312231 * np.log(t - 10.0) - 305.0447927307
    else:
        red = 329.698727446 * (t - 60.0) ** -0.1332047592
        green = 288.1221695283 * (t - 60.0) ** -0.0755148492
        blue = 255.0
    rgb = np.clip(np.array([red, green, blue], dtype=float), 1.0, 255.0)
    return rgb / rgb.max()
