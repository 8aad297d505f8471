"""
A real camera's imperfections applied to MuJoCo's ideal render: a pure post-processing stage.

In the order light meets them: exposure (automatic, metered on the scene), white balance (none
or imperfect, so the lights' colour temperature shows as a cast), vignetting, motion blur from
the robot's motion during the exposure, lens distortion (plumb_bob, with the ``D`` and ``K``
that camera_info publishes), shot and read noise per channel, and JPEG artefacts.

Lens distortion: the distorted image is resampled from the pinhole render. Barrel distortion
(k1 < 0) pulls the image's corners from beyond the render's field of view, so the published
focal length is the render's scaled up until every output pixel comes from inside the render:
camera_info's K and D describe the output exactly, and :meth:`CameraModel.distort` gives the
ground truth the same mapping. Every random draw derives from the seed and the physics step of
the frame, so the same run gives the same frames bit for bit. Pure: no ROS, no MuJoCo.
"""

import cv2
from followbot_sim.realism import kelvin_to_rgb, Realism
import numpy as np

# Auto-exposure aims the scene's mean brightness here (8-bit), reacting with this exponent
# (1 = fully, at once) and within these gains.
EXPOSURE_TARGET_LEVEL = 115.0
EXPOSURE_RESPONSE = 0.7
EXPOSURE_GAIN_LIMITS = (0.4, 6.0)
# Metering reads every this-many-th pixel each way.
METERING_STEP_PX = 8
# Motion blur shorter than this (pixels) is left out: it would not show.
MIN_BLUR_PX = 1.5
# Forward motion smears the floor mostly near the image's bottom; this share of the full
# vertical speed in pixels is applied to the whole frame.
FORWARD_BLUR_SHARE = 0.5
NOISE_BANK_FRAMES = 2
SCALE_SEARCH_STEPS = 30
UNDISTORT_NEWTON_STEPS = 20


def plumb_bob_distort(x, y, coefficients):
    """
    Apply the plumb_bob (Brown-Conrady) model to normalised image coordinates.

    :param x: x / z of the points.
    :param y: y / z of the points.
    :param coefficients: (k1, k2, p1, p2, k3).
    :return: the distorted (x, y).
    """
    k1, k2, p1, p2, k3 = coefficients
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y)


def radial_undistortion_factor(distorted_radius, coefficients):
    """
    Invert the radial part of plumb_bob: the factor from distorted to undistorted coordinates.

    Newton's method on ``r (1 + k1 r^2 + k2 r^4 + k3 r^6) = r_d`` from ``r = r_d``; exact for
    this module's cameras, which have no tangential terms.

    :param distorted_radius: distorted radii (normalised coordinates), an array.
    :param coefficients: (k1, k2, p1, p2, k3); p1 and p2 must be 0.
    :return: undistorted / distorted radius, per point (1 at the centre).
    """
    k1, k2, p1, p2, k3 = coefficients
    if p1 or p2:
        raise ValueError('radial_undistortion_factor inverts radial distortion only, got '
                         f'tangential terms p1={p1}, p2={p2}.')
    radius = np.array(distorted_radius, dtype=np.float64)
    for _ in range(UNDISTORT_NEWTON_STEPS):
        r2 = radius * radius
        value = radius * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) - distorted_radius
        slope = 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3))
        radius -= value / slope
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(distorted_radius > 0.0, radius / distorted_radius, 1.0)


class CameraModel:
    """A seeded real camera behind MuJoCo's pinhole render."""

    def __init__(self, realism: Realism, intrinsics: tuple, size_px: tuple):
        """
        Prepare the per-frame stages: gain map, distortion maps, noise bank.

        :param realism: the drawn camera settings.
        :param intrinsics: the render's pinhole (fx, fy, cx, cy) in pixels.
        :param size_px: (width, height) of the image.
        """
        self._realism = realism
        self._render_intrinsics = tuple(float(value) for value in intrinsics)
        self._size_px = (int(size_px[0]), int(size_px[1]))
        width_px, height_px = self._size_px
        k1 = realism.radial_distortion_k1
        self._coefficients = (k1, 0.0, 0.0, 0.0, 0.0)
        self._scale = self._focal_scale() if k1 != 0.0 else 1.0
        self._gain_map = self._make_gain_map()
        self._mean_gain = float(self._gain_map.mean())
        self._maps = self._make_distortion_maps() if k1 != 0.0 else None
        self._noise_bank = None
        if realism.read_noise_levels > 0.0 or realism.shot_noise_gain > 0.0:
            rng = realism.generator('sensor_noise')
            self._noise_bank = rng.standard_normal(
                NOISE_BANK_FRAMES * width_px * height_px * 3, dtype=np.float32)
        # The noise's standard deviation at each 8-bit level: shot noise's variance grows
        # with the signal, read noise's does not.
        self._noise_sigma = np.sqrt(
            realism.shot_noise_gain * np.arange(256.0) + realism.read_noise_levels ** 2
        ).astype(np.float32).reshape(256, 1)
        self._frame = np.empty((height_px, width_px, 3), np.float32)
        self._blurred = np.empty((height_px, width_px, 3), np.uint8)
        self._sums = np.empty((height_px, width_px, 3), np.uint16)
        self._output = np.empty((height_px, width_px, 3), np.uint8)
        self.exposure_gain = 1.0

    @property
    def distortion_coefficients(self) -> list:
        """Return camera_info's D (plumb_bob: k1, k2, p1, p2, k3)."""
        return list(self._coefficients)

    @property
    def intrinsics(self) -> tuple:
        """Return camera_info's (fx, fy, cx, cy): the output image's, not the render's."""
        fx_px, fy_px, cx_px, cy_px = self._render_intrinsics
        return fx_px * self._scale, fy_px * self._scale, cx_px, cy_px

    @property
    def distort(self):
        """Return the lens's mapping of normalised coordinates, or None for a pinhole."""
        if self._maps is None:
            return None
        return lambda x, y: self._distort_unfolded(x, y)

    def _distort_unfolded(self, x, y):
        """Distort, marking as NaN the points beyond the radius where the model folds back."""
        k1 = self._coefficients[0]
        distorted_x, distorted_y = plumb_bob_distort(x, y, self._coefficients)
        if k1 < 0.0:
            beyond = (x * x + y * y) > 1.0 / (-3.0 * k1)
            distorted_x = np.where(beyond, np.nan, distorted_x)
            distorted_y = np.where(beyond, np.nan, distorted_y)
        return distorted_x, distorted_y

    def _output_border_px(self) -> np.ndarray:
        width_px, height_px = self._size_px
        columns = np.linspace(-0.5, width_px - 0.5, 64)
        rows = np.linspace(-0.5, height_px - 0.5, 48)
        return np.concatenate([
            np.column_stack([columns, np.full_like(columns, -0.5)]),
            np.column_stack([columns, np.full_like(columns, height_px - 0.5)]),
            np.column_stack([np.full_like(rows, -0.5), rows]),
            np.column_stack([np.full_like(rows, width_px - 0.5), rows])])

    def _render_pixels_of(self, output_px: np.ndarray, scale: float) -> np.ndarray:
        """Map output (distorted) pixels to the render's pixels for a focal scale."""
        fx_px, fy_px, cx_px, cy_px = self._render_intrinsics
        points = output_px.reshape(-1, 2).astype(np.float64)
        distorted_x = (points[:, 0] - cx_px) / (fx_px * scale)
        distorted_y = (points[:, 1] - cy_px) / (fy_px * scale)
        factor = radial_undistortion_factor(np.hypot(distorted_x, distorted_y),
                                            self._coefficients)
        return np.column_stack([cx_px + fx_px * distorted_x * factor,
                                cy_px + fy_px * distorted_y * factor])

    def _focal_scale(self) -> float:
        """Find the smallest focal scale (zoom) whose output pixels all come from the render."""
        width_px, height_px = self._size_px
        border = self._output_border_px()
        low, high = 1.0, 2.0
        for _ in range(SCALE_SEARCH_STEPS):
            scale = (low + high) / 2.0
            mapped = self._render_pixels_of(border, scale)
            inside = (np.all(mapped[:, 0] >= -0.5) and np.all(mapped[:, 0] <= width_px - 0.5)
                      and np.all(mapped[:, 1] >= -0.5)
                      and np.all(mapped[:, 1] <= height_px - 0.5))
            if inside:
                high = scale
            else:
                low = scale
        return high

    def _make_distortion_maps(self):
        width_px, height_px = self._size_px
        columns, rows = np.meshgrid(np.arange(width_px, dtype=np.float64),
                                    np.arange(height_px, dtype=np.float64))
        mapped = self._render_pixels_of(np.stack([columns, rows], axis=-1), self._scale)
        map_x = mapped[:, 0].reshape(height_px, width_px).astype(np.float32)
        map_y = mapped[:, 1].reshape(height_px, width_px).astype(np.float32)
        return cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)

    def _make_gain_map(self) -> np.ndarray:
        """Vignetting (cos^4-like fall-off) times the white balance's per-channel gains."""
        width_px, height_px = self._size_px
        fx_px, _, cx_px, cy_px = self._render_intrinsics
        columns, rows = np.meshgrid(np.arange(width_px), np.arange(height_px))
        radius2 = ((columns - cx_px) ** 2 + (rows - cy_px) ** 2) / (fx_px * fx_px)
        corner2 = (cx_px ** 2 + cy_px ** 2) / (fx_px * fx_px)
        vignette = 1.0 - self._realism.vignetting * radius2 / corner2
        return (vignette[..., None] * self._white_balance_gains()).astype(np.float32)

    def _white_balance_gains(self) -> np.ndarray:
        realism = self._realism
        if not realism.light_temperatures_k or realism.white_balance_error is None:
            return np.ones(3)
        # The camera misjudges the light as warmer or cooler by the error, as seeded.
        sign = 1.0 if realism.generator('white_balance').uniform() < 0.5 else -1.0
        estimate_k = np.mean(realism.light_temperatures_k) * (
            1.0 + sign * realism.white_balance_error)
        gains = 1.0 / kelvin_to_rgb(estimate_k)
        return gains / gains[1]

    def process(self, image: np.ndarray, step_index: int, forward_mps: float,
                yaw_rate_radps: float) -> np.ndarray:
        """
        Turn one ideal RGB render into what the camera delivers.

        :param image: the render, RGB uint8 (height, width, 3).
        :param step_index: the physics step of the frame (seeds its noise).
        :param forward_mps: the robot's forward speed (motion blur).
        :param yaw_rate_radps: the robot's yaw rate (motion blur).
        :return: the camera's RGB uint8 image; reused by the next call.
        """
        realism = self._realism
        if self._maps is not None:
            # Resampled first, on 8 bits: the lens acts before the sensor, and remapping a
            # byte image costs a third of a float one.
            image = cv2.remap(image, *self._maps, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        gain = 1.0
        if realism.auto_exposure:
            metered = float(image[::METERING_STEP_PX, ::METERING_STEP_PX].mean()) * float(
                self._mean_gain)
            gain = (EXPOSURE_TARGET_LEVEL / max(metered, 1.0)) ** EXPOSURE_RESPONSE
            self.exposure_gain = gain = float(np.clip(gain, *EXPOSURE_GAIN_LIMITS))
        # Exposure, vignetting and white balance in one pass, rounded and saturated to 8 bits
        # as the sensor's converter does; blur and noise work on those bytes.
        output = cv2.multiply(image, self._gain_map, scale=gain, dtype=cv2.CV_8U,
                              dst=self._output)
        fx_px, fy_px, _, _ = self.intrinsics
        blur_x = abs(yaw_rate_radps) * realism.exposure_time_s * fx_px
        blur_y = abs(forward_mps) * realism.exposure_time_s * fy_px * FORWARD_BLUR_SHARE
        if max(blur_x, blur_y) >= MIN_BLUR_PX:
            kernel = (max(1, int(round(blur_x))), max(1, int(round(blur_y))))
            # Summed exactly in 16 bits, then divided and rounded once: OpenCV's 8-bit box
            # filter rounds even kernels up (by 0.75 of a level for a 2-pixel smear), which
            # would brighten every moving frame. (The same bytes as averaging in floats, in
            # two thirds of the time.)
            cv2.boxFilter(output, cv2.CV_16U, kernel, dst=self._sums, normalize=False)
            output = cv2.convertScaleAbs(self._sums, dst=self._blurred,
                                         alpha=1.0 / (kernel[0] * kernel[1]))
        if self._noise_bank is not None:
            output = self._add_noise(output, step_index)
        if realism.jpeg_quality > 0:
            ok, encoded = cv2.imencode('.jpg', cv2.cvtColor(output, cv2.COLOR_RGB2BGR),
                                       [cv2.IMWRITE_JPEG_QUALITY, int(realism.jpeg_quality)])
            if ok:
                cv2.cvtColor(cv2.imdecode(encoded, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB,
                             dst=output)
        return output

    def _add_noise(self, image: np.ndarray, step_index: int) -> np.ndarray:
        """
        Add shot noise (variance ~ signal) and read noise from the bank, seeded per step.

        :param image: the 8-bit image; the noise's spread at each level comes from a table.
        :return: the noisy image, rounded and saturated to 8 bits (in the output buffer).
        """
        realism = self._realism
        size = image.size
        rng = np.random.Generator(np.random.PCG64([realism.seed, int(step_index), 7]))
        offset = int(rng.integers(0, len(self._noise_bank) - size, endpoint=True))
        normal = self._noise_bank[offset:offset + size].reshape(image.shape)
        noise = cv2.LUT(image, self._noise_sigma, dst=self._frame)
        cv2.multiply(noise, normal, dst=noise)
        return cv2.add(image, noise, dst=self._output, dtype=cv2.CV_8U)
