"""Tests of YAML course files and of load_course, which takes a built-in name or a file."""

import math
from pathlib import Path
import textwrap

from followbot_sim.course import BOOK_LINE_WIDTH_M
from followbot_sim.course import Distractor
from followbot_sim.course import LightingZone
from followbot_sim.course_file import course_file_realism
from followbot_sim.course_file import load_course
from followbot_sim.course_file import load_course_file
from followbot_sim.course_library import COURSES
from followbot_sim.course_library import LIGHTING_ZONE_GAINS
import numpy as np
import pytest

POINTS_COURSE_YAML = """
    name: triangle_loop
    floor_size_m: 8.0
    line_width_m: 0.1
    centre_line:
      points: [[1.0, -1.0], [1.0, 2.0], [-2.0, -1.0]]
"""

# A 4 m square whose corners, rounded to 0.5 m, leave 3 m straight sides; driven
# counter-clockwise from its south side.
SEGMENTS_COURSE_YAML = """
    centre_line:
      start: [-0.5, -2.0, 0]
      segments:
        - {straight_m: 2.0}
        - {arc_radius_m: 0.5, arc_angle_deg: 90}
        - {straight_m: 3.0}
        - {arc_radius_m: 0.5, arc_angle_deg: 90}
        - {straight_m: 3.0}
        - {arc_radius_m: 0.5, arc_angle_deg: 90}
        - {straight_m: 3.0}
        - {arc_radius_m: 0.5, arc_angle_deg: 90}
        - {straight_m: 1.0}
"""

# A 4 m square of straights and sharp corners, turning right (clockwise).
SHARP_SQUARE_YAML = """
    centre_line:
      start: [-2.0, 2.0, 0]
      segments:
        - {straight_m: 4.0}
        - {arc_radius_m: 0.001, arc_angle_deg: -90}
        - {straight_m: 4.0}
        - {arc_radius_m: 0.001, arc_angle_deg: -90}
        - {straight_m: 4.0}
        - {arc_radius_m: 0.001, arc_angle_deg: -90}
        - {straight_m: 4.0}
        - {arc_radius_m: 0.001, arc_angle_deg: -90}
"""

PAINT_OPTIONS_YAML = """
    dashes: {dash_length_m: 0.3, gap_length_m: 0.15}
    distractors:
      - {x_m: 0.0, y_m: 0.0, length_m: 0.4, width_m: 0.1, yaw_deg: 90}
      - {x_m: 0.5, y_m: 0.5, length_m: 0.2, width_m: 0.2}
    lighting_zones:
      - {x_m: 1.0, y_m: 0.0, radius_m: 0.8, gain: 1.7}
"""


def write_course_file(directory, text, file_name='course.yaml'):
    """Write a course file (text dedented) and return its path."""
    path = Path(directory) / file_name
    path.write_text(textwrap.dedent(text), encoding='utf-8')
    return path


def test_realism_in_a_course_file_is_read_and_built_in_courses_have_none(tmp_path):
    text = ('centre_line:\n  points: [[1.0, -1.0], [1.0, 2.0], [-2.0, -1.0]]\n'
            'realism: {preset: warehouse, seed: 12}\n')
    path = write_course_file(tmp_path, text)
    assert course_file_realism(path) == ('warehouse', 12)
    assert load_course_file(path).length_m > 0.0
    assert course_file_realism('book_loop') is None


# --- centre lines ----------------------------------------------------------------------------

def test_points_course_follows_its_points_in_order(tmp_path):
    course = load_course_file(write_course_file(tmp_path, POINTS_COURSE_YAML))
    assert course.name == 'triangle_loop'
    assert course.floor_size_m == 8.0
    assert course.line_width_m == 0.1
    assert course.length_m == pytest.approx(3.0 + 3.0 + 3.0 * math.sqrt(2.0))
    assert course.start_pose() == pytest.approx((1.0, -1.0, math.pi / 2.0))


def test_name_defaults_to_the_file_stem_and_sizes_to_the_books(tmp_path):
    text = 'centre_line:\n  points: [[1.0, -1.0], [1.0, 2.0], [-2.0, -1.0]]\n'
    course = load_course_file(write_course_file(tmp_path, text, 'my_loop.yml'))
    assert course.name == 'my_loop'
    assert course.floor_size_m == 10.0
    assert course.line_width_m == BOOK_LINE_WIDTH_M


def test_segments_course_traces_a_rounded_square(tmp_path):
    course = load_course_file(write_course_file(tmp_path, SEGMENTS_COURSE_YAML))
    assert course.length_m == pytest.approx(12.0 + math.pi, abs=1e-3)
    assert course.start_pose() == pytest.approx((-0.5, -2.0, 0.0))
    assert np.min(course.centre_line_xy, axis=0) == pytest.approx([-2.0, -2.0], abs=1e-9)
    assert np.max(course.centre_line_xy, axis=0) == pytest.approx([2.0, 2.0], abs=1e-9)
    assert course.min_radius_of_curvature_m() == pytest.approx(0.5, rel=0.01)


def test_segments_course_with_sharp_right_turns_runs_clockwise(tmp_path):
    course = load_course_file(write_course_file(tmp_path, SHARP_SQUARE_YAML))
    assert course.length_m == pytest.approx(16.0, abs=0.01)
    # After the first straight east the line turns to head south.
    assert course.point_at(6.0)[:2] == pytest.approx((2.0, 0.0), abs=0.01)
    x_m, y_m = course.centre_line_xy[:, 0], course.centre_line_xy[:, 1]
    assert 0.5 * np.sum(x_m * np.roll(y_m, -1) - np.roll(x_m, -1) * y_m) < 0.0


def test_paint_options_are_applied(tmp_path):
    course = load_course_file(
        write_course_file(tmp_path, SEGMENTS_COURSE_YAML + PAINT_OPTIONS_YAML))
    assert (course.dash_length_m, course.gap_length_m) == (0.3, 0.15)
    assert course.distractors == (Distractor(0.0, 0.0, 0.4, 0.1, math.radians(90.0)),
                                  Distractor(0.5, 0.5, 0.2, 0.2, 0.0))
    assert course.lighting_zones == (LightingZone(1.0, 0.0, 0.8, 1.7),)


# --- errors ------------------------------------------------------------------------------------

@pytest.mark.parametrize('text, message', [
    ('name: both\ncentre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\nimage:\n  file: a.png\n',
     'exactly one of centre_line or image, got centre_line and image'),
    ('name: neither\n', 'exactly one of centre_line or image, got neither'),
    ('centre_line:\n  points: [[0, 0], [6, 0], [1, 1]]\n',
     'centre_line: the line must stay on the 10.0 m floor'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments:\n    - {straight_m: 2.0}\n'
     '    - {arc_radius_m: 0.5, arc_angle_deg: 90}\n',
     r'centre_line.segments: the turtle path ends 2\.\d+ m from its start'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n  start: [0, 0, 0]\n',
     'centre_line: needs either points or start and segments, not both'),
    ('centre_line:\n  start: [0, 0, 0]\n', 'centre_line: needs either points, or start and'),
    ('centre_line:\n  points: [[0, 0], [1, 0]]\n', 'centre_line: centre_line_xy needs at least'),
    ('centre_line:\n  points: [[0, 0], [1, zero], [1, 1]]\n',
     r'centre_line.points\[1\]\[1\]: must be a finite number'),
    ('centre_line:\n  points: [[0, 0], [1, 0, 3], [1, 1]]\n',
     r'centre_line.points\[1\]: must be a list of 2 numbers'),
    ('centre_line:\n  points: {x: 1}\n', 'centre_line.points: must be a list'),
    ('centre_line:\n  start: [0, 0]\n  segments: []\n',
     'centre_line.start: must be a list of 3 numbers'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: []\n',
     'centre_line.segments: a turtle path needs at least one segment'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: [{straight_m: -1}]\n',
     r'centre_line.segments\[0\]: a straight needs a positive'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: [{arc_radius_m: 1, arc_angle_deg: 0}]\n',
     r'centre_line.segments\[0\]: an arc needs a non-zero'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: [{arc_radius_m: 1}]\n',
     r'centre_line.segments\[0\]: needs the keys arc_angle_deg'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: [{straight_m: 1, turn: 2}]\n',
     r'centre_line.segments\[0\]: has unknown keys turn'),
    ('centre_line:\n  start: [0, 0, 0]\n  segments: [forward]\n',
     r'centre_line.segments\[0\]: must be \{straight_m'),
    ('floor_size_m: -3\ncentre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n',
     'floor_size_m: must be positive'),
    ('line_width_m: true\ncentre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n',
     'line_width_m: must be a finite number'),
    ('name: 7\ncentre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n',
     'name: must be a non-empty string'),
    ('colour: red\ncentre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n',
     'top level: has unknown keys colour'),
    ('- just\n- a list\n', 'top level: must be a mapping'),
    ('', 'top level: must be a mapping'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\ndashes: {dash_length_m: 0.3}\n',
     'dashes: needs the keys gap_length_m'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n'
     'dashes: {dash_length_m: 3, gap_length_m: 1}\n', 'dashes: a dash and a gap'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n'
     'distractors: [{x_m: 0, y_m: 0, length_m: 0, width_m: 0.1}]\n',
     r'distractors\[0\]: Distractor length_m must be positive'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n'
     'distractors: {x_m: 0, y_m: 0, length_m: 1, width_m: 0.1}\n', 'distractors: must be a list'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n'
     'lighting_zones: [{x_m: 0, y_m: 0, radius_m: 1}]\n',
     r'lighting_zones\[0\]: needs the keys gain'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\n'
     'lighting_zones: [{x_m: 0, y_m: 0, radius_m: 1, gain: -2}]\n',
     r'lighting_zones\[0\]: LightingZone gain must not be negative'),
    ('image:\n  start: [0, 0, 0]\n', 'image: needs the keys file'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\nrealism: {preset: foggy}\n',
     'realism.preset: must be one of clean, lab'),
    ('centre_line:\n  points: [[0, 0], [1, 0], [1, 1]]\nrealism: {preset: lab, seed: -2}\n',
     'realism.seed: must be a non-negative integer'),
    ('image:\n  file: no_such_image.png\n', 'image.file: no image file at'),
])
def test_invalid_course_files_are_rejected_naming_the_file_and_key(tmp_path, text, message):
    path = write_course_file(tmp_path, text)
    with pytest.raises(ValueError, match=message) as error:
        load_course_file(path)
    assert str(error.value).startswith(f'course file {path}: ')


def test_a_missing_course_file_is_rejected_naming_it(tmp_path):
    path = tmp_path / 'absent.yaml'
    with pytest.raises(ValueError, match='cannot read course file .*absent.yaml: No such file'):
        load_course_file(path)


@pytest.mark.parametrize('text', [
    'centre_line: [unclosed\n',
    'centre_line:\n  points: [[0, 0]\n   - oops: {\n',
    'name: "unterminated\n',
])
def test_a_course_file_that_is_not_yaml_is_rejected_naming_it(tmp_path, text):
    path = write_course_file(tmp_path, text)
    with pytest.raises(ValueError, match=f'course file {path} is not valid YAML') as error:
        load_course_file(path)
    # One line, as a startup error is logged: the parser's quoted source line is left out.
    assert '\n' not in str(error.value)


def test_a_yaml_error_says_where_in_one_line(tmp_path):
    path = write_course_file(tmp_path, 'name: x\n  bad: [1, 2\n')
    with pytest.raises(ValueError) as error:
        load_course_file(path)
    assert str(error.value) == (f'course file {path} is not valid YAML: mapping values are not '
                                'allowed here (line 2, column 6).')


def test_a_course_file_that_is_not_text_is_rejected(tmp_path):
    path = tmp_path / 'binary.yaml'
    path.write_bytes(b'\xff\xfe\x00name')
    with pytest.raises(ValueError, match='course file .*binary.yaml'):
        load_course_file(path)


# --- image courses -------------------------------------------------------------------------------

def test_image_course_is_built_from_the_image_with_the_files_options(tmp_path):
    course_image = pytest.importorskip('followbot_sim.course_image')
    cv2 = pytest.importorskip('cv2')
    book = COURSES['book_loop']()
    cv2.imwrite(str(tmp_path / 'floor.png'), book.draw_texture(1024)[:, :, ::-1])
    x_m, y_m, yaw_rad = book.start_pose()
    text = (f'name: from_image\nimage:\n  file: floor.png\n'
            f'  start: [{x_m}, {y_m}, {math.degrees(yaw_rad)}]\n'
            'lighting_zones: [{x_m: 0, y_m: 0, radius_m: 0.5, gain: 1.5}]\n')
    course = load_course_file(write_course_file(tmp_path, text))
    assert course_image.course_from_image is not None
    assert course.name == 'from_image'
    assert course.floor_image_rgb is not None
    assert course.lighting_zones == (LightingZone(0.0, 0.0, 0.5, 1.5),)
    assert course.length_m == pytest.approx(book.length_m, rel=0.05)


# --- load_course -------------------------------------------------------------------------------

@pytest.mark.parametrize('name', sorted(COURSES))
def test_load_course_builds_built_in_courses_by_name(name):
    assert load_course(name).name == name


def test_load_course_reads_course_files_by_path(tmp_path):
    path = write_course_file(tmp_path, POINTS_COURSE_YAML, 'triangle.YAML')
    assert load_course(str(path)).name == 'triangle_loop'
    assert load_course(path).name == 'triangle_loop'


@pytest.mark.parametrize('spec', ['book_loop', 'FILE'])
def test_load_course_adds_lighting_on_request(tmp_path, spec):
    if spec == 'FILE':
        spec = write_course_file(tmp_path, POINTS_COURSE_YAML)
    plain, lit = load_course(spec), load_course(spec, lighting=True)
    assert plain.lighting_zones == ()
    assert [zone.gain for zone in lit.lighting_zones] == list(LIGHTING_ZONE_GAINS)
    assert lit.name == f'{plain.name}+lighting'


@pytest.mark.parametrize('spec', ['no_such_course', 'course.json', '', None, 3])
def test_load_course_rejects_other_specs_listing_the_choices(spec):
    with pytest.raises(ValueError) as error:
        load_course(spec)
    message = str(error.value)
    assert all(name in message for name in COURSES)
    assert '.yaml' in message and '.yml' in message


def test_load_course_reports_a_missing_course_file(tmp_path):
    with pytest.raises(ValueError, match='cannot read course file'):
        load_course(tmp_path / 'missing.yml')
