"""Small vector helpers, one home each: lengths, unit vectors and the angle between two.

Arrays carry components on the last axis: (3,) or (N, 3), float64.
"""

from __future__ import annotations

import numpy as np


def norm(v: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis: () for (3,), (N,) for (N, 3)."""
    return np.linalg.norm(v, axis=-1)


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` scaled to unit length along the last axis (a zero vector gives NaN)."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angle_between_rad(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle in [0, pi] between vectors ``u`` and ``v`` (k,) or (N, k), of any lengths.

    For 3-vectors ``atan2(|u x v|, u . v)``; in other dimensions Kahan's
    ``2 atan2(|a - b|, |a + b|)`` of the unit vectors a, b. Both are accurate to rounding at
    every angle, where ``arccos`` of the normalised dot product loses half the digits near
    0 and pi (about 1e-8 rad). A zero vector gives 0.
    """
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    if u.shape[-1] == 3:
        return np.arctan2(norm(np.cross(u, v)), np.sum(u * v, axis=-1))
    nu = np.linalg.norm(u, axis=-1, keepdims=True)
    nv = np.linalg.norm(v, axis=-1, keepdims=True)
    a = u / np.where(nu > 0, nu, 1.0)
    b = v / np.where(nv > 0, nv, 1.0)
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))
