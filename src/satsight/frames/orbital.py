"""Orbit-attached frames (RTN, LVLH) and relative motion expressed in them.

Both frames are built from an object's inertial position r (m) and velocity v (m/s); each
function returns ``R_frame_from_inertial``, whose rows are the frame's unit axes written in
the inertial frame, so ``x_frame = R_frame_from_inertial @ x_inertial``. Inputs may be a
single state, shapes (3,), giving a (3, 3) matrix, or a stack (N, 3) giving (N, 3, 3).

RTN (Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed., Sec. 3.3, the
"RSW" frame; also called RIC or Hill frame):

    R = r / |r|               radial, away from the Earth's centre
    N = (r x v) / |r x v|     orbit normal, along the angular momentum
    T = N x R                 along-track (equal to v / |v| for a circular orbit)

LVLH, local vertical / local horizontal in the convention of the CCSDS Navigation Data
Messages (CCSDS 500.0-G-4, Navigation Data: Definitions and Conventions, Sec. on local
orbital frames; the usual crewed-spacecraft attitude frame):

    z = -r / |r|              nadir
    y = -(r x v) / |r x v|    negative orbit normal
    x = y x z                 local horizontal, along v for a circular orbit

so x = T, y = -N, z = -R: the same directions as RTN, reordered and signed.
"""

from __future__ import annotations

import numpy as np

from satsight.errors import SatsightError


def _check_states(r_m: np.ndarray, v_m_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(r_m, dtype=np.float64)
    v = np.asarray(v_m_s, dtype=np.float64)
    if r.shape != v.shape or r.ndim not in (1, 2) or r.shape[-1] != 3:
        raise SatsightError(
            f"r_m and v_m_s must both have shape (3,) or (N, 3); got {r.shape} and {v.shape}"
        )
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(v))):
        raise SatsightError("r_m and v_m_s must be finite")
    return r, v


def _unit_axes(r: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit radial, along-track and orbit-normal vectors (..., 3) of the RTN frame."""
    h = np.cross(r, v)
    r_norm = np.linalg.norm(r, axis=-1, keepdims=True)
    h_norm = np.linalg.norm(h, axis=-1, keepdims=True)
    # keepdims on every norm: (N, 1) against (N,) would broadcast to (N, N).
    v_norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(r_norm == 0.0) or np.any(h_norm <= 1e-12 * r_norm * v_norm):
        raise SatsightError(
            "the orbital frame is undefined: r_m is zero or parallel to v_m_s (no orbit plane)"
        )
    radial = r / r_norm
    normal = h / h_norm
    along = np.cross(normal, radial)
    return radial, along, normal


def rtn_from_inertial(r_m: np.ndarray, v_m_s: np.ndarray) -> np.ndarray:
    """R_rtn_from_inertial, (3, 3) or (N, 3, 3): rows R (radial), T (along-track), N (normal).

    r_m, v_m_s: inertial position (m) and velocity (m/s), shapes (3,) or (N, 3).
    """
    r, v = _check_states(r_m, v_m_s)
    radial, along, normal = _unit_axes(r, v)
    return np.stack([radial, along, normal], axis=-2)


def lvlh_from_inertial(r_m: np.ndarray, v_m_s: np.ndarray) -> np.ndarray:
    """R_lvlh_from_inertial, (3, 3) or (N, 3, 3), in the CCSDS LVLH convention (module doc).

    Rows: x = y x z (horizontal, along v for circular orbits), y = -orbit normal, z = nadir.
    r_m, v_m_s: inertial position (m) and velocity (m/s), shapes (3,) or (N, 3).
    """
    r, v = _check_states(r_m, v_m_s)
    radial, _, normal = _unit_axes(r, v)
    z = -radial
    y = -normal
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-2)


def relative_rtn(
    r_target_m: np.ndarray,
    v_target_m_s: np.ndarray,
    r_chaser_m: np.ndarray,
    v_chaser_m_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The chaser's position (m) and velocity (m/s) relative to the target, in target RTN.

    All inputs are inertial, shapes (3,) or (N, 3). The relative position is
    ``rho = R_rtn_from_inertial (r_chaser - r_target)``. The relative velocity is the rate of
    change of rho seen in the rotating RTN frame, which turns with angular velocity
    ``omega = (r x v) / |r|^2`` (along N; exact for the osculating frame of a Keplerian
    orbit, where dT/dt = -|omega| R):

        rho_dot = R_rtn_from_inertial ((v_chaser - v_target) - omega x (r_chaser - r_target))

    Two objects on the same circular orbit thus keep a constant rho and zero rho_dot.
    Returns (rho_rtn_m, rho_dot_rtn_m_s), each of the input shape.
    """
    r_t, v_t = _check_states(r_target_m, v_target_m_s)
    r_c, v_c = _check_states(r_chaser_m, v_chaser_m_s)
    if r_c.shape != r_t.shape:
        raise SatsightError(
            f"the target and chaser states must have the same shape; got {r_t.shape} and "
            f"{r_c.shape}"
        )
    R = rtn_from_inertial(r_t, v_t)
    omega = np.cross(r_t, v_t) / np.sum(r_t * r_t, axis=-1, keepdims=True)
    rho = r_c - r_t
    rho_dot_rotating = (v_c - v_t) - np.cross(omega, rho)
    rho_rtn = np.einsum("...ij,...j->...i", R, rho)
    rho_dot_rtn = np.einsum("...ij,...j->...i", R, rho_dot_rotating)
    return rho_rtn, rho_dot_rtn


def inertial_from_relative_rtn(
    r_target_m: np.ndarray,
    v_target_m_s: np.ndarray,
    rho_rtn_m: np.ndarray,
    rho_dot_rtn_m_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The chaser's inertial position (m) and velocity (m/s) from its state relative to a target.

    The exact inverse of `relative_rtn`, with the same frame rate
    ``omega = (r_target x v_target) / |r_target|^2``. With ``R = R_rtn_from_inertial`` of the
    target and ``rho = R^T rho_rtn`` the offset in inertial axes:

        r_chaser = r_target + rho
        v_chaser = v_target + R^T rho_dot_rtn + omega x rho

    r_target_m, v_target_m_s: the target's inertial state; rho_rtn_m, rho_dot_rtn_m_s: the
    chaser's position and rate of change seen in the target's rotating RTN frame (rows R, T,
    N). All shapes (3,) or (N, 3), all the same. Returns (r_chaser_m, v_chaser_m_s), each of
    the input shape.
    """
    r_t, v_t = _check_states(r_target_m, v_target_m_s)
    rho_rtn, rho_dot_rtn = _check_states(rho_rtn_m, rho_dot_rtn_m_s)
    if rho_rtn.shape != r_t.shape:
        raise SatsightError(
            f"the target state and the relative state must have the same shape; got "
            f"{r_t.shape} and {rho_rtn.shape}"
        )
    R = rtn_from_inertial(r_t, v_t)
    omega = np.cross(r_t, v_t) / np.sum(r_t * r_t, axis=-1, keepdims=True)
    rho = np.einsum("...ji,...j->...i", R, rho_rtn)
    rho_dot_rotating = np.einsum("...ji,...j->...i", R, rho_dot_rtn)
    return r_t + rho, v_t + rho_dot_rotating + np.cross(omega, rho)
