"""Real spherical harmonics: basis, quadrature, projection, Funk-Hecke convolution, rotation.

Oracles: SciPy's complex SH ``sph_harm_y`` (with the Condon-Shortley phase) through the real/
complex relation of the module docstring; the closed forms of the low-order real SH written
out by hand; the addition theorem ``sum_m Y_lm(a) Y_lm(b) = (2l + 1)/(4 pi) P_l(a . b)``; the
exact sphere moments of monomials (Folland 2001, "How to integrate a polynomial over a
sphere", Amer. Math. Monthly 108); ``scipy.integrate.quad`` and ``scipy.special`` for
Legendre integrals and the modified spherical Bessel functions (``lambda_l = 4 pi i_l(k)``
for the kernel ``exp(k t)``); closed-form irradiances of a uniform cap and of a clamped-cosine
lobe; and quadratures split along the kink of a lobe, built here from NumPy's Gauss-Legendre
nodes, which integrate piecewise polynomials exactly.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import Legendre
from scipy.integrate import quad
from scipy.spatial.transform import Rotation
from scipy.special import eval_legendre, sph_harm_y, spherical_in

from satsight.errors import SatsightError
from satsight.lighting.sh import (
    clamped_cosine_coeffs,
    convolve,
    delta_coeffs,
    evaluate,
    irradiance_coeffs,
    project,
    project_samples,
    quadrature_for,
    rotate,
    rotation_matrix,
    sh_count,
    sh_degrees,
    sh_eval,
    sh_eval_dr,
    sh_index,
    sh_l_max,
    sphere_quadrature,
    zonal_kernel_coeffs,
)

ATOL = 1e-12  # float64 algebra on values of order 1 (Y_lm <= sqrt((2l + 1)/(4 pi)))
QUAD_ATOL = 1e-10  # sums over a few thousand quadrature nodes
FLOAT32_RTOL = 1e-5  # Dr.Jit single precision, relative to max |Y|
PROPERTY = settings(max_examples=40, deadline=None)
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)
Z = np.array([0.0, 0.0, 1.0])


def random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """n unit vectors, uniform on the sphere, plus both poles and two equator points."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    special = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, -1.0, 0]])
    return np.concatenate([d, special])


def split_quadrature(
    z_split: float, n_nodes: int, n_phi: int, rotation: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Sphere quadrature split at ``z = z_split``: Gauss-Legendre in z on each side, uniform phi.

    Exact for functions that are polynomials of degree <= 2 n_nodes - 1 in z on each side of
    the circle (azimuthal orders |m| < n_phi). With ``rotation`` R the nodes are mapped to
    ``R w``, i.e. the split circle is around ``R e_z`` (weights unchanged).
    """
    u, w = np.polynomial.legendre.leggauss(n_nodes)
    lo, hi = -1.0, z_split
    z_lo = 0.5 * (hi - lo) * u + 0.5 * (hi + lo)
    w_lo = 0.5 * (hi - lo) * w
    lo, hi = z_split, 1.0
    z_hi = 0.5 * (hi - lo) * u + 0.5 * (hi + lo)
    w_hi = 0.5 * (hi - lo) * w
    z = np.concatenate([z_lo, z_hi])
    wz = np.concatenate([w_lo, w_hi])
    phi = 2.0 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    s = np.sqrt(1.0 - z * z)
    d = np.stack(
        [np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)), np.outer(z, np.ones(n_phi))], axis=-1
    ).reshape(-1, 3)
    weights = np.repeat(wz * 2.0 * np.pi / n_phi, n_phi)
    if rotation is not None:
        d = d @ rotation.T
    return d, weights


def random_rotation(seed: int) -> np.ndarray:
    return Rotation.random(rng=np.random.default_rng(seed)).as_matrix()


def rotation_taking_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation R with R e_z = axis (unit)."""
    axis = axis / np.linalg.norm(axis)
    rot, _ = Rotation.align_vectors([axis], [Z])
    r = rot.as_matrix()
    np.testing.assert_allclose(r @ Z, axis, atol=1e-14)
    return r


def clamped_cosine_residual(l_max: int) -> float:
    """Energy of max(n . w, 0) above degree l_max: 2 pi/3 - sum_l A_l^2 (2l + 1)/(4 pi)."""
    l = np.arange(l_max + 1)
    a = clamped_cosine_coeffs(l_max)
    return 2.0 * np.pi / 3.0 - float(np.sum(a * a * (2 * l + 1) / (4.0 * np.pi)))


# --- indexing ---------------------------------------------------------------------------------
def test_count_index_and_degree_agree() -> None:
    for l_max in range(10):
        pairs = [(l, m) for l in range(l_max + 1) for m in range(-l, l + 1)]
        assert sh_count(l_max) == len(pairs) == (l_max + 1) ** 2
        assert [sh_index(l, m) for l, m in pairs] == list(range(len(pairs)))
        assert sh_degrees(l_max).tolist() == [l for l, _ in pairs]
        assert sh_l_max(sh_count(l_max)) == l_max
    assert sh_index(4, -4) == 16 and sh_index(4, 4) == 24


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: sh_index(2, 3), r"\|m\| <= l, got l=2, m=3"),
        (lambda: sh_count(-1), "l_max must be an integer >= 0, got -1"),
        (lambda: sh_l_max(5), r"\(l_max \+ 1\)\^2 coefficients .* got 5"),
    ],
)
def test_bad_indices_raise(call, message) -> None:
    with pytest.raises(SatsightError, match=message):
        call()


# --- evaluation -------------------------------------------------------------------------------
def test_low_orders_match_hand_written_cartesian_forms() -> None:
    """Y_00..Y_22 in the convention of Ramamoorthi & Hanrahan 2001 (no Condon-Shortley)."""
    d = random_directions(np.random.default_rng(0), 200)
    x, y, z = d.T
    pi = math.pi
    expected = np.stack(
        [
            np.full_like(x, 0.5 / math.sqrt(pi)),
            math.sqrt(3 / (4 * pi)) * y,
            math.sqrt(3 / (4 * pi)) * z,
            math.sqrt(3 / (4 * pi)) * x,
            0.5 * math.sqrt(15 / pi) * x * y,
            0.5 * math.sqrt(15 / pi) * y * z,
            0.25 * math.sqrt(5 / pi) * (3 * z * z - 1),
            0.5 * math.sqrt(15 / pi) * x * z,
            0.25 * math.sqrt(15 / pi) * (x * x - y * y),
        ],
        axis=-1,
    )
    np.testing.assert_allclose(sh_eval(d, 2), expected, rtol=0, atol=ATOL)


@pytest.mark.parametrize("l_max", [4, 8, 20])
def test_matches_scipy_complex_sh_through_the_real_relation(l_max: int) -> None:
    """Y_l,m = sqrt2 (-1)^m Re Y_l^m, Y_l,-m = sqrt2 (-1)^m Im Y_l^m (m > 0), Y_l,0 = Y_l^0."""
    d = random_directions(np.random.default_rng(l_max), 300)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2.0 * np.pi)
    ours = sh_eval(d, l_max)
    for l in range(l_max + 1):
        np.testing.assert_allclose(
            ours[:, sh_index(l, 0)], sph_harm_y(l, 0, theta, phi).real, rtol=0, atol=ATOL
        )
        for m in range(1, l + 1):
            ref = math.sqrt(2.0) * (-1) ** m * sph_harm_y(l, m, theta, phi)
            np.testing.assert_allclose(ours[:, sh_index(l, m)], ref.real, rtol=0, atol=ATOL)
            np.testing.assert_allclose(ours[:, sh_index(l, -m)], ref.imag, rtol=0, atol=ATOL)


@PROPERTY
@given(seed=SEEDS)
def test_addition_theorem_up_to_degree_24(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = random_directions(rng, 2)[:2]
    ya, yb = sh_eval(a, 24), sh_eval(b, 24)
    for l in range(25):
        band = slice(l * l, (l + 1) ** 2)
        expected = (2 * l + 1) / (4 * np.pi) * eval_legendre(l, float(a @ b))
        assert abs(ya[band] @ yb[band] - expected) <= 1e-11


def test_directions_are_normalised_and_batch_shape_kept() -> None:
    d = random_directions(np.random.default_rng(1), 20)[:20]
    scaled = (d * np.linspace(0.1, 7.0, 20)[:, None]).reshape(4, 5, 3)
    out = sh_eval(scaled, 3)
    assert out.shape == (4, 5, 16) and out.dtype == np.float64
    np.testing.assert_allclose(out.reshape(20, 16), sh_eval(d, 3), rtol=0, atol=ATOL)
    assert sh_eval(np.array([0.0, 0.0, 5.0]), 1).shape == (4,)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.zeros(3), "finite, non-zero 3-vectors"),
        (np.array([1.0, np.nan, 0.0]), "finite, non-zero 3-vectors"),
        (np.ones((4, 2)), r"shape \(\.\.\., 3\), got \(4, 2\)"),
        (np.float64(1.0), r"shape \(\.\.\., 3\), got \(\)"),
    ],
)
def test_bad_directions_raise(bad, message) -> None:
    with pytest.raises(SatsightError, match=message):
        sh_eval(bad, 2)


# --- quadrature -------------------------------------------------------------------------------
def sphere_moment(a: int, b: int, c: int) -> float:
    """Exact integral of x^a y^b z^c over the unit sphere (Folland 2001)."""
    if a % 2 or b % 2 or c % 2:
        return 0.0
    beta = [(p + 1) / 2 for p in (a, b, c)]
    return 2.0 * math.prod(math.gamma(v) for v in beta) / math.gamma(sum(beta))


@pytest.mark.parametrize(("n_theta", "n_phi"), [(1, 2), (3, None), (5, 10), (6, 17)])
def test_quadrature_integrates_monomials_exactly(n_theta: int, n_phi: int | None) -> None:
    d, w = sphere_quadrature(n_theta, n_phi)
    assert d.shape == (n_theta * (n_phi or 2 * n_theta), 3) and w.shape == d.shape[:1]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-15)
    assert abs(w.sum() - 4.0 * np.pi) <= 1e-13
    degree = 2 * n_theta - 1
    for a in range(degree + 1):
        for b in range(degree + 1 - a):
            for c in range(degree + 1 - a - b):
                got = np.sum(w * d[:, 0] ** a * d[:, 1] ** b * d[:, 2] ** c)
                assert abs(got - sphere_moment(a, b, c)) <= 1e-13, (a, b, c)


@pytest.mark.parametrize("quadrature", [lambda: quadrature_for(8), lambda: sphere_quadrature(30)])
def test_basis_is_orthonormal_to_degree_8(quadrature) -> None:
    d, w = quadrature()
    y = sh_eval(d, 8)
    gram = y.T @ (w[:, None] * y)
    np.testing.assert_allclose(gram, np.eye(81), rtol=0, atol=QUAD_ATOL)


# --- projection -------------------------------------------------------------------------------
@PROPERTY
@given(seed=SEEDS, l_max=st.integers(0, 6), channels=st.sampled_from([None, 1, 3]))
def test_band_limited_function_projects_back_exactly(
    seed: int, l_max: int, channels: int | None
) -> None:
    rng = np.random.default_rng(seed)
    shape = (sh_count(l_max),) if channels is None else (sh_count(l_max), channels)
    c = rng.normal(size=shape)

    def f(d: np.ndarray) -> np.ndarray:
        return evaluate(c, d)

    np.testing.assert_allclose(project(f, l_max), c, rtol=0, atol=ATOL)
    d, w = quadrature_for(l_max)
    np.testing.assert_allclose(project_samples(d, f(d), w, l_max), c, rtol=0, atol=ATOL)
    higher = project(f, l_max + 2)
    np.testing.assert_allclose(higher[: len(c)], c, rtol=0, atol=ATOL)
    np.testing.assert_allclose(higher[len(c) :], 0.0, rtol=0, atol=ATOL)


def test_project_samples_rejects_mismatched_shapes() -> None:
    d, w = quadrature_for(2)
    with pytest.raises(SatsightError, match=r"project_samples needs directions \(N, 3\)"):
        project_samples(d, np.ones(len(w) - 1), w, 2)


def test_delta_coefficients_sift_a_band_limited_function() -> None:
    """sum_k Y_k(s) c_k = f(s): the defining property of the projected Dirac delta."""
    rng = np.random.default_rng(3)
    c = rng.normal(size=(sh_count(5), 2))
    for s in random_directions(rng, 10):
        np.testing.assert_allclose(delta_coeffs(3.0 * s, 5) @ c, evaluate(c, s), atol=ATOL)


# --- irradiance and zonal kernels -------------------------------------------------------------
def half_legendre_moment(l: int, power: int) -> float:
    """integral_0^1 t^p P_l(t) dt, exactly, by NumPy's Legendre-series algebra."""
    antiderivative = (Legendre.basis(l) * Legendre([0.0, 1.0]) ** power).integ()
    return float(antiderivative(1.0) - antiderivative(0.0))


@PROPERTY
@given(seed=SEEDS, radiance=st.floats(1e-3, 1e4))
def test_constant_environment_gives_pi_l_on_any_normal(seed: int, radiance: float) -> None:
    coeffs = project(lambda d: np.full(len(d), radiance), 4)
    expected = np.zeros(25)
    expected[0] = radiance * math.sqrt(4.0 * np.pi)
    np.testing.assert_allclose(coeffs, expected, rtol=1e-13, atol=1e-13 * radiance)
    normals = random_directions(np.random.default_rng(seed), 30)
    e = evaluate(irradiance_coeffs(coeffs), normals)
    np.testing.assert_allclose(e, np.pi * radiance, rtol=1e-13)


def test_clamped_cosine_factors_match_closed_and_numerical_values() -> None:
    a = clamped_cosine_coeffs(30)
    pi = math.pi
    np.testing.assert_allclose(a[:7], [pi, 2 * pi / 3, pi / 4, 0, -pi / 24, 0, pi / 64], atol=ATOL)
    for l in range(31):
        assert abs(a[l] - 2.0 * pi * half_legendre_moment(l, 1)) <= 1e-12, l
    assert clamped_cosine_coeffs(0).shape == (1,)


def test_funk_hecke_factors_of_known_kernels() -> None:
    l_max = 24
    np.testing.assert_allclose(
        zonal_kernel_coeffs(lambda t: np.maximum(t, 0.0), l_max),
        clamped_cosine_coeffs(l_max),
        rtol=0,
        atol=QUAD_ATOL,
    )
    constant = np.zeros(l_max + 1)
    constant[0] = 4.0 * np.pi
    np.testing.assert_allclose(zonal_kernel_coeffs(lambda t: 1.0, l_max), constant, atol=ATOL)
    cos2 = zonal_kernel_coeffs(lambda t: np.maximum(t, 0.0) ** 2, l_max)
    for l in range(l_max + 1):
        assert abs(cos2[l] - 2.0 * np.pi * half_legendre_moment(l, 2)) <= 1e-12, l
    kappa = 3.0  # exp(k t): lambda_l = 4 pi i_l(k) (modified spherical Bessel function)
    expo = zonal_kernel_coeffs(lambda t: np.exp(kappa * t), l_max)
    ref = 4.0 * np.pi * spherical_in(np.arange(l_max + 1), kappa)
    np.testing.assert_allclose(expo, ref, rtol=1e-12, atol=1e-14 * ref[0])  # sum of ~ref[0]


def test_zonal_function_projects_onto_m_zero_with_funk_hecke_factors() -> None:
    """h(w . e_z) has c_lm = lambda_l Y_lm(e_z) = lambda_l sqrt((2l+1)/(4 pi)) delta_m0."""
    l_max = 10
    d, w = split_quadrature(0.0, 20, 2 * l_max + 4)

    def kernel(t):
        return np.maximum(t, 0.0) ** 3 + 0.5 * t

    c = project_samples(d, kernel(d[:, 2]), w, l_max)
    expected = zonal_kernel_coeffs(kernel, l_max)[sh_degrees(l_max)] * sh_eval(Z, l_max)
    np.testing.assert_allclose(c, expected, rtol=0, atol=ATOL)


@PROPERTY
@given(seed=SEEDS)
def test_convolution_with_a_smooth_kernel_matches_direct_integration(seed: int) -> None:
    """g(n) = integral exp(k n . w) f(w) dw by quadrature vs convolve() of f's coefficients."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(sh_count(6), 2))
    kappa = 2.0
    d, w = sphere_quadrature(40)
    f = evaluate(c, d)
    normals = random_directions(rng, 8)
    direct = np.exp(kappa * normals @ d.T) @ (w[:, None] * f)
    g = convolve(c, zonal_kernel_coeffs(lambda t: np.exp(kappa * t), 6))
    np.testing.assert_allclose(evaluate(g, normals), direct, rtol=0, atol=1e-11)


def test_convolve_rejects_too_few_factors() -> None:
    with pytest.raises(SatsightError, match=r"kernel_coeffs must have shape \(>= 5,\)"):
        convolve(np.ones(25), np.ones(3))


def lobe(power: int):
    """Normalised lobe f(w) = (p + 1)/(2 pi) max(w . e_z, 0)^p: integral f cos = 1 on e_z."""
    return lambda d: (power + 1) / (2.0 * np.pi) * np.maximum(d[:, 2], 0.0) ** power


def lobe_norm2(power: int) -> float:
    """integral f^2 dw = ((p + 1)/(2 pi))^2 2 pi/(2p + 1)."""
    return ((power + 1) / (2.0 * np.pi)) ** 2 * 2.0 * np.pi / (2 * power + 1)


def lobe_irradiance(power: int, cos_beta: float) -> float:
    """E(n) = integral f(w) max(n . w, 0) dw for a lobe on e_z and n . e_z = cos(beta).

    Azimuth done in closed form, integral_0^{2 pi} max(A + B cos phi, 0) dphi, with
    A = cos(beta) mu, B = sin(beta) sqrt(1 - mu^2); the kink of the remaining 1-D integrand is
    at mu = sin(beta) and is given to quad as a break point.
    """
    sin_beta = math.sqrt(max(0.0, 1.0 - cos_beta * cos_beta))

    def azimuth(mu: float) -> float:
        a, b = cos_beta * mu, sin_beta * math.sqrt(max(0.0, 1.0 - mu * mu))
        if a >= b:
            return 2.0 * np.pi * a
        if a <= -b:
            return 0.0
        return 2.0 * (a * math.acos(-a / b) + math.sqrt(b * b - a * a))

    value, _ = quad(
        lambda mu: mu**power * azimuth(mu),
        0.0,
        1.0,
        points=[sin_beta],
        epsabs=1e-14,
        epsrel=1e-13,
        limit=200,
    )
    return (power + 1) / (2.0 * np.pi) * value


@pytest.mark.parametrize("power", [1, 2, 3, 8])
def test_order4_lobe_error_equals_energy_of_discarded_bands(power: int) -> None:
    """||f - f_4||^2 (direct, exact split quadrature) = ||f||^2 - sum_{l<=4} c^2 (Parseval)."""
    d, w = split_quadrature(0.0, 24, 48)
    f = lobe(power)(d)
    c = project_samples(d, f, w, 4)
    residual = np.sum(w * (f - evaluate(c, d)) ** 2)
    discarded = lobe_norm2(power) - np.sum(c * c)
    assert residual > 0.0
    assert abs(residual - discarded) <= 1e-10
    # the same energy measured band by band from a high-order projection
    # (bands 5..40 hold all but the slowly decaying tail of the kinked p = 1 lobe)
    d_high, w_high = split_quadrature(0.0, 32, 96)
    c_high = project_samples(d_high, lobe(power)(d_high), w_high, 40)
    np.testing.assert_allclose(c_high[:25], c, rtol=0, atol=ATOL)
    assert -1e-12 <= discarded - np.sum(c_high[25:] ** 2) <= 1e-2 * discarded
    # a lobe about another axis: rotated coefficients, same discarded energy
    r = random_rotation(power)
    d_r, w_r = split_quadrature(0.0, 24, 48, rotation=r)
    residual_r = np.sum(w_r * (lobe(power)(d_r @ r) - evaluate(rotate(c, r), d_r)) ** 2)
    assert abs(residual_r - discarded) <= 1e-10


@pytest.mark.parametrize("power", [1, 2, 5])
def test_lobe_irradiance_error_is_within_the_truncation_bound(power: int) -> None:
    """|E - E_L| <= ||f - f_L|| ||h - h_L|| (Cauchy-Schwarz: f - f_L is orthogonal to h_L).

    h(w) = max(n . w, 0) has ||h - h_L||^2 = 2 pi/3 - sum_{l<=L} A_l^2 (2l+1)/(4 pi). For the
    p = 1 lobe f is proportional to h on its own axis, where the bound is attained.
    """
    d, w = split_quadrature(0.0, 24, 48)
    f = lobe(power)(d)
    rng = np.random.default_rng(power)
    axis = random_directions(rng, 1)[0]
    r = rotation_taking_z_to(axis)
    normals = np.concatenate([axis[None], random_directions(rng, 12)])
    exact = np.array([lobe_irradiance(power, float(n @ axis)) for n in normals])
    assert abs(exact[0] - (power + 1) / (power + 2)) <= 1e-12
    previous_bound = math.inf
    for l_max in (2, 4, 6, 8):
        c = project_samples(d, f, w, l_max)
        e_sh = evaluate(irradiance_coeffs(rotate(c, r)), normals)
        bound = math.sqrt((lobe_norm2(power) - np.sum(c * c)) * clamped_cosine_residual(l_max))
        assert np.all(np.abs(e_sh - exact) <= bound * (1 + 1e-9) + 1e-12), l_max
        assert bound < previous_bound
        previous_bound = bound
        if power == 1:
            assert abs(abs(e_sh[0] - exact[0]) - bound) <= 1e-10
        if l_max == 4:
            assert np.max(np.abs(e_sh - exact)) <= 0.02 * exact[0]


def test_small_uniform_cap_coefficients_and_irradiance() -> None:
    """Cap of half-angle alpha and radiance L0 about axis a.

    c_l0 = L0 2 pi sqrt((2l+1)/(4 pi)) (P_l-1(cos a) - P_l+1(cos a))/(2l + 1) (l >= 1), and
    E(n) = L0 pi sin^2(alpha) (n . a) while the whole cap is above the horizon of n.
    """
    radiance, alpha = 250.0, math.radians(15.0)
    cos_a = math.cos(alpha)
    l_max_high = 16
    d, w = split_quadrature(cos_a, 24, 2 * l_max_high + 4)
    on_cap = d[:, 2] >= cos_a  # the nodes of the cone only
    c = project_samples(d[on_cap], np.full(on_cap.sum(), radiance), w[on_cap], l_max_high)
    l = np.arange(l_max_high + 1)
    c_l0 = radiance * 2.0 * np.pi * np.sqrt((2 * l + 1) / (4 * np.pi)) / (2 * l + 1)
    c_l0 = c_l0 * np.where(
        l == 0, 1.0 - cos_a, eval_legendre(l - 1, cos_a) - eval_legendre(l + 1, cos_a)
    )
    expected = np.zeros(sh_count(l_max_high))
    expected[l * (l + 1)] = c_l0
    np.testing.assert_allclose(c, expected, rtol=0, atol=1e-12 * radiance)

    rng = np.random.default_rng(4)
    axis = random_directions(rng, 1)[0]
    r = rotation_taking_z_to(axis)
    normals = random_directions(rng, 400)
    normals = normals[normals @ axis >= math.sin(alpha)][:30]  # cap entirely above horizon
    exact = radiance * np.pi * math.sin(alpha) ** 2 * (normals @ axis)
    cap_norm2 = radiance**2 * 2.0 * np.pi * (1.0 - cos_a)
    errors = []
    for l_max in (2, 4, 8, 16):
        c_l = rotate(c[: sh_count(l_max)], r)
        e_sh = evaluate(irradiance_coeffs(c_l), normals)
        discarded = cap_norm2 - np.sum(c[: sh_count(l_max)] ** 2)
        bound = math.sqrt(discarded * clamped_cosine_residual(l_max))
        errors.append(np.max(np.abs(e_sh - exact)))
        assert errors[-1] <= bound * (1 + 1e-9), l_max
    assert errors[-1] < errors[0]


def test_collimated_sun_irradiance_converges_with_degree() -> None:
    """E delta(w - s) convolved with the clamped cosine approximates E max(n . s, 0).

    The L2 error over normals is computed on a quadrature split along n . s = 0 (exact, the
    error being a polynomial on each hemisphere), checked against E^2 ||h - h_L||^2, and
    must decrease for L = 2, 4, 6, 8.
    """
    irradiance = 1361.0
    s = np.array([0.3, -0.5, 0.8])
    s /= np.linalg.norm(s)
    d, w = split_quadrature(0.0, 12, 24, rotation=rotation_taking_z_to(s))
    exact = irradiance * np.maximum(d @ s, 0.0)
    errors = []
    for l_max in (2, 4, 6, 8):
        coeffs = irradiance_coeffs(irradiance * delta_coeffs(s, l_max))
        err2 = np.sum(w * (evaluate(coeffs, d) - exact) ** 2)
        expected = irradiance**2 * clamped_cosine_residual(l_max)
        assert abs(err2 - expected) <= 1e-10 * irradiance**2
        errors.append(math.sqrt(err2))
    assert all(b < a for a, b in itertools.pairwise(errors)), errors


# --- rotation ---------------------------------------------------------------------------------
@PROPERTY
@given(seed=SEEDS, l_max=st.integers(0, 8))
def test_rotated_coefficients_evaluate_like_rotated_directions(seed: int, l_max: int) -> None:
    """g(w_b) = f(R^T w_b): evaluate(M c, w_b) = evaluate(c, R^T w_b)."""
    rng = np.random.default_rng(seed)
    r = random_rotation(seed)
    c = rng.normal(size=(sh_count(l_max), 3))
    d_b = random_directions(rng, 40)
    np.testing.assert_allclose(evaluate(rotate(c, r), d_b), evaluate(c, d_b @ r), atol=QUAD_ATOL)


@PROPERTY
@given(seed1=SEEDS, seed2=SEEDS)
def test_rotation_matrices_are_orthogonal_block_diagonal_and_compose(
    seed1: int, seed2: int
) -> None:
    r1, r2 = random_rotation(seed1), random_rotation(seed2)
    l_max = 6
    m1, m2 = rotation_matrix(r1, l_max), rotation_matrix(r2, l_max)
    np.testing.assert_allclose(m1 @ m1.T, np.eye(sh_count(l_max)), rtol=0, atol=ATOL)
    degrees = sh_degrees(l_max)
    assert np.all(m1[degrees[:, None] != degrees[None, :]] == 0.0)
    np.testing.assert_allclose(rotation_matrix(r2 @ r1, l_max), m2 @ m1, rtol=0, atol=ATOL)
    # band 1 is (y, z, x): its block is P R P^T with P the cyclic permutation
    p = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], dtype=float)
    np.testing.assert_allclose(m1[1:4, 1:4], p @ r1 @ p.T, rtol=0, atol=ATOL)


def test_rotation_about_z_turns_each_order_by_m_gamma() -> None:
    gamma = 0.7
    r = Rotation.from_rotvec([0.0, 0.0, gamma]).as_matrix()
    l_max = 6
    m = rotation_matrix(r, l_max)
    expected = np.zeros_like(m)
    for l in range(l_max + 1):
        expected[sh_index(l, 0), sh_index(l, 0)] = 1.0
        for k in range(1, l + 1):
            cos, sin = math.cos(k * gamma), math.sin(k * gamma)
            expected[sh_index(l, k), sh_index(l, k)] = cos
            expected[sh_index(l, -k), sh_index(l, -k)] = cos
            expected[sh_index(l, -k), sh_index(l, k)] = sin  # cos(k(phi - g)) has + sin(k g)
            expected[sh_index(l, k), sh_index(l, -k)] = -sin
    np.testing.assert_allclose(m, expected, rtol=0, atol=ATOL)
    np.testing.assert_allclose(rotation_matrix(np.eye(3), l_max), np.eye(49), rtol=0, atol=ATOL)


def test_rotation_matrix_rejects_non_orthogonal_input() -> None:
    with pytest.raises(SatsightError, match="orthogonal 3x3 matrix"):
        rotation_matrix(np.diag([1.0, 2.0, 1.0]), 2)


# --- Dr.Jit -----------------------------------------------------------------------------------
def _dr_against_numpy(vector_type, float_type, l_max: int) -> None:
    d = random_directions(np.random.default_rng(l_max), 300) * 2.5
    d32 = d.astype(np.float32)
    v = vector_type(*(float_type(np.ascontiguousarray(d32[:, i])) for i in range(3)))
    out = sh_eval_dr(v, l_max)
    assert isinstance(out, list) and len(out) == sh_count(l_max)
    got = np.stack([np.asarray(term, dtype=np.float64) for term in out], axis=-1)
    ref = sh_eval(d32.astype(np.float64), l_max)
    scale = np.max(np.abs(ref))
    np.testing.assert_allclose(got, ref, rtol=0, atol=FLOAT32_RTOL * scale)


@pytest.mark.parametrize("l_max", [0, 1, 2, 4, 8])
def test_drjit_evaluation_matches_numpy(llvm_variant, l_max: int) -> None:
    import mitsuba as mi

    _dr_against_numpy(mi.Vector3f, mi.Float, l_max)


def test_drjit_evaluation_on_plain_llvm_arrays(llvm_variant) -> None:
    import drjit as dr

    _dr_against_numpy(dr.llvm.ad.Array3f, dr.llvm.ad.Float, 4)


@pytest.mark.gpu
def test_drjit_evaluation_on_cuda_arrays() -> None:
    from satsight.render.backend import gpu_available

    if not gpu_available():
        pytest.skip("no working NVIDIA GPU / cuda_ad_rgb variant on this machine")
    import drjit as dr

    _dr_against_numpy(dr.cuda.ad.Array3f, dr.cuda.ad.Float, 8)
