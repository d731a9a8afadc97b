"""Viewpoints given by direction and distance in the target's body frame.

A view places the camera on the sphere of radius ``distance_m`` about the target's
bounding-box centre, in the direction (azimuth, elevation) of the body frame::

    direction = (cos el cos az, cos el sin az, sin el)

The boresight points at the centre; image "up" is the body +z axis projected on the image
plane (the body +x axis when looking along z), then the camera rolls by ``roll_rad`` about
its boresight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform, look_at_cam_from_body


def direction_from_angles(azimuth_rad: float, elevation_rad: float) -> np.ndarray:
    """Unit vector (3,) at azimuth (from +x towards +y) and elevation (towards +z)."""
    ce = np.cos(elevation_rad)
    return np.array([ce * np.cos(azimuth_rad), ce * np.sin(azimuth_rad), np.sin(elevation_rad)])


@dataclass(frozen=True)
class View:
    """A camera viewpoint about the target.

    distance_m: from the camera to the target's bounding-box centre. azimuth_rad,
    elevation_rad: direction from the target to the camera in the body frame.
    roll_rad: rotation of the camera about its boresight (right hand about +z_cam).
    """

    distance_m: float
    azimuth_rad: float
    elevation_rad: float
    roll_rad: float = 0.0

    def __post_init__(self) -> None:
        if not self.distance_m > 0:
            raise SatsightError(f"view distance must be positive, got {self.distance_m} m")

    def cam_from_body(self, target_center_body_m: np.ndarray) -> RigidTransform:
        """Camera pose: body-frame points to camera-frame points."""
        center = np.asarray(target_center_body_m, dtype=np.float64)
        direction = direction_from_angles(self.azimuth_rad, self.elevation_rad)
        up = np.array([0.0, 0.0, 1.0]) if abs(direction[2]) < 0.999 else np.array([1.0, 0, 0])
        return look_at_cam_from_body(
            center + self.distance_m * direction, center, up_hint_body=up, roll_rad=self.roll_rad
        )
