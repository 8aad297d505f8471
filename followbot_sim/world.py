"""
The MuJoCo world of the follow-bot: a TurtleBot 2 on a course, stepped and rendered off-screen.

No ROS import: the simulator node wires this to topics, and tests and benchmarks use it directly.
Rendering needs an OpenGL context; headless machines use ``MUJOCO_GL=egl`` (Mesa on the CPU).
The context belongs to the thread that first renders, so render from one thread only.
"""

import math
import os
from pathlib import Path
import sys

from followbot_sim.course import Course
from followbot_sim.diff_drive import DiffDriveLimits, wheel_speeds_radps
import mujoco
import numpy as np

PACKAGE_NAME = 'followbot'
SCENE_FILE = 'scene.xml'
ROBOT_BODY = 'base_footprint'
ROBOT_FREE_JOINT = 'base_free'
CAMERA_NAME = 'camera_rgb'
OVERVIEW_CAMERA_NAME = 'overview'
COURSE_TEXTURE_NAME = 'course'
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


class RenderingUnavailableError(RuntimeError):
    """MuJoCo cannot render off-screen on this machine; the message says what to check."""


def models_directory() -> Path:
    """
    Find the folder holding the MJCF models, from a source checkout or an install.

    A source checkout (or an editable install) has ``models/`` beside the Python packages;
    an installed package (colcon, or pip into a prefix) has it in ``share/followbot/models``,
    found through the ament index when the workspace is sourced, else under ``sys.prefix``.

    :return: the models folder.
    :raises FileNotFoundError: if no folder holds the scene.
    """
    candidates = [Path(__file__).resolve().parent.parent / 'models']
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE_NAME)) / 'models')
    except (ImportError, LookupError, OSError):
        pass  # No ament index holds this package: not a sourced ROS install.
    candidates.append(Path(sys.prefix) / 'share' / PACKAGE_NAME / 'models')
    for candidate in candidates:
        if (candidate / SCENE_FILE).is_file():
            return candidate
    searched = ', '.join(str(path) for path in candidates)
    raise FileNotFoundError(f'No {SCENE_FILE} found for {PACKAGE_NAME}; looked in: {searched}.')


def focal_length_px(image_width_px: int, horizontal_fov_deg: float) -> float:
    """
    Return the focal length in pixels of a pinhole camera with the given horizontal FOV.

    :param image_width_px: image width in pixels.
    :param horizontal_fov_deg: full horizontal field of view in degrees.
    :return: fx (= fy, square pixels) in pixels.
    """
    return (image_width_px / 2.0) / math.tan(math.radians(horizontal_fov_deg) / 2.0)


class FollowbotWorld:
    """
    A TurtleBot 2 with a Kinect-style camera on a course, in MuJoCo.

    Drive it with :meth:`set_twist` or :meth:`set_wheel_speeds`, advance it with :meth:`step`,
    read the camera with :meth:`render_camera` and the true pose with :meth:`robot_pose`.
    """

    def __init__(self, course: Course, image_width_px: int = DEFAULT_IMAGE_WIDTH_PX,
                 image_height_px: int = DEFAULT_IMAGE_HEIGHT_PX,
                 horizontal_fov_deg: float = DEFAULT_HORIZONTAL_FOV_DEG,
                 camera_pitch_deg: float = DEFAULT_CAMERA_PITCH_DEG,
                 texture_size_px: int = 2048, limits: DiffDriveLimits = DiffDriveLimits(),
                 models_dir: Path | None = None):
        """
        Load the scene, paint the course on the floor and put the robot at the course start.

        :param course: the course whose line is painted and where the robot starts.
        :param image_width_px: camera image width in pixels.
        :param image_height_px: camera image height in pixels.
        :param horizontal_fov_deg: camera horizontal field of view in degrees.
        :param camera_pitch_deg: downward tilt of the camera from level, in degrees.
        :param texture_size_px: side of the square floor texture in pixels.
        :param limits: geometry and speed limits of the base.
        :param models_dir: folder with ``scene.xml``; found automatically when None.
        :raises ValueError: for a non-positive image size, a field of view outside (0, 180) or
            a pitch outside [-90, 90].
        """
        if image_width_px <= 0 or image_height_px <= 0:
            raise ValueError(
                f'Image size must be positive, got {image_width_px}x{image_height_px}.')
        if not 0.0 < horizontal_fov_deg < 180.0:
            raise ValueError(
                f'horizontal_fov_deg must be in (0, 180), got {horizontal_fov_deg}.')
        if not -90.0 <= camera_pitch_deg <= 90.0:
            raise ValueError(f'camera_pitch_deg must be in [-90, 90], got {camera_pitch_deg}.')
        self._course = course
        self._limits = limits
        self._image_size_px = (image_width_px, image_height_px)
        models_dir = Path(models_dir) if models_dir is not None else models_directory()
        spec = mujoco.MjSpec.from_file(str(models_dir / SCENE_FILE))
        spec.texture(COURSE_TEXTURE_NAME).width = texture_size_px
        spec.texture(COURSE_TEXTURE_NAME).height = texture_size_px
        # The off-screen buffer must hold the camera image; keep room for the overview too.
        spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, image_width_px)
        spec.visual.global_.offheight = max(spec.visual.global_.offheight, image_height_px)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._paint_course(texture_size_px)

        self._fx_px = focal_length_px(image_width_px, horizontal_fov_deg)
        camera_id = self.model.camera(CAMERA_NAME).id
        self.model.cam_fovy[camera_id] = math.degrees(
            2.0 * math.atan((image_height_px / 2.0) / self._fx_px))
        self._camera_id = camera_id
        # Pitch down = a positive rotation about the body's y axis (left), applied to the
        # level camera orientation of the model.
        half_pitch_rad = math.radians(camera_pitch_deg) / 2.0
        pitch_quat = np.array([math.cos(half_pitch_rad), 0.0, math.sin(half_pitch_rad), 0.0])
        level_quat = self.model.cam_quat[camera_id].copy()
        mujoco.mju_mulQuat(self.model.cam_quat[camera_id], pitch_quat, level_quat)
        self._left_actuator = self.model.actuator(LEFT_MOTOR).id
        self._right_actuator = self.model.actuator(RIGHT_MOTOR).id
        self._free_joint_qpos = self.model.joint(ROBOT_FREE_JOINT).qposadr[0]
        self._free_joint_qvel = self.model.joint(ROBOT_FREE_JOINT).dofadr[0]
        self._robot_body = self.model.body(ROBOT_BODY).id
        self._renderer = None
        self._overview_renderer = None
        self._camera_image = np.empty((image_height_px, image_width_px, 3), np.uint8)
        self.reset()

    def _paint_course(self, texture_size_px: int) -> None:
        texture_id = self.model.texture(COURSE_TEXTURE_NAME).id
        start = self.model.tex_adr[texture_id]
        texture = self._course.draw_texture(texture_size_px)
        self.model.tex_data[start:start + texture.size] = texture.reshape(-1)

    @property
    def course(self) -> Course:
        """Return the course the robot drives on."""
        return self._course

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

    def camera_intrinsics(self) -> tuple[float, float, float, float]:
        """
        Return the pinhole intrinsics of the rendered camera image.

        MuJoCo's camera is an ideal pinhole with square pixels; the principal point is the image
        centre in the ROS convention where pixel centres sit at integer coordinates.

        :return: (fx, fy, cx, cy) in pixels.
        """
        width_px, height_px = self._image_size_px
        return self._fx_px, self._fx_px, (width_px - 1) / 2.0, (height_px - 1) / 2.0

    def reset(self) -> None:
        """Put the robot at rest at the course start and set the time to zero."""
        mujoco.mj_resetData(self.model, self.data)
        x_m, y_m, yaw_rad = self._course.start_pose()
        qpos = self._free_joint_qpos
        self.data.qpos[qpos:qpos + 3] = (x_m, y_m, 0.0)
        self.data.qpos[qpos + 3:qpos + 7] = (math.cos(yaw_rad / 2.0), 0.0, 0.0,
                                             math.sin(yaw_rad / 2.0))
        mujoco.mj_forward(self.model, self.data)

    def set_wheel_speeds(self, left_radps: float, right_radps: float) -> None:
        """
        Set the wheel velocity targets of the motors.

        :param left_radps: left wheel speed in rad/s, positive rolling forward.
        :param right_radps: right wheel speed in rad/s, positive rolling forward.
        """
        self.data.ctrl[self._left_actuator] = left_radps
        self.data.ctrl[self._right_actuator] = right_radps

    def set_twist(self, linear_mps: float, angular_radps: float) -> None:
        """
        Drive the base with a body twist, limited like a Kobuki.

        :param linear_mps: forward speed in m/s.
        :param angular_radps: yaw rate in rad/s, positive to the left.
        """
        self.set_wheel_speeds(*wheel_speeds_radps(linear_mps, angular_radps, self._limits))

    def step(self, duration_s: float) -> None:
        """
        Advance the physics by ``duration_s`` (rounded to whole time steps, at least one).

        :param duration_s: simulated seconds to advance.
        """
        steps = max(1, round(duration_s / self.model.opt.timestep))
        mujoco.mj_step(self.model, self.data, nstep=steps)

    def robot_pose(self) -> tuple[float, float, float]:
        """
        Return the true planar pose of ``base_footprint``.

        :return: (x m, y m, yaw rad) in the world frame.
        """
        qpos = self._free_joint_qpos
        x_m, y_m = self.data.qpos[qpos:qpos + 2]
        w, qx, qy, qz = self.data.qpos[qpos + 3:qpos + 7]
        yaw_rad = math.atan2(2.0 * (w * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        return float(x_m), float(y_m), yaw_rad

    def robot_twist(self) -> tuple[float, float]:
        """
        Return the true forward speed and yaw rate of the base.

        :return: (linear m/s along the robot's heading, angular rad/s).
        """
        qvel = self._free_joint_qvel
        vx, vy = self.data.qvel[qvel:qvel + 2]
        _, _, yaw_rad = self.robot_pose()
        forward_mps = vx * math.cos(yaw_rad) + vy * math.sin(yaw_rad)
        return float(forward_mps), float(self.data.qvel[qvel + 5])

    def wheel_speeds(self) -> tuple[float, float]:
        """
        Return the measured wheel speeds.

        :return: (left, right) in rad/s.
        """
        left = self.model.joint(LEFT_WHEEL_JOINT).dofadr[0]
        right = self.model.joint(RIGHT_WHEEL_JOINT).dofadr[0]
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

    def render_camera(self) -> np.ndarray:
        """
        Render the robot's RGB camera.

        The returned array is reused by the next call: copy it to keep it.

        :return: an RGB uint8 array of shape (height, width, 3).
        """
        if self._renderer is None:
            width_px, height_px = self._image_size_px
            self._renderer = self._make_renderer(height_px, width_px)
        self._renderer.update_scene(self.data, camera=self._camera_id)
        return self._renderer.render(out=self._camera_image)

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

    def close(self) -> None:
        """Release the renderers' OpenGL resources (on the thread that rendered)."""
        for renderer in (self._renderer, self._overview_renderer):
            if renderer is not None:
                renderer.close()
        self._renderer = None
        self._overview_renderer = None
