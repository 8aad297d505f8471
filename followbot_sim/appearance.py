"""
What a realistic world looks like: procedural floors, worn tape, lights and clutter, by seed.

Everything is drawn with numpy and OpenCV from a :class:`followbot_sim.realism.Realism` (no
image files): :func:`paint_floor` turns the clean course texture (grey floor, yellow line) into a
floor of the chosen kind with the tape laid on it; :func:`furnish` adds lights, clutter and walls
to the MuJoCo spec before it is compiled. The floor texture spans the whole floor (~5 mm per
texel on the book's 10 m floor), so patterns are drawn at scales a camera 0.3 m up resolves:
planks, tiles, seams, stains, mottling.
"""

import math

import cv2
from followbot_sim.course import FLOOR_GREY
from followbot_sim.realism import kelvin_to_rgb, Realism, SECOND_LINE_COLOURS
import numpy as np

# OpenCV hue (0-179) of the tape's yellow and its brightness (value, 0-255).
TAPE_HUE = 28
TAPE_VALUE = 235
# Tape comes in rolls: a join (the next piece overlapping the last) every this many metres.
TAPE_PIECE_M = (1.0, 3.0)
TAPE_JOIN_M = 0.02
# The second line lies this far beside the course line, over this stretch of it.
SECOND_LINE_OFFSET_M = 0.55
SECOND_LINE_LENGTH_M = (2.0, 4.0)
SECOND_LINE_WIDTH_M = 0.05
# Clutter stands at least this far from the centre line (the robot is 0.35 m across) ...
CLUTTER_MIN_CLEARANCE_M = 0.5
CLUTTER_MAX_CLEARANCE_M = 1.5
CLUTTER_SIZE_M = (0.08, 0.3)
# ... and walls this high round the floor's edge.
WALL_HEIGHT_M = 1.5
WALL_THICKNESS_M = 0.05
LIGHT_HEIGHT_M = (2.2, 3.0)
LAMP_SPREAD_M = 1.0
YELLOW_RGB = (0.95, 0.8, 0.1)
# Object colours: muted browns, greys, blues, as boxes and bins are.
CLUTTER_COLOURS = ((0.55, 0.42, 0.3), (0.4, 0.4, 0.42), (0.25, 0.3, 0.45),
                   (0.6, 0.6, 0.58), (0.3, 0.25, 0.2), (0.5, 0.15, 0.12))
WALL_COLOURS = ((0.82, 0.8, 0.75), (0.7, 0.72, 0.74), (0.78, 0.74, 0.66))
# Floor gloss: (specular, shininess) of each kind's material.
FLOOR_GLOSS = {'concrete': (0.35, 0.6), 'wood': (0.45, 0.7), 'vinyl': (0.3, 0.5),
               'carpet': (0.0, 0.0), 'rubber': (0.1, 0.2)}


def smooth_noise(rng: np.random.Generator, size_px: int, scale_px: float) -> np.ndarray:
    """
    Return smooth random noise, zero-mean and unit-ish spread, varying over ``scale_px``.

    :param rng: the generator.
    :param size_px: side of the square result.
    :param scale_px: the pattern's typical feature size in pixels.
    :return: a float32 (size, size) array.
    """
    cells = max(2, int(round(size_px / max(scale_px, 1.0))) + 1)
    coarse = rng.standard_normal((cells, cells)).astype(np.float32)
    return cv2.resize(coarse, (size_px, size_px), interpolation=cv2.INTER_CUBIC)


def _concrete(rng, size_px, texel_m):
    base = rng.uniform(140.0, 175.0)
    tone = base + 10.0 * smooth_noise(rng, size_px, 1.0 / texel_m)
    tone += 5.0 * smooth_noise(rng, size_px, 0.1 / texel_m)
    tone += rng.normal(0.0, 4.0, (size_px, size_px)).astype(np.float32)
    stains = np.zeros((size_px, size_px), np.float32)
    for _ in range(int(rng.integers(8, 20))):
        centre = tuple(int(value) for value in rng.integers(0, size_px, 2))
        axes = tuple(int(value) for value in rng.uniform(0.1, 0.6, 2) / texel_m)
        cv2.ellipse(stains, centre, axes, float(rng.uniform(0, 180)), 0, 360,
                    float(rng.uniform(10.0, 35.0)), -1)
    stains = cv2.GaussianBlur(stains, (0, 0), 0.05 / texel_m)
    grey = np.clip(tone - stains, 0, 255)
    return np.stack([grey, grey * 0.99, grey * 0.96], axis=-1)


def _wood(rng, size_px, texel_m):
    plank_px = max(4, int(rng.uniform(0.12, 0.2) / texel_m))
    rows = np.arange(size_px)
    plank_index = rows // plank_px
    plank_tone = rng.uniform(0.8, 1.15, plank_index.max() + 1)[plank_index]
    base = np.array([150.0, 100.0, 60.0]) * rng.uniform(0.85, 1.15)
    grain = np.sin(np.arange(size_px)[None, :] * 0.0 + rows[:, None] * 2.1
                   + 3.0 * smooth_noise(rng, size_px, 0.3 / texel_m))
    tone = plank_tone[:, None] * (1.0 + 0.06 * grain + 0.04 * smooth_noise(
        rng, size_px, 0.05 / texel_m))
    seams = (rows % plank_px == 0)[:, None] & np.ones((1, size_px), bool)
    # Plank ends: each plank row is cut at its own offsets.
    length_px = int(1.2 / texel_m)
    for index in range(plank_index.max() + 1):
        offset = int(rng.integers(0, length_px))
        seams[index * plank_px:(index + 1) * plank_px, offset::length_px] = True
    tone = np.where(seams, 0.55, tone)
    return tone[..., None] * base


def _vinyl(rng, size_px, texel_m):
    tile_px = max(4, int(0.3 / texel_m))
    index = np.arange(size_px) // tile_px
    count = index.max() + 1
    tone = rng.uniform(0.9, 1.1, (count, count))[index[:, None], index[None, :]]
    base = np.array(SECOND_LINE_COLOURS['white'], float) * rng.uniform(0.7, 0.85)
    base *= np.array([1.0, 0.97, rng.uniform(0.85, 0.95)])
    speckle = 0.05 * smooth_noise(rng, size_px, 0.02 / texel_m)
    seams = (np.arange(size_px) % tile_px == 0)
    tone = np.where(seams[:, None] | seams[None, :], 0.7, tone + speckle)
    return tone[..., None] * base


def _carpet(rng, size_px, texel_m):
    colours = ((90.0, 95.0, 110.0), (120.0, 70.0, 60.0), (110.0, 105.0, 95.0))
    base = np.array(colours[int(rng.integers(len(colours)))])
    tone = (1.0 + 0.12 * smooth_noise(rng, size_px, 0.4 / texel_m)
            + 0.15 * rng.standard_normal((size_px, size_px)).astype(np.float32))
    return tone[..., None] * base


def _rubber(rng, size_px, texel_m):
    level = rng.uniform(35.0, 55.0)
    stud_px = max(3, int(0.08 / texel_m))
    rows = np.arange(size_px) % stud_px
    studs = ((rows[:, None] - stud_px / 2) ** 2 + (rows[None, :] - stud_px / 2) ** 2
             < (stud_px / 3) ** 2)
    tone = level * (1.0 + 0.15 * studs + 0.08 * smooth_noise(rng, size_px, 0.5 / texel_m))
    return np.stack([tone, tone, tone * 1.03], axis=-1)


FLOOR_PAINTERS = {'concrete': _concrete, 'wood': _wood, 'vinyl': _vinyl, 'carpet': _carpet,
                  'rubber': _rubber}


def floor_pattern(kind: str, rng: np.random.Generator, size_px: int,
                  floor_size_m: float) -> np.ndarray:
    """
    Draw a floor of one kind.

    :param kind: one of :data:`followbot_sim.realism.FLOOR_KINDS`.
    :param rng: the generator.
    :param size_px: side of the square texture.
    :param floor_size_m: side of the floor it covers.
    :return: a float32 (size, size, 3) RGB image, 0-255.
    """
    return FLOOR_PAINTERS[kind](rng, size_px, floor_size_m / size_px).astype(np.float32)


def line_coverage(clean_texture: np.ndarray) -> np.ndarray:
    """
    Recover how much of each texel the line covers from the clean course texture.

    The clean texture blends yellow (255, 246, 0) over grey 116, then scales by the lighting
    zones; blue over red undoes the scale: ``b / r = 116 (1 - c) / (116 + 139 c)``.

    :param clean_texture: the course's RGB uint8 texture.
    :return: float32 coverage in [0, 1].
    """
    red = clean_texture[..., 0].astype(np.float32)
    blue = clean_texture[..., 2].astype(np.float32)
    ratio = np.divide(blue, red, out=np.zeros_like(red), where=red > 0)
    line_gap = 255.0 - FLOOR_GREY
    coverage = FLOOR_GREY * (1.0 - ratio) / (FLOOR_GREY + line_gap * ratio)
    return np.clip(coverage, 0.0, 1.0)


def tape_colour(saturation_levels: float) -> np.ndarray:
    """
    Return the tape's RGB colour for a saturation (OpenCV 0-255 scale).

    :param saturation_levels: saturation of the tape.
    :return: float32 RGB, 0-255.
    """
    hsv = np.array([[[TAPE_HUE, int(round(saturation_levels)), TAPE_VALUE]]], np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0].astype(np.float32)


def paint_floor(clean_texture: np.ndarray, realism: Realism, course) -> np.ndarray:
    """
    Paint the realistic floor with the tape on it, keeping the line exactly where it was.

    :param clean_texture: the course's clean RGB uint8 texture (its line is the truth).
    :param realism: the drawn world.
    :param course: the course (for the centre line, floor size and where to put a second
        line).
    :return: an RGB uint8 texture of the same size.
    """
    size_px = clean_texture.shape[0]
    texel_m = course.floor_size_m / size_px
    rng = realism.generator('floor')
    floor = floor_pattern(realism.floor, rng, size_px, course.floor_size_m)
    coverage = line_coverage(clean_texture)
    wear = realism.tape_wear
    tape_rng = realism.generator('tape')
    if wear > 0.0:
        # Ragged edges: the edge moves by a texel or two; worn patches let the floor through.
        edge_noise = smooth_noise(tape_rng, size_px, 0.01 / texel_m)
        coverage = np.clip(coverage + 0.25 * wear * edge_noise * (coverage * (1 - coverage) * 4),
                           0.0, 1.0)
        worn = np.clip(smooth_noise(tape_rng, size_px, 0.15 / texel_m) * 0.5 + 0.5, 0, 1)
        coverage *= 1.0 - 0.6 * wear * worn ** 2
    tape = np.broadcast_to(tape_colour(realism.tape_saturation_levels), floor.shape).copy()
    if wear > 0.0:
        dirt = np.clip(smooth_noise(tape_rng, size_px, 0.03 / texel_m), 0, None)
        tape *= (1.0 - 0.35 * wear * np.minimum(dirt, 1.0))[..., None]
    _draw_tape_joins(tape, tape_rng, course, size_px)
    image = floor * (1.0 - coverage[..., None]) + tape * coverage[..., None]
    if realism.second_line:
        _draw_second_line(image, realism.generator('second_line'), course, size_px)
    return np.clip(image, 0, 255).astype(np.uint8)


def _draw_tape_joins(tape, rng, course, size_px):
    """Darken short stretches across the tape where one piece overlaps the next."""
    arc_m = rng.uniform(*TAPE_PIECE_M)
    half_width_m = course.line_width_m * 0.6
    while arc_m < course.length_m:
        x_m, y_m, heading_rad = course.point_at(arc_m)
        across = np.array([-math.sin(heading_rad), math.cos(heading_rad)]) * half_width_m
        ends = [course.world_to_texture_px(x_m + sign * across[0], y_m + sign * across[1],
                                           size_px) for sign in (-1.0, 1.0)]
        thickness = max(1, int(round(TAPE_JOIN_M * size_px / course.floor_size_m)))
        mask = np.zeros(tape.shape[:2], np.uint8)
        cv2.line(mask, *(tuple(int(round(value)) for value in end) for end in ends), 1,
                 thickness)
        tape[mask > 0] *= 0.82
        arc_m += rng.uniform(*TAPE_PIECE_M)


def _draw_second_line(image, rng, course, size_px):
    """Paint a stretch of a line of another colour beside the course line, outside the loop."""
    points_xy = course.centre_line_xy
    length_m = rng.uniform(*SECOND_LINE_LENGTH_M)
    start_m = rng.uniform(0.0, course.length_m)
    arcs_m = start_m + np.linspace(0.0, length_m, max(2, int(length_m / 0.02)))
    stretch = []
    centroid = points_xy.mean(axis=0)
    for arc_m in arcs_m:
        x_m, y_m, heading_rad = course.point_at(arc_m)
        normal = np.array([-math.sin(heading_rad), math.cos(heading_rad)])
        if np.dot(normal, np.array([x_m, y_m]) - centroid) < 0.0:
            normal = -normal
        point = np.array([x_m, y_m]) + SECOND_LINE_OFFSET_M * normal
        limit_m = course.floor_size_m / 2.0 - 0.1
        if np.all(np.abs(point) < limit_m):
            stretch.append(course.world_to_texture_px(point[0], point[1], size_px))
    if len(stretch) < 2:
        return
    name = sorted(SECOND_LINE_COLOURS)[int(rng.integers(len(SECOND_LINE_COLOURS)))]
    colour = tuple(float(value) for value in SECOND_LINE_COLOURS[name])
    thickness = max(1, int(round(SECOND_LINE_WIDTH_M * size_px / course.floor_size_m)))
    cv2.polylines(image, [np.round(np.array(stretch)).astype(np.int32)], False, colour,
                  thickness, cv2.LINE_AA)


def furnish(spec, realism: Realism, course, floor_geom_name: str) -> None:
    """
    Add the realistic world's lights, clutter and walls to a MuJoCo spec (before compiling).

    Clutter and walls are visual only (no contacts): a robot that leaves the line by half a
    metre is off course anyway, and contacts would change the physics of every run.

    :param spec: the scene's MjSpec.
    :param realism: the drawn world.
    :param course: the course (clutter stays clear of its line).
    :param floor_geom_name: name of the floor geom (its material gets the floor's gloss).
    """
    import mujoco
    specular, shininess = FLOOR_GLOSS[realism.floor]
    floor_material = spec.material(spec.geom(floor_geom_name).material)
    floor_material.specular = specular
    floor_material.shininess = shininess
    half_m = course.floor_size_m / 2.0
    rng = realism.generator('lights')
    if realism.light_temperatures_k:
        # The added lights replace the clean scene's white sun; a little ambient remains.
        for light in spec.lights:
            light.active = False
        spec.visual.headlight.ambient = [0.03] * 3
        spec.visual.headlight.diffuse = [0.02] * 3
    # Overlapping pools of light must not clip the tape's red in the render (the camera's
    # white balance would then turn it green): the lights share the level between them, and
    # the camera's auto-exposure brings the frame up.
    level = realism.light_level / math.sqrt(max(1, len(realism.light_temperatures_k)))
    for index, temperature_k in enumerate(realism.light_temperatures_k):
        colour = kelvin_to_rgb(temperature_k) * level
        outdoor = realism.preset == 'outdoor'
        # Lamps hang over the course (a room is lit where people work), spread along it.
        x_m, y_m, _ = course.point_at(course.length_m * (index + rng.uniform()) / max(
            1, len(realism.light_temperatures_k)))
        position = [float(np.clip(value + rng.uniform(-LAMP_SPREAD_M, LAMP_SPREAD_M),
                                  -half_m, half_m)) for value in (x_m, y_m)]
        height_m = float(rng.uniform(*LIGHT_HEIGHT_M))
        light = spec.worldbody.add_light(
            name=f'realism_light_{index}', pos=[*position, 6.0 if outdoor else height_m],
            castshadow=bool(realism.shadows and index == 0), diffuse=colour.tolist(),
            specular=(0.3 * colour).tolist(), ambient=(0.6 * colour).tolist())
        if outdoor:
            light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
            tilt = rng.uniform(-0.6, 0.6, 2)
            light.dir = [float(tilt[0]), float(tilt[1]), -1.0]
        else:
            light.dir = [0.0, 0.0, -1.0]
            # Wide, even ceiling lamps: a room is lit everywhere, brighter under each lamp.
            light.cutoff = 85.0
            light.exponent = 1.0
            light.attenuation = [1.0, 0.0, 0.02]
    if realism.shadows and realism.light_temperatures_k:
        spec.visual.quality.shadowsize = 1024
    _add_clutter(spec, realism, course)
    if realism.walls:
        _add_walls(spec, realism, half_m)


def _add_clutter(spec, realism, course):
    import mujoco
    rng = realism.generator('clutter')
    half_m = course.floor_size_m / 2.0 - 0.2
    placed = 0
    attempts = 0
    while placed < realism.clutter_count and attempts < 200 * (realism.clutter_count + 1):
        attempts += 1
        x_m, y_m = (float(value) for value in rng.uniform(-half_m, half_m, 2))
        distance_m = abs(course.signed_offset(x_m, y_m)[0])
        size_m = float(rng.uniform(*CLUTTER_SIZE_M))
        if not CLUTTER_MIN_CLEARANCE_M + size_m <= distance_m <= CLUTTER_MAX_CLEARANCE_M:
            continue
        yellow = rng.uniform() < realism.yellow_clutter_share
        colour = YELLOW_RGB if yellow else CLUTTER_COLOURS[int(rng.integers(
            len(CLUTTER_COLOURS)))]
        height_m = float(rng.uniform(0.1, 0.5))
        cylinder = rng.uniform() < 0.4
        spec.worldbody.add_geom(
            name=f'realism_clutter_{placed}',
            type=mujoco.mjtGeom.mjGEOM_CYLINDER if cylinder else mujoco.mjtGeom.mjGEOM_BOX,
            size=[size_m / 2.0, height_m / 2.0 if cylinder else size_m / 2.0, height_m / 2.0],
            pos=[x_m, y_m, height_m / 2.0], euler=[0.0, 0.0, float(rng.uniform(0, math.pi))],
            rgba=[*colour, 1.0], contype=0, conaffinity=0)
        placed += 1


def _add_walls(spec, realism, half_m):
    import mujoco
    rng = realism.generator('walls')
    colour = WALL_COLOURS[int(rng.integers(len(WALL_COLOURS)))]
    for index, (x_m, y_m, length_m, across_m) in enumerate((
            (0.0, half_m, half_m, WALL_THICKNESS_M), (0.0, -half_m, half_m, WALL_THICKNESS_M),
            (half_m, 0.0, WALL_THICKNESS_M, half_m), (-half_m, 0.0, WALL_THICKNESS_M, half_m))):
        spec.worldbody.add_geom(
            name=f'realism_wall_{index}', type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[length_m, across_m, WALL_HEIGHT_M / 2.0],
            pos=[x_m, y_m, WALL_HEIGHT_M / 2.0], rgba=[*colour, 1.0], contype=0, conaffinity=0)
