"""What a render produces for one frame: radiance and the geometric label images."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SunLight:
    """The Sun as a collimated source.

    direction_body: (3,) unit vector from the target toward the Sun, body frame.
    irradiance_w_m2: in-band irradiance on a surface facing the Sun, W m^-2.
    """

    direction_body: np.ndarray
    irradiance_w_m2: float

    def __post_init__(self) -> None:
        d = np.asarray(self.direction_body, dtype=np.float64).reshape(3)
        object.__setattr__(self, "direction_body", d / np.linalg.norm(d))


@dataclass(frozen=True)
class RadianceImage:
    """One rendered frame, (H, W) images with pixel (0, 0) the top-left pixel centre.

    radiance_w_m2_sr: (H, W, 3) float32 radiance towards the camera per colour channel.
    depth_m: (H, W) float32 distance along the optical axis (+z), 0 where no surface.
    part_id: (H, W) uint16 part index + 1 of the visible surface, 0 for background.
    normals_cam: (H, W, 3) float32 unit surface normals in the camera frame, facing the
    camera; zero for background.
    """

    radiance_w_m2_sr: np.ndarray
    depth_m: np.ndarray
    part_id: np.ndarray
    normals_cam: np.ndarray

    @property
    def object_mask(self) -> np.ndarray:
        """(H, W) bool: True where a ray from the pixel centre hits the target."""
        return self.part_id > 0

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth_m.shape
