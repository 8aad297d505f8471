"""
Course files: courses described in YAML, so that users can define them without code.

A course file is a YAML mapping; lengths are in metres, angles in degrees, positions in the
floor frame (origin at the floor centre, x east, y north)::

    name: warehouse_loop          # optional, default: the file name without its extension
    floor_size_m: 10.0            # optional, default 10.0
    line_width_m: 0.19            # optional, default 0.19 (an image course may measure it)
    # exactly one of centre_line or image:
    centre_line:
      points: [[x_m, y_m], ...]   # a closed loop, first point = start, direction = point order
      # or, instead of points, a turtle path, closed automatically; it must end within
      # 5 cm of its start:
      start: [x_m, y_m, yaw_deg]
      segments:
        - {straight_m: 2.0}
        - {arc_radius_m: 1.0, arc_angle_deg: 90}      # positive = left turn
    image:
      file: course.png            # an image of the whole floor, relative to the YAML file:
                                  # PNG or JPEG, square, at most 4096x4096 px
      start: [x_m, y_m, yaw_deg]  # optional: where the robot starts, heading along the line
    dashes: {dash_length_m: 0.3, gap_length_m: 0.15}                            # optional
    distractors: [{x_m: .., y_m: .., length_m: .., width_m: .., yaw_deg: ..}]  # optional
    lighting_zones: [{x_m: .., y_m: .., radius_m: .., gain: ..}]              # optional
    realism: {preset: home, seed: 3}  # optional: the simulator's realism:=/realism_seed:=

A distractor's ``yaw_deg`` (counter-clockwise from east, along its length) may be left out for
0. An image course cannot have dashes: its image already shows the line as it is.

:func:`load_course` takes either a built-in course name or the path of a course file.
"""

import math
import os
from pathlib import Path

from followbot_sim.course import BOOK_FLOOR_SIZE_M
from followbot_sim.course import BOOK_LINE_WIDTH_M
from followbot_sim.course import Course
from followbot_sim.course import Distractor
from followbot_sim.course import LightingZone
from followbot_sim.course import make_course
from followbot_sim.course_library import Arc
from followbot_sim.course_library import COURSES
from followbot_sim.course_library import Straight
from followbot_sim.course_library import turtle_loop_xy
from followbot_sim.course_library import with_lighting_zones
from followbot_sim.realism import CLEAN, PRESET_NAMES
import yaml

# File name endings that load_course reads as course files.
COURSE_FILE_SUFFIXES = ('.yaml', '.yml')
_TOP_LEVEL_KEYS = ('name', 'floor_size_m', 'line_width_m', 'centre_line', 'image', 'dashes',
                   'distractors', 'lighting_zones', 'realism')
_REALISM_KEYS = ('preset', 'seed')
_POSE_LENGTH = 3  # [x_m, y_m, yaw_deg]
_POINT_LENGTH = 2  # [x_m, y_m]


class _CourseFileReader:
    """Check the values of one course file, with error messages naming the file and key."""

    def __init__(self, path):
        """
        Start reading a course file.

        :param path: the file's path, for error messages and relative image paths.
        """
        self.path = Path(path)

    def error(self, key, message):
        """
        Build the error for a wrong value.

        :param key: where the value is in the file, e.g. ``centre_line.points[3]``.
        :param message: what is wrong and what is allowed, a sentence.
        :return: a ValueError naming the file and the key.
        """
        return ValueError(f'course file {self.path}: {key}: {message}')

    def mapping(self, value, key, required=(), optional=()):
        """
        Check that a value is a mapping with the required keys and no others.

        :param value: the value.
        :param key: where it is in the file.
        :param required: keys it must have.
        :param optional: keys it may have.
        :return: the mapping.
        :raises ValueError: if it is not a mapping, lacks a key or has an unknown one.
        """
        allowed = tuple(required) + tuple(optional)
        if not isinstance(value, dict):
            raise self.error(key, f'must be a mapping with keys {", ".join(allowed)}, got '
                             f'{value!r}.')
        unknown = [str(name) for name in value if name not in allowed]
        if unknown:
            raise self.error(key, f'has unknown keys {", ".join(unknown)}; allowed keys are '
                             f'{", ".join(allowed)}.')
        missing = [name for name in required if name not in value]
        if missing:
            raise self.error(key, f'needs the keys {", ".join(missing)}.')
        return value

    def sequence(self, value, key):
        """
        Check that a value is a list.

        :param value: the value.
        :param key: where it is in the file.
        :return: the list.
        :raises ValueError: if it is not a list.
        """
        if not isinstance(value, list):
            raise self.error(key, f'must be a list, got {value!r}.')
        return value

    def number(self, value, key, positive=False):
        """
        Check that a value is a finite number.

        :param value: the value.
        :param key: where it is in the file.
        :param positive: whether it must also be above zero.
        :return: the number as a float.
        :raises ValueError: if it is not a finite number (or not positive when required).
        """
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise self.error(key, f'must be a finite number, got {value!r}.')
        if positive and value <= 0.0:
            raise self.error(key, f'must be positive, got {value!r}.')
        return float(value)

    def numbers(self, value, key, count):
        """
        Check that a value is a list of a given count of finite numbers.

        :param value: the value.
        :param key: where it is in the file.
        :param count: how many numbers it must hold.
        :return: the numbers as a list of floats.
        :raises ValueError: if it is not such a list.
        """
        if not isinstance(value, list) or len(value) != count:
            raise self.error(key, f'must be a list of {count} numbers, got {value!r}.')
        return [self.number(item, f'{key}[{index}]') for index, item in enumerate(value)]

    def numbers_of(self, value, key, required, optional=()):
        """
        Check that a value is a mapping of finite numbers with the required keys.

        :param value: the value.
        :param key: where it is in the file.
        :param required: keys it must have.
        :param optional: keys it may have.
        :return: a dict of the numbers as floats by key.
        :raises ValueError: if it is not such a mapping.
        """
        value = self.mapping(value, key, required=required, optional=optional)
        return {name: self.number(item, f'{key}.{name}') for name, item in value.items()}

    def build(self, constructor, key, *args, **kwargs):
        """
        Make an object of values read, turning its complaints into errors of the file.

        :param constructor: a class or function that validates its arguments.
        :param key: where the values are in the file.
        :param args: its positional arguments.
        :param kwargs: its keyword arguments.
        :return: the object.
        :raises ValueError: if the constructor rejects the values.
        """
        try:
            return constructor(*args, **kwargs)
        except ValueError as error:
            raise self.error(key, str(error)) from None

    def pose(self, value, key):
        """
        Read a pose written as ``[x_m, y_m, yaw_deg]``.

        :param value: the value.
        :param key: where it is in the file.
        :return: ``(x_m, y_m, yaw_rad)``.
        :raises ValueError: if it is not a list of three numbers.
        """
        x_m, y_m, yaw_deg = self.numbers(value, key, _POSE_LENGTH)
        return x_m, y_m, math.radians(yaw_deg)


def _read_document(path):
    """Read a course file's YAML into its checked top-level mapping."""
    reader = _CourseFileReader(path)
    try:
        text = reader.path.read_text(encoding='utf-8')
    except OSError as error:
        raise ValueError(
            f'cannot read course file {reader.path}: {error.strerror or error}.') from None
    except UnicodeDecodeError as error:
        raise ValueError(f'course file {reader.path} is not UTF-8 text: {error}.') from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ValueError(
            f'course file {reader.path} is not valid YAML: {_yaml_problem(error)}.') from None
    document = reader.mapping(document, 'top level', optional=_TOP_LEVEL_KEYS)
    if 'realism' in document:
        realism = reader.mapping(document['realism'], 'realism', optional=_REALISM_KEYS)
        preset = realism.get('preset', CLEAN)
        if preset not in PRESET_NAMES:
            raise reader.error('realism.preset', f'must be one of {", ".join(PRESET_NAMES)}, '
                               f'got {preset!r}.')
        seed = realism.get('seed', 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise reader.error('realism.seed', f'must be a non-negative integer, got {seed!r}.')
    return reader, document


def course_file_realism(spec):
    """
    Return the realism a course file asks for, if any.

    :param spec: a built-in course name or a course file's path (as :func:`load_course`).
    :return: ``(preset, seed)`` from the file's ``realism`` mapping, None when the course is
        built in or its file has no ``realism``.
    :raises ValueError: if the file is invalid.
    """
    if not (isinstance(spec, (str, os.PathLike))
            and Path(spec).suffix.lower() in COURSE_FILE_SUFFIXES):
        return None
    _, document = _read_document(spec)
    if 'realism' not in document:
        return None
    return document['realism'].get('preset', CLEAN), int(document['realism'].get('seed', 0))


def load_course_file(path):
    """
    Build a course from a YAML course file (the schema is in this module's docstring).

    :param path: path of the file.
    :return: the course.
    :raises ValueError: if the file cannot be read, is not valid YAML or does not follow the
        schema, or the course it describes is invalid (off the floor, not closed, ...); the
        message names the file and the key.
    """
    reader, document = _read_document(path)
    name = document.get('name', reader.path.stem)
    if not isinstance(name, str) or not name:
        raise reader.error('name', f'must be a non-empty string, got {name!r}.')
    floor_size_m = reader.number(document.get('floor_size_m', BOOK_FLOOR_SIZE_M),
                                 'floor_size_m', positive=True)
    line_width_m = None
    if 'line_width_m' in document:
        line_width_m = reader.number(document['line_width_m'], 'line_width_m', positive=True)
    shapes = [key for key in ('centre_line', 'image') if key in document]
    if len(shapes) != 1:
        raise reader.error('top level', 'needs exactly one of centre_line or image, got '
                           f'{" and ".join(shapes) if shapes else "neither"}.')
    if 'centre_line' in document:
        course = _centre_line_course(reader, document['centre_line'], name, floor_size_m,
                                     BOOK_LINE_WIDTH_M if line_width_m is None else line_width_m)
    else:
        course = _image_course(reader, document['image'], name, floor_size_m, line_width_m)
    return _with_paint_options(reader, document, course)


def _yaml_problem(error):
    """
    Say in one line what the YAML parser found wrong, and where.

    PyYAML's own message spans several lines (it quotes the line with a caret under it); a
    startup error is one log line.

    :param error: the parser's exception.
    :return: e.g. ``mapping values are not allowed here (line 2, column 6)``.
    """
    problem = getattr(error, 'problem', None) or str(error).splitlines()[0]
    mark = getattr(error, 'problem_mark', None)
    where = '' if mark is None else f' (line {mark.line + 1}, column {mark.column + 1})'
    return ' '.join(f'{problem}{where}'.split())


def _centre_line_course(reader, section, name, floor_size_m, line_width_m):
    """
    Build the course of a ``centre_line`` section.

    :param reader: the file's reader.
    :param section: the section's value.
    :param name: name of the course.
    :param floor_size_m: side of the floor in metres.
    :param line_width_m: width of the line in metres.
    :return: the course.
    :raises ValueError: if the section does not follow the schema or the line is invalid.
    """
    section = reader.mapping(section, 'centre_line', optional=('points', 'start', 'segments'))
    if 'points' in section:
        if 'start' in section or 'segments' in section:
            raise reader.error('centre_line', 'needs either points or start and segments, '
                               'not both.')
        points = reader.sequence(section['points'], 'centre_line.points')
        points_xy = [reader.numbers(point, f'centre_line.points[{index}]', _POINT_LENGTH)
                     for index, point in enumerate(points)]
    elif 'start' in section and 'segments' in section:
        points_xy = _turtle_points(reader, section['start'], section['segments'])
    else:
        raise reader.error('centre_line', 'needs either points, or start and segments.')
    return reader.build(Course, 'centre_line', points_xy, line_width_m, floor_size_m, name)


def _turtle_points(reader, start, segments):
    """
    Trace the points of a turtle path from a ``centre_line`` section.

    :param reader: the file's reader.
    :param start: the ``start`` value.
    :param segments: the ``segments`` value.
    :return: (N, 2) points in metres.
    :raises ValueError: if a value does not follow the schema or the path does not close.
    """
    start_pose = reader.pose(start, 'centre_line.start')
    pieces = []
    for index, segment in enumerate(reader.sequence(segments, 'centre_line.segments')):
        key = f'centre_line.segments[{index}]'
        if not isinstance(segment, dict):
            raise reader.error(key, 'must be {straight_m: ...} or {arc_radius_m: ..., '
                               f'arc_angle_deg: ...}}, got {segment!r}.')
        if 'straight_m' in segment:
            segment = reader.mapping(segment, key, required=('straight_m',))
            length_m = reader.number(segment['straight_m'], f'{key}.straight_m')
            pieces.append(reader.build(Straight, key, length_m))
        else:
            segment = reader.mapping(segment, key, required=('arc_radius_m', 'arc_angle_deg'))
            radius_m = reader.number(segment['arc_radius_m'], f'{key}.arc_radius_m')
            angle_deg = reader.number(segment['arc_angle_deg'], f'{key}.arc_angle_deg')
            pieces.append(reader.build(Arc, key, radius_m, math.radians(angle_deg)))
    return reader.build(turtle_loop_xy, 'centre_line.segments', start_pose, pieces)


def _image_course(reader, section, name, floor_size_m, line_width_m):
    """
    Build the course of an ``image`` section.

    :param reader: the file's reader.
    :param section: the section's value.
    :param name: name of the course.
    :param floor_size_m: side of the floor in metres.
    :param line_width_m: width of the line in metres, or None to let the image tell.
    :return: the course.
    :raises ValueError: if the section does not follow the schema, the image file is
        missing or no course can be made of the image.
    """
    section = reader.mapping(section, 'image', required=('file',), optional=('start',))
    if not isinstance(section['file'], str) or not section['file']:
        raise reader.error('image.file', f'must be a file name, got {section["file"]!r}.')
    image_path = reader.path.parent / section['file']
    if not image_path.is_file():
        raise reader.error('image.file', f'no image file at {image_path}.')
    start_pose = None
    if 'start' in section:
        start_pose = reader.pose(section['start'], 'image.start')
    # Imported here: image courses need the image module only when a file asks for one.
    from followbot_sim.course_image import course_from_image
    return reader.build(course_from_image, 'image', str(image_path), floor_size_m, start_pose,
                        name=name, line_width_m=line_width_m)


def _with_paint_options(reader, document, course):
    """
    Apply a file's dashes, distractors and lighting zones to its course.

    :param reader: the file's reader.
    :param document: the file's top-level mapping.
    :param course: the course built from its centre line or image.
    :return: the course with those options, or the same course when there are none.
    :raises ValueError: if an option does not follow the schema or does not suit the course.
    """
    changes = {}
    if 'dashes' in document:
        dashes = reader.mapping(document['dashes'], 'dashes',
                                required=('dash_length_m', 'gap_length_m'))
        changes['dash_length_m'] = reader.number(dashes['dash_length_m'],
                                                 'dashes.dash_length_m', positive=True)
        changes['gap_length_m'] = reader.number(dashes['gap_length_m'],
                                                'dashes.gap_length_m', positive=True)
    if 'distractors' in document:
        items = reader.sequence(document['distractors'], 'distractors')
        changes['distractors'] = course.distractors + tuple(
            _distractor(reader, item, f'distractors[{index}]') for index, item in enumerate(items))
    if 'lighting_zones' in document:
        items = reader.sequence(document['lighting_zones'], 'lighting_zones')
        changes['lighting_zones'] = course.lighting_zones + tuple(
            _lighting_zone(reader, item, f'lighting_zones[{index}]')
            for index, item in enumerate(items))
    if not changes:
        return course
    # Only the dashes can clash with the course (too long for it, or on an image course).
    return reader.build(course.replace, 'dashes', **changes)


def _distractor(reader, item, key):
    """
    Read one distractor of a course file.

    :param reader: the file's reader.
    :param item: the item's value.
    :param key: where it is in the file.
    :return: the :class:`Distractor`.
    :raises ValueError: if the item is not a mapping of its numbers or they are invalid.
    """
    numbers = reader.numbers_of(item, key, ('x_m', 'y_m', 'length_m', 'width_m'),
                                optional=('yaw_deg',))
    yaw_rad = math.radians(numbers.pop('yaw_deg', 0.0))
    return reader.build(Distractor, key, yaw_rad=yaw_rad, **numbers)


def _lighting_zone(reader, item, key):
    """
    Read one lighting zone of a course file.

    :param reader: the file's reader.
    :param item: the item's value.
    :param key: where it is in the file.
    :return: the :class:`LightingZone`.
    :raises ValueError: if the item is not a mapping of its numbers or they are invalid.
    """
    numbers = reader.numbers_of(item, key, ('x_m', 'y_m', 'radius_m', 'gain'))
    return reader.build(LightingZone, key, **numbers)


def load_course(spec, lighting=False):
    """
    Build a course from a built-in course name or the path of a YAML course file.

    :param spec: a key of :data:`followbot_sim.course_library.COURSES`, or a path ending in
        ``.yaml`` or ``.yml``.
    :param lighting: add the standard bright and dim pools of light along the line
        (:func:`followbot_sim.course_library.with_lighting_zones`).
    :return: the course.
    :raises ValueError: if ``spec`` is neither a built-in name nor a course file's path, or the
        file is invalid.
    """
    if isinstance(spec, str) and spec in COURSES:
        course = make_course(spec)
    elif isinstance(spec, (str, os.PathLike)) \
            and Path(spec).suffix.lower() in COURSE_FILE_SUFFIXES:
        course = load_course_file(spec)
    else:
        raise ValueError(
            f'unknown course {spec!r}: give a built-in course name '
            f'({", ".join(sorted(COURSES))}) or the path of a YAML course file ending in '
            f'{" or ".join(COURSE_FILE_SUFFIXES)}.')
    return with_lighting_zones(course) if lighting else course
