"""Small vector helpers, one home each: lengths, unit vectors, the angle between two, and
the look-at construction of a camera's axes.

Arrays carry components on the last axis: (3,) or (N, 3), float64.
"""

from __future__ import annotations

import numpy as np

from satsight.errors import SatsightError


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


LOOK_AT_AXES = ("x", "-x", "y", "-y")
# A reference closer than this (sine of the angle) to the boresight cannot fix the roll; the
# fallback directions below are tried in its place, in order.
LOOK_AT_PARALLEL_SINE = 1e-6
LOOK_AT_FALLBACKS = (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))


def look_at_axes(
    eye_m: np.ndarray,
    target_m: np.ndarray,
    reference: np.ndarray,
    reference_axis: str = "-y",
    roll_rad: float | np.ndarray = 0.0,
) -> np.ndarray:
    """R_world_from_cam, (3, 3) or (N, 3, 3), of a camera at ``eye_m`` looking at ``target_m``.

    The one look-at construction of the package (OpenCV camera: +x image right, +y image
    down, +z boresight; the columns of the result are the camera axes in world axes). Inputs
    are (3,) or (N, 3), broadcast against each other; ``roll_rad`` is a scalar or (N,).

    1. z = (target - eye) / |target - eye|, the boresight;
    2. p = the unit projection of ``reference`` (any length > 0) on the image plane; it is
       the camera axis named by ``reference_axis`` ("x" image right, "-y" image up, "-x",
       "y"), and the third axis completes the right-handed triad (x = y x z or y = z x x);
    3. a right-hand roll about +z: x' = cos x + sin y, y' = -sin x + cos y.

    A reference within `LOOK_AT_PARALLEL_SINE` (sine of the angle) of the boresight cannot
    fix the roll, nor can a zero reference: world +Z is used in its place, or +X when the
    boresight is along +-Z too. The result is deterministic but jumps there; choose a
    reference away from the line of sight. Raises SatsightError on non-finite input or an
    eye on the target.
    """
    if reference_axis not in LOOK_AT_AXES:
        raise SatsightError(f"reference_axis must be one of {LOOK_AT_AXES}; got {reference_axis!r}")
    arrays = []
    for name, value in (("eye_m", eye_m), ("target_m", target_m), ("reference", reference)):
        array = np.asarray(value, dtype=np.float64)
        if array.ndim not in (1, 2) or array.shape[-1] != 3:
            raise SatsightError(f"{name} must have shape (3,) or (N, 3); got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise SatsightError(f"{name} must be finite; got {array!r}")
        arrays.append(array)
    roll = np.asarray(roll_rad, dtype=np.float64)
    if roll.ndim > 1 or not np.all(np.isfinite(roll)):
        raise SatsightError(f"roll_rad must be a finite scalar or (N,) array; got {roll!r}")
    single = all(a.ndim == 1 for a in arrays) and roll.ndim == 0
    try:
        eye, target, ref, roll_col = np.broadcast_arrays(
            *(np.atleast_2d(a) for a in arrays), roll.reshape(-1, 1)
        )
    except ValueError:
        shapes = ", ".join(str(np.shape(a)) for a in (*arrays, roll))
        raise SatsightError(
            f"cannot pair these stacks ({shapes}): give one row, or the same N rows, for each"
        ) from None
    roll_col = roll_col[:, :1]
    line_of_sight = target - eye
    distance = np.linalg.norm(line_of_sight, axis=-1, keepdims=True)
    if np.any(distance == 0.0):
        raise SatsightError(
            "the camera position coincides with the point it should look at; place the "
            "camera at a non-zero distance from the target"
        )
    z = line_of_sight / distance
    ref_norm = np.linalg.norm(ref, axis=-1, keepdims=True)
    ref = ref / np.where(ref_norm > 0.0, ref_norm, 1.0)  # a zero reference takes the fallback
    projected = ref - np.sum(ref * z, axis=-1, keepdims=True) * z
    for fallback in LOOK_AT_FALLBACKS:
        degenerate = np.linalg.norm(projected, axis=-1, keepdims=True) <= LOOK_AT_PARALLEL_SINE
        if not np.any(degenerate):
            break
        fallback_projected = fallback - np.sum(fallback * z, axis=-1, keepdims=True) * z
        projected = np.where(degenerate, fallback_projected, projected)
    # Near the boresight the projection keeps a rounding error along z of relative size
    # eps / sin(angle): a second pass removes it, so the axes are orthonormal to ~1e-16.
    projected = projected - np.sum(projected * z, axis=-1, keepdims=True) * z
    p = projected / np.linalg.norm(projected, axis=-1, keepdims=True)
    if reference_axis in ("x", "-x"):
        x = p if reference_axis == "x" else -p
        y = np.cross(z, x)
    else:
        y = p if reference_axis == "y" else -p
        x = np.cross(y, z)
    cos_roll, sin_roll = np.cos(roll_col), np.sin(roll_col)
    x, y = cos_roll * x + sin_roll * y, -sin_roll * x + cos_roll * y
    R = np.stack([x, y, z], axis=-1)
    return R[0] if single else R
