"""Argument handling and small vector helpers shared by the visibility geometry modules.

:mod:`satsight.ephemeris.occultation`, :mod:`satsight.ephemeris.shadow` and
:mod:`satsight.ephemeris.visibility` take GCRS vectors in metres of shape (3,) or (N, 3)
(components on the last axis, float64), a (3,) argument broadcast against (N, 3) ones, and
optionally the Earth's orientation ``R_itrs_from_gcrs`` as one rotation (3, 3) or one per
row (N, 3, 3), with ``x_itrs = R_itrs_from_gcrs @ x_gcrs``. They return a Python scalar
when every argument is a single vector (and a single rotation), else an (N,) array.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from satsight.errors import SatsightError
from satsight.vectors import norm

# How far R @ R.T may be from the identity (and det R from 1) for R_itrs_from_gcrs to count
# as a rotation: loose enough for matrices stored in float32, tight enough to catch a
# transposed stack of skyfield's (3, 3, N) layout or a matrix in the wrong units.
ROTATION_TOLERANCE = 1e-6


def stack(
    R_itrs_from_gcrs: ArrayLike | None = None, **vectors: ArrayLike
) -> tuple[list[np.ndarray], np.ndarray | None, bool]:
    """The named vectors as (N, 3) float64 arrays with a common N, the rotations as
    (N, 3, 3) (or None), and whether every input was a single (3,) vector / (3, 3) matrix.

    Each vector must be (3,) or (N, 3) and finite; (3,) ones are broadcast to the common N.
    R_itrs_from_gcrs, if given, must be (3, 3) or (N, 3, 3) proper rotations; a stack also
    sets N.
    """
    arrays: list[np.ndarray] = []
    n: int | None = None
    n_from = ""

    def claim(rows: int, name: str) -> None:
        nonlocal n, n_from
        if n is None:
            n, n_from = rows, name
        elif rows != n:
            raise SatsightError(
                f"{n_from} has {n} rows but {name} has {rows}: give stacks of the same "
                "length N, or a single (3,) vector / (3, 3) rotation to use at every row"
            )

    for name, value in vectors.items():
        array = np.asarray(value, dtype=np.float64)
        if array.ndim not in (1, 2) or array.shape[-1] != 3:
            raise SatsightError(
                f"{name} must be a GCRS vector in metres of shape (3,) or a stack (N, 3); "
                f"got shape {array.shape}"
            )
        if not np.all(np.isfinite(array)):
            raise SatsightError(f"{name} must be finite; got non-finite values in {name}")
        if array.ndim == 2:
            claim(array.shape[0], name)
        arrays.append(array)
    rotation = None
    if R_itrs_from_gcrs is not None:
        rotation = _check_rotations(R_itrs_from_gcrs)
        if rotation.ndim == 3:
            claim(rotation.shape[0], "R_itrs_from_gcrs")
    single = n is None
    rows = 1 if n is None else n
    stacked = [np.broadcast_to(np.atleast_2d(a), (rows, 3)) for a in arrays]
    if rotation is not None:
        rotation = np.broadcast_to(rotation.reshape(-1, 3, 3), (rows, 3, 3))
    return stacked, rotation, single


def _check_rotations(value: ArrayLike) -> np.ndarray:
    R = np.asarray(value, dtype=np.float64)
    if R.ndim not in (2, 3) or R.shape[-2:] != (3, 3):
        raise SatsightError(
            "R_itrs_from_gcrs must be a rotation matrix (3, 3) or a stack (N, 3, 3) "
            f"(x_itrs = R @ x_gcrs); got shape {R.shape}. skyfield's "
            "itrs.rotation_at(t) for N instants is (3, 3, N): pass np.moveaxis(R, -1, 0)"
        )
    if not np.all(np.isfinite(R)):
        raise SatsightError("R_itrs_from_gcrs must be finite")
    gram = np.einsum("...ij,...kj->...ik", R, R)
    off = float(np.max(np.abs(gram - np.eye(3))))
    det = np.linalg.det(R)
    if off > ROTATION_TOLERANCE or float(np.max(np.abs(det - 1.0))) > ROTATION_TOLERANCE:
        raise SatsightError(
            "R_itrs_from_gcrs must be proper rotations (R @ R.T = I, det R = +1); got "
            f"|R @ R.T - I| up to {off:.3g} and det R in [{float(np.min(det)):.6g}, "
            f"{float(np.max(det)):.6g}]. For N instants give (N, 3, 3), not skyfield's "
            "(3, 3, N) layout"
        )
    return R


def rotate(R: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """R (N, 3, 3) applied to the rows of vectors (N, 3)."""
    return np.einsum("nij,nj->ni", R, vectors)


def finish(values: np.ndarray, single: bool) -> float | bool | np.ndarray:
    """values (N,) as they are, or their one element as a Python scalar when single."""
    if single:
        return values[0].item()
    return values


def positive_length(value: float, name: str) -> float:
    """value as a float, or SatsightError unless it is a finite length > 0 m."""
    length = float(value)
    if not (math.isfinite(length) and length > 0.0):
        raise SatsightError(f"{name} must be a finite length > 0 m; got {value}")
    return length


def require_nonzero(v: np.ndarray, what: str) -> None:
    """SatsightError if any row of v (N, 3) is the zero vector (an undefined direction)."""
    if np.any(norm(v) == 0.0):
        raise SatsightError(
            f"{what} is the zero vector in some row, so the angle is undefined; give distinct "
            "positions"
        )
