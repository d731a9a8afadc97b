"""Goodness-of-fit tests and quadratures for the BRDF sampler and energy tests.

Directions are unit vectors in the local shading frame (normal +z). The statistics and
quadratures are numpy float64; the adapters at the end wrap the Dr.Jit functions of
``satsight.render`` (``*_eval(wi, wo, params)``, ``*_sample(wo, u_lobe, u2, params)``,
``*_pdf(wi, wo, params)``) into numpy callables and need a Mitsuba variant to be set.

chi2_direction_test: sampled directions are binned over the upper hemisphere on a grid
uniform in (cos theta, phi), so every cell has the solid angle d(cos theta) d(phi). The
expected count of a cell is n times the integral of the pdf over it (Gauss-Legendre
sub-grid); directions that the sampler marks invalid (below the horizon) go to one more
cell whose expected count is n (1 - integral of the pdf over the hemisphere). Cells with an
expected count below 5 are pooled (the usual condition for Pearson's statistic to follow
the chi-square law) and the p-value comes from scipy.stats.chi2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

MIN_EXPECTED_COUNT = 5.0


@dataclass(frozen=True)
class Chi2Result:
    """Pearson statistic, degrees of freedom and p-value of a sampler against its pdf."""

    statistic: float
    dof: int
    p_value: float
    pdf_integral: float  # integral of the pdf over the upper hemisphere
    valid_fraction: float  # fraction of samples marked valid

    def __str__(self) -> str:
        return (
            f"chi2 = {self.statistic:.1f} with {self.dof} dof, p = {self.p_value:.3g}; "
            f"pdf integral {self.pdf_integral:.5f}, valid samples {self.valid_fraction:.5f}"
        )


def _gauss_legendre_01(n: int):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def hemisphere_cell_quadrature(n_cos: int = 20, n_phi: int = 40, sub: int = 8):
    """Directions, weights (sr) and cell index of a sub x sub Gauss-Legendre rule in each
    cell of the (cos theta, phi) grid over the upper hemisphere."""
    x, w = _gauss_legendre_01(sub)
    i_cos, i_phi, k_cos, k_phi = np.meshgrid(
        np.arange(n_cos), np.arange(n_phi), np.arange(sub), np.arange(sub), indexing="ij"
    )
    d_cos, d_phi = 1.0 / n_cos, 2.0 * math.pi / n_phi
    cos_t = (i_cos + x[k_cos]) * d_cos
    phi = (i_phi + x[k_phi]) * d_phi
    sin_t = np.sqrt(np.maximum(1.0 - cos_t**2, 0.0))
    dirs = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1).reshape(-1, 3)
    weights = (w[k_cos] * w[k_phi] * d_cos * d_phi).reshape(-1)
    cell = (i_cos * n_phi + i_phi).reshape(-1)
    return dirs, weights, cell


def bin_directions(dirs: np.ndarray, n_cos: int = 20, n_phi: int = 40) -> np.ndarray:
    """Counts of directions (upper hemisphere) per (cos theta, phi) cell, flat array."""
    i_cos = np.clip((dirs[:, 2] * n_cos).astype(np.int64), 0, n_cos - 1)
    phi = np.mod(np.arctan2(dirs[:, 1], dirs[:, 0]), 2.0 * math.pi)
    i_phi = np.clip((phi / (2.0 * math.pi) * n_phi).astype(np.int64), 0, n_phi - 1)
    return np.bincount(i_cos * n_phi + i_phi, minlength=n_cos * n_phi).astype(np.float64)


def _pooled(observed: np.ndarray, expected: np.ndarray):
    """Merge the cells of smallest expected count until the merged cell reaches 5."""
    order = np.argsort(expected)
    cumulative = np.cumsum(expected[order])
    small = int(np.count_nonzero(expected < MIN_EXPECTED_COUNT))
    if small == 0:
        return observed, expected
    k = max(small, int(np.searchsorted(cumulative, MIN_EXPECTED_COUNT)) + 1)
    k = min(k, expected.size)
    pool, rest = order[:k], order[k:]
    return (
        np.append(observed[rest], observed[pool].sum()),
        np.append(expected[rest], expected[pool].sum()),
    )


def chi2_direction_test(
    samples: np.ndarray,
    valid: np.ndarray,
    pdf: Callable[[np.ndarray], np.ndarray],
    n_cos: int = 20,
    n_phi: int = 40,
    sub: int = 8,
) -> Chi2Result:
    """Pearson chi-square test of sampled directions against a density in solid angle.

    samples: (n, 3) directions; valid: (n,) bool, False for samples the sampler rejected
    (below the horizon); pdf: callable (m, 3) -> (m,) density in sr^-1 over the upper
    hemisphere (0 where the sampler never goes).
    """
    n = samples.shape[0]
    observed = np.append(bin_directions(samples[valid], n_cos, n_phi), np.count_nonzero(~valid))
    dirs, weights, cell = hemisphere_cell_quadrature(n_cos, n_phi, sub)
    probability = np.bincount(cell, weights=pdf(dirs) * weights, minlength=n_cos * n_phi)
    integral = float(probability.sum())
    expected = n * np.append(probability, max(1.0 - integral, 0.0))
    obs, exp = _pooled(observed, expected)
    statistic = float(np.sum((obs - exp) ** 2 / np.maximum(exp, 1e-300)))
    dof = obs.size - 1
    return Chi2Result(
        statistic=statistic,
        dof=dof,
        p_value=float(stats.chi2.sf(statistic, dof)),
        pdf_integral=integral,
        valid_fraction=float(np.count_nonzero(valid)) / n,
    )


def hemisphere_integral(
    f: Callable[[np.ndarray], np.ndarray], n_cos: int = 40, n_phi: int = 80, sub: int = 8
) -> float:
    """Integral over the upper hemisphere of a smooth f(dirs) (m, 3) -> (m,), in sr."""
    dirs, weights, _ = hemisphere_cell_quadrature(n_cos, n_phi, sub)
    return float(np.dot(f(dirs), weights))


def hemisphere_quadrature_around(
    axis: np.ndarray, width_rad: float, n_phi: int = 96, nodes: int = 16
) -> tuple[np.ndarray, np.ndarray]:
    """Directions and weights (sr) of a rule over the upper hemisphere centred on ``axis``.

    In the angle beta to the axis: Gauss-Legendre on segments [0, w/4], [w/4, w/2], ...
    doubling up to pi, so that a lobe of angular width w = ``width_rad`` around the axis and
    its tails are resolved whatever w. On each cone of half-angle beta around the axis the
    height is z = A + B cos(phi) (phi measured from the upward tangent, A = cos(beta) a_z,
    B = sin(beta) sqrt(1 - a_z^2)), so the part above the horizon is |phi| < phi0 =
    arccos(-A / B); the azimuth rule is Gauss-Legendre on exactly that arc. The horizon
    thus cuts no cell, and integrands that vanish there (f cos(theta)) stay smooth.
    """
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    horizontal = math.hypot(a[0], a[1])
    if horizontal > 1e-12:
        t1 = np.array([-a[0] * a[2], -a[1] * a[2], horizontal**2]) / horizontal  # upward
    else:
        t1 = np.array([1.0, 0.0, 0.0])
    t2 = np.cross(a, t1)
    elevation = math.asin(np.clip(a[2], -1.0, 1.0))
    edges = {0.0, math.pi}
    edge = 0.25 * min(width_rad, 1.0)
    while edge < math.pi:
        edges.add(edge)
        edge *= 2.0
    # The cone starts to cross the horizon at beta = elevation of the axis (A = B) and lies
    # below it from beta = pi - elevation (A = -B); pi / 2 separates the two kinks.
    kinks = (elevation, math.pi - elevation)
    for edge in (*kinks, 0.5 * math.pi):
        if 0.0 < edge < math.pi:
            edges.add(edge)
    edges = np.array(sorted(edges))
    x, w = _gauss_legendre_01(nodes)
    lo, hi = edges[:-1, None], edges[1:, None]
    # Next to the two kinks the arc length behaves like sqrt(|beta - kink|): there the nodes
    # are placed with beta = kink +- (length) s^2, which makes the integrand smooth in s.
    after = (lo == kinks[0]) & (lo > 0.0)
    before = (hi == kinks[1]) & (hi < math.pi)
    s_lo = np.where(after, x * x, np.where(before, 1.0 - (1.0 - x) ** 2, x))
    jac = np.where(after, 2.0 * x, np.where(before, 2.0 * (1.0 - x), 1.0))
    beta = (lo + (hi - lo) * s_lo).reshape(-1)
    w_beta = ((hi - lo) * w * jac).reshape(-1) * np.sin(beta)
    big_a = np.cos(beta) * a[2]
    big_b = np.sin(beta) * horizontal
    ratio = np.where(big_b > 0.0, -big_a / np.where(big_b > 0.0, big_b, 1.0), -np.sign(big_a))
    phi0 = np.arccos(np.clip(ratio, -1.0, 1.0))  # pi: whole cone above, 0: none
    xp, wp = _gauss_legendre_01(n_phi)
    phi = phi0[:, None] * (2.0 * xp - 1.0)
    weights = (w_beta * 2.0 * phi0)[:, None] * wp
    b = np.broadcast_to(beta[:, None], phi.shape)
    dirs = (
        np.cos(b)[..., None] * a
        + (np.sin(b) * np.cos(phi))[..., None] * t1
        + (np.sin(b) * np.sin(phi))[..., None] * t2
    ).reshape(-1, 3)
    keep = weights.reshape(-1) > 0.0
    return dirs[keep], weights.reshape(-1)[keep]


def direction(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    """Unit vector at polar angle theta and azimuth phi (degrees) in the local frame."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def mirror(v: np.ndarray) -> np.ndarray:
    """Mirror direction of v about the normal +z."""
    return np.array([-v[0], -v[1], v[2]])


# --- Dr.Jit adapters ---------------------------------------------------------------------------
def to_vector3f(dirs: np.ndarray):
    """(n, 3) numpy directions as an ``mi.Vector3f`` of the current variant."""
    import mitsuba as mi

    return mi.Vector3f(np.ascontiguousarray(np.asarray(dirs, dtype=np.float32).T))


def to_numpy(value) -> np.ndarray:
    """Dr.Jit array to float64 numpy: Color3f / Vector3f to (n, 3), Float to (n,)."""
    a = np.array(value, dtype=np.float64)
    return a.T if a.ndim == 2 else a


def sample_directions(sample_fn, params, w_fixed: np.ndarray, n: int, seed: int):
    """(directions (n, 3), densities (n,)) drawn by a sampler at one fixed direction."""
    import mitsuba as mi

    u = np.random.default_rng(seed).random((n, 3), dtype=np.float32)
    fixed = to_vector3f(np.broadcast_to(w_fixed, (n, 3)))
    d, pdf = sample_fn(fixed, mi.Float(u[:, 0]), mi.Point2f(u[:, 1], u[:, 2]), params)
    return to_numpy(d), to_numpy(pdf)


def check_sample_density_is_pdf(sample_fn, pdf_fn, params, wo: np.ndarray, seed: int) -> None:
    """For per-lane viewer directions wo (n, 3): sampled wi are unit vectors, the density a
    sampler returns equals pdf_fn at the same wi, and it is 0 exactly below the horizon."""
    import mitsuba as mi

    n = len(wo)
    u = np.random.default_rng(seed).random((n, 3), dtype=np.float32)
    wi, pdf = sample_fn(to_vector3f(wo), mi.Float(u[:, 0]), mi.Point2f(u[:, 1], u[:, 2]), params)
    wi, pdf = to_numpy(wi), to_numpy(pdf)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(
        pdf, to_numpy(pdf_fn(to_vector3f(wi), to_vector3f(wo), params)), rtol=1e-5
    )
    below = (wi[:, 2] <= 0.0) | (wo[:, 2] <= 0.0)
    assert np.all(pdf[below] == 0.0)
    assert np.all(pdf[~below] > 0.0)


def check_pdf_integral_is_valid_fraction(
    sample_fn, pdf_fn, params, wo: np.ndarray, lobe_width: float, seed: int, atol: float, **quad
) -> float:
    """The pdf integrated over the hemisphere (quadrature around the mirror direction of
    wo, of the given lobe width) is at most 1 and equals the fraction of samples that land
    above the horizon, within 5 binomial standard deviations plus ``atol``. Returns it."""
    dirs, weights = hemisphere_quadrature_around(mirror(wo), lobe_width, **quad)
    integral = float(np.dot(pdf_callable(pdf_fn, params, wo)(dirs), weights))
    n = 200_000
    _, pdf = sample_directions(sample_fn, params, wo, n, seed=seed)
    valid = np.count_nonzero(pdf > 0.0) / n
    sigma = math.sqrt(max(valid * (1.0 - valid), 1.0 / n) / n)
    assert integral <= 1.0 + 1e-4
    assert abs(integral - valid) <= 5.0 * sigma + atol, (integral, valid)
    return integral


def pdf_callable(pdf_fn, params, w_fixed: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """numpy callable dirs -> pdf_fn(dirs, w_fixed, params)."""

    def pdf(dirs: np.ndarray) -> np.ndarray:
        fixed = to_vector3f(np.broadcast_to(w_fixed, dirs.shape))
        return to_numpy(pdf_fn(to_vector3f(dirs), fixed, params))

    return pdf


def importance_sampled_albedo(
    sample_fn, eval_fn, params, w_fixed: np.ndarray, n: int, seed: int, fixed_is_light: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Directional albedo per channel by importance sampling, and its standard error.

    The mean of f cos(theta) / pdf over directions drawn by the model's sampler at the fixed
    direction; samples with pdf 0 (below the horizon) contribute 0. With fixed_is_light the
    fixed direction is wi and the integral runs over viewer directions (the energy balance
    of a non-reciprocal model); the sampler then serves as a proposal density, which is
    valid wherever it is positive where f is.
    """
    d, pdf = sample_directions(sample_fn, params, w_fixed, n, seed)
    fixed = to_vector3f(np.broadcast_to(w_fixed, (n, 3)))
    free = to_vector3f(d)
    f = to_numpy(eval_fn(fixed, free, params) if fixed_is_light else eval_fn(free, fixed, params))
    ok = pdf > 0.0
    weight = np.zeros_like(f)
    weight[ok] = f[ok] * (d[ok, 2] / pdf[ok])[:, None]
    return weight.mean(axis=0), weight.std(axis=0) / math.sqrt(n)


def quadrature_albedo(
    eval_fn, params, w_fixed: np.ndarray, width_rad: float, fixed_is_light: bool
) -> np.ndarray:
    """Directional albedo per channel with ``hemisphere_quadrature_around`` the mirror
    direction of the fixed one (float32 BRDF values at float32-rounded directions)."""
    dirs, weights = hemisphere_quadrature_around(mirror(w_fixed), width_rad)
    dirs32 = dirs.astype(np.float32).astype(np.float64)
    fixed = to_vector3f(np.broadcast_to(w_fixed, dirs.shape))
    free = to_vector3f(dirs32)
    f = to_numpy(eval_fn(fixed, free, params) if fixed_is_light else eval_fn(free, fixed, params))
    return (f * (dirs32[:, 2] * weights)[:, None]).sum(axis=0)
