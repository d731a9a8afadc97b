"""Real spherical harmonics (SH): evaluation, projection, zonal convolution and rotation.

A function on the unit sphere of directions (a radiance ``L(w)`` in W m^-2 sr^-1, an
irradiance ``E(n)`` in W m^-2, ...) is written ``f(w) = sum_k c_k Y_k(w)`` with real,
orthonormal SH ``Y_k`` (``integral Y_k Y_k' dw = delta_kk'`` over 4 pi sr), so a coefficient
has the unit of ``f`` times sr^(1/2) and Parseval holds: ``integral f^2 dw = sum_k c_k^2``.

Indexing: degree ``l >= 0``, order ``-l <= m <= l``, flat index ``k = l (l + 1) + m``; a
degree-``l_max`` expansion has ``(l_max + 1)^2`` coefficients (25 for ``l_max = 4``).

Directions: unit 3-vectors ``w = (x, y, z)`` on the last array axis, in whatever frame the
caller works in, with polar angle ``theta`` from +z and azimuth ``phi`` from +x towards +y:
``x = sin(theta) cos(phi)``, ``y = sin(theta) sin(phi)``, ``z = cos(theta)``.

Phase convention (no Condon-Shortley phase in the real basis, as in Ramamoorthi & Hanrahan
2001 and Sloan 2008). With ``N_lm = sqrt((2l + 1)/(4 pi) (l - m)!/(l + m)!)`` and ``P_l^m``
the associated Legendre function *without* the ``(-1)^m`` factor::

    Y_{l,0}  = N_l0 P_l(cos theta)
    Y_{l,m}  = sqrt(2) N_lm P_l^m(cos theta) cos(m phi)        (m > 0)
    Y_{l,-m} = sqrt(2) N_lm P_l^m(cos theta) sin(m phi)        (m > 0)

so ``Y_{1,-1}, Y_{1,0}, Y_{1,1} = sqrt(3/(4 pi)) (y, z, x)``. In terms of the complex SH
``Y_l^m`` *with* the Condon-Shortley phase (SciPy's ``scipy.special.sph_harm_y``), for
``m > 0``: ``Y_{l,m} = sqrt(2) (-1)^m Re Y_l^m`` and ``Y_{l,-m} = sqrt(2) (-1)^m Im Y_l^m``.

Evaluation uses the Cartesian form ``sin^m(theta) (cos m phi + i sin m phi) = (x + i y)^m``
and the fully normalised three-term recurrence in ``z`` for ``N_lm P_l^m / sin^m theta``
(Holmes & Featherstone 2002, J. Geodesy 76, 279-299): no trigonometric functions, stable to
high degree, and the same arithmetic runs in NumPy (float64) and Dr.Jit (``sh_eval_dr``).

Zonal convolution follows the Funk-Hecke theorem: for a kernel ``h(n . w)``,
``integral h(n . w) Y_lm(w) dw = lambda_l Y_lm(n)`` with
``lambda_l = 2 pi integral_{-1}^{1} h(t) P_l(t) dt``. For the clamped cosine ``max(t, 0)``
these are the ``A_l`` of Ramamoorthi & Hanrahan 2001 ("An efficient representation for
irradiance environment maps", SIGGRAPH), so the irradiance on a surface of normal ``n`` is
``E(n) = sum_lm A_l L_lm Y_lm(n)`` for a radiance ``L(w) = sum_lm L_lm Y_lm(w)``.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from satsight.errors import SatsightError

DEFAULT_L_MAX = 4
_Y00 = 0.5 / math.sqrt(math.pi)  # Y_00 = 1 / sqrt(4 pi)
_SQRT2 = math.sqrt(2.0)
_EVAL_CHUNK = 32768  # directions per block in sh_eval (keeps temporaries in cache)
_ORTHOGONAL_ATOL = 1e-9


# --------------------------------------------------------------------------- indexing


def _check_l_max(l_max: Any) -> int:
    try:
        value = operator.index(l_max)
    except TypeError:
        raise SatsightError(f"l_max must be an integer >= 0, got {l_max!r}") from None
    if value < 0:
        raise SatsightError(f"l_max must be an integer >= 0, got {value}")
    return value


def sh_count(l_max: int) -> int:
    """Number of real SH coefficients up to degree ``l_max``: ``(l_max + 1)^2``."""
    l_max = _check_l_max(l_max)
    return (l_max + 1) ** 2


def sh_index(l: int, m: int) -> int:
    """Flat index ``k = l (l + 1) + m`` of the real SH of degree ``l`` and order ``m``."""
    l = _check_l_max(l)
    m = operator.index(m)
    if abs(m) > l:
        raise SatsightError(f"SH order must satisfy |m| <= l, got l={l}, m={m}")
    return l * (l + 1) + m


def sh_l_max(n_coeffs: int) -> int:
    """Degree ``l_max`` of an expansion with ``n_coeffs = (l_max + 1)^2`` coefficients."""
    n = operator.index(n_coeffs)
    root = math.isqrt(max(n, 0))
    if n < 1 or root * root != n:
        raise SatsightError(
            f"an SH expansion has (l_max + 1)^2 coefficients (1, 4, 9, 16, 25, ...), got {n}"
        )
    return root - 1


def sh_degrees(l_max: int) -> np.ndarray:
    """Degree ``l`` of each flat index ``k``: shape (sh_count(l_max),), int."""
    l_max = _check_l_max(l_max)
    return np.repeat(np.arange(l_max + 1), 2 * np.arange(l_max + 1) + 1)


# --------------------------------------------------------------------------- evaluation


@cache
def _recurrence_constants(l_max: int) -> tuple[tuple[float, ...], dict[tuple[int, int], tuple]]:
    """``Pbar_mm`` and the (a_lm, b_lm) of ``Pbar_lm = a_lm (z Pbar_l-1,m - b_lm Pbar_l-2,m)``.

    ``Pbar_lm = N_lm P_l^m(z) / sin^m(theta)`` is a polynomial in ``z``; ``Pbar_mm`` is a
    constant, ``Pbar_00 = 1/sqrt(4 pi)`` and ``Pbar_mm = Pbar_m-1,m-1 sqrt((2m + 1)/(2m))``.
    """
    diag = [_Y00]
    for m in range(1, l_max + 1):
        diag.append(diag[-1] * math.sqrt((2.0 * m + 1.0) / (2.0 * m)))
    ab: dict[tuple[int, int], tuple[float, float]] = {}
    for m in range(l_max + 1):
        for l in range(m + 1, l_max + 1):
            a = math.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = math.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            ab[(l, m)] = (a, b)
    return tuple(diag), ab


def _sh_terms(x: Any, y: Any, z: Any, l_max: int) -> list:
    """Real SH ``Y_k(x, y, z)`` for unit ``(x, y, z)``, as a list indexed by ``k``.

    Uses only ``+``, ``-`` and ``*`` on the inputs, so it runs on NumPy arrays and on Dr.Jit
    arrays alike.
    """
    diag, ab = _recurrence_constants(l_max)
    terms: list = [None] * ((l_max + 1) ** 2)
    zero = x * 0.0
    cos_m = zero + 1.0  # Re (x + i y)^m = sin^m(theta) cos(m phi)
    sin_m = zero  # Im (x + i y)^m = sin^m(theta) sin(m phi)
    for m in range(l_max + 1):
        if m > 0:
            cos_m, sin_m = x * cos_m - y * sin_m, x * sin_m + y * cos_m
            re, im = cos_m * _SQRT2, sin_m * _SQRT2
        else:
            re, im = cos_m, None
        p_prev2 = None
        p_prev = diag[m]  # Pbar_mm (a constant)
        for l in range(m, l_max + 1):
            if l == m + 1:
                p = z * (ab[(l, m)][0] * diag[m])
            elif l > m + 1:
                a, b = ab[(l, m)]
                p = (z * p_prev - p_prev2 * b) * a
            else:
                p = p_prev
            if l > m:
                p_prev2, p_prev = p_prev, p
            base = l * (l + 1)
            terms[base + m] = re * p
            if im is not None:
                terms[base - m] = im * p
    return terms


def _unit_directions(directions: Any, name: str = "directions") -> np.ndarray:
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim == 0 or d.shape[-1] != 3:
        raise SatsightError(f"{name} must have shape (..., 3), got {d.shape}")
    norm = np.sqrt(np.einsum("...i,...i->...", d, d))
    if not np.all(np.isfinite(norm) & (norm > 0.0)):
        raise SatsightError(f"{name} must be finite, non-zero 3-vectors")
    return d / norm[..., None]


def sh_eval(directions: Any, l_max: int = DEFAULT_L_MAX) -> np.ndarray:
    """Real orthonormal SH ``Y_k(w)`` at the given directions.

    directions: (..., 3) direction vectors in any frame (normalised here; unitless).
    Returns (..., sh_count(l_max)) float64 values in sr^(-1/2), index ``k = l (l + 1) + m``,
    with the phase convention of the module docstring.
    """
    l_max = _check_l_max(l_max)
    d = _unit_directions(directions)
    batch = d.shape[:-1]
    flat = d.reshape(-1, 3)
    n = sh_count(l_max)
    out = np.empty((flat.shape[0], n), dtype=np.float64)
    for start in range(0, flat.shape[0], _EVAL_CHUNK):
        block = flat[start : start + _EVAL_CHUNK]
        terms = _sh_terms(block[:, 0], block[:, 1], block[:, 2], l_max)
        np.stack(terms, axis=-1, out=out[start : start + block.shape[0]])
    return out.reshape(*batch, n)


def sh_eval_dr(direction: Any, l_max: int = DEFAULT_L_MAX) -> list:
    """Real orthonormal SH ``Y_k(w)`` in Dr.Jit, for use inside Mitsuba/Dr.Jit kernels.

    direction: a Dr.Jit 3-vector (``mitsuba.Vector3f`` of any variant, ``drjit.llvm.ad.Array3f``,
    ``drjit.cuda.ad.Array3f``, ...), normalised here.
    Returns a Python list of ``sh_count(l_max)`` Dr.Jit Float arrays (sr^(-1/2)), index
    ``k = l (l + 1) + m``, same convention as ``sh_eval`` (computed in the array's precision).
    """
    import drjit as dr

    l_max = _check_l_max(l_max)
    d = dr.normalize(direction)
    return _sh_terms(d.x, d.y, d.z, l_max)


def delta_coeffs(direction: Any, l_max: int = DEFAULT_L_MAX) -> np.ndarray:
    """SH coefficients of a Dirac delta on the sphere at ``direction``: ``c_k = Y_k(direction)``.

    direction: (3,) (or (..., 3)) direction, normalised here. Returns (sh_count,) (or
    (..., sh_count)) in sr^(-1/2). A collimated source of irradiance ``E`` (W m^-2) arriving
    from direction ``s`` has radiance ``E delta(w - s)`` whose coefficients are ``E Y_k(s)``.
    """
    return sh_eval(direction, l_max)


def evaluate(coeffs: Any, directions: Any) -> np.ndarray:
    """Reconstruct ``f(w) = sum_k c_k Y_k(w)``.

    coeffs: (n,) or (n, C) with ``n = (l_max + 1)^2`` (unit of ``f`` times sr^(1/2)).
    directions: (..., 3), normalised here. Returns (...) or (..., C) in the unit of ``f``.
    """
    c = _as_coeffs(coeffs)
    return sh_eval(directions, sh_l_max(c.shape[0])) @ c


def _as_coeffs(coeffs: Any) -> np.ndarray:
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim not in (1, 2):
        raise SatsightError(f"SH coefficients must have shape (n,) or (n, C), got {c.shape}")
    sh_l_max(c.shape[0])
    return c


# --------------------------------------------------------------------------- quadrature


@cache
def _sphere_quadrature(n_theta: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    mu, w_mu = np.polynomial.legendre.leggauss(n_theta)
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    sin_theta = np.sqrt(np.clip(1.0 - mu * mu, 0.0, None))
    directions = np.stack(
        [
            np.outer(sin_theta, np.cos(phi)),
            np.outer(sin_theta, np.sin(phi)),
            np.repeat(mu[:, None], n_phi, axis=1),
        ],
        axis=-1,
    ).reshape(-1, 3)
    weights = np.repeat(w_mu * (2.0 * np.pi / n_phi), n_phi)
    directions.setflags(write=False)
    weights.setflags(write=False)
    return directions, weights


def sphere_quadrature(n_theta: int, n_phi: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Product quadrature on the unit sphere: Gauss-Legendre in ``cos(theta)``, uniform in ``phi``.

    ``n_theta`` Gauss-Legendre nodes in ``z = cos(theta)`` on [-1, 1] times ``n_phi`` equally
    spaced azimuths (default ``2 n_theta``). Integrates every polynomial in (x, y, z) of degree
    ``<= 2 n_theta - 1`` exactly (to rounding) when ``n_phi >= 2 n_theta``.
    Returns directions (N, 3), unit vectors, and weights (N,) in sr summing to 4 pi
    (``N = n_theta n_phi``; read-only arrays).
    """
    n_theta = operator.index(n_theta)
    n_phi = 2 * n_theta if n_phi is None else operator.index(n_phi)
    if n_theta < 1 or n_phi < 1:
        raise SatsightError(f"quadrature needs n_theta, n_phi >= 1, got {n_theta}, {n_phi}")
    return _sphere_quadrature(n_theta, n_phi)


def quadrature_for(l_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Smallest ``sphere_quadrature`` exact for products of two degree-``l_max`` expansions.

    ``n_theta = l_max + 1``, ``n_phi = 2 l_max + 2``: exact for polynomials of degree
    ``2 l_max + 1``, hence Gram matrices, projections of functions band-limited to ``l_max``
    and rotations of degree-``l_max`` expansions are exact. Returns directions (N, 3) and
    weights (N,) in sr.
    """
    l_max = _check_l_max(l_max)
    return sphere_quadrature(l_max + 1, 2 * l_max + 2)


def project_samples(
    directions: Any, values: Any, weights: Any, l_max: int = DEFAULT_L_MAX
) -> np.ndarray:
    """SH coefficients ``c_k = sum_i w_i f(w_i) Y_k(w_i)`` from explicit quadrature nodes.

    directions: (N, 3) nodes (normalised here); values: (N,) or (N, C) samples of ``f``;
    weights: (N,) quadrature weights in sr (they need not cover the whole sphere, e.g. a
    quadrature over a cone for a function that vanishes outside it).
    Returns (sh_count,) or (sh_count, C) coefficients (unit of ``f`` times sr^(1/2)).
    """
    d = _unit_directions(directions)
    v = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if d.ndim != 2 or w.shape != d.shape[:1] or v.ndim not in (1, 2) or v.shape[0] != w.shape[0]:
        raise SatsightError(
            "project_samples needs directions (N, 3), values (N,) or (N, C) and weights (N,), "
            f"got {d.shape}, {v.shape}, {w.shape}"
        )
    weighted = v * w if v.ndim == 1 else v * w[:, None]
    # Y as (sh_count, N) rows, each term written whole (sh_eval's (N, sh_count) layout
    # would scatter them column by column): 2x faster on the 32768 nodes of a body.
    out = np.empty((sh_count(l_max), d.shape[0]), dtype=np.float64)
    for start in range(0, d.shape[0], _EVAL_CHUNK):
        block = d[start : start + _EVAL_CHUNK]
        terms = _sh_terms(block[:, 0], block[:, 1], block[:, 2], _check_l_max(l_max))
        np.stack(terms, axis=0, out=out[:, start : start + block.shape[0]])
    return out @ weighted


def project(
    func: Callable[[np.ndarray], Any],
    l_max: int = DEFAULT_L_MAX,
    n_theta: int | None = None,
    n_phi: int | None = None,
) -> np.ndarray:
    """SH coefficients of ``f`` up to degree ``l_max`` by quadrature over the whole sphere.

    func: maps unit directions (N, 3) to values (N,) or (N, C).
    n_theta, n_phi: ``sphere_quadrature`` size, default ``n_theta = 2 l_max + 16`` (exact for
    ``f`` band-limited to degree ``3 l_max + 31``; smooth functions converge quickly, functions
    with kinks or edges only algebraically) and ``n_phi = 2 n_theta``.
    Returns (sh_count,) or (sh_count, C) coefficients (unit of ``f`` times sr^(1/2)).
    """
    l_max = _check_l_max(l_max)
    n_theta = 2 * l_max + 16 if n_theta is None else n_theta
    directions, weights = sphere_quadrature(n_theta, n_phi)
    values = np.asarray(func(np.array(directions)), dtype=np.float64)
    return project_samples(directions, values, weights, l_max)


# --------------------------------------------------------------------------- zonal kernels


def _legendre_table(t: np.ndarray, l_max: int) -> np.ndarray:
    """Legendre polynomials ``P_l(t)`` for l = 0..l_max: shape (l_max + 1, len(t))."""
    p = np.empty((l_max + 1, t.shape[0]), dtype=np.float64)
    p[0] = 1.0
    if l_max >= 1:
        p[1] = t
    for l in range(2, l_max + 1):
        p[l] = ((2 * l - 1) * t * p[l - 1] - (l - 1) * p[l - 2]) / l
    return p


def zonal_kernel_coeffs(
    kernel: Callable[[np.ndarray], Any], l_max: int = DEFAULT_L_MAX, n_nodes: int | None = None
) -> np.ndarray:
    """Funk-Hecke factors ``lambda_l = 2 pi integral_{-1}^{1} h(t) P_l(t) dt`` of a zonal kernel.

    kernel: ``h(t)`` as a function of ``t = cos(angle)`` between the kernel axis and the
    direction, vectorised over a 1-D array (a constant return value is broadcast).
    The integral is split at ``t = 0`` and each half uses ``n_nodes`` Gauss-Legendre nodes
    (default ``l_max + 64``), so kernels that are polynomials on each half (``max(t, 0)^p``)
    are integrated exactly up to ``p + l_max <= 2 n_nodes - 1``.
    Returns (l_max + 1,) factors (unit of ``h`` times sr): convolving ``f`` with ``h``,
    ``g(n) = integral h(n . w) f(w) dw``, multiplies band ``l`` of ``f`` by ``lambda_l``
    (Funk-Hecke theorem).
    """
    l_max = _check_l_max(l_max)
    n_nodes = l_max + 64 if n_nodes is None else operator.index(n_nodes)
    if n_nodes < 1:
        raise SatsightError(f"n_nodes must be >= 1, got {n_nodes}")
    u, w = np.polynomial.legendre.leggauss(n_nodes)
    t = np.concatenate([0.5 * (u - 1.0), 0.5 * (u + 1.0)])  # [-1, 0] then [0, 1]
    weights = np.concatenate([0.5 * w, 0.5 * w])
    h = np.broadcast_to(np.asarray(kernel(t), dtype=np.float64), t.shape)
    return 2.0 * np.pi * (_legendre_table(t, l_max) @ (weights * h))


def clamped_cosine_coeffs(l_max: int = DEFAULT_L_MAX) -> np.ndarray:
    """Funk-Hecke factors ``A_l`` of the clamped cosine ``max(cos, 0)``, in sr.

    Closed form of Ramamoorthi & Hanrahan 2001 (Eq. 8, their ``A-hat_l``): ``A_0 = pi``,
    ``A_1 = 2 pi / 3``, ``A_l = 0`` for odd ``l > 1`` and, for even ``l``,
    ``A_l = 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2)``
    (``pi/4``, ``-pi/24``, ``pi/64``, ...). Returns (l_max + 1,).
    """
    l_max = _check_l_max(l_max)
    a = np.zeros(l_max + 1)
    a[0] = np.pi
    if l_max >= 1:
        a[1] = 2.0 * np.pi / 3.0
    for l in range(2, l_max + 1, 2):
        sign = -1.0 if (l // 2 - 1) % 2 else 1.0
        a[l] = 2.0 * np.pi * sign / ((l + 2) * (l - 1)) * (math.comb(l, l // 2) / 2**l)
    return a


def convolve(coeffs: Any, kernel_coeffs: Any) -> np.ndarray:
    """Zonal convolution: multiply every band ``l`` of ``coeffs`` by ``kernel_coeffs[l]``.

    coeffs: (n,) or (n, C) SH coefficients of ``f``; kernel_coeffs: (>= l_max + 1,) Funk-Hecke
    factors ``lambda_l`` (``zonal_kernel_coeffs``, ``clamped_cosine_coeffs``). Returns the
    coefficients of ``g(n) = integral h(n . w) f(w) dw``, same shape as ``coeffs``.
    """
    c = _as_coeffs(coeffs)
    l_max = sh_l_max(c.shape[0])
    lam = np.asarray(kernel_coeffs, dtype=np.float64)
    if lam.ndim != 1 or lam.shape[0] < l_max + 1:
        raise SatsightError(
            f"kernel_coeffs must have shape (>= {l_max + 1},) for l_max={l_max}, got {lam.shape}"
        )
    factor = lam[sh_degrees(l_max)]
    return c * factor if c.ndim == 1 else c * factor[:, None]


def irradiance_coeffs(radiance_coeffs: Any) -> np.ndarray:
    """SH coefficients of the irradiance ``E(n) = integral L(w) max(n . w, 0) dw``.

    radiance_coeffs: (n,) or (n, C) coefficients of the radiance ``L(w)`` (``w`` towards the
    source) in W m^-2 sr^-1 sr^(1/2). Returns the coefficients of ``E(n)`` in W m^-2 sr^(1/2),
    ``E_lm = A_l L_lm`` (Ramamoorthi & Hanrahan 2001).
    """
    c = _as_coeffs(radiance_coeffs)
    return convolve(c, clamped_cosine_coeffs(sh_l_max(c.shape[0])))


# --------------------------------------------------------------------------- rotation


def rotation_matrix(rotation: Any, l_max: int = DEFAULT_L_MAX) -> np.ndarray:
    """Block-diagonal SH rotation matrix for a 3x3 rotation ``R_b_from_a``.

    If ``f`` has coefficients ``c`` in frame a (``f(w_a) = sum_k c_k Y_k(w_a)``), the same
    function written in frame b, ``g(w_b) = f(R^T w_b)``, has coefficients ``M @ c``.
    Each band is built by projecting the rotated basis functions with ``quadrature_for``,
    which is exact for degree-``l_max`` expansions, so every block is orthogonal to rounding.
    rotation: (3, 3) orthogonal matrix. Returns (sh_count, sh_count) float64.
    """
    l_max = _check_l_max(l_max)
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.allclose(r.T @ r, np.eye(3), rtol=0.0, atol=_ORTHOGONAL_ATOL):
        raise SatsightError(f"rotation must be an orthogonal 3x3 matrix, got {r!r}")
    directions, weights = quadrature_for(l_max)
    y_b = sh_eval(directions, l_max)
    y_rotated = sh_eval(directions @ r, l_max)  # rows: Y_k(R^T w_b)
    n = sh_count(l_max)
    m = np.zeros((n, n))
    for l in range(l_max + 1):
        band = slice(l * l, (l + 1) ** 2)
        m[band, band] = y_b[:, band].T @ (weights[:, None] * y_rotated[:, band])
    return m


def rotate(coeffs: Any, rotation: Any) -> np.ndarray:
    """Coefficients in frame b of a function given by ``coeffs`` in frame a.

    coeffs: (n,) or (n, C); rotation: (3, 3) ``R_b_from_a``. Returns the same shape:
    ``rotation_matrix(R, l_max) @ coeffs``.
    """
    c = _as_coeffs(coeffs)
    return rotation_matrix(rotation, sh_l_max(c.shape[0])) @ c
