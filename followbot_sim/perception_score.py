"""
Score what the line detector saw in each band against where the line truly is.

The truth of a band comes from labelled frames (real camera frames labelled by hand) or from
the simulator's ground truth: the line's centre and width at each row, where it is visible.
A band's truth is one of:

- ``present``: the line crosses the band's centre row;
- ``absent``: the line touches no row of the band (nor comes within ``EDGE_MARGIN_PX`` of it);
- ``either``: the line touches the band but not its centre row (a dash ending in it), or the
  rows are marked as undecidable: seeing it and not seeing it are both right.

A band's verdict is ``right``, ``false`` (a stripe reported where the line is not, or where it
is not at all) or ``missed`` (the line crosses the band and nothing was reported).

A follower follows one line. Where a frame holds several (two lanes' lines, the far arm of a
bend seen apart from the near one), the labelled pieces are grouped into lines (a dash leads on
to the next, :func:`group_lines`), and the line the detection followed is the one its stripes
lie on: a band only another line crosses may be seen or not. A stripe on any line is right; a
detection that reports nothing misses every line. A reported
stripe is on the line when its centroid lies on the line's width at any row of the band (or
within ``EDGE_MARGIN_PX`` rows of it), give or take ``max(MIN_TOLERANCE_PX, TOLERANCE_WIDTHS *
width)``.
"""

import dataclasses
import math
from typing import NamedTuple

from followbot.line_detector import MIN_WIDTH_RATIO

PRESENT = 'present'
ABSENT = 'absent'
EITHER = 'either'
RIGHT = 'right'
FALSE = 'false'
MISSED = 'missed'
VERDICTS = (RIGHT, FALSE, MISSED)
# A line ending this close above or below a band may show in its rows (blur, the label's
# precision): such a band may or may not see it, and a stripe reported on it is on the line.
EDGE_MARGIN_PX = 3.0
# How far off the labelled centre a centroid may be and still be on the line.
MIN_TOLERANCE_PX = 4.0
TOLERANCE_WIDTHS = 0.25
# A reported stripe is "confidently false" when the detection's confidence reaches this.
CONFIDENT = 0.5
# A line piece leads on to another whose start lies within this many of its own lengths (plus
# LEAD_MIN_PX) ahead of its far end, sideways within its width plus LEAD_SLACK of the distance.
LEAD_LENGTHS = 3.0
LEAD_MIN_PX = 20.0
LEAD_SLACK = 0.35


class BandTruth(NamedTuple):
    """Where the line is in one band: its state and the column intervals it covers."""

    state: str
    intervals: tuple


def polyline_crossings(polyline, row_px: float) -> list:
    """
    Return where a labelled polyline crosses an image row.

    :param polyline: points ``(x, y, width)`` of the line's centre, in order.
    :param row_px: the row.
    :return: (x, width) pairs, one per segment that spans the row; a segment lying along the
        row gives its middle and its whole length plus the width as the width.
    """
    crossings = []
    for (x0, y0, w0), (x1, y1, w1) in zip(polyline, polyline[1:]):
        low, high = min(y0, y1), max(y0, y1)
        if not low <= row_px <= high:
            continue
        if high - low < 1e-9:
            crossings.append(((x0 + x1) / 2.0, abs(x1 - x0) + max(w0, w1)))
            continue
        t = (row_px - y0) / (y1 - y0)
        crossings.append((x0 + t * (x1 - x0), w0 + t * (w1 - w0)))
    return crossings


def _touches(polyline, top_px: float, bottom_px: float) -> bool:
    """Tell whether a polyline reaches into rows top..bottom (inclusive) at all."""
    return any(min(y0, y1) <= bottom_px and max(y0, y1) >= top_px
               for (_, y0, _), (_, y1, _) in zip(polyline, polyline[1:]))


def band_truth(polylines, top_px: int, bottom_px: int, ignored_rows=(),
               min_width_px: float = 0.0) -> BandTruth:
    """
    Return the truth of a band of rows from the line's labelled centre polylines.

    :param polylines: lists of ``(x, y, width)`` points, one list per visible piece of line.
    :param top_px: first row of the band.
    :param bottom_px: one past the band's last row.
    :param ignored_rows: ``(first, last)`` row ranges where no one can tell.
    :param min_width_px: a labelled line narrower than this at the band is another, thinner
        marking than the tape the follower is set up for (an island's outline beside a lane's
        edge line): finding it is right, missing it too.
    :return: the BandTruth; its intervals are the line's extent at every row of the band.
    """
    centre_px = (top_px + bottom_px - 1) / 2.0
    intervals = []
    # A label's rows are as exact as its eye: a stripe on a line passing just above or below
    # the band is on the line.
    for row in range(top_px - int(EDGE_MARGIN_PX), bottom_px + int(EDGE_MARGIN_PX)):
        for polyline in polylines:
            for x_px, width_px in polyline_crossings(polyline, row):
                tolerance_px = max(MIN_TOLERANCE_PX, TOLERANCE_WIDTHS * width_px)
                half_px = width_px / 2.0 + tolerance_px
                intervals.append((x_px - half_px, x_px + half_px))
    crossings = [width_px for polyline in polylines
                 for _, width_px in polyline_crossings(polyline, centre_px)]
    crosses_centre = any(width_px >= min_width_px for width_px in crossings)
    if crossings and not crosses_centre:
        return BandTruth(EITHER, tuple(intervals))
    if any(first <= bottom_px - 1 and last >= top_px for first, last in ignored_rows):
        return BandTruth(EITHER, tuple(intervals))
    if crosses_centre:
        return BandTruth(PRESENT, tuple(intervals))
    if any(_touches(polyline, top_px - EDGE_MARGIN_PX, bottom_px - 1 + EDGE_MARGIN_PX)
           for polyline in polylines):
        return BandTruth(EITHER, tuple(intervals))
    return BandTruth(ABSENT, ())


def thinnest_line_px(detection, geometry, line_width_m: float) -> list:
    """
    Return, per band of a detection, the narrowest marking that counts as the line (pixels).

    Markings much thinner than the tape the detector is set up for are not the line it
    follows: the bound is the detector's own narrowest stripe, ``MIN_WIDTH_RATIO`` of the
    tape's width in the band.

    :param detection: the line_detector.Detection whose bands are judged.
    :param geometry: the CameraGeometry, or None (then every marking counts: 0).
    :param line_width_m: the width of the tape the detector is set up for.
    :return: one width per band, nearest band first.
    """
    centres_px = [(band.top_px + band.bottom_px - 1) / 2.0 for band in detection.bands]
    if geometry is None:
        return [0.0] * len(centres_px)
    return [float(MIN_WIDTH_RATIO * width_px)
            for width_px in geometry.line_width_px(centres_px, line_width_m)]


def band_verdict(truth: BandTruth, found: bool, x_px: float) -> str:
    """
    Judge one band's detection.

    :param truth: where the line is in the band.
    :param found: whether the detector reported a stripe in the band.
    :param x_px: the stripe's centroid column (ignored when not found).
    :return: RIGHT, FALSE or MISSED.
    """
    if not found:
        return MISSED if truth.state == PRESENT else RIGHT
    on_line = math.isfinite(x_px) and any(low <= x_px <= high for low, high in truth.intervals)
    return RIGHT if on_line else FALSE


def _leads_to(polyline, other, reach_px: float) -> bool:
    """Tell whether a line piece, carried on straight from its far end, reaches another's start."""
    (x0, y0, _), (x1, y1, width_px) = polyline[-2], polyline[-1]
    start_x, start_y, start_width_px = other[0]
    if len(polyline) < 2:
        return False
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    if length == 0.0:
        return False
    along = ((start_x - x1) * dx + (start_y - y1) * dy) / length
    across = abs((start_x - x1) * dy - (start_y - y1) * dx) / length
    return -max(width_px, start_width_px) <= along <= reach_px and across <= max(
        width_px, start_width_px, MIN_TOLERANCE_PX) + LEAD_SLACK * max(along, 0.0)


def group_lines(polylines) -> list:
    """
    Group labelled line pieces into lines.

    A piece whose straight continuation reaches the start of another (the next dash, the far
    part beyond a hidden stretch) is the same line.

    :param polylines: lists of ``(x, y, width)`` points, near end first.
    :return: lists of polylines, one list per line.
    """
    parent = list(range(len(polylines)))

    def root(index):
        while parent[index] != index:
            parent[index] = parent[parent[index]]
            index = parent[index]
        return index

    for index, polyline in enumerate(polylines):
        if len(polyline) < 2:
            continue
        reach_px = LEAD_LENGTHS * math.dist(polyline[0][:2], polyline[-1][:2]) + LEAD_MIN_PX
        for other_index, other in enumerate(polylines):
            if other_index != index and _leads_to(polyline, other, reach_px):
                parent[root(other_index)] = root(index)
    groups = {}
    for index, polyline in enumerate(polylines):
        groups.setdefault(root(index), []).append(polyline)
    return list(groups.values())


def frame_verdicts(line_truths, detection) -> list:
    """
    Judge a detection's bands against the lines of a frame.

    :param line_truths: per line of the frame, one BandTruth per band (nearest first); empty
        when the frame holds no line.
    :param detection: the line_detector.Detection.
    :return: (the verdicts, the BandTruth each was judged by), nearest band first.
    """
    count = len(detection.bands)
    if not line_truths:
        line_truths = [[BandTruth(ABSENT, ())] * count]
    on_line = [sum(band.found and band_verdict(truth, True, band.centroid_x_px) == RIGHT
                   for truth, band in zip(truths, detection.bands)) for truths in line_truths]
    if not detection.found or max(on_line) == 0:
        truths = [_union(band_truths) for band_truths in zip(*line_truths)]
    else:
        followed = on_line.index(max(on_line))
        truths = []
        for index, band_truths in enumerate(zip(*line_truths)):
            truth = _union(band_truths)
            if (band_truths[followed].state != PRESENT and truth.state == PRESENT):
                # Only another line crosses here: not the follower's business.
                truth = BandTruth(EITHER, truth.intervals)
            truths.append(truth)
    verdicts = [band_verdict(truth, band.found, band.centroid_x_px)
                for truth, band in zip(truths, detection.bands)]
    return verdicts, truths


def _union(band_truths) -> BandTruth:
    """Return the truth of a band for all lines together."""
    intervals = tuple(interval for truth in band_truths for interval in truth.intervals)
    for state in (PRESENT, EITHER):
        if any(truth.state == state for truth in band_truths):
            return BandTruth(state, intervals)
    return BandTruth(ABSENT, intervals)


@dataclasses.dataclass
class PerceptionTally:
    """Counts of band verdicts, and of frames with a confidently reported false stripe."""

    bands: int = 0
    right: int = 0
    false: int = 0
    missed: int = 0
    line_bands: int = 0
    line_bands_right: int = 0
    frames: int = 0
    confident_false_frames: int = 0

    def add_frame(self, line_truths, detection) -> list:
        """
        Score one frame's detection.

        :param line_truths: per line of the frame, one BandTruth per band of the detection,
            nearest first (see :func:`frame_verdicts`).
        :param detection: the line_detector.Detection of the frame.
        :return: the verdicts, nearest band first.
        """
        verdicts, truths = frame_verdicts(line_truths, detection)
        self.frames += 1
        self.bands += len(verdicts)
        self.right += verdicts.count(RIGHT)
        self.false += verdicts.count(FALSE)
        self.missed += verdicts.count(MISSED)
        present = [verdict for truth, verdict in zip(truths, verdicts) if truth.state == PRESENT]
        self.line_bands += len(present)
        self.line_bands_right += present.count(RIGHT)
        if FALSE in verdicts and detection.confidence >= CONFIDENT:
            self.confident_false_frames += 1
        return verdicts

    def merge(self, other: 'PerceptionTally') -> None:
        """Add another tally's counts to this one."""
        for field in dataclasses.fields(self):
            setattr(self, field.name, getattr(self, field.name) + getattr(other, field.name))

    def share(self, count: int) -> float:
        """Return a count as a fraction of the bands scored (0 when none were)."""
        return count / self.bands if self.bands else 0.0

    @property
    def right_share(self) -> float:
        """Return the fraction of bands judged right."""
        return self.share(self.right)

    @property
    def false_share(self) -> float:
        """Return the fraction of bands with a false stripe."""
        return self.share(self.false)

    @property
    def missed_share(self) -> float:
        """Return the fraction of bands where the line was missed."""
        return self.share(self.missed)

    @property
    def line_recall(self) -> float:
        """Return the fraction of bands crossed by the line where it was found right."""
        return self.line_bands_right / self.line_bands if self.line_bands else 0.0
