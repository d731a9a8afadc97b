"""Pinhole camera in the OpenCV convention.

Camera frame: +x right, +y down, +z along the boresight. Pixel coordinates (u, v) have
u to the right and v down, and (0, 0) is the *centre* of the top-left pixel, so the image
centre of a W x H sensor is ((W - 1) / 2, (H - 1) / 2). Projection::

    [u, v, 1]^T ~ K [X, Y, Z]^T,  K = [[f/p, 0, cx], [0, f/p, cy], [0, 0, 1]]

with focal length f and pixel pitch p in metres (square pixels).

Presets follow the paper's camera (section 4.2, Table 2): a CCD231-84-class sensor of
4096 x 4112 pixels of 15 um, with f = 3 m (high resolution) or f = 0.7 m (wide field).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from satsight.errors import SatsightError


def _is_whole_number(value: object) -> bool:
    try:
        return not isinstance(value, bool) and float(value).is_integer()  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


def _check_last_axis(name: str, array: np.ndarray, n: int) -> None:
    if array.shape[-1:] != (n,):
        raise SatsightError(
            f"{name} needs {n} components on the last axis; got shape {array.shape}"
        )


@dataclass(frozen=True)
class PinholeCamera:
    """An ideal pinhole camera.

    focal_length_m: effective focal length. pixel_pitch_m: pixel size (square pixels).
    width_px, height_px: sensor size in pixels. cx_px, cy_px: principal point in pixels,
    defaulting to the sensor centre ((W - 1) / 2, (H - 1) / 2).
    """

    focal_length_m: float
    pixel_pitch_m: float
    width_px: int
    height_px: int
    cx_px: float | None = None
    cy_px: float | None = None

    def __post_init__(self) -> None:
        if not (self.focal_length_m > 0 and math.isfinite(self.focal_length_m)):
            raise SatsightError(f"focal length must be positive, got {self.focal_length_m} m")
        if not (self.pixel_pitch_m > 0 and math.isfinite(self.pixel_pitch_m)):
            raise SatsightError(f"pixel pitch must be positive, got {self.pixel_pitch_m} m")
        if not (_is_whole_number(self.width_px) and _is_whole_number(self.height_px)) or (
            int(self.width_px) < 1 or int(self.height_px) < 1
        ):
            raise SatsightError(
                "image size must be whole numbers of pixels, at least 1 x 1; "
                f"got {self.width_px} x {self.height_px}"
            )
        object.__setattr__(self, "width_px", int(self.width_px))
        object.__setattr__(self, "height_px", int(self.height_px))
        if self.cx_px is None:
            object.__setattr__(self, "cx_px", (self.width_px - 1) / 2.0)
        if self.cy_px is None:
            object.__setattr__(self, "cy_px", (self.height_px - 1) / 2.0)

    # --- presets -------------------------------------------------------------------------
    @classmethod
    def high_resolution(cls) -> PinholeCamera:
        """Paper's high-resolution mode: f = 3 m, 4096 x 4112 px of 15 um."""
        return cls(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=4096, height_px=4112)

    @classmethod
    def wide_field(cls) -> PinholeCamera:
        """Paper's wide-field mode: f = 0.7 m, 4096 x 4112 px of 15 um."""
        return cls(focal_length_m=0.7, pixel_pitch_m=15e-6, width_px=4096, height_px=4112)

    # --- intrinsics ----------------------------------------------------------------------
    @property
    def focal_length_px(self) -> float:
        """Focal length in pixels, f / p."""
        return self.focal_length_m / self.pixel_pitch_m

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix (3, 3), pixels."""
        f = self.focal_length_px
        return np.array([[f, 0.0, self.cx_px], [0.0, f, self.cy_px], [0.0, 0.0, 1.0]])

    @property
    def sensor_width_m(self) -> float:
        return self.width_px * self.pixel_pitch_m

    @property
    def sensor_height_m(self) -> float:
        return self.height_px * self.pixel_pitch_m

    @property
    def fov_x_rad(self) -> float:
        """Full horizontal field of view, 2 atan(W p / 2 f)."""
        return 2.0 * math.atan(self.sensor_width_m / (2.0 * self.focal_length_m))

    @property
    def fov_y_rad(self) -> float:
        """Full vertical field of view, 2 atan(H p / 2 f)."""
        return 2.0 * math.atan(self.sensor_height_m / (2.0 * self.focal_length_m))

    @property
    def fov_diagonal_rad(self) -> float:
        """Full diagonal field of view."""
        diag = math.hypot(self.sensor_width_m, self.sensor_height_m)
        return 2.0 * math.atan(diag / (2.0 * self.focal_length_m))

    @property
    def ifov_rad(self) -> float:
        """Instantaneous field of view of one pixel at the centre, p / f."""
        return self.pixel_pitch_m / self.focal_length_m

    def gsd_m(self, range_m: float | np.ndarray) -> float | np.ndarray:
        """Sample distance (m per pixel) on a plane facing the camera at ``range_m``."""
        return np.asarray(range_m, dtype=np.float64) * self.ifov_rad

    def pixels_spanned(self, size_m: float, range_m: float) -> float:
        """How many pixels an object of ``size_m`` across spans at ``range_m`` (on axis)."""
        return 2.0 * self.focal_length_px * math.tan(math.atan(0.5 * size_m / range_m))

    def with_size(self, width_px: int, height_px: int) -> PinholeCamera:
        """Same optics with another sensor size (principal point re-centred)."""
        return replace(self, width_px=width_px, height_px=height_px, cx_px=None, cy_px=None)

    # --- projection ----------------------------------------------------------------------
    def project(self, points_cam_m: np.ndarray) -> np.ndarray:
        """Project points (N, 3) in the camera frame to pixels (N, 2).

        Points at or behind the camera (Z <= 0) give NaN.
        """
        p = np.asarray(points_cam_m, dtype=np.float64)
        _check_last_axis("points_cam_m", p, 3)
        z = p[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.focal_length_px * p[..., 0] / z + self.cx_px
            v = self.focal_length_px * p[..., 1] / z + self.cy_px
        uv = np.stack([u, v], axis=-1)
        uv[z <= 0] = np.nan
        return uv

    def backproject(self, pixels_px: np.ndarray, depth_m: np.ndarray) -> np.ndarray:
        """Points (N, 3) in the camera frame from pixels (N, 2) and depth along +z (N,)."""
        uv = np.asarray(pixels_px, dtype=np.float64)
        _check_last_axis("pixels_px", uv, 2)
        z = np.asarray(depth_m, dtype=np.float64)
        x = (uv[..., 0] - self.cx_px) / self.focal_length_px * z
        y = (uv[..., 1] - self.cy_px) / self.focal_length_px * z
        return np.stack([x, y, z], axis=-1)

    def ray_directions_cam(self, pixels_px: np.ndarray) -> np.ndarray:
        """Unit viewing directions (N, 3) in the camera frame through pixel positions."""
        d = self.backproject(pixels_px, np.ones(np.shape(pixels_px)[:-1]))
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


CAMERA_PRESETS = {
    "high_resolution": PinholeCamera.high_resolution,
    "wide_field": PinholeCamera.wide_field,
}
