"""
The course from above with the robot's trail, drawn with OpenCV for the run's video.

Pure drawing: the floor comes from the course's own painting (:meth:`Course.draw_texture`, the
same line, dashes, distractors and light the camera sees), the trail and the robot from the
poses given. No MuJoCo camera is needed, so a frame costs a copy and a few OpenCV calls.
"""

import math

import cv2
import numpy as np

# Floor shown around the course's centre line, so the robot stays in view when it leaves it.
VIEW_MARGIN_M = 0.6
# Beyond the floor's edge (a course close to it, seen with the margin).
OUTSIDE_FLOOR_BGR = (40, 40, 40)
TRAIL_BGR = (0, 0, 255)
TRAIL_THICKNESS_PX = 2
ROBOT_BGR = (255, 128, 0)
# The Kobuki's body, as drawn: a disc of its diameter with a stroke to its heading.
ROBOT_DIAMETER_M = 0.35
ROBOT_OUTLINE_PX = 2
CAPTION_BGR = (255, 255, 255)
# The caption sits on a dark box: legible on the grey floor, the yellow line and the trail.
CAPTION_BOX_BGR = (0, 0, 0)
CAPTION_BOX_OPACITY = 0.6
CAPTION_SCALE = 0.5
CAPTION_LINE_PX = 20
CAPTION_MARGIN_PX = 6
# OpenCV draws with integer pixels; this many fractional bits keep the trail smooth.
SUBPIXEL_BITS = 4
SUBPIXEL_SCALE = 1 << SUBPIXEL_BITS


class TopDownView:
    """A square view of a course from above that accumulates the robot's trail."""

    def __init__(self, course, size_px: int, margin_m: float = VIEW_MARGIN_M):
        """
        Paint the floor once, framed on the course's centre line.

        :param course: the :class:`followbot_sim.course.Course` driven on.
        :param size_px: side of the square view in pixels.
        :param margin_m: floor shown beyond the centre line's extent on every side.
        :raises ValueError: if ``size_px`` is not a positive integer or ``margin_m`` is
            negative.
        """
        if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) \
                or size_px < 1:
            raise ValueError(f'size_px must be a positive integer, got {size_px!r}.')
        if not margin_m >= 0.0:
            raise ValueError(f'margin_m must not be negative, got {margin_m!r}.')
        self._size_px = int(size_px)
        points_xy = np.asarray(course.centre_line_xy)
        low_xy, high_xy = points_xy.min(axis=0), points_xy.max(axis=0)
        centre_xy = (low_xy + high_xy) / 2.0
        view_m = float(np.max(high_xy - low_xy)) + 2.0 * margin_m
        self._px_per_m = self._size_px / view_m
        # Row 0 at the north edge, as the course's texture: x east is right, y north is up.
        # Pixel centres at integers (OpenCV's convention): the view's centre is at size / 2 - 0.5.
        middle_px = self._size_px / 2.0 - 0.5
        self._origin_px = np.array([middle_px - centre_xy[0] * self._px_per_m,
                                    middle_px + centre_xy[1] * self._px_per_m])
        self._canvas = self._paint_floor(course)
        self._last_trail_px = None

    def _paint_floor(self, course) -> np.ndarray:
        # The course paints its whole floor at this scale; one shift frames the view on it.
        texture_px = max(1, round(course.floor_size_m * self._px_per_m))
        floor_bgr = cv2.cvtColor(course.draw_texture(texture_px), cv2.COLOR_RGB2BGR)
        # Texture pixel (0, 0) is centred half a texture pixel inside the north-west corner.
        corner_x_m, corner_y_m = -course.floor_size_m / 2.0, course.floor_size_m / 2.0
        shift_px = self.to_pixels(corner_x_m, corner_y_m)
        texel_px = course.floor_size_m / texture_px * self._px_per_m
        shift = np.float32([[texel_px, 0.0, shift_px[0] + 0.5 * texel_px],
                            [0.0, texel_px, shift_px[1] + 0.5 * texel_px]])
        return cv2.warpAffine(floor_bgr, shift, (self._size_px, self._size_px),
                              flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=OUTSIDE_FLOOR_BGR)

    @property
    def size_px(self) -> int:
        """Return the side of the square view in pixels."""
        return self._size_px

    @property
    def px_per_m(self) -> float:
        """Return the view's scale."""
        return self._px_per_m

    def to_pixels(self, x_m, y_m) -> np.ndarray:
        """
        Convert floor coordinates to continuous view pixels.

        :param x_m: east coordinate(s) in metres.
        :param y_m: north coordinate(s) in metres.
        :return: ``(col, row)`` as floats (or arrays), pixel centres at integers.
        """
        return np.array([self._origin_px[0] + np.asarray(x_m, dtype=float) * self._px_per_m,
                         self._origin_px[1] - np.asarray(y_m, dtype=float) * self._px_per_m])

    def add_trail_point(self, x_m: float, y_m: float) -> None:
        """
        Extend the trail to where the robot is, once it has moved a pixel or more.

        :param x_m: east coordinate of the robot in metres.
        :param y_m: north coordinate of the robot in metres.
        """
        point_px = self.to_pixels(x_m, y_m)
        if self._last_trail_px is not None:
            if np.hypot(*(point_px - self._last_trail_px)) < 1.0:
                return
            # Drawn once into the canvas: a frame costs the same however long the trail.
            cv2.line(self._canvas, _fixed_point(self._last_trail_px), _fixed_point(point_px),
                     TRAIL_BGR, TRAIL_THICKNESS_PX, cv2.LINE_AA, SUBPIXEL_BITS)
        self._last_trail_px = point_px

    def draw(self, robot_pose=None, caption_lines=()) -> np.ndarray:
        """
        Draw the view: floor, trail, the robot at a pose and a caption.

        :param robot_pose: ``(x_m, y_m, yaw_rad)`` of the robot, or None to leave it out.
        :param caption_lines: lines of text written in the top-left corner.
        :return: a new BGR uint8 image of shape (size_px, size_px, 3).
        """
        image = self._canvas.copy()
        if robot_pose is not None:
            x_m, y_m, yaw_rad = robot_pose
            centre_px = self.to_pixels(x_m, y_m)
            radius_m = ROBOT_DIAMETER_M / 2.0
            nose_px = self.to_pixels(x_m + radius_m * math.cos(yaw_rad),
                                     y_m + radius_m * math.sin(yaw_rad))
            radius_px = max(1, round(radius_m * self._px_per_m * SUBPIXEL_SCALE))
            cv2.circle(image, _fixed_point(centre_px), radius_px, ROBOT_BGR, ROBOT_OUTLINE_PX,
                       cv2.LINE_AA, SUBPIXEL_BITS)
            cv2.line(image, _fixed_point(centre_px), _fixed_point(nose_px), ROBOT_BGR,
                     ROBOT_OUTLINE_PX, cv2.LINE_AA, SUBPIXEL_BITS)
        write_caption(image, caption_lines)
        return image


def write_caption(image: np.ndarray, lines) -> None:
    """
    Write lines of text in an image's top-left corner, readable on any background.

    :param image: BGR image, drawn on in place.
    :param lines: the lines, top first.
    """
    lines = list(lines)
    if not lines:
        return
    width_px = max(cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, CAPTION_SCALE, 1)[0][0]
                   for text in lines)
    box = image[:CAPTION_LINE_PX * len(lines) + 2 * CAPTION_MARGIN_PX,
                :width_px + 2 * CAPTION_MARGIN_PX]
    box[:] = (box * (1.0 - CAPTION_BOX_OPACITY)
              + np.multiply(CAPTION_BOX_BGR, CAPTION_BOX_OPACITY)).astype(np.uint8)
    for index, text in enumerate(lines):
        # Baseline a few pixels above the line's bottom: room for descenders.
        origin = (CAPTION_MARGIN_PX, CAPTION_MARGIN_PX + CAPTION_LINE_PX * (index + 1) - 6)
        cv2.putText(image, text, origin, cv2.FONT_HERSHEY_SIMPLEX, CAPTION_SCALE, CAPTION_BGR,
                    1, cv2.LINE_AA)


def side_by_side(camera_bgr: np.ndarray, top_down_bgr: np.ndarray) -> np.ndarray:
    """
    Put the camera view and the top-down view next to each other, camera on the left.

    :param camera_bgr: BGR uint8 camera image.
    :param top_down_bgr: BGR uint8 top-down view of the camera image's height.
    :return: one image, as wide as both.
    :raises ValueError: if the heights differ or an image is not 3-channel.
    """
    if camera_bgr.ndim != 3 or top_down_bgr.ndim != 3 \
            or camera_bgr.shape[2] != 3 or top_down_bgr.shape[2] != 3:
        raise ValueError(f'side_by_side takes two BGR images, got shapes {camera_bgr.shape} '
                         f'and {top_down_bgr.shape}.')
    if camera_bgr.shape[0] != top_down_bgr.shape[0]:
        raise ValueError(f'The camera image is {camera_bgr.shape[0]} px high and the top-down '
                         f'view {top_down_bgr.shape[0]} px: they must match.')
    return np.hstack((camera_bgr, top_down_bgr))


def _fixed_point(point_px) -> tuple:
    """Return a continuous pixel position as the fixed-point integers OpenCV draws with."""
    return (int(round(float(point_px[0]) * SUBPIXEL_SCALE)),
            int(round(float(point_px[1]) * SUBPIXEL_SCALE)))
