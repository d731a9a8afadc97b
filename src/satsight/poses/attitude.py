"""Attitude laws of the target and pointing of the camera, vectorised over N frames.

Frames: "gcrs" is the Earth-centred inertial frame of `satsight.ephemeris.orbits`; "body"
is the target's mesh frame; "cam" is the camera frame in the OpenCV convention (+x image
right, +y image down, +z boresight). Attitudes are unit quaternions ``q_a_from_b``
(scalar first, Hamilton product, written with qw >= 0; `satsight.frames.quaternion`), stacks
(N, 4), with ``x_a = R(q_a_from_b) @ x_b``. Positions are inertial, m, stacks (N, 3).

Target attitude laws:

* `lvlh_fixed_attitude`: three-axis stabilised in its local orbital frame (CCSDS LVLH,
  `satsight.frames.orbital.lvlh_from_inertial`) with a fixed offset: Earth-pointing, one
  inertial revolution per orbit about the orbit normal (the LVLH -y axis);
* `inertial_attitude`: fixed in inertial space;
* `spinning_attitude`: constant angular velocity in the body frame (torque-free spin about a
  principal axis, or a kinematic tumble).

Camera pointing (`pointing_gcrs_from_cam`): the boresight looks from the observer at a
target point, and the roll about the boresight is fixed by a reference direction whose
projection on the image plane is put along a named image axis. The roll policy
"orbit_normal" of `camera_reference` is the paper's convention: the optical axis (z)
initially along -T and the x axis along the orbit normal N, the optical axis then kept on
the target. The observer is then ahead of the target on the V-bar, looking back, and
+y = z x x = -R: the Earth is at the bottom of the image. With "zenith_up" image up (-y) is
the radial direction at every position.
`cam_from_body` combines both into the pose label ``x_cam = R(q_cam_from_body) x_body +
t_cam_from_body_m`` (Hartley and Zisserman, "Multiple View Geometry in Computer Vision",
2nd ed., Sec. 6.1: x_cam = R (X - C) for a camera at C).
"""

from __future__ import annotations

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.orbital import lvlh_from_inertial, rtn_from_inertial
from satsight.frames.quaternion import (
    canonical_quaternion,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_multiply,
    rotate_vectors,
)
from satsight.vectors import LOOK_AT_AXES, look_at_axes

ROLL_POLICIES = ("orbit_normal", "zenith_up")
REFERENCE_AXES = LOOK_AT_AXES

_UNIT_TOLERANCE = 1e-6


def _vectors(value: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim not in (1, 2) or array.shape[-1] != 3:
        raise SatsightError(f"{name} must have shape (3,) or (N, 3); got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise SatsightError(f"{name} must be finite")
    return array


def _unit_quaternions(value: np.ndarray, name: str) -> np.ndarray:
    q = np.asarray(value, dtype=np.float64)
    if q.ndim not in (1, 2) or q.shape[-1] != 4:
        raise SatsightError(
            f"{name} must be a quaternion [qw, qx, qy, qz] of shape (4,) or (N, 4); got {q.shape}"
        )
    if not np.all(np.isfinite(q)):
        raise SatsightError(f"{name} must be finite")
    norm = np.linalg.norm(q, axis=-1)
    if np.any(np.abs(norm - 1.0) > _UNIT_TOLERANCE):
        raise SatsightError(
            f"{name} must be unit quaternions (norm 1 to 1e-6); got norms from "
            f"{norm.min():.9g} to {norm.max():.9g}. Normalise them, e.g. with "
            "satsight.frames.quaternion.canonical_quaternion"
        )
    return canonical_quaternion(q)


def _broadcast(arrays: list[np.ndarray], names: list[str]) -> list[np.ndarray]:
    try:
        shape = np.broadcast_shapes(*(a.shape[:-1] for a in arrays))
    except ValueError as exc:
        shapes = ", ".join(f"{n} {a.shape}" for n, a in zip(names, arrays, strict=True))
        raise SatsightError(
            f"cannot pair these stacks ({shapes}): give one row, or the same N rows, for each"
        ) from exc
    return [np.broadcast_to(a, (*shape, a.shape[-1])) for a in arrays]


def lvlh_fixed_attitude(
    r_m: np.ndarray,
    v_m_s: np.ndarray,
    q_lvlh_from_body: np.ndarray = (1.0, 0.0, 0.0, 0.0),
) -> np.ndarray:
    """q_gcrs_from_body of a target held fixed in its CCSDS LVLH frame, (4,) or (N, 4).

    r_m, v_m_s: the target's inertial position (m) and velocity (m/s), (3,) or (N, 3).
    q_lvlh_from_body: the fixed attitude of the body in LVLH, (4,) or (N, 4); the identity
    puts body +x along the local horizontal (along v for a circular orbit), +y along the
    negative orbit normal and +z at nadir. Returns
    ``q_gcrs_from_body = q_gcrs_from_lvlh * q_lvlh_from_body`` with q_gcrs_from_lvlh from the
    rows of `satsight.frames.orbital.lvlh_from_inertial`. On a circular orbit the body turns
    once per orbit, at the mean motion, about the LVLH -y axis (the orbit normal).
    """
    R_lvlh_from_gcrs = lvlh_from_inertial(r_m, v_m_s)
    q_gcrs_from_lvlh = quaternion_from_matrix(np.swapaxes(R_lvlh_from_gcrs, -1, -2))
    q_offset = _unit_quaternions(q_lvlh_from_body, "q_lvlh_from_body")
    q_gcrs_from_lvlh, q_offset = _broadcast(
        [q_gcrs_from_lvlh, q_offset], ["the states", "q_lvlh_from_body"]
    )
    return canonical_quaternion(quaternion_multiply(q_gcrs_from_lvlh, q_offset))


def inertial_attitude(q_gcrs_from_body: np.ndarray, n: int) -> np.ndarray:
    """The same inertial attitude at n frames: q_gcrs_from_body (4,) repeated, (n, 4)."""
    q = _unit_quaternions(q_gcrs_from_body, "q_gcrs_from_body")
    if q.shape != (4,):
        raise SatsightError(f"q_gcrs_from_body must be one quaternion of shape (4,); got {q.shape}")
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise SatsightError(f"n must be a positive whole number of frames; got {n!r}")
    return np.tile(q, (int(n), 1))


def spinning_attitude(
    q0_gcrs_from_body: np.ndarray,
    omega_body_rad_s: np.ndarray,
    times_s: np.ndarray,
) -> np.ndarray:
    """q_gcrs_from_body (N, 4) of a body turning at a constant body-frame angular velocity.

    q0_gcrs_from_body (4,): the attitude at t = 0. omega_body_rad_s (3,), rad/s: the angular
    velocity of the body relative to the inertial frame, in body axes. times_s (N,), s from
    that epoch (any order and sign). The solution of the kinematic equation
    ``dq/dt = 1/2 q * (0, omega_body)`` (Hamilton product, body-frame rate) for constant
    omega is

        q(t) = q0 * exp(1/2 (0, omega) t)
             = q0 * [cos(|omega| t / 2), sin(|omega| t / 2) omega / |omega|]

    (J. Sola, "Quaternion kinematics for the error-state Kalman filter", arXiv:1711.02508,
    2017: Sec. 1.3.4, exponential of pure quaternions, and the section on time derivatives
    with local angular rates). The body turns by |omega| t about the axis omega, which stays
    fixed in both the body and the inertial frame (a torque-free spin about a principal axis,
    or a prescribed tumble; nutation of a free asymmetric body is not modelled). Each row is
    written with qw >= 0, so consecutive rows may differ in overall sign.
    """
    q0 = _unit_quaternions(q0_gcrs_from_body, "q0_gcrs_from_body")
    if q0.shape != (4,):
        raise SatsightError(
            f"q0_gcrs_from_body must be one quaternion of shape (4,); got {q0.shape}"
        )
    omega = _vectors(omega_body_rad_s, "omega_body_rad_s")
    if omega.shape != (3,):
        raise SatsightError(f"omega_body_rad_s must have shape (3,); got {omega.shape}")
    times = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise SatsightError(f"times_s must be a 1-D array of finite s; got shape {times.shape}")
    rate_rad_s = float(np.linalg.norm(omega))
    if rate_rad_s == 0.0:
        return np.tile(q0, (times.size, 1))
    half_angle = 0.5 * rate_rad_s * times
    delta = np.concatenate(
        [np.cos(half_angle)[:, None], np.sin(half_angle)[:, None] * (omega / rate_rad_s)], axis=-1
    )
    return canonical_quaternion(quaternion_multiply(q0, delta))


def camera_reference(
    policy: str, r_observer_m: np.ndarray, v_observer_m_s: np.ndarray
) -> tuple[np.ndarray, str]:
    """Roll reference of a policy: (reference_gcrs (3,) or (N, 3) unit, reference_axis).

    r_observer_m, v_observer_m_s: the observer's inertial position (m) and velocity (m/s),
    (3,) or (N, 3). Policies (`ROLL_POLICIES`):

    * "orbit_normal": the observer's orbit normal N = (r x v) / |r x v| along image +x
      (reference_axis "x"). An observer on the target's V-bar looking along -T (ahead of the
      target) then has +x = N, +y = -R; looking along +T (behind it), +x = N, +y = +R;
    * "zenith_up": the observer's radial direction r / |r| along image up (reference_axis
      "-y"), so the Earth is at the bottom of the image.
    """
    R_rtn_from_gcrs = rtn_from_inertial(r_observer_m, v_observer_m_s)
    if policy == "orbit_normal":
        return R_rtn_from_gcrs[..., 2, :].copy(), "x"
    if policy == "zenith_up":
        return R_rtn_from_gcrs[..., 0, :].copy(), "-y"
    raise SatsightError(f"the roll policy must be one of {ROLL_POLICIES}; got {policy!r}")


def pointing_gcrs_from_cam(
    observer_m: np.ndarray,
    target_m: np.ndarray,
    reference_gcrs: np.ndarray,
    roll_rad: float | np.ndarray = 0.0,
    reference_axis: str = "x",
) -> np.ndarray:
    """q_gcrs_from_cam (4,) or (N, 4) of a camera at observer_m looking at target_m.

    observer_m, target_m: inertial positions, m, (3,) or (N, 3). reference_gcrs: a direction
    (any length > 0) in inertial axes, (3,) or (N, 3), that fixes the roll. roll_rad: scalar
    or (N,). reference_axis: the camera axis the projected reference lies along at zero roll,
    one of `REFERENCE_AXES`: "x" image right, "-y" image up, "-x", "y" (image down).

    Construction (OpenCV camera, columns of R_gcrs_from_cam = camera axes in GCRS):

    1. z = (target - observer) / |target - observer|: the boresight;
    2. p = reference - (reference . z) z, the reference projected on the image plane,
       normalised: the named axis (x = p for "x", y = -p for "-y", ...);
    3. the third axis completes the right-handed triad (x = y x z, y = z x x);
    4. a right-hand roll about +z by roll_rad: x' = cos x + sin y, y' = -sin x + cos y.

    If the reference is within 1e-6 rad (sine) of the boresight, it cannot fix the roll and
    the inertial +Z axis is used in its place, or +X if the boresight is along +-Z too; the
    result is deterministic but jumps there, so choose a reference away from the line of
    sight. Raises SatsightError if observer and target coincide.
    """
    if reference_axis not in REFERENCE_AXES:
        raise SatsightError(
            f"reference_axis must be one of {REFERENCE_AXES}; got {reference_axis!r}"
        )
    observer = _vectors(observer_m, "observer_m")
    target = _vectors(target_m, "target_m")
    reference = _vectors(reference_gcrs, "reference_gcrs")
    single = observer.ndim == target.ndim == reference.ndim == 1
    roll = np.asarray(roll_rad, dtype=np.float64)
    if roll.ndim > 1 or not np.all(np.isfinite(roll)):
        raise SatsightError(f"roll_rad must be a finite scalar or (N,) array; got {roll!r}")
    single = single and roll.ndim == 0
    observer, target, reference, roll_col = _broadcast(
        [np.atleast_2d(observer), np.atleast_2d(target), np.atleast_2d(reference), roll[..., None]],
        ["observer_m", "target_m", "reference_gcrs", "roll_rad"],
    )
    if np.any(np.linalg.norm(reference, axis=-1) == 0.0):
        raise SatsightError("reference_gcrs must be a non-zero direction in every row")
    R_gcrs_from_cam = look_at_axes(observer, target, reference, reference_axis, roll_col[:, 0])
    q = quaternion_from_matrix(R_gcrs_from_cam)
    return q[0] if single else q


def cam_from_body(
    q_gcrs_from_cam: np.ndarray,
    q_gcrs_from_body: np.ndarray,
    observer_m: np.ndarray,
    target_origin_m: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The pose label (q_cam_from_body, t_cam_from_body_m), (N, 4) and (N, 3), or single.

    q_gcrs_from_cam, q_gcrs_from_body: (4,) or (N, 4). observer_m: the camera's inertial
    position, m; target_origin_m: the inertial position, m, of the body frame's origin; each
    (3,) or (N, 3). Then ``x_cam = R(q_cam_from_body) x_body + t_cam_from_body_m`` with

        q_cam_from_body = conj(q_gcrs_from_cam) * q_gcrs_from_body
        t_cam_from_body_m = R_cam_from_gcrs (target_origin - observer)

    (the body origin seen from the camera, in camera axes; on the boresight when the camera
    looks at the origin).
    """
    q_cam = _unit_quaternions(q_gcrs_from_cam, "q_gcrs_from_cam")
    q_body = _unit_quaternions(q_gcrs_from_body, "q_gcrs_from_body")
    observer = _vectors(observer_m, "observer_m")
    origin = _vectors(target_origin_m, "target_origin_m")
    single = q_cam.ndim == q_body.ndim == 1 and observer.ndim == origin.ndim == 1
    q_cam, q_body, observer, origin = _broadcast(
        [np.atleast_2d(a) for a in (q_cam, q_body, observer, origin)],
        ["q_gcrs_from_cam", "q_gcrs_from_body", "observer_m", "target_origin_m"],
    )
    q_cam_from_gcrs = quaternion_conjugate(q_cam)
    q = canonical_quaternion(quaternion_multiply(q_cam_from_gcrs, q_body))
    t = rotate_vectors(q_cam_from_gcrs, origin - observer)
    if single:
        return q[0], t[0]
    return q, t
