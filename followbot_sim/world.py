"""
The MuJoCo world of the follow-bot: a TurtleBot 2 on a course, stepped and rendered off-screen.

No ROS import: the simulator node wires this to topics, and tests and benchmarks use it directly.
Rendering needs an OpenGL context; headless machines use ``MUJOCO_GL=egl`` (Mesa on the CPU).
The context belongs to the thread that first renders, so render from one thread only.

The robot carries a Kinect: an RGB camera ``camera_rgb`` and, 2.5 cm to its left, a depth (IR)
camera ``camera_depth`` with the same orientation and intrinsics. The whole Kinect
(``camera_link``) is tilted down by the camera pitch; :meth:`FollowbotWorld.sensor_frames` gives
the robot's fixed frames read from the compiled model.
"""

import math
import os
from pathlib import Path
import time

from followbot.frames import (BASE_FOOTPRINT_FRAME, BASE_LINK_FRAME, CAMERA_DEPTH_FRAME,
                              CAMERA_DEPTH_OPTICAL_FRAME, CAMERA_LINK_FRAME, CAMERA_RGB_FRAME,
                              CAMERA_RGB_OPTICAL_FRAME, FrameTransform, optical_rotation_xyzw,
                              quaternion_from_matrix, yaw_from_quaternion)
from followbot.package_files import share_file
from followbot_sim import appearance
from followbot_sim.camera_model import CameraModel
from followbot_sim.course import Course
from followbot_sim.diff_drive import DiffDriveLimits, wheel_speeds_radps
from followbot_sim.line_truth import line_truth, LineTruth, PinholeView, sampled_rows
from followbot_sim.realism import Realism
from followbot_sim.robots import (DEFAULT_ROBOT_SPACING_M, robot_prefix, SINGLE_ROBOT,
                                  start_arc_lengths_m)
import mujoco
import numpy as np

SCENE_FILE = 'scene.xml'
# The robot alone, for worlds of several robots (scene.xml includes it once, unprefixed).
ROBOT_FILE = 'turtlebot2.xml'
ROBOT_BODY = BASE_FOOTPRINT_FRAME
ROBOT_FREE_JOINT = 'base_free'
# The bodies of the robot's fixed frames carry the frames' names.
BASE_LINK_BODY = BASE_LINK_FRAME
CAMERA_LINK_BODY = CAMERA_LINK_FRAME
CAMERA_NAME = 'camera_rgb'
DEPTH_CAMERA_NAME = 'camera_depth'
OVERVIEW_CAMERA_NAME = 'overview'
COURSE_TEXTURE_NAME = 'course'
FLOOR_GEOM = 'floor'
LEFT_MOTOR = 'wheel_left_motor'
RIGHT_MOTOR = 'wheel_right_motor'
LEFT_WHEEL_JOINT = 'wheel_left_joint'
RIGHT_WHEEL_JOINT = 'wheel_right_joint'

DEFAULT_IMAGE_WIDTH_PX = 640
DEFAULT_IMAGE_HEIGHT_PX = 480
# The Kinect's RGB camera as Gazebo models it: 60 degrees across, square pixels.
DEFAULT_HORIZONTAL_FOV_DEG = 60.0
# The book's Kinect looks level (pitch 0): its band of rows at 3/4 of the image then sees the
# floor ~1.3 m ahead, further than the course's tightest bends (~1 m radius) allow a follower
# to track, so it cuts them by tens of centimetres. Tilted down 30 degrees the same band sees
# ~0.45 m ahead of the robot centre and the robot stays on the line.
DEFAULT_CAMERA_PITCH_DEG = 30.0
# The range a Kinect (v1) reports depth in; beyond it a real one reads no data (NaN). The far
# limit is the default; the near one is not: tilted down 30 degrees, the camera sees the floor
# at the follower's band rows ~0.44 m away, and simulated depth there is worth having. Pass
# min_depth_m=KINECT_MIN_DEPTH_M for a Kinect's blind zone.
KINECT_MIN_DEPTH_M = 0.45
KINECT_MAX_DEPTH_M = 8.0
DEFAULT_MIN_DEPTH_M = 0.0
DEFAULT_MAX_DEPTH_M = KINECT_MAX_DEPTH_M
# MuJoCo cameras look along their -z axis with +y up: the columns of this matrix are the axes of
# a REP-103 body frame (x forward, y left, z up) in MuJoCo camera coordinates.
MUJOCO_CAMERA_TO_BODY_AXES = np.array([[0.0, -1.0, 0.0],
                                       [0.0, 0.0, 1.0],
                                       [-1.0, 0.0, 0.0]])
# ... and these flip MuJoCo's camera axes (x right, y up, looking along -z) to an optical
# frame's (x right, y down, looking along +z).
MUJOCO_CAMERA_TO_OPTICAL_AXES = np.diag([1.0, -1.0, -1.0])
# A pixel where nothing was hit reads as the far clipping distance, up to float32 rounding.
FAR_PLANE_FRACTION = 0.999
# The noise bank holds this many frames' worth of values; each frame reads it from a random
# offset, so consecutive frames get different noise at every pixel without drawing new normals.
NOISE_BANK_FRAMES = 2
MAX_INTENSITY = 255
# The passive viewer copies the whole state on every sync: a screen's refresh rate is plenty,
# and the physics (500 steps/s) is not slowed by syncing after each step.
VIEWER_SYNC_PERIOD_S = 1.0 / 60.0
# The viewer's camera starts behind the robot, looking down on it and the line ahead.
VIEWER_DISTANCE_M = 2.5
VIEWER_ELEVATION_DEG = -30.0


class RenderingUnavailableError(RuntimeError):
    """MuJoCo cannot render off-screen on this machine; the message says what to check."""


class ViewerUnavailableError(RuntimeError):
    """MuJoCo's interactive viewer cannot open here (no display); the message says why."""


def models_directory() -> Path:
    """
    Find the folder holding the MJCF models, from a source checkout or an install.

    :return: the models folder.
    :raises FileNotFoundError: if no folder holds the scene.
    """
    return share_file('models', SCENE_FILE).parent


def focal_length_px(image_width_px: int, horizontal_fov_deg: float) -> float:
    """
    Return the focal length in pixels of a pinhole camera with the given horizontal FOV.

    :param image_width_px: image width in pixels.
    :param horizontal_fov_deg: full horizontal field of view in degrees.
    :return: fx (= fy, square pixels) in pixels.
    """
    return (image_width_px / 2.0) / math.tan(math.radians(horizontal_fov_deg) / 2.0)


def _mujoco_to_xyzw(quaternion_wxyz) -> tuple[float, float, float, float]:
    w, x, y, z = (float(value) for value in quaternion_wxyz)
    return x, y, z, w


class _RobotParts:
    """The model indices of one robot's joints, motors, cameras and root body."""

    def __init__(self, model: mujoco.MjModel, prefix: str):
        self.camera_id = model.camera(prefix + CAMERA_NAME).id
        self.depth_camera_id = model.camera(prefix + DEPTH_CAMERA_NAME).id
        self.left_actuator = model.actuator(prefix + LEFT_MOTOR).id
        self.right_actuator = model.actuator(prefix + RIGHT_MOTOR).id
        free_joint = model.joint(prefix + ROBOT_FREE_JOINT)
        self.free_joint_qpos = free_joint.qposadr[0]
        self.free_joint_qvel = free_joint.dofadr[0]
        left_wheel = model.joint(prefix + LEFT_WHEEL_JOINT)
        right_wheel = model.joint(prefix + RIGHT_WHEEL_JOINT)
        self.wheel_qpos = (left_wheel.qposadr[0], right_wheel.qposadr[0])
        self.wheel_qvel = (left_wheel.dofadr[0], right_wheel.dofadr[0])
        self.body_id = model.body(prefix + ROBOT_BODY).id


class FollowbotWorld:
    """
    TurtleBot 2s with a Kinect-style camera on a course, in MuJoCo: one, or several that collide.

    Drive a robot with :meth:`set_twist` or :meth:`set_wheel_speeds`, advance the world with
    :meth:`step`, read the cameras with :meth:`render_camera` and :meth:`render_depth`, the
    wheel encoders with :meth:`wheel_angles`, and the true pose with :meth:`robot_pose`. Each
    takes the robot's index in :attr:`robot_names` (0, the first, by default).
    """

    def __init__(self, course: Course, image_width_px: int = DEFAULT_IMAGE_WIDTH_PX,
                 image_height_px: int = DEFAULT_IMAGE_HEIGHT_PX,
                 horizontal_fov_deg: float = DEFAULT_HORIZONTAL_FOV_DEG,
                 camera_pitch_deg: float = DEFAULT_CAMERA_PITCH_DEG,
                 texture_size_px: int = 2048, limits: DiffDriveLimits = DiffDriveLimits(),
                 models_dir: Path | None = None, camera_noise_stddev: float = 0.0,
                 noise_seed: int = 0, min_depth_m: float = DEFAULT_MIN_DEPTH_M,
                 max_depth_m: float = DEFAULT_MAX_DEPTH_M,
                 robot_names: tuple[str, ...] = (SINGLE_ROBOT,),
                 robot_spacing_m: float = DEFAULT_ROBOT_SPACING_M,
                 realism: Realism | None = None, start_lateral_offset_m: float = 0.0,
                 start_heading_offset_deg: float = 0.0):
        """
        Load the scene, paint the course on the floor and put the robot at the course start.

        The floor plane takes the course's ``floor_size_m`` and the overview camera rises with
        it, so the overview always shows the whole floor.

        :param course: the course whose line is painted and where the robot starts.
        :param image_width_px: camera image width in pixels (RGB and depth).
        :param image_height_px: camera image height in pixels (RGB and depth).
        :param horizontal_fov_deg: camera horizontal field of view in degrees.
        :param camera_pitch_deg: downward tilt of the Kinect from level, in degrees.
        :param texture_size_px: side of the square floor texture in pixels.
        :param limits: geometry and speed limits of the base.
        :param models_dir: folder with ``scene.xml``; found automatically when None.
        :param camera_noise_stddev: standard deviation of the Gaussian noise added to every RGB
            frame, in 8-bit intensity levels; 0 leaves frames untouched.
        :param noise_seed: seed of the noise generator (PCG64), a non-negative integer.
        :param min_depth_m: nearer depths read as NaN; 0 (the default) keeps all, a Kinect's
            blind zone is ``KINECT_MIN_DEPTH_M`` (0.45 m).
        :param max_depth_m: farther depths read as NaN (the Kinect's ~8 m; ``math.inf`` keeps
            all up to the renderer's far clipping plane).
        :param robot_names: the robots, from :func:`followbot_sim.robots.robot_names`: one
            unnamed robot (plain model names) by default; named robots' model elements are
            prefixed ``<name>/``. The first starts at the course start, each next one
            ``robot_spacing_m`` behind the one before it along the line.
        :param robot_spacing_m: centre-to-centre distance between robots along the line.
        :param realism: a world and camera drawn from a realism preset
            (:func:`followbot_sim.realism.realise`); None or ``clean`` keeps the ideal scene.
        :param start_lateral_offset_m: the robots start this far to the left of the line
            (negative: to the right) at their starts, as a robot put down by hand would.
        :param start_heading_offset_deg: and turned this far to the left of the line's
            direction (negative: to the right).
        :raises ValueError: for a non-positive image size, a field of view outside (0, 180),
            a pitch outside [-90, 90], a negative or non-finite noise level, a negative seed,
            a depth range that is not 0 <= min < max, robots that do not fit the course or a
            start offset that is not finite.
        """
        if image_width_px <= 0 or image_height_px <= 0:
            raise ValueError(
                f'Image size must be positive, got {image_width_px}x{image_height_px}.')
        if not 0.0 < horizontal_fov_deg < 180.0:
            raise ValueError(
                f'horizontal_fov_deg must be in (0, 180), got {horizontal_fov_deg}.')
        if not -90.0 <= camera_pitch_deg <= 90.0:
            raise ValueError(f'camera_pitch_deg must be in [-90, 90], got {camera_pitch_deg}.')
        if not (math.isfinite(camera_noise_stddev) and camera_noise_stddev >= 0.0):
            raise ValueError('camera_noise_stddev must be a finite number >= 0 (intensity '
                             f'levels), got {camera_noise_stddev}.')
        if int(noise_seed) != noise_seed or noise_seed < 0:
            raise ValueError(f'noise_seed must be a non-negative integer, got {noise_seed!r}.')
        if not 0.0 <= min_depth_m < max_depth_m:
            raise ValueError('The depth range must satisfy 0 <= min_depth_m < max_depth_m, got '
                             f'min_depth_m={min_depth_m}, max_depth_m={max_depth_m}.')
        if not (math.isfinite(start_lateral_offset_m)
                and math.isfinite(start_heading_offset_deg)):
            raise ValueError('The start offset must be finite, got '
                             f'start_lateral_offset_m={start_lateral_offset_m}, '
                             f'start_heading_offset_deg={start_heading_offset_deg}.')
        self._start_offset = (float(start_lateral_offset_m),
                              math.radians(start_heading_offset_deg))
        if not robot_names or (SINGLE_ROBOT in robot_names and len(robot_names) > 1):
            raise ValueError(f'robot_names must be one unnamed robot or named robots, got '
                             f'{list(robot_names)}.')
        self._robot_names = tuple(robot_names)
        self._start_arcs_m = start_arc_lengths_m(len(robot_names), robot_spacing_m)
        if len(robot_names) * robot_spacing_m > course.length_m:
            raise ValueError(f'{len(robot_names)} robots {robot_spacing_m} m apart do not fit '
                             f'on the {course.length_m:.1f} m course {course.name}.')
        self._course = course
        self._realism = None if realism is None or realism.is_clean else realism
        self._limits = limits
        self._image_size_px = (image_width_px, image_height_px)
        self._camera_pitch_deg = float(camera_pitch_deg)
        self._fx_px = focal_length_px(image_width_px, horizontal_fov_deg)
        models_dir = Path(models_dir) if models_dir is not None else models_directory()
        spec = mujoco.MjSpec.from_file(str(models_dir / SCENE_FILE))
        if self._robot_names != (SINGLE_ROBOT,):
            self._replace_robot_with_named_ones(spec, models_dir)
        spec.texture(COURSE_TEXTURE_NAME).width = texture_size_px
        spec.texture(COURSE_TEXTURE_NAME).height = texture_size_px
        # The off-screen buffer must hold the camera image; keep room for the overview too.
        spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, image_width_px)
        spec.visual.global_.offheight = max(spec.visual.global_.offheight, image_height_px)
        self._fit_floor_to_course(spec)
        if self._realism is not None:
            appearance.furnish(spec, self._realism, course, FLOOR_GEOM)
        camera_fovy_deg = math.degrees(2.0 * math.atan((image_height_px / 2.0) / self._fx_px))
        for prefix in self._robot_prefixes():
            self._tilt_kinect(spec, camera_pitch_deg, prefix)
            for camera_name in (CAMERA_NAME, DEPTH_CAMERA_NAME):
                spec.camera(prefix + camera_name).fovy = camera_fovy_deg
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._paint_course(texture_size_px)

        self._robots = [_RobotParts(self.model, prefix) for prefix in self._robot_prefixes()]
        self._all_wheel_qpos = [address for robot in self._robots
                                for address in robot.wheel_qpos]
        self._renderer = None
        self._overview_renderer = None
        self._viewer = None
        self._last_viewer_sync_s = -math.inf
        self._camera_image = np.empty((image_height_px, image_width_px, 3), np.uint8)
        self._depth_image = np.empty((image_height_px, image_width_px), np.float32)
        # The renderer's far clipping plane: MuJoCo scales the model's zfar by its extent.
        far_clip_m = float(self.model.vis.map.zfar * self.model.stat.extent)
        self._min_depth_m = float(min_depth_m)
        self._max_depth_m = min(float(max_depth_m), FAR_PLANE_FRACTION * far_clip_m)
        self._noise_stddev = float(camera_noise_stddev)
        self._noise_seed = int(noise_seed)
        self._noise_bank = None
        self._painted_points = None
        self._camera_model = None if self._realism is None else CameraModel(
            self._realism, self.camera_intrinsics(), self._image_size_px)
        self.reset()

    def _robot_prefixes(self) -> list[str]:
        return [robot_prefix(name) for name in self._robot_names]

    def _replace_robot_with_named_ones(self, spec: mujoco.MjSpec, models_dir: Path) -> None:
        """
        Take out the scene's unnamed robot and put in a copy per name, its elements prefixed.

        :param spec: the scene's spec, before compiling.
        :param models_dir: folder with the robot's own model file.
        """
        spec.delete(spec.body(ROBOT_BODY))
        for actuator in list(spec.actuators):
            spec.delete(actuator)
        for prefix in self._robot_prefixes():
            robot_spec = mujoco.MjSpec.from_file(str(models_dir / ROBOT_FILE))
            # Attached at the origin: _place_robot sets each robot's pose on its free joint.
            spec.worldbody.add_frame().attach_body(robot_spec.body(ROBOT_BODY), prefix, '')

    def _fit_floor_to_course(self, spec: mujoco.MjSpec) -> None:
        """
        Size the floor plane to the course and raise the overview camera in proportion.

        :param spec: the scene's spec, before compiling.
        """
        floor = spec.geom(FLOOR_GEOM)
        scene_floor_size_m = 2.0 * float(floor.size[0])
        floor_size_m = float(self._course.floor_size_m)
        floor.size = [floor_size_m / 2.0, floor_size_m / 2.0, float(floor.size[2])]
        overview = spec.camera(OVERVIEW_CAMERA_NAME)
        # Same field of view, height scaled with the floor: the same margin around it.
        overview.pos = [float(overview.pos[0]), float(overview.pos[1]),
                        float(overview.pos[2]) * floor_size_m / scene_floor_size_m]

    @staticmethod
    def _tilt_kinect(spec: mujoco.MjSpec, camera_pitch_deg: float, prefix: str) -> None:
        """
        Pitch the whole Kinect (``camera_link`` and the cameras on it) of one robot down.

        :param spec: the scene's spec, before compiling.
        :param camera_pitch_deg: downward tilt in degrees.
        :param prefix: the robot's name prefix.
        """
        # Pitch down = a positive rotation about the body's y axis (left), applied to the
        # level mounting of the model.
        half_pitch_rad = math.radians(camera_pitch_deg) / 2.0
        pitch_quat = np.array([math.cos(half_pitch_rad), 0.0, math.sin(half_pitch_rad), 0.0])
        camera_link = spec.body(prefix + CAMERA_LINK_BODY)
        tilted_quat = np.empty(4)
        mujoco.mju_mulQuat(tilted_quat, np.asarray(camera_link.quat, dtype=float), pitch_quat)
        camera_link.quat = tilted_quat

    def _paint_course(self, texture_size_px: int) -> None:
        texture_id = self.model.texture(COURSE_TEXTURE_NAME).id
        start = self.model.tex_adr[texture_id]
        texture = self._course.draw_texture(texture_size_px)
        if self._realism is not None:
            texture = appearance.paint_floor(texture, self._realism, self._course)
        self.model.tex_data[start:start + texture.size] = texture.reshape(-1)

    @property
    def course(self) -> Course:
        """Return the course the robot drives on."""
        return self._course

    @property
    def robot_names(self) -> tuple[str, ...]:
        """Return the robots' names, in index order (``('',)`` for one unnamed robot)."""
        return self._robot_names

    @property
    def limits(self) -> DiffDriveLimits:
        """Return the geometry and speed limits of the base."""
        return self._limits

    @property
    def time_s(self) -> float:
        """Return the simulated time in seconds since the last reset."""
        return float(self.data.time)

    @property
    def timestep_s(self) -> float:
        """Return the physics time step in seconds."""
        return float(self.model.opt.timestep)

    @property
    def image_size_px(self) -> tuple[int, int]:
        """Return the camera image (width, height) in pixels."""
        return self._image_size_px

    @property
    def camera_pitch_deg(self) -> float:
        """Return the downward tilt of the Kinect from level in degrees."""
        return self._camera_pitch_deg

    @property
    def camera_noise_stddev(self) -> float:
        """Return the standard deviation of the RGB noise in 8-bit intensity levels."""
        return self._noise_stddev

    @property
    def depth_range_m(self) -> tuple[float, float]:
        """Return the (nearest, farthest) depth in metres that reads as a number, not NaN."""
        return self._min_depth_m, self._max_depth_m

    def camera_intrinsics(self) -> tuple[float, float, float, float]:
        """
        Return the pinhole intrinsics of the rendered camera images, RGB and depth alike.

        MuJoCo's camera is an ideal pinhole with square pixels; the principal point is the image
        centre in the ROS convention where pixel centres sit at integer coordinates.

        :return: (fx, fy, cx, cy) in pixels.
        """
        width_px, height_px = self._image_size_px
        return self._fx_px, self._fx_px, (width_px - 1) / 2.0, (height_px - 1) / 2.0

    def camera_view(self, robot: int = 0) -> PinholeView:
        """
        Return a robot's RGB camera pose and intrinsics as the next render will use them.

        :param robot: the robot's index.
        :return: the pinhole view (pose from the current state, optical-frame axes).
        """
        width_px, height_px = self._image_size_px
        fx_px, fy_px, cx_px, cy_px = self.camera_intrinsics()
        camera_id = self._robots[robot].camera_id
        mujoco_axes = self.data.cam_xmat[camera_id].reshape(3, 3)
        return PinholeView(self.data.cam_xpos[camera_id].copy(),
                           mujoco_axes @ MUJOCO_CAMERA_TO_OPTICAL_AXES, fx_px, fy_px, cx_px,
                           cy_px, width_px, height_px)

    def line_truth(self, row_step_px: int = 1, distort=None, robot: int = 0) -> LineTruth:
        """
        Return where the course's centre line is drawn in a robot's RGB image right now.

        :param row_step_px: report the paint's stretches at every this many rows, from row 0.
        :param distort: the lens distortion of normalised coordinates the camera image has
            (see :mod:`followbot_sim.line_truth`), None for the pinhole MuJoCo renders.
        :param robot: the robot's index.
        :return: the visible pieces of the centre line and the paint's stretches along the
            sampled rows.
        """
        if self._painted_points is None:
            points_xy = self._course.centre_line_xy
            steps_m = np.hypot(*np.diff(points_xy, axis=0).T)
            arc_m = np.concatenate([[0.0], np.cumsum(steps_m)])
            self._painted_points = self._course.dash_signed_distance_m(arc_m) >= 0.0
        view = self.camera_view(robot)
        if self._camera_model is not None and distort is None:
            # The camera's output, not MuJoCo's pinhole: camera_info's K and D.
            fx_px, fy_px, cx_px, cy_px = self._camera_model.intrinsics
            view = PinholeView(view.position_m, view.rotation, fx_px, fy_px, cx_px, cy_px,
                               view.width_px, view.height_px)
            distort = self._camera_model.distort
        return line_truth(self._course.centre_line_xy, self._painted_points,
                          self._course.line_width_m, view,
                          sampled_rows(self._image_size_px[1], row_step_px), distort)

    @property
    def realism(self) -> Realism | None:
        """Return the realistic world and camera in use, None for the clean scene."""
        return self._realism

    def published_camera_model(self) -> tuple:
        """
        Return what camera_info must say of the RGB image this world delivers.

        :return: ((fx, fy, cx, cy) in pixels, plumb_bob D as a list of five).
        """
        if self._camera_model is None:
            return self.camera_intrinsics(), [0.0] * 5
        return self._camera_model.intrinsics, self._camera_model.distortion_coefficients

    def sensor_frames(self, robot: int = 0) -> list[FrameTransform]:
        """
        Return a robot's fixed frames, read from the compiled model.

        The chain is base_footprint -> base_link -> camera_link (with the Kinect's pitch) ->
        camera_rgb_frame -> camera_rgb_optical_frame, and camera_link -> camera_depth_frame ->
        camera_depth_optical_frame. With ``world -> base_footprint`` from :meth:`robot_pose`
        and :meth:`camera_intrinsics` it maps floor points to where MuJoCo draws them. A named
        robot's frames carry its prefix (``r1/base_link``), as its bodies do.

        :param robot: the robot's index.
        :return: the transforms, parents before children.
        """
        prefix = robot_prefix(self._robot_names[robot])
        parts = self._robots[robot]
        transforms = [self._body_transform(prefix + BASE_LINK_BODY),
                      self._body_transform(prefix + CAMERA_LINK_BODY)]
        for camera_id, body_frame, optical_frame in (
                (parts.camera_id, prefix + CAMERA_RGB_FRAME, prefix + CAMERA_RGB_OPTICAL_FRAME),
                (parts.depth_camera_id, prefix + CAMERA_DEPTH_FRAME,
                 prefix + CAMERA_DEPTH_OPTICAL_FRAME)):
            parent = self.model.body(self.model.cam_bodyid[camera_id]).name
            camera_axes = np.empty(9)
            mujoco.mju_quat2Mat(camera_axes, self.model.cam_quat[camera_id])
            body_axes = camera_axes.reshape(3, 3) @ MUJOCO_CAMERA_TO_BODY_AXES
            transforms.append(FrameTransform(parent, body_frame,
                                             tuple(self.model.cam_pos[camera_id]),
                                             quaternion_from_matrix(body_axes)))
            transforms.append(FrameTransform(body_frame, optical_frame,
                                             rotation_xyzw=optical_rotation_xyzw()))
        return transforms

    def _body_transform(self, body_name: str) -> FrameTransform:
        """
        Return the fixed pose of a body in its parent body, as a transform between their frames.

        :param body_name: a body whose frame has the body's name.
        :return: the transform from the parent body's frame to the body's.
        """
        body = self.model.body(body_name)
        parent = self.model.body(body.parentid[0]).name
        return FrameTransform(parent, body_name, tuple(body.pos), _mujoco_to_xyzw(body.quat))

    def reset(self) -> None:
        """Put the robots at rest at their starts and set the time to zero."""
        mujoco.mj_resetData(self.model, self.data)
        self._place_robots()
        self._draw_noise_bank()

    def reset_robot(self, pose: tuple[float, float, float] | None = None) -> None:
        """
        Put the robots at rest at their starts, the first at a pose if given, keeping the time.

        The starts are the course's, moved by the world's start offset.

        The simulator's clock never goes backwards. The wheel angles are kept, as a real
        robot's encoders keep their counts when it is carried back: wheel odometry sees no
        motion (restart it if it should read the start).

        :param pose: (x m, y m, yaw rad) of the first robot's ``base_footprint`` on the floor;
            None for the course's start pose.
        """
        time_s = self.data.time
        wheel_angles_rad = self.data.qpos[self._all_wheel_qpos].copy()
        mujoco.mj_resetData(self.model, self.data)
        self.data.time = time_s
        self.data.qpos[self._all_wheel_qpos] = wheel_angles_rad
        self._place_robots(pose)

    def _place_robots(self, first_pose=None) -> None:
        lateral_m, heading_rad = self._start_offset
        for parts, start_arc_m in zip(self._robots, self._start_arcs_m):
            x_m, y_m, yaw_rad = self._course.point_at(start_arc_m, lateral_m)
            yaw_rad += heading_rad
            if first_pose is not None and parts is self._robots[0]:
                x_m, y_m, yaw_rad = first_pose
            qpos = parts.free_joint_qpos
            self.data.qpos[qpos:qpos + 3] = (x_m, y_m, 0.0)
            self.data.qpos[qpos + 3:qpos + 7] = (math.cos(yaw_rad / 2.0), 0.0, 0.0,
                                                 math.sin(yaw_rad / 2.0))
        mujoco.mj_forward(self.model, self.data)

    def _draw_noise_bank(self) -> None:
        """Draw the noise bank from the seed, the first time noise is needed."""
        if self._noise_stddev == 0.0 or self._noise_bank is not None:
            return
        generator = np.random.Generator(np.random.PCG64(self._noise_seed))
        width_px, height_px = self._image_size_px
        bank_size = NOISE_BANK_FRAMES * height_px * width_px * 3
        levels = np.rint(generator.standard_normal(bank_size, dtype=np.float32)
                         * np.float32(self._noise_stddev))
        np.clip(levels, -MAX_INTENSITY, MAX_INTENSITY, out=levels)
        raise_levels = np.maximum(levels, 0.0).astype(np.uint8)
        lower_levels = np.maximum(-levels, 0.0).astype(np.uint8)
        # (raise, headroom below saturation, lower): see _add_camera_noise.
        self._noise_bank = (raise_levels, MAX_INTENSITY - raise_levels, lower_levels)

    def _add_camera_noise(self, image: np.ndarray, robot: int) -> None:
        """
        Add the noise of this instant to an RGB image in place, saturating at 0 and 255.

        Reads the bank from an offset drawn from the seed and the physics step count, so a
        frame's noise depends only on when it is taken, not on how many frames were rendered
        before: a simulator that skips frames nobody watches still repeats its runs exactly.
        Each value either raises or lowers its pixel, so min(x, 255 - raise) + raise then
        max(x, lower) - lower is clip(x + noise, 0, 255) in four uint8 operations without
        overflow.

        :param image: a C-contiguous uint8 image.
        :param robot: the index of the robot whose camera took it: each robot's noise differs.
        """
        raise_levels, headroom_levels, lower_levels = self._noise_bank
        size = image.size
        step_index = round(self.data.time / self.model.opt.timestep)
        # The first robot keeps the single robot's sequence; the others draw their own.
        entropy = [self._noise_seed, step_index] + ([robot] if robot else [])
        generator = np.random.Generator(np.random.PCG64(entropy))
        offset = int(generator.integers(0, len(raise_levels) - size, endpoint=True))
        window = slice(offset, offset + size)
        flat = image.reshape(-1)
        np.minimum(flat, headroom_levels[window], out=flat)
        flat += raise_levels[window]
        np.maximum(flat, lower_levels[window], out=flat)
        flat -= lower_levels[window]

    def set_wheel_speeds(self, left_radps: float, right_radps: float, robot: int = 0) -> None:
        """
        Set the wheel velocity targets of a robot's motors.

        :param left_radps: left wheel speed in rad/s, positive rolling forward.
        :param right_radps: right wheel speed in rad/s, positive rolling forward.
        :param robot: the robot's index.
        """
        parts = self._robots[robot]
        self.data.ctrl[parts.left_actuator] = left_radps
        self.data.ctrl[parts.right_actuator] = right_radps

    def set_twist(self, linear_mps: float, angular_radps: float, robot: int = 0) -> None:
        """
        Drive a robot's base with a body twist, limited like a Kobuki.

        :param linear_mps: forward speed in m/s.
        :param angular_radps: yaw rate in rad/s, positive to the left.
        :param robot: the robot's index.
        """
        self.set_wheel_speeds(*wheel_speeds_radps(linear_mps, angular_radps, self._limits),
                              robot=robot)

    def step(self, duration_s: float) -> None:
        """
        Advance the physics by ``duration_s`` (rounded to whole time steps, at least one).

        :param duration_s: simulated seconds to advance.
        """
        steps = max(1, round(duration_s / self.model.opt.timestep))
        mujoco.mj_step(self.model, self.data, nstep=steps)

    def robot_pose(self, robot: int = 0) -> tuple[float, float, float]:
        """
        Return the true planar pose of a robot's ``base_footprint``.

        :param robot: the robot's index.
        :return: (x m, y m, yaw rad) in the world frame.
        """
        qpos = self._robots[robot].free_joint_qpos
        x_m, y_m = self.data.qpos[qpos:qpos + 2]
        yaw_rad = yaw_from_quaternion(_mujoco_to_xyzw(self.data.qpos[qpos + 3:qpos + 7]))
        return float(x_m), float(y_m), yaw_rad

    def robot_twist(self, robot: int = 0) -> tuple[float, float]:
        """
        Return the true forward speed and yaw rate of a robot's base.

        :param robot: the robot's index.
        :return: (linear m/s along the robot's heading, angular rad/s).
        """
        qvel = self._robots[robot].free_joint_qvel
        vx, vy = self.data.qvel[qvel:qvel + 2]
        _, _, yaw_rad = self.robot_pose(robot)
        forward_mps = vx * math.cos(yaw_rad) + vy * math.sin(yaw_rad)
        return float(forward_mps), float(self.data.qvel[qvel + 5])

    def wheel_angles(self, robot: int = 0) -> tuple[float, float]:
        """
        Return a robot's wheel joint angles, as encoders would count them.

        :param robot: the robot's index.
        :return: (left, right) in radians, increasing when rolling forward, zero at
            :meth:`reset`.
        """
        left, right = self._robots[robot].wheel_qpos
        return float(self.data.qpos[left]), float(self.data.qpos[right])

    def wheel_speeds(self, robot: int = 0) -> tuple[float, float]:
        """
        Return a robot's measured wheel speeds.

        :param robot: the robot's index.
        :return: (left, right) in rad/s.
        """
        left, right = self._robots[robot].wheel_qvel
        return float(self.data.qvel[left]), float(self.data.qvel[right])

    def _make_renderer(self, height_px: int, width_px: int) -> mujoco.Renderer:
        try:
            return mujoco.Renderer(self.model, height_px, width_px)
        except Exception as error:  # GL back ends fail with many error types.
            backend = os.environ.get('MUJOCO_GL', '(unset)')
            raise RenderingUnavailableError(
                f'MuJoCo cannot render off-screen with MUJOCO_GL={backend} '
                f"({str(error).rstrip('.')}). Headless "
                'machines need Mesa EGL (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri); '
                'MUJOCO_GL=osmesa or glfw (with a display) are alternatives.') from error

    def _camera_renderer(self) -> mujoco.Renderer:
        if self._renderer is None:
            width_px, height_px = self._image_size_px
            self._renderer = self._make_renderer(height_px, width_px)
            # Nothing in the world reflects (every material has reflectance 0), yet the
            # reflection pass costs ~1 ms of a ~5 ms frame on the CPU: skip it.
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        return self._renderer

    def render_camera(self, robot: int = 0) -> np.ndarray:
        """
        Render a robot's RGB camera, with its noise if any.

        The returned array is reused by the next call (of any robot): copy it to keep it.

        :param robot: the robot's index.
        :return: an RGB uint8 array of shape (height, width, 3).
        """
        renderer = self._camera_renderer()
        renderer.disable_depth_rendering()
        renderer.update_scene(self.data, camera=self._robots[robot].camera_id)
        image = renderer.render(out=self._camera_image)
        if self._camera_model is not None:
            step_index = round(self.data.time / self.model.opt.timestep)
            image = self._camera_model.process(image, step_index, *self.robot_twist(robot))
        if self._noise_bank is not None:
            self._add_camera_noise(image, robot)
        return image

    def render_depth(self, robot: int = 0) -> np.ndarray:
        """
        Render a robot's Kinect depth camera as metric depth, like a ROS ``32FC1`` depth image.

        Each pixel holds z in ``camera_depth_optical_frame`` (the distance along the optical
        axis, not along the ray) in metres. MuJoCo's Renderer in depth mode already returns
        this linear depth (it undoes the projection of the depth buffer). NaN marks no data:
        pixels that hit nothing (sky, and beyond the floor's edge; they read as the far
        clipping plane, ``zfar * extent`` of the model, ~53 m) and depths outside
        :attr:`depth_range_m` (``min_depth_m`` and ``max_depth_m`` of the constructor: 0-8 m
        by default; a real Kinect's is ~0.45-8 m). The renderer's near clipping plane
        (``znear * extent``, ~1 cm) clips nothing the camera can see. The depth camera is
        another viewpoint than the RGB camera, so rendering both costs two passes.

        The returned array is reused by the next call (of any robot): copy it to keep it.

        :param robot: the robot's index.
        :return: a float32 array of shape (height, width).
        """
        renderer = self._camera_renderer()
        renderer.enable_depth_rendering()
        renderer.update_scene(self.data, camera=self._robots[robot].depth_camera_id)
        depth_m = renderer.render(out=self._depth_image)
        renderer.disable_depth_rendering()
        np.copyto(depth_m, np.nan,
                  where=(depth_m < self._min_depth_m) | (depth_m > self._max_depth_m))
        return depth_m

    def render_overview(self, size_px: int = 800) -> np.ndarray:
        """
        Render the whole course from above, north up, with the robot on it.

        :param size_px: side of the square image in pixels (at most the off-screen buffer).
        :return: an RGB uint8 array of shape (size_px, size_px, 3).
        """
        if self._overview_renderer is None or self._overview_renderer.width != size_px:
            if self._overview_renderer is not None:
                self._overview_renderer.close()
            self._overview_renderer = self._make_renderer(size_px, size_px)
        self._overview_renderer.update_scene(self.data, camera=OVERVIEW_CAMERA_NAME)
        return self._overview_renderer.render()

    def overview_pixels(self, points_xy: np.ndarray, size_px: int) -> np.ndarray:
        """
        Project floor points into the overview image, for drawing on it.

        :param points_xy: (N, 2) world coordinates in metres on the floor.
        :param size_px: side of the square overview image in pixels.
        :return: (N, 2) pixel coordinates (column, row), pixel centres at integers.
        """
        camera = self.model.camera(OVERVIEW_CAMERA_NAME)
        height_m = float(camera.pos[2])
        focal_px = (size_px / 2.0) / math.tan(math.radians(float(camera.fovy[0])) / 2.0)
        centre_px = (size_px - 1) / 2.0
        points_xy = np.asarray(points_xy, dtype=float)
        columns = centre_px + focal_px * (points_xy[:, 0] - camera.pos[0]) / height_m
        rows = centre_px - focal_px * (points_xy[:, 1] - camera.pos[1]) / height_m
        return np.stack([columns, rows], axis=1)

    def open_viewer(self) -> None:
        """
        Open MuJoCo's interactive viewer on this world; it shows the state at each sync.

        The viewer runs in its own thread with its own (GLFW) OpenGL context, beside the
        off-screen renderer. Opening it again while it is open does nothing.

        :raises ViewerUnavailableError: if no display is set (``DISPLAY`` or
            ``WAYLAND_DISPLAY``) or the viewer fails to start.
        """
        if self._viewer is not None and self._viewer.is_running():
            return
        if not (os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')):
            raise ViewerUnavailableError(
                "MuJoCo's viewer needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is "
                'set (a headless machine can run one with Xvfb).')
        try:
            import mujoco.viewer
            self._viewer = mujoco.viewer.launch_passive(self.model, self.data)
        except Exception as error:  # GLFW and the viewer fail with many error types.
            raise ViewerUnavailableError(
                f"MuJoCo's viewer failed to open ({str(error).rstrip('.')}).") from error
        with self._viewer.lock():
            # Follow the robot from behind and above; the user can still orbit and zoom.
            camera = self._viewer.cam
            camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            camera.trackbodyid = self._robots[0].body_id
            camera.distance = VIEWER_DISTANCE_M
            camera.elevation = VIEWER_ELEVATION_DEG
            # The azimuth is the direction the camera looks: along the robot's heading.
            camera.azimuth = math.degrees(self.robot_pose()[2])
        self._last_viewer_sync_s = -math.inf

    def sync_viewer(self) -> bool:
        """
        Show the current state in the viewer, at most ~60 times per wall-clock second.

        Cheap when the viewer is closed: call it after every step.

        :return: whether the viewer is open (False once its window was closed).
        """
        if self._viewer is None:
            return False
        if not self._viewer.is_running():
            self._viewer.close()
            self._viewer = None
            return False
        now_s = time.monotonic()
        if now_s - self._last_viewer_sync_s >= VIEWER_SYNC_PERIOD_S:
            self._viewer.sync()
            self._last_viewer_sync_s = now_s
        return True

    def close(self) -> None:
        """Close the viewer and release the renderers' OpenGL resources (on the render thread)."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        for renderer in (self._renderer, self._overview_renderer):
            if renderer is not None:
                renderer.close()
        self._renderer = None
        self._overview_renderer = None
