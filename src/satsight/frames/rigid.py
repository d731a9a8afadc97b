"""Rigid transforms ``x_a = R_a_from_b @ x_b + t_a_from_b_m`` and the look-at camera pose.

A ``RigidTransform`` named ``cam_from_body`` maps points given in the body (mesh) frame to
the camera frame. ``a_from_b @ b_from_c`` gives ``a_from_c``: the names cancel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion, quaternion_from_matrix
from satsight.vectors import look_at_axes

_ROTATION_TOLERANCE = 1e-6


@dataclass(frozen=True)
class RigidTransform:
    """A proper rigid motion from frame b to frame a.

    R_a_from_b: (3, 3) rotation matrix. t_a_from_b_m: (3,) origin of b expressed in a, metres.
    """

    R_a_from_b: np.ndarray
    t_a_from_b_m: np.ndarray

    def __post_init__(self) -> None:
        R = np.asarray(self.R_a_from_b, dtype=np.float64)
        t = np.asarray(self.t_a_from_b_m, dtype=np.float64)
        if R.shape != (3, 3) or t.shape != (3,):
            raise SatsightError(
                f"a rigid transform needs R_a_from_b of shape (3, 3) and t_a_from_b_m of shape "
                f"(3,); got {R.shape} and {t.shape}"
            )
        if not np.all(np.isfinite(t)):
            raise SatsightError(f"t_a_from_b_m must be finite; got {t}")
        if not (np.allclose(R.T @ R, np.eye(3), atol=_ROTATION_TOLERANCE) and np.linalg.det(R) > 0):
            raise SatsightError(
                "R_a_from_b is not a proper rotation (R^T R != I or det(R) != +1 to 1e-6); "
                "build it with matrix_from_quaternion or scipy's Rotation"
            )
        object.__setattr__(self, "R_a_from_b", R)
        object.__setattr__(self, "t_a_from_b_m", t)

    @classmethod
    def identity(cls) -> RigidTransform:
        return cls(np.eye(3), np.zeros(3))

    @classmethod
    def from_quaternion(cls, q_a_from_b: np.ndarray, t_a_from_b_m: np.ndarray) -> RigidTransform:
        return cls(matrix_from_quaternion(q_a_from_b), t_a_from_b_m)

    @property
    def q_a_from_b(self) -> np.ndarray:
        """Canonical scalar-first quaternion of the rotation part."""
        return quaternion_from_matrix(self.R_a_from_b)

    def apply(self, points_b_m: np.ndarray) -> np.ndarray:
        """Transform points (..., 3) from frame b to frame a."""
        return np.asarray(points_b_m, dtype=np.float64) @ self.R_a_from_b.T + self.t_a_from_b_m

    def rotate(self, vectors_b: np.ndarray) -> np.ndarray:
        """Rotate free vectors (..., 3), e.g. directions and normals, from b to a."""
        return np.asarray(vectors_b, dtype=np.float64) @ self.R_a_from_b.T

    def inverse(self) -> RigidTransform:
        """The b_from_a transform."""
        R_b_from_a = self.R_a_from_b.T
        return RigidTransform(R_b_from_a, -R_b_from_a @ self.t_a_from_b_m)

    def __matmul__(self, b_from_c: RigidTransform) -> RigidTransform:
        """Composition: ``a_from_b @ b_from_c = a_from_c``."""
        return RigidTransform(
            self.R_a_from_b @ b_from_c.R_a_from_b,
            self.R_a_from_b @ b_from_c.t_a_from_b_m + self.t_a_from_b_m,
        )

    def as_matrix(self) -> np.ndarray:
        """Homogeneous 4x4 matrix."""
        M = np.eye(4)
        M[:3, :3] = self.R_a_from_b
        M[:3, 3] = self.t_a_from_b_m
        return M


def look_at_cam_from_body(
    camera_position_body_m: np.ndarray,
    target_point_body_m: np.ndarray,
    up_hint_body: np.ndarray = (0.0, 0.0, 1.0),
    roll_rad: float = 0.0,
) -> RigidTransform:
    """Camera pose (OpenCV axes: +x right, +y down, +z boresight) looking at a point.

    The boresight +z points from the camera to ``target_point_body_m``. With zero roll the
    image "up" (-y) is the projection of ``up_hint_body`` on the image plane; ``roll_rad``
    then turns the camera about its boresight (positive: right hand about +z). The axes are
    `satsight.vectors.look_at_axes` with the hint as reference for image up ("-y"); a hint
    parallel to the boresight falls back to +z, then +x of the body frame.
    """
    c = np.asarray(camera_position_body_m, dtype=np.float64)
    target = np.asarray(target_point_body_m, dtype=np.float64)
    up = np.asarray(up_hint_body, dtype=np.float64)
    for name, v in (
        ("camera_position_body_m", c),
        ("target_point_body_m", target),
        ("up_hint_body", up),
    ):
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise SatsightError(f"{name} must be 3 finite numbers; got {v!r}")
    if not math.isfinite(roll_rad):
        raise SatsightError(f"roll_rad must be finite; got {roll_rad}")
    R_cam_from_body = look_at_axes(c, target, up, reference_axis="-y", roll_rad=roll_rad).T
    return RigidTransform(R_cam_from_body, -R_cam_from_body @ c)
