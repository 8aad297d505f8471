"""
Real camera frames of lines, labelled by hand, and the follower's perception scored on them.

The frames are third-party photographs from public robot projects. They are not part of this
repository: they are read from ``../shared/real-frames/`` beside the checkout (or the folder
``FOLLOWBOT_REAL_FRAMES`` names), whose ``MANIFEST.md`` gives their sources and licences. The
labels are this project's own work, in ``test/data/real_frames/<source>.yaml`` (their format is
described in that folder's README): per source the robot's camera and its tape's width, per
frame the centre line of every yellow, white or black line as polylines.

Scoring runs the follower's detector as the follower node would (its default parameters, with
the line colour preset of the line scored, the source's tape width and camera) on each frame
and judges every band with :mod:`followbot_sim.perception_score`.
"""

import dataclasses
import math
import os
from pathlib import Path

import cv2
from followbot.ground_projection import CameraGeometry
from followbot.line_detector import DetectorConfig, LineDetector
from followbot_sim.perception_score import (band_truth, group_lines, PerceptionTally,
                                            thinnest_line_px)
import numpy as np
import yaml

PACKAGE_DIR = Path(__file__).resolve().parent.parent
LABELS_DIR = PACKAGE_DIR / 'test' / 'data' / 'real_frames'
FRAMES_VARIABLE = 'FOLLOWBOT_REAL_FRAMES'
DEFAULT_FRAMES_DIR = PACKAGE_DIR.parent / 'shared' / 'real-frames'
LABELLED_COLOURS = ('yellow', 'white', 'black')
# The schematic of a frame: what the labels say and what the detector did, drawn on a plain
# canvas, so a picture of a hard frame holds none of the third-party frame's pixels.
SCHEMATIC_CANVAS_BGR = (90, 90, 90)
SCHEMATIC_LINE_BGR = {'yellow': (0, 215, 255), 'white': (235, 235, 235), 'black': (25, 25, 25)}
SCHEMATIC_HORIZON_BGR = (160, 160, 160)
SCHEMATIC_BAND_BGR = (140, 140, 140)
SCHEMATIC_VERDICT_BGR = {'right': (0, 200, 0), 'false': (0, 0, 255), 'missed': (255, 0, 255)}
SCHEMATIC_MARK_RADIUS_PX = 7
SCHEMATIC_TEXT_BGR = (255, 255, 255)
# The frames are also scored at half their size: a 320x240 camera (the TurtleBot3 camera of
# the volvo-tb3 project, a USB camera on a slow link) sees the scene much as the frame
# averaged over squares of 2x2 pixels. The follower's configuration stays the same: only the
# camera's calibration follows the image size, as camera_info does.
HALF_SIZE = 0.5
CAMERA_PIXEL_FIELDS = ('fx_px', 'fy_px')
CAMERA_CENTRE_FIELDS = ('cx_px', 'cy_px')


@dataclasses.dataclass(frozen=True)
class LabelledFrame:
    """One labelled frame: its file, and the labelled lines of each colour."""

    source: str
    name: str
    size: tuple
    horizon_y_px: float
    lines: dict
    ignore_rows: tuple
    camera: dict | None = None

    def polylines(self, colour: str) -> list:
        """Return the frame's labelled lines of a colour (none if it has none)."""
        return self.lines.get(colour, [])

    def resized(self, factor: float) -> 'LabelledFrame':
        """
        Return the labels of this frame resized by a factor (its lines, rows and camera).

        :param factor: the new size over the labelled one.
        :return: the LabelledFrame of the resized image.
        """
        return dataclasses.replace(
            self, size=tuple(round(value * factor) for value in self.size),
            horizon_y_px=_resized_px(self.horizon_y_px, factor),
            lines={colour: [[_resized_point(point, factor) for point in polyline]
                            for polyline in polylines]
                   for colour, polylines in self.lines.items()},
            ignore_rows=tuple((_resized_px(first, factor), _resized_px(last, factor))
                              for first, last in self.ignore_rows),
            camera=self.camera and _resized_camera(self.camera, factor))


@dataclasses.dataclass(frozen=True)
class LabelledSource:
    """A source of frames: the robot's camera, its tape widths, and its labelled frames."""

    name: str
    camera: dict
    line_width_m: dict
    frames: tuple

    def resized(self, factor: float) -> 'LabelledSource':
        """
        Return the source with its camera and every frame's labels resized by a factor.

        :param factor: the new image size over the labelled one.
        :return: the LabelledSource of the resized images.
        """
        return dataclasses.replace(self, camera=_resized_camera(self.camera, factor),
                                   frames=tuple(frame.resized(factor) for frame in self.frames))

    def geometry(self, frame: LabelledFrame | None = None) -> CameraGeometry:
        """
        Return the camera's geometry, as the robot's camera_info and mounting say.

        :param frame: a frame taken by another camera than the source's (its own ``camera``).
        :return: the geometry.
        """
        camera = frame.camera if frame is not None and frame.camera else self.camera
        return CameraGeometry(fx_px=camera['fx_px'], fy_px=camera['fy_px'],
                              cx_px=camera['cx_px'], cy_px=camera['cy_px'],
                              height_m=camera['height_m'],
                              pitch_rad=math.radians(camera['pitch_deg']))


def _resized_px(value: float, factor: float) -> float:
    """Return a pixel coordinate (pixel centres at whole numbers) in the resized image."""
    return (value + 0.5) * factor - 0.5


def _resized_point(point: tuple, factor: float) -> tuple:
    """Return a labelled line's point (x, y, width, in pixels) in the resized image."""
    x_px, y_px, width_px = point
    return _resized_px(x_px, factor), _resized_px(y_px, factor), width_px * factor


def _resized_camera(camera: dict, factor: float) -> dict:
    """Return a camera's calibration for its image resized by a factor (its mounting kept)."""
    resized = dict(camera)
    for field in CAMERA_PIXEL_FIELDS:
        resized[field] = camera[field] * factor
    for field in CAMERA_CENTRE_FIELDS:
        resized[field] = _resized_px(camera[field], factor)
    return resized


def load_labels(labels_dir: Path = LABELS_DIR) -> list:
    """
    Read every source's labels.

    :param labels_dir: the folder of ``<source>.yaml`` label files.
    :return: LabelledSource list, sorted by name.
    :raises FileNotFoundError: if the folder holds no label files.
    """
    paths = sorted(Path(labels_dir).glob('*.yaml'))
    if not paths:
        raise FileNotFoundError(f'No label files (*.yaml) in {labels_dir}.')
    sources = []
    for path in paths:
        document = yaml.safe_load(path.read_text())
        name = document['source']
        frames = tuple(
            LabelledFrame(source=name, name=frame_name, size=tuple(frame['size']),
                          horizon_y_px=float(frame.get('horizon_y_px', math.nan)),
                          lines={colour: [[tuple(point) for point in polyline]
                                          for polyline in polylines]
                                 for colour, polylines in (frame.get('lines') or {}).items()},
                          ignore_rows=tuple((first, last) for first, last, *_ in
                                            frame.get('ignore_rows') or ()),
                          camera=frame.get('camera'))
            for frame_name, frame in document['frames'].items())
        sources.append(LabelledSource(name=name, camera=document['camera'],
                                      line_width_m=document['line_width_m'], frames=frames))
    return sources


def frames_folder() -> tuple:
    """
    Find the folder of real frames.

    :return: (the folder or None, a one-line reason when it is None).
    """
    chosen = os.environ.get(FRAMES_VARIABLE)
    folder = Path(chosen) if chosen else DEFAULT_FRAMES_DIR
    if not folder.is_dir():
        return None, (f'no real frames at {folder} (third-party files, not in the repository; '
                      f'set {FRAMES_VARIABLE} to their folder)')
    return folder, ''


def detector_config(source: LabelledSource, colour: str, **overrides) -> DetectorConfig:
    """
    Return the follower's default detector configuration for a source's line of a colour.

    :param source: the source (its tape width for that colour).
    :param colour: the line colour preset.
    :param overrides: further DetectorConfig fields.
    :return: the configuration.
    """
    width_m = source.line_width_m.get(colour, DetectorConfig().line_width_m)
    return DetectorConfig(line_colour=colour, line_width_m=width_m, **overrides)


@dataclasses.dataclass
class FrameResult:
    """What the detector made of one frame: its verdicts, confidence and detection."""

    frame: LabelledFrame
    colour: str
    verdicts: list
    detection: object


def frame_line_truths(frame, colour: str, detection, geometry, line_width_m: float) -> list:
    """
    Return the truth of each band of a detection, per line of a labelled frame's colour.

    :param frame: the LabelledFrame.
    :param colour: the line colour whose labelled lines are the truth.
    :param detection: the line_detector.Detection whose bands are judged.
    :param geometry: the frame's CameraGeometry (for the tape's width in each band), or None.
    :param line_width_m: the width of the tape the detector is set up for.
    :return: per line, one BandTruth per band (see perception_score.frame_verdicts).
    """
    thinnest_px = thinnest_line_px(detection, geometry, line_width_m)
    return [[band_truth(line, band.top_px, band.bottom_px, frame.ignore_rows, min_width_px)
             for band, min_width_px in zip(detection.bands, thinnest_px)]
            for line in group_lines(frame.polylines(colour))]


def score_source(source: LabelledSource, frames_dir: Path, colour: str, frames=None, *,
                 size_factor: float = 1.0, **overrides) -> tuple:
    """
    Score the follower's detector on a source's frames for a line colour.

    Every frame is a first sight (the detector is reset): a still, not a sequence.

    :param source: the labelled source.
    :param frames_dir: the folder of real frames (holding ``<source>/<file>``).
    :param colour: the line colour preset; each frame's lines of that colour are the truth
        (a frame without any is all absent).
    :param frames: the frames to score (default: all the source's).
    :param size_factor: score each frame reduced to this share of its size (area averaging),
        with its labels and camera calibration resized to match (see HALF_SIZE); at most 1.
    :param overrides: DetectorConfig fields to change from the defaults.
    :return: (PerceptionTally, list of FrameResult, whose frames are the resized labels).
    :raises ValueError: for a size factor not in (0, 1].
    """
    if not 0.0 < size_factor <= 1.0:
        raise ValueError(f'size_factor must be in (0, 1], got {size_factor}.')
    frames = source.frames if frames is None else frames
    if size_factor != 1.0:
        source = source.resized(size_factor)
        frames = [frame.resized(size_factor) for frame in frames]
    detector = LineDetector(detector_config(source, colour, **overrides))
    tally = PerceptionTally()
    results = []
    for frame in frames:
        image = cv2.imread(str(Path(frames_dir) / source.name / frame.name))
        if image is None:
            raise FileNotFoundError(f'Cannot read {frames_dir}/{source.name}/{frame.name}.')
        if size_factor != 1.0:
            image = cv2.resize(image, frame.size, interpolation=cv2.INTER_AREA)
        detector.reset()
        geometry = source.geometry(frame)
        detection = detector.detect(image, 'bgr8', geometry)
        line_truths = frame_line_truths(frame, colour, detection, geometry,
                                        detector.config.line_width_m)
        verdicts = tally.add_frame(line_truths, detection)
        results.append(FrameResult(frame, colour, verdicts, detection))
    return tally, results


def draw_schematic(result: FrameResult):
    """
    Draw a frame's labels and the detector's verdicts, without the frame's pixels.

    The labelled lines of every colour are drawn at their labelled width, the horizon as a grey
    line, each band's rows as a thin outline, and each band's stripe (or, when missed, the
    band's centre) as a circle: green right, red false, magenta missed.

    :param result: the FrameResult of :func:`score_source`.
    :return: the BGR picture, of the frame's size.
    """
    width_px, height_px = result.frame.size
    picture = np.full((height_px, width_px, 3), SCHEMATIC_CANVAS_BGR, np.uint8)
    if math.isfinite(result.frame.horizon_y_px) and 0 <= result.frame.horizon_y_px < height_px:
        row = round(result.frame.horizon_y_px)
        cv2.line(picture, (0, row), (width_px - 1, row), SCHEMATIC_HORIZON_BGR, 1)
    for colour, polylines in result.frame.lines.items():
        for polyline in polylines:
            for (x0, y0, w0), (x1, y1, w1) in zip(polyline, polyline[1:]):
                cv2.line(picture, (round(x0), round(y0)), (round(x1), round(y1)),
                         SCHEMATIC_LINE_BGR.get(colour, SCHEMATIC_TEXT_BGR),
                         max(1, round((w0 + w1) / 2)), cv2.LINE_AA)
    for band, verdict in zip(result.detection.bands, result.verdicts):
        cv2.rectangle(picture, (0, band.top_px), (width_px - 1, band.bottom_px - 1),
                      SCHEMATIC_BAND_BGR, 1)
        x_px = band.centroid_x_px if band.found else width_px / 2.0
        y_px = (band.top_px + band.bottom_px - 1) / 2.0
        cv2.circle(picture, (round(x_px), round(y_px)), SCHEMATIC_MARK_RADIUS_PX,
                   SCHEMATIC_VERDICT_BGR[verdict], 2 if band.found else 1, cv2.LINE_AA)
    cv2.putText(picture, f'{result.frame.name} ({result.colour}) confidence '
                f'{result.detection.confidence:.2f}', (10, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                SCHEMATIC_TEXT_BGR, 1, cv2.LINE_AA)
    return picture
