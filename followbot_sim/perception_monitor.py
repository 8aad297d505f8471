"""
Score the follower's line detector against the simulator's ground truth, frame by frame.

A node beside the follower: it takes the same camera frames, runs a detector configured like the
follower's defaults (the same camera geometry from camera_info), and judges each band of each
frame against ``camera/rgb/line_truth`` of the same stamp with
:mod:`followbot_sim.perception_score` (the scoring used for labelled real frames). The scorecard
and the benchmark run it for the realistic table: per band right / false / missed.

The truth topic samples rows (``line_truth_row_step_px``; 1 for scoring): each stretch of a row
the paint covers becomes a one-row piece, ``(x, row - 0.5, w)`` to ``(x, row + 0.5, w)``, as a
labelled real frame gives the line's middle and extent along its rows.
"""

import math

from followbot.ground_projection import CameraGeometry, CameraIntrinsics
from followbot.image_conversion import image_to_array
from followbot.line_detector import DetectorConfig, LineDetector
from followbot_sim.perception_score import (band_truth, EDGE_MARGIN_PX, PerceptionTally,
                                            thinnest_line_px)
from geometry_msgs.msg import PolygonStamped
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

# Truths wait this many frames for their image (and images for their truth) before they go.
MAX_PENDING_FRAMES = 10
ROW_HALF_PX = 0.5


def truth_polylines(points) -> list:
    """
    Turn line-truth points (the PolygonStamped layout) into one-row pieces of the line.

    :param points: objects with x (middle column), y (row) and z (length px along the row, 0
        where not seen).
    :return: ``[(x, y, w), (x, y, w)]`` polylines, one per stretch, sorted by row.
    """
    pieces = []
    for point in points:
        if point.z > 0.0 and math.isfinite(point.x):
            pieces.append([(point.x, point.y - ROW_HALF_PX, point.z),
                           (point.x, point.y + ROW_HALF_PX, point.z)])
    pieces.sort(key=lambda piece: piece[0][1])
    return pieces


def detection_line_truths(pieces, detection, geometry, line_width_m: float) -> list:
    """
    Return the truth of each band of a detection, with every visible piece as one line.

    :param pieces: from :func:`truth_polylines`.
    :param detection: the line_detector.Detection.
    :param geometry: the CameraGeometry (for the narrowest tape counted as the line), or None.
    :param line_width_m: the tape's width the detector is set up for.
    :return: ``[bands]``: one list of BandTruth, nearest band first (one line).
    """
    truths = []
    reach_px = EDGE_MARGIN_PX + 1.0
    for band, min_width_px in zip(detection.bands,
                                  thinnest_line_px(detection, geometry, line_width_m)):
        near = [piece for piece in pieces
                if band.top_px - reach_px <= piece[0][1] <= band.bottom_px + reach_px]
        truths.append(band_truth(near, band.top_px, band.bottom_px, (), min_width_px))
    return [truths]


class PerceptionMonitor(Node):
    """Run the follower's default detector on the camera and tally it against the truth."""

    def __init__(self, camera_height_m: float, camera_pitch_deg: float,
                 camera_forward_m: float, detector_config: DetectorConfig | None = None,
                 **kwargs):
        """
        Subscribe to the camera, its camera_info and the line truth.

        :param camera_height_m: the follower's camera height (for the camera geometry).
        :param camera_pitch_deg: the follower's camera pitch.
        :param camera_forward_m: the follower's camera offset ahead of the robot centre.
        :param detector_config: the detector's configuration; the follower's defaults if None.
        :param kwargs: forwarded to :class:`rclpy.node.Node`.
        """
        super().__init__('perception_monitor', **kwargs)
        self._detector = LineDetector(detector_config or DetectorConfig())
        self._mount = (camera_height_m, math.radians(camera_pitch_deg), camera_forward_m)
        self._geometry = None
        self._images = {}
        self._truths = {}
        self.tally = PerceptionTally()
        self.create_subscription(CameraInfo, 'camera/rgb/camera_info',
                                 self.camera_info_callback, 10)
        self.create_subscription(Image, 'camera/rgb/image_raw', self.image_callback, 10)
        self.create_subscription(PolygonStamped, 'camera/rgb/line_truth',
                                 self.line_truth_callback, 10)

    def camera_info_callback(self, msg: CameraInfo) -> None:
        """Keep the camera geometry the follower would make from this camera_info."""
        if self._geometry is None:
            self._geometry = CameraGeometry.from_intrinsics(
                CameraIntrinsics.from_camera_info(msg), *self._mount)

    def image_callback(self, msg: Image) -> None:
        """Detect the line in a frame; score it once its truth is here."""
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        self._images[stamp] = self._detector.detect(image_to_array(msg), msg.encoding,
                                                    self._geometry)
        self._match(stamp)

    def line_truth_callback(self, msg: PolygonStamped) -> None:
        """Keep a frame's truth; score the frame once its detection is here."""
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        self._truths[stamp] = truth_polylines(msg.polygon.points)
        self._match(stamp)

    def _match(self, stamp) -> None:
        if stamp in self._images and stamp in self._truths:
            detection = self._images.pop(stamp)
            pieces = self._truths.pop(stamp)
            self.tally.add_frame(detection_line_truths(
                pieces, detection, self._geometry, self._detector.config.line_width_m),
                detection)
        for pending in (self._images, self._truths):
            while len(pending) > MAX_PENDING_FRAMES:
                pending.pop(next(iter(pending)))
