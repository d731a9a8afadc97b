"""How a frame's pose changes over a short interval: the rates the plan records and the pose
they give at an offset from the frame's time (motion during an exposure).

A planned frame records (``PoseTrack``) the camera's inertial angular velocity in camera axes
``omega_cam_rad_s`` (w_c), the target's in body axes ``omega_body_rad_s`` (w_b), and the rate
of the translation ``t_dot_cam_from_body_m_s``. With ``Exp`` the rotation by a rotation
vector (the exponential map of SO(3)) and the body-axis rates defined by
``dR_gcrs_from_x / dt = R_gcrs_from_x [w_x]x``, the pose at an offset tau from the frame is

    R_cam_from_body(tau) = Exp(-w_c tau) R_cam_from_body(0) Exp(w_b tau)
    t_cam_from_body(tau) = t_cam_from_body(0) + t_dot tau

and a direction fixed in inertial axes (the Sun, the Earth's and the Moon's centres, a
star) turns in camera axes as ``d_cam(tau) = Exp(-w_c tau) d_cam(0)``.

Error budget (|tau| <= half an exposure, at most 0.1 s for the longest 0.2 s exposure):

- rotation: constant rates are exact for a spinning or inertial target (the attitude laws
  turn at a constant body rate) and for the LVLH law up to the orbit's rate change
  (< 1e-9 rad over 0.1 s). A camera tracking a fly-by turns at w ~ v / rho with an angular
  acceleration up to ~ 2 w^2; the neglected alpha tau^2 / 2 is 1e-4 rad for v = 10 m/s at
  rho = 100 m (w = 0.1 rad/s), i.e. 0.1 px at 1000 px/rad, and shrinks as w^2.
- translation: the neglected term t_ddot tau^2 / 2 holds the differential gravity (n^2 rho
  ~ 1.2e-6 s^-2 x rho in low orbit: 6e-5 m at rho = 10 km) and the frame's turn
  (|w_c|^2 |t| tau^2 / 2, along the boresight for a camera that keeps the target centred).
- the inertial directions of the Sun, Earth and Moon are held fixed: the target moves
  ~0.75 km in 0.1 s in low orbit, so the Earth's centre turns by < 1.1e-4 rad and the Sun's
  by 5e-12 rad.

The rates come from central differences of the planner's own pointing and attitude law at
t +- ``RATE_STEP_S``, both craft moved along their velocities (their accelerations change
the positions by a dt^2 / 2, which cancels in a central difference): exact for constant
rates, otherwise O(dt^2) of the rate. The roll reference's own turn under J2 (the orbit
normal's precession, ~1e-6 rad/s in low orbit) is left out: 1e-7 rad over 0.1 s.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.quaternion import (
    canonical_quaternion,
    matrix_from_quaternion,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_multiply,
)
from satsight.poses.track import PoseTrack

#: Half the interval of the plan's central differences of pose (s).
RATE_STEP_S = 0.05


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """The rotation vector (..., 3), rad, of unit quaternions ``q`` (..., 4), scalar first:
    axis times angle, angle in [0, pi]."""
    q = canonical_quaternion(np.asarray(q, dtype=np.float64))
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    # angle / s -> 2 as s -> 0 (sin(angle / 2) ~ angle / 2).
    scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0)
    return v * scale[..., None]


def rotation_from_vector(rotation_vector_rad: np.ndarray) -> np.ndarray:
    """(3, 3) rotation by the rotation vector (3,) rad (Rodrigues' formula)."""
    return rotations_from_vectors(np.reshape(rotation_vector_rad, (1, 3)))[0]


def rotations_from_vectors(rotation_vectors_rad: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotations by the rotation vectors (K, 3) rad (Rodrigues' formula); the
    identity below 1e-15 rad."""
    w = np.asarray(rotation_vectors_rad, dtype=np.float64).reshape(-1, 3)
    angle = np.sqrt(np.einsum("ki,ki->k", w, w))
    still = angle < 1e-15
    k = w / np.where(still, 1.0, angle)[:, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    R = (
        np.eye(3)
        + np.sin(angle)[:, None, None] * K
        + (1.0 - np.cos(angle))[:, None, None] * (K @ K)
    )
    R[still] = np.eye(3)
    return R


def body_rate_rad_s(q_ref_from_x_before: np.ndarray, q_ref_from_x_after: np.ndarray,
                    dt_s: np.ndarray) -> np.ndarray:  # fmt: skip
    """Angular velocity (N, 3), rad/s, of frame x in its own axes from its attitude
    ``q_ref_from_x`` (N, 4) at two instants ``dt_s`` (N,) s apart: the rotation vector of
    conj(q_before) q_after over dt (exact for a constant rate)."""
    dt = np.asarray(dt_s, dtype=np.float64)
    if np.any(dt <= 0):
        raise SatsightError("the instants of a rate difference must be in increasing order")
    relative = quaternion_multiply(quaternion_conjugate(q_ref_from_x_before), q_ref_from_x_after)
    return rotation_vector(relative) / dt[..., None]


def pose_at_offset(track: PoseTrack, index: int, offset_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(R_cam_from_body (3, 3), t_cam_from_body_m (3,)) of frame ``index`` at ``offset_s``
    from its time, from the frame's rates (module docstring)."""
    R, t = poses_at_offsets(track, index, np.array([float(offset_s)]))
    return R[0], t[0]


def poses_at_offsets(
    track: PoseTrack, index: int, offsets_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(R_cam_from_body (K, 3, 3), t_cam_from_body_m (K, 3)) of frame ``index`` at the
    offsets ``offsets_s`` (K,) from its time, from the frame's rates (module docstring)."""
    tau = np.asarray(offsets_s, dtype=np.float64).reshape(-1)
    R0 = matrix_from_quaternion(track.q_cam_from_body[index])
    turn_cam = rotations_from_vectors(-track.omega_cam_rad_s[index] * tau[:, None])
    turn_body = rotations_from_vectors(track.omega_body_rad_s[index] * tau[:, None])
    R = turn_cam @ R0 @ turn_body
    t = track.t_cam_from_body_m[index] + track.t_dot_cam_from_body_m_s[index] * tau[:, None]
    return R, t


def track_at_offset(track: PoseTrack, index: int, offset_s: float) -> PoseTrack:
    """Frame ``index`` moved to ``offset_s`` from its time: a one-frame ``PoseTrack`` with
    the pose at that instant and the inertial directions (Sun, Earth, Moon, the camera's
    attitude) turned with the camera; distances, epoch, flags and rates are the frame's."""
    R, t = pose_at_offset(track, index, offset_s)
    row = track.select(np.array([index]))
    R_cam_now_from_cam = rotation_from_vector(-track.omega_cam_rad_s[index] * float(offset_s))
    values = {field.name: getattr(row, field.name) for field in dataclasses.fields(row)}
    values["time_s"] = row.time_s + float(offset_s)
    values["q_cam_from_body"] = quaternion_from_matrix(R)[None, :]
    values["t_cam_from_body_m"] = t[None, :]
    for name in ("sun_from_target_cam", "earth_from_target_cam", "moon_from_target_cam"):
        values[name] = getattr(row, name) @ R_cam_now_from_cam.T
    if track.has_sky:
        q_cam_now_from_cam = quaternion_from_matrix(R_cam_now_from_cam)
        values["q_cam_from_gcrs"] = quaternion_multiply(q_cam_now_from_cam, row.q_cam_from_gcrs)
    return PoseTrack(**values)
