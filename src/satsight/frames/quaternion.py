"""Unit quaternions: scalar-first ``[qw, qx, qy, qz]``, Hamilton product, written with qw >= 0.

This module owns every quaternion conversion in satsight. Naming follows the transform
convention: ``q_a_from_b`` rotates vectors expressed in frame b into frame a,
``v_a = q_a_from_b * v_b * conj(q_a_from_b)``, and
``R_a_from_b = matrix_from_quaternion(q_a_from_b)``.
Composition cancels names: ``q_a_from_c = quaternion_multiply(q_a_from_b, q_b_from_c)``.

Arrays carry components on the last axis: a single quaternion is shape (4,), a batch (N, 4).
"""

from __future__ import annotations

import numpy as np

from satsight.errors import SatsightError

_NORM_TOLERANCE = 1e-6


def _as_quaternion_array(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (4,):
        raise SatsightError(
            "a quaternion needs 4 components [qw, qx, qy, qz] on the last axis; "
            f"got shape {q.shape}"
        )
    return q


def _normalised(q: np.ndarray) -> np.ndarray:
    q = _as_quaternion_array(q)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < _NORM_TOLERANCE):
        raise SatsightError("cannot normalise a quaternion of (near) zero length")
    return q / norm


def canonical_quaternion(q: np.ndarray) -> np.ndarray:
    """Return q normalised to unit length and flipped to the hemisphere qw >= 0.

    q and -q are the same rotation; the canonical form makes labels unique. When |qw| is
    at most 1e-12 the first clearly non-zero vector component is made positive instead, and
    qw is written as |qw|, so qw >= 0 always holds (a change of at most 2e-12).
    """
    q = _normalised(q)
    # Sign chosen by the first component that is clearly non-zero (qw, then qx, qy, qz).
    lead = np.zeros(q.shape[:-1])
    for k in range(4):
        undecided = lead == 0
        lead = np.where(undecided & (np.abs(q[..., k]) > 1e-12), np.sign(q[..., k]), lead)
    lead = np.where(lead == 0, 1.0, lead)
    q = q * lead[..., None]
    # A qw within 1e-12 of zero did not decide the sign and may have come out as -0 or a
    # tiny negative; write it as its magnitude so qw >= 0 holds exactly. The rotation
    # changes by at most 2e-12 rad, and q and -q still give the same result.
    qw = q[..., 0]
    q[..., 0] = np.where(np.abs(qw) <= 1e-12, np.abs(qw), qw)
    return q


def quaternion_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion): q_b_from_a from q_a_from_b."""
    q = _as_quaternion_array(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quaternion_multiply(q_a_from_b: np.ndarray, q_b_from_c: np.ndarray) -> np.ndarray:
    """Hamilton product ``q_a_from_b * q_b_from_c = q_a_from_c`` (not canonicalised)."""
    p = _as_quaternion_array(q_a_from_b)
    q = _as_quaternion_array(q_b_from_c)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def matrix_from_quaternion(q_a_from_b: np.ndarray) -> np.ndarray:
    """Rotation matrix R_a_from_b (..., 3, 3) from a unit quaternion (paper Eq. 3)."""
    q = _normalised(q_a_from_b)  # q and -q give the same matrix: no sign choice needed
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def quaternion_from_matrix(R_a_from_b: np.ndarray) -> np.ndarray:
    """Canonical unit quaternion q_a_from_b from a rotation matrix (..., 3, 3).

    Raises SatsightError when the matrix is not a proper rotation (orthonormal, det +1)
    to 1e-6.
    """
    R = np.asarray(R_a_from_b, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise SatsightError(f"a rotation matrix has shape (..., 3, 3); got {R.shape}")
    eye = np.broadcast_to(np.eye(3), R.shape)
    if not np.allclose(np.swapaxes(R, -1, -2) @ R, eye, atol=1e-6) or np.any(np.linalg.det(R) < 0):
        raise SatsightError("matrix is not a proper rotation (R^T R != I or det(R) != +1)")
    flat = R.reshape(-1, 3, 3)
    from scipy.spatial.transform import Rotation  # here: scipy.spatial takes 0.19 s to import

    q = Rotation.from_matrix(flat).as_quat(scalar_first=True)
    return canonical_quaternion(q.reshape((*R.shape[:-2], 4)))


def rotate_vectors(q_a_from_b: np.ndarray, vectors_b: np.ndarray) -> np.ndarray:
    """Express vectors (..., 3) given in frame b in frame a."""
    R = matrix_from_quaternion(q_a_from_b)
    v = np.asarray(vectors_b, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise SatsightError(f"vectors need 3 components on the last axis; got shape {v.shape}")
    try:
        return np.einsum("...ij,...j->...i", R, v)
    except ValueError as exc:
        raise SatsightError(
            f"cannot pair quaternions of batch shape {R.shape[:-2]} with vectors of batch "
            f"shape {v.shape[:-1]}: give one quaternion, or one per vector"
        ) from exc


def quaternion_from_axis_angle(axis: np.ndarray, angle_rad: float | np.ndarray) -> np.ndarray:
    """Quaternion rotating by ``angle_rad`` (right hand) about the unit ``axis`` (..., 3)."""
    axis = np.asarray(axis, dtype=np.float64)
    if axis.shape[-1:] != (3,):
        raise SatsightError(f"a rotation axis has 3 components; got shape {axis.shape}")
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(norm < _NORM_TOLERANCE):
        raise SatsightError("rotation axis must be a non-zero vector")
    half = 0.5 * np.asarray(angle_rad, dtype=np.float64)[..., None]
    vector = np.sin(half) * axis / norm  # broadcasts a batch of axes against a batch of angles
    scalar = np.broadcast_to(np.cos(half), (*vector.shape[:-1], 1))
    return canonical_quaternion(np.concatenate([scalar, vector], axis=-1))


def angle_between_quaternions_rad(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, pi]) of q1^-1 q2: the geodesic distance between attitudes.

    Computed as 2 atan2(|v|, |w|) of the relative quaternion (w, v), which stays accurate
    for small angles (arccos of the dot product loses about 1e-8 rad near zero).
    """
    rel = quaternion_multiply(quaternion_conjugate(_normalised(q1)), _normalised(q2))
    return 2.0 * np.arctan2(np.linalg.norm(rel[..., 1:], axis=-1), np.abs(rel[..., 0]))
