"""
Property-based tests of the course loaders: a course or a one-line ValueError, nothing else.

Whatever a course file or a course image holds, the loader returns a course or raises a
ValueError whose message is one line (what a node logs when it cannot start).

The number of examples is set by the hypothesis profile in conftest.py (``FOLLOWBOT_FUZZ_EXAMPLES``
for a longer, random run).
"""

from pathlib import Path

import cv2
from followbot_sim.course import Course, LINE_RGB
from followbot_sim.course_file import load_course_file
from followbot_sim.course_image import course_from_image
from hypothesis import given, strategies
import numpy as np
import yaml

FLOOR_SIZE_M = 10.0
# Keys of the course file schema, and words near them, so that examples reach past the top
# level into each section's checks.
SCHEMA_KEYS = ['name', 'floor_size_m', 'line_width_m', 'centre_line', 'image', 'dashes',
               'distractors', 'lighting_zones', 'points', 'start', 'segments', 'straight_m',
               'arc_radius_m', 'arc_angle_deg', 'file', 'dash_length_m', 'gap_length_m',
               'x_m', 'y_m', 'length_m', 'width_m', 'yaw_deg', 'radius_m', 'gain']
IMAGE_FILE = 'floor.png'

numbers = strategies.one_of(
    strategies.integers(-10**6, 10**6), strategies.floats(allow_nan=True, allow_infinity=True),
    strategies.floats(-12.0, 12.0))
scalars = strategies.one_of(strategies.none(), strategies.booleans(), numbers,
                            strategies.text(max_size=8), strategies.sampled_from([IMAGE_FILE]))
yaml_values = strategies.recursive(
    scalars,
    lambda children: strategies.one_of(
        strategies.lists(children, max_size=6),
        strategies.dictionaries(strategies.sampled_from(SCHEMA_KEYS) | strategies.text(max_size=4),
                                children, max_size=5)),
    max_leaves=30)
# Whole documents shaped like course files: the schema's top-level keys with any values.
course_documents = strategies.dictionaries(strategies.sampled_from(SCHEMA_KEYS), yaml_values,
                                           min_size=1, max_size=6)


def assert_course_or_one_line(load, *args):
    """Call a loader; it must return a Course or raise a ValueError whose message is one line."""
    try:
        course = load(*args)
    except ValueError as error:
        message = str(error)
        assert message and '\n' not in message, repr(message)
        return None
    assert isinstance(course, Course)
    return course


def small_line_image(size_px, thickness_px, radius_px):
    """Return a PNG of a yellow ring on grey, a few pixels to a few hundred across."""
    image_bgr = np.full((size_px, size_px, 3), 116, dtype=np.uint8)
    cv2.circle(image_bgr, (size_px // 2, size_px // 2), radius_px, LINE_RGB[::-1], thickness_px)
    ok, encoded = cv2.imencode('.png', image_bgr)
    assert ok
    return encoded.tobytes()


VALID_PNG = small_line_image(96, 4, 34)


def with_files(folder: Path, document_text: str, image_bytes: bytes | None = None):
    """Write a course file and its image into a folder; return the course file's path."""
    path = folder / 'course.yaml'
    path.write_text(document_text, encoding='utf-8', errors='surrogatepass')
    (folder / IMAGE_FILE).write_bytes(VALID_PNG if image_bytes is None else image_bytes)
    return path


@given(strategies.text(max_size=300))
def test_any_text_as_a_course_file_loads_or_fails_in_one_line(tmp_path, text):
    assert_course_or_one_line(load_course_file, with_files(tmp_path, text))


@given(course_documents)
def test_any_course_shaped_document_loads_or_fails_in_one_line(tmp_path, document):
    text = yaml.safe_dump(document, allow_unicode=True)
    assert_course_or_one_line(load_course_file, with_files(tmp_path, text))


@given(strategies.binary(max_size=400))
def test_any_bytes_as_a_course_image_load_or_fail_in_one_line(tmp_path, data):
    assert_course_or_one_line(load_course_file,
                              with_files(tmp_path, f'image: {{file: {IMAGE_FILE}}}\n', data))


@given(strategies.data())
def test_a_damaged_png_loads_or_fails_in_one_line(tmp_path, data):
    damaged = bytearray(VALID_PNG)
    # Cut it short somewhere, or overwrite a few bytes (the size fields are in the first 24).
    if data.draw(strategies.booleans(), label='truncate'):
        damaged = damaged[:data.draw(strategies.integers(0, len(damaged)), label='length')]
    else:
        for _ in range(data.draw(strategies.integers(1, 8), label='changes')):
            position = data.draw(strategies.integers(0, min(len(damaged) - 1, 64))
                                 | strategies.integers(0, len(damaged) - 1), label='at')
            damaged[position] = data.draw(strategies.integers(0, 255), label='byte')
    path = tmp_path / IMAGE_FILE
    path.write_bytes(bytes(damaged))
    assert_course_or_one_line(course_from_image, path, FLOOR_SIZE_M)


@given(strategies.integers(1, 300), strategies.integers(-3, 40), strategies.integers(0, 200))
def test_any_small_ring_image_loads_or_fails_in_one_line(
        tmp_path, size_px, thickness_px, radius_px):
    path = tmp_path / IMAGE_FILE
    path.write_bytes(small_line_image(size_px, thickness_px, radius_px))
    assert_course_or_one_line(course_from_image, path, FLOOR_SIZE_M)


def test_the_valid_ring_loads_as_a_course(tmp_path):
    # The fuzzed files start from an image that does load: damage, not the base, makes errors.
    path = with_files(tmp_path, f'image: {{file: {IMAGE_FILE}}}\n')
    assert assert_course_or_one_line(load_course_file, path) is not None
