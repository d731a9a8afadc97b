"""Detector chain: closed forms of the linear camera model and its noise statistics.

Statistical checks use 512 x 512 = 262144 pixels; each tolerance is a multiple (5) of the
standard error of the estimated quantity, stated next to it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.constants as const
from scipy import stats

from qe_oracle import blackbody_qe, solar_qe
from satsight.errors import SatsightError
from satsight.sensor import fixed_pattern
from satsight.sensor.detector import (
    DetectorParameters,
    expected_electrons,
    mean_photon_energy_j,
    photons_per_pixel,
)
from satsight.sensor.exposure import (
    exposure_for_fill,
    mean_electrons_image,
    saturate_electrons,
    simulate_detector,
)
from satsight.sensor.fixed_pattern import _draw_camera_maps, fixed_pattern_maps
from satsight.sensor.noise import (
    SHOT_NOISE_NORMAL_MIN_MEAN_E,
    SHOT_NOISE_SPARSE_MAX_MEAN_E,
    _standard_normal_f32,
    read_out_dn,
    shot_noise_electrons,
)

BAND_NM = (450.0, 900.0)
SHAPE = (512, 512)
N_PIX = SHAPE[0] * SHAPE[1]
N_SIGMA = 5.0
HC_J_M = const.h * const.c
NO_FPN = DetectorParameters(prnu_fraction=0.0, dsnu_e_per_s=0.0)
#: The CCD231-84 curve's photon-weighted mean over the band for E-490 sunlight, from the
#: data files (tests/qe_oracle.py); the library's node sums agree to < 1e-6 relative.
SOLAR_QE = solar_qe(*BAND_NM)


def _qe(params: DetectorParameters) -> float:
    """The eta a detector applies to sunlight over BAND_NM: its override, or the curve's."""
    return SOLAR_QE if params.quantum_efficiency is None else params.quantum_efficiency


def _irradiance_for_electrons(params: DetectorParameters, mean_e: float, t_s: float) -> float:
    """Irradiance (W m^-2) that gives ``mean_e`` photo-electrons in ``t_s`` (flat band)."""
    photon_energy_j = mean_photon_energy_j(BAND_NM)
    return mean_e * photon_energy_j / (_qe(params) * params.pixel_area_m2 * t_s)


# --- photon collection -----------------------------------------------------------------
def test_photon_count_closed_form_at_550_nm() -> None:
    photon_energy_j = mean_photon_energy_j((500.0, 600.0))
    assert photon_energy_j == pytest.approx(HC_J_M / 550e-9, rel=1e-15)
    photons = photons_per_pixel(np.ones((2, 3)), (15e-6) ** 2, 1.0, photon_energy_j)
    # 1 W m^-2 on 225e-12 m^2 for 1 s: 225e-12 J, each photon h c / 550 nm.
    assert photons.shape == (2, 3)
    np.testing.assert_allclose(photons, 225e-12 * 550e-9 / HC_J_M, rtol=1e-12)


def test_mean_photon_energy_matches_flat_spectrum_integral() -> None:
    # Flat spectral irradiance: photons = int (E / dl) l / (h c) dl over the band.
    lam_m = np.linspace(450e-9, 900e-9, 200001)
    photons_per_joule = np.trapezoid(lam_m / HC_J_M, lam_m) / (lam_m[-1] - lam_m[0])
    assert 1.0 / mean_photon_energy_j(BAND_NM) == pytest.approx(photons_per_joule, rel=1e-12)
    assert mean_photon_energy_j(BAND_NM, 600e-9) == pytest.approx(HC_J_M / 600e-9, rel=1e-15)


# --- mean signal -------------------------------------------------------------------------
@pytest.mark.parametrize("fixed_pattern", [False, True])
def test_flat_field_mean_dn_matches_linear_model(fixed_pattern: bool) -> None:
    if fixed_pattern:
        params = DetectorParameters(dark_current_e_per_s=200.0, dsnu_e_per_s=100.0)
    else:
        params = DetectorParameters(dark_current_e_per_s=200.0, prnu_fraction=0, dsnu_e_per_s=0)
    t_s = 10.0
    irradiance = _irradiance_for_electrons(params, 1e5, t_s)
    dn = simulate_detector(
        np.full(SHAPE, irradiance), t_s, params, BAND_NM, np.random.default_rng(1), 3
    )
    assert dn.dtype == np.uint16
    assert dn.shape == SHAPE
    g = params.conversion_gain_e_per_dn
    photo_e = 1e5
    dark_e = params.dark_current_e_per_s * t_s
    expected_dn = params.bias_dn + (photo_e + dark_e) / g
    # Per-pixel variance: shot + read + quantisation, plus the fixed pattern spread
    # (PRNU: (p mu_photo)^2, DSNU: (s_dsnu t)^2), which averages down like the noise.
    var_e = photo_e + dark_e + params.read_noise_e**2
    var_e += (params.prnu_fraction * photo_e) ** 2 + (params.dsnu_e_per_s * t_s) ** 2
    standard_error_dn = math.sqrt((var_e / g**2 + 1.0 / 12.0) / N_PIX)
    assert abs(dn.mean() - expected_dn) < N_SIGMA * standard_error_dn
    # The measured spread matches the predicted one (relative SE of a variance ~ sqrt(2/N)).
    predicted_var = var_e / g**2 + 1.0 / 12.0
    assert dn.var() == pytest.approx(predicted_var, rel=N_SIGMA * math.sqrt(2.0 / N_PIX))


def test_fixed_pattern_maps_have_documented_statistics() -> None:
    params = DetectorParameters(dark_current_e_per_s=1.0, dsnu_e_per_s=0.5, prnu_fraction=0.02)
    prnu, dsnu = fixed_pattern_maps(SHAPE, params, camera_seed=11)
    assert prnu.shape == dsnu.shape == SHAPE
    assert abs(prnu.mean() - 1.0) < N_SIGMA * 0.02 / math.sqrt(N_PIX)
    assert prnu.std() == pytest.approx(0.02, rel=N_SIGMA * math.sqrt(2.0 / N_PIX))
    # Lognormal dark current: mean unchanged (SE 0.5/sqrt(N)), never negative.
    assert abs(dsnu.mean()) < N_SIGMA * 0.5 / math.sqrt(N_PIX)
    assert np.all(1.0 + dsnu >= 0.0)
    # The spread of a lognormal sample variance is wider than sqrt(2/N); 5 % is > 10 SE here.
    assert dsnu.std() == pytest.approx(0.5, rel=0.05)


# --- photon transfer ------------------------------------------------------------------
def test_photon_transfer_curve_slope_and_read_noise_floor() -> None:
    params = DetectorParameters()  # with PRNU/DSNU: the frame difference cancels them
    g = params.conversion_gain_e_per_dn
    t_s = 1.0
    levels_e = np.array([0.0, 2e3, 1e4, 3e4, 6e4, 1e5, 1.5e5, 2e5, 2.5e5])
    means, variances = [], []
    for i, level in enumerate(levels_e):
        irradiance = np.full(SHAPE, _irradiance_for_electrons(params, level, t_s))
        a, b = (
            simulate_detector(
                irradiance, t_s, params, BAND_NM, np.random.default_rng([i, k]), 5
            ).astype(np.float64)
            for k in range(2)
        )
        means.append(0.5 * (a.mean() + b.mean()) - params.bias_dn)
        variances.append(np.var(a - b) / 2.0)
    x, y = np.array(means), np.array(variances)
    # SE of each variance estimate: var sqrt(2 / (N - 1)); weighted straight-line fit.
    se = y * math.sqrt(2.0 / (N_PIX - 1))
    design = np.stack([np.ones_like(x), x], axis=1) / se[:, None]
    coef, *_ = np.linalg.lstsq(design, y / se, rcond=None)
    cov = np.linalg.inv(design.T @ design)
    intercept, slope = coef
    floor_dn2 = (params.read_noise_e / g) ** 2 + 1.0 / 12.0
    assert slope == pytest.approx(1.0 / g, rel=0.02)
    assert abs(slope - 1.0 / g) < N_SIGMA * math.sqrt(cov[1, 1])
    assert abs(intercept - floor_dn2) < N_SIGMA * math.sqrt(cov[0, 0])
    # The zero-signal frame alone (bias + dark only) measures the floor directly.
    dark_dn2 = params.dark_current_e_per_s * t_s / g**2
    assert abs(y[0] - floor_dn2 - dark_dn2) < N_SIGMA * se[0]


def test_shot_noise_is_poisson_even_for_large_means() -> None:
    rng = np.random.default_rng(2)
    for mean in (0.3, 50.0, 1e9):
        draws = shot_noise_electrons(np.full(SHAPE, mean), rng)
        assert draws.dtype == np.float64
        assert abs(draws.mean() - mean) < N_SIGMA * math.sqrt(mean / N_PIX)
        assert draws.var() == pytest.approx(mean, rel=N_SIGMA * math.sqrt(2.0 / N_PIX) + 0.01)


# --- saturation -----------------------------------------------------------------------
def test_saturated_pixels_read_the_full_well_level() -> None:
    params = dataclasses.replace(NO_FPN, blooming=False)
    irradiance = np.full(SHAPE, _irradiance_for_electrons(params, 5 * params.full_well_e, 1.0))
    dn = simulate_detector(irradiance, 1.0, params, BAND_NM, np.random.default_rng(3), 0)
    g = params.conversion_gain_e_per_dn
    full_well_dn = params.bias_dn + params.full_well_e / g  # 61000 DN, below 65535
    sigma_dn = math.sqrt((params.read_noise_e / g) ** 2 + 1.0 / 12.0)
    assert abs(dn.mean() - full_well_dn) < N_SIGMA * sigma_dn / math.sqrt(N_PIX)
    assert dn.max() <= full_well_dn + 6 * sigma_dn + 0.5


def test_adc_clips_at_its_top_code_and_at_zero() -> None:
    # 1 e-/DN: the 350 ke- full well would be 351000 DN, far above the 16-bit ADC.
    params = dataclasses.replace(NO_FPN, conversion_gain_e_per_dn=1.0, blooming=False)
    irradiance = np.full(SHAPE, _irradiance_for_electrons(params, 1e5, 1.0))
    dn = simulate_detector(irradiance, 1.0, params, BAND_NM, np.random.default_rng(4), 0)
    assert np.all(dn == 65535)
    # No bias and no signal: half the read-noise draws are negative and clip to 0.
    params0 = dataclasses.replace(NO_FPN, bias_dn=0.0)
    dn0 = read_out_dn(np.zeros(SHAPE), params0, np.random.default_rng(5))
    assert dn0.min() == 0
    assert np.count_nonzero(dn0 == 0) > N_PIX // 3
    # A 12-bit ADC clips at 4095.
    params12 = dataclasses.replace(NO_FPN, adc_bits=12, bias_dn=100.0)
    dn12 = read_out_dn(np.full((4, 4), 1e6), params12, np.random.default_rng(6))
    assert np.all(dn12 == 4095)


def test_saturation_without_blooming_clips() -> None:
    e = np.array([[1.0, 500.0], [99.0, 101.0]])
    np.testing.assert_array_equal(saturate_electrons(e, 100.0, False), [[1, 100], [99, 100]])


def test_blooming_conserves_column_charge_and_spreads_vertically() -> None:
    fw = 1000.0
    e = np.full((64, 5), 100.0)
    e[30, 2] = 10 * fw  # excess 9 fw: 4.5 fw up, 4.5 fw down, 900 e- of room per pixel
    e[10, 4] = 1.5 * fw
    e[11, 4] = 1.2 * fw  # a run of two: excess 0.7 fw
    out = saturate_electrons(e, fw, True)
    assert out.max() <= fw
    np.testing.assert_allclose(out.sum(axis=0), e.sum(axis=0), rtol=1e-12)
    np.testing.assert_array_equal(out[:, [0, 1, 3]], e[:, [0, 1, 3]])
    # 4.5 fw / 0.9 fw = 5 pixels filled exactly on each side of row 30.
    column = out[:, 2]
    np.testing.assert_allclose(column[25:36], fw, rtol=1e-12)
    np.testing.assert_array_equal(column[:25], 100.0)
    np.testing.assert_array_equal(column[36:], 100.0)
    # 350 e- each way: rows 9 and 12 get 350 e- more.
    np.testing.assert_allclose(out[[9, 12], 4], 450.0, rtol=1e-12)
    np.testing.assert_allclose(out[[10, 11], 4], fw, rtol=1e-12)


def test_blooming_loses_charge_only_over_the_frame_edge() -> None:
    fw = 1000.0
    e = np.full((8, 1), 500.0)
    e[1, 0] = 5 * fw  # excess 4 fw: 2 fw up (row 0 takes 500, 1500 leaves), 2 fw down
    out = saturate_electrons(e, fw, True)
    assert out.sum() == pytest.approx(e.sum() - 1500.0, rel=1e-12)
    np.testing.assert_allclose(out[:, 0], [fw, fw, fw, fw, fw, fw, 500, 500], rtol=1e-12)
    # Two over-full runs in one column: the first run's spill passes through the second.
    e2 = np.zeros((20, 1))
    e2[5, 0] = 3 * fw
    e2[7, 0] = 2 * fw
    out2 = saturate_electrons(e2, fw, True)
    assert out2.sum() == pytest.approx(e2.sum(), rel=1e-12)
    assert out2.max() <= fw


def test_blooming_in_the_chain_keeps_columns_separate() -> None:
    params = dataclasses.replace(NO_FPN, read_noise_e=0.0)
    irradiance = np.zeros((64, 8))
    irradiance[32, 3] = _irradiance_for_electrons(params, 20 * params.full_well_e, 1.0)
    dn = simulate_detector(irradiance, 1.0, params, BAND_NM, np.random.default_rng(7), 0)
    bright = dn > params.bias_dn + 1
    assert set(np.flatnonzero(bright.any(axis=0))) == {3}
    assert 15 <= np.count_nonzero(bright[:, 3]) <= 25  # ~20 full pixels along the column


# --- reproducibility ------------------------------------------------------------------
def test_same_seed_same_bytes_different_seed_different() -> None:
    params = DetectorParameters()
    irradiance = np.full((64, 64), _irradiance_for_electrons(params, 1e4, 1.0))

    def frame(seed: int, camera_seed: int = 9) -> bytes:
        rng = np.random.default_rng(seed)
        return simulate_detector(irradiance, 1.0, params, BAND_NM, rng, camera_seed).tobytes()

    assert frame(1) == frame(1)
    assert frame(1) != frame(2)
    assert frame(1, camera_seed=9) != frame(1, camera_seed=10)


def test_fixed_pattern_depends_only_on_camera_seed() -> None:
    params = DetectorParameters()
    prnu_a, dsnu_a = fixed_pattern_maps((32, 48), params, 4)
    # Disturb the state the maps could leak from or into: a frame's temporal generator,
    # drawn through the whole detector (which reads this camera's maps), and the
    # process-wide cache of camera maps, emptied so that the second call draws the maps
    # afresh instead of returning the cached arrays.
    rng = np.random.default_rng(0)
    simulate_detector(np.full((32, 48), 1e-3), 1.0, params, BAND_NM, rng, 4)
    with fixed_pattern._CAMERA_MAPS_LOCK:
        fixed_pattern._CAMERA_MAPS.clear()
    prnu_b, dsnu_b = fixed_pattern_maps((32, 48), params, 4)
    assert not np.shares_memory(prnu_a, prnu_b)  # drawn again, not the cached arrays
    np.testing.assert_array_equal(prnu_a, prnu_b)
    np.testing.assert_array_equal(dsnu_a, dsnu_b)
    prnu_c, dsnu_c = fixed_pattern_maps((32, 48), params, 5)
    assert not np.array_equal(prnu_a, prnu_c)
    assert not np.array_equal(dsnu_a, dsnu_c)
    # Switching PRNU off leaves the DSNU map unchanged.
    _, dsnu_d = fixed_pattern_maps((32, 48), dataclasses.replace(params, prnu_fraction=0.0), 4)
    np.testing.assert_array_equal(dsnu_a, dsnu_d)
    assert not prnu_a.flags.writeable
    # The mean-electron image of one camera does not depend on the temporal generator: the
    # frames drawn in between (different generators) leave it unchanged.
    irradiance = np.full((32, 48), 1e-3)
    before = mean_electrons_image(irradiance, 1.0, params, BAND_NM, 4)
    for seed in (1, 2):
        simulate_detector(irradiance, 1.0, params, BAND_NM, np.random.default_rng(seed), 4)
    np.testing.assert_array_equal(mean_electrons_image(irradiance, 1.0, params, BAND_NM, 4), before)


# --- exposure -------------------------------------------------------------------------
@pytest.mark.parametrize("fill_fraction", [0.7, 0.25, 1.0])
@pytest.mark.parametrize("override", [None, 0.85])
def test_exposure_for_fill_puts_irradiance_at_fill_fraction(
    fill_fraction: float, override: float | None
) -> None:
    """The closed form t = f FW / (eta E A / <E_ph> + D) inverts the mean signal: exactly
    (1e-12) with a scalar eta, to the QE oracle's 1e-6 with the curve's."""
    params = DetectorParameters(quantum_efficiency=override)
    irradiance = 3.7e-5
    t_s = exposure_for_fill(irradiance, params, BAND_NM, fill_fraction)
    photons = photons_per_pixel(
        np.array([[irradiance]]), params.pixel_area_m2, t_s, mean_photon_energy_j(BAND_NM)
    )
    mean_e = expected_electrons(photons, _qe(params), 1.0, params.dark_current_e_per_s, 0.0, t_s)
    rel = 1e-12 if override is not None else 1e-6
    assert mean_e[0, 0] == pytest.approx(fill_fraction * params.full_well_e, rel=rel)


def test_the_quantum_efficiency_is_the_curves_unless_overridden() -> None:
    """None: the curve's photon-weighted mean, for sunlight (0.8127 over 450-900 nm) and for
    each star's black body; a number: that number for every light. A bad eta passed to an
    exposure is refused."""
    curve = DetectorParameters()
    assert curve.quantum_efficiency is None
    assert curve.band_quantum_efficiency(BAND_NM) == pytest.approx(SOLAR_QE, rel=1e-6)
    assert curve.band_quantum_efficiency((750.0, 900.0)) == pytest.approx(
        solar_qe(750.0, 900.0), rel=1e-5
    )
    temps = np.array([3000.0, 10000.0])
    np.testing.assert_allclose(
        curve.star_quantum_efficiency(BAND_NM, temps), blackbody_qe(*BAND_NM, temps), rtol=1e-6
    )
    assert curve.quantum_efficiency_source(BAND_NM).startswith("CCD231-84 curve")
    fixed = DetectorParameters(quantum_efficiency=0.6)
    assert fixed.band_quantum_efficiency(BAND_NM) == 0.6
    np.testing.assert_array_equal(fixed.star_quantum_efficiency(BAND_NM, temps), [0.6, 0.6])
    assert fixed.quantum_efficiency_source(BAND_NM) == "scalar override"
    # Electrons scale with eta: the override, and an eta passed to the exposure directly.
    irradiance = np.full((4, 4), 1e-3)
    dark = dataclasses.replace(NO_FPN, dark_current_e_per_s=0.0)
    ratio = mean_electrons_image(irradiance, 1.0, dark, BAND_NM, 0, quantum_efficiency=0.4)
    ratio /= mean_electrons_image(irradiance, 1.0, dark, BAND_NM, 0)
    np.testing.assert_allclose(ratio, 0.4 / SOLAR_QE, rtol=1e-6)
    with pytest.raises(SatsightError, match="quantum_efficiency must be in"):
        exposure_for_fill(1e-3, curve, BAND_NM, quantum_efficiency=1.5)


# --- errors ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "overrides",
    [
        {"quantum_efficiency": 1.2},
        {"quantum_efficiency": 0.0},
        {"quantum_efficiency": float("nan")},
        {"pixel_pitch_m": -15e-6},
        {"dark_current_e_per_s": -1.0},
        {"read_noise_e": float("nan")},
        {"full_well_e": 0.0},
        {"conversion_gain_e_per_dn": 0.0},
        {"bias_dn": 70000.0},
        {"adc_bits": 17},
        {"adc_bits": 12.5},
        {"prnu_fraction": 0.5},
        {"dsnu_e_per_s": -1.0},
        {"dark_current_e_per_s": 0.0, "dsnu_e_per_s": 1.0},
        {"blooming": "yes"},
    ],
)
def test_bad_parameters_are_refused(overrides: dict[str, object]) -> None:
    with pytest.raises(SatsightError, match="got"):
        DetectorParameters(**overrides)  # type: ignore[arg-type]


def test_bad_inputs_are_refused() -> None:
    params = DetectorParameters()
    rng = np.random.default_rng(0)
    good = np.ones((4, 4)) * 1e-4
    with pytest.raises(SatsightError, match="exposure_time_s"):
        simulate_detector(good, -1.0, params, BAND_NM, rng, 0)
    with pytest.raises(SatsightError, match="irradiance_w_m2"):
        simulate_detector(-good, 1.0, params, BAND_NM, rng, 0)
    with pytest.raises(SatsightError, match="irradiance_w_m2"):
        simulate_detector(np.full((4, 4), np.nan), 1.0, params, BAND_NM, rng, 0)
    with pytest.raises(SatsightError, match=r"\(H, W\)"):
        simulate_detector(np.ones((4, 4, 3)), 1.0, params, BAND_NM, rng, 0)
    with pytest.raises(SatsightError, match="band_nm"):
        simulate_detector(good, 1.0, params, (900.0, 450.0), rng, 0)
    with pytest.raises(SatsightError, match="Generator"):
        simulate_detector(good, 1.0, params, BAND_NM, 0, 0)  # type: ignore[arg-type]
    with pytest.raises(SatsightError, match="camera_seed"):
        simulate_detector(good, 1.0, params, BAND_NM, rng, -1)
    with pytest.raises(SatsightError, match="effective_wavelength_m"):
        mean_photon_energy_j(BAND_NM, 1000e-9)
    with pytest.raises(SatsightError, match="fill_fraction"):
        exposure_for_fill(1e-4, params, BAND_NM, 1.5)
    with pytest.raises(SatsightError, match="no signal"):
        exposure_for_fill(
            0.0, dataclasses.replace(params, dark_current_e_per_s=0.0, dsnu_e_per_s=0.0), BAND_NM
        )
    with pytest.raises(SatsightError, match="<="):
        shot_noise_electrons(np.full((2, 2), 1e17), rng)


# --- shot-noise samplers -----------------------------------------------------------------
def _chi_square_poisson_p_value(draws: np.ndarray, mean: float) -> float:
    """Pearson chi-square p-value of integer draws against the Poisson(mean) pmf.

    Bins k = 0, 1, ... while the expected count is >= 20, then one bin for the upper tail
    (merged into the last bin if its expected count is below 20).
    """
    n = draws.size
    edges = []
    k = 0
    while n * stats.poisson.pmf(k, mean) >= 20 or k <= mean:
        edges.append(k)
        k += 1
    expected = n * stats.poisson.pmf(edges, mean)
    observed = np.array([np.count_nonzero(draws == k) for k in edges], dtype=np.float64)
    tail_expected = n - expected.sum()
    tail_observed = n - observed.sum()
    if tail_expected >= 20:
        expected = np.append(expected, tail_expected)
        observed = np.append(observed, tail_observed)
    else:
        expected[-1] += tail_expected
        observed[-1] += tail_observed
    return float(stats.chisquare(observed, expected).pvalue)


@pytest.mark.parametrize("mean", [1e-3, 0.05, 0.099, 0.101, 3.0])
def test_shot_noise_small_means_follow_the_poisson_pmf(mean: float) -> None:
    # 0.099 and 0.101 sit on both sides of the thinning limit (0.1 e-); 1e-3 is the dark
    # signal of a 1 s exposure. Pearson's chi-square at 0.1 % significance (fixed seeds).
    assert SHOT_NOISE_SPARSE_MAX_MEAN_E == 0.1
    rng = np.random.default_rng(20)
    draws = shot_noise_electrons(np.full(SHAPE, mean), rng)
    assert np.array_equal(draws, np.rint(draws))
    assert abs(draws.mean() - mean) < N_SIGMA * math.sqrt(mean / N_PIX)
    assert _chi_square_poisson_p_value(draws, mean) > 1e-3


def test_shot_noise_thinning_in_a_mixed_band() -> None:
    # Columns of dark sky (tiny means, thinned), faint (exact sampler) and bright (normal)
    # pixels side by side in one band: each group keeps its own Poisson statistics.
    levels = np.array([2e-3, 0.08, 7.0, 500.0, 4000.0])
    means = np.tile(levels, (512, 103))[:, :512]
    draws = shot_noise_electrons(means, np.random.default_rng(21))
    for level in levels:
        group = draws[means == level]
        n = group.size
        assert abs(group.mean() - level) < N_SIGMA * math.sqrt(level / n)
        # SE of a Poisson sample variance: sqrt((2 mu^2 + mu) / n).
        assert abs(group.var() - level) < N_SIGMA * math.sqrt((2 * level**2 + level) / n)
        if level < 10:
            assert _chi_square_poisson_p_value(group, level) > 1e-3


@pytest.mark.parametrize("mean", [900.0, 999.0, 1000.0, 1001.0, 5000.0, 3e5])
def test_shot_noise_mean_and_variance_on_both_sides_of_the_normal_limit(mean: float) -> None:
    # Below 1000 e- the exact sampler, from 1000 e- on rint(mu + sqrt(mu - 1/12) z). Both
    # give mean mu (SE sqrt(mu / N)) and variance mu (SE sqrt((2 mu^2 + mu) / N) ~ mu
    # sqrt(2 / N)), whole electrons, skewness 1/sqrt(mu) for Poisson and ~0 for the normal
    # limit (SE of the sample skewness sqrt(6 / N) = 0.0048).
    assert SHOT_NOISE_NORMAL_MIN_MEAN_E == 1000.0
    draws = shot_noise_electrons(np.full(SHAPE, mean), np.random.default_rng(22))
    assert np.array_equal(draws, np.rint(draws))
    assert abs(draws.mean() - mean) < N_SIGMA * math.sqrt(mean / N_PIX)
    assert abs(draws.var() - mean) < N_SIGMA * math.sqrt((2 * mean**2 + mean) / N_PIX)
    skew = float(stats.skew(draws.ravel()))
    expected_skew = 1.0 / math.sqrt(mean) if mean < SHOT_NOISE_NORMAL_MIN_MEAN_E else 0.0
    assert abs(skew - expected_skew) < N_SIGMA * math.sqrt(6.0 / N_PIX)
    # Exact everywhere on request: Poisson skewness above the limit too.
    if mean == 5000.0:
        exact = shot_noise_electrons(
            np.full(SHAPE, mean), np.random.default_rng(23), normal_min_mean_e=math.inf
        )
        assert abs(exact.mean() - mean) < N_SIGMA * math.sqrt(mean / N_PIX)


def test_box_muller_normals_are_standard_normal() -> None:
    # 2^20 draws (odd count: the last pair is cut): mean 0 (SE 1/sqrt(N)), variance 1 (SE
    # sqrt(2/N)), kurtosis 3 (SE sqrt(24/N)), and the Kolmogorov-Smirnov test at 0.1 %.
    n = (1 << 20) + 1
    z = _standard_normal_f32(np.random.default_rng(24), np.empty(n, dtype=np.float32))
    z64 = z.astype(np.float64)
    assert np.all(np.isfinite(z64))
    assert abs(z64.mean()) < N_SIGMA / math.sqrt(n)
    assert abs(z64.var() - 1.0) < N_SIGMA * math.sqrt(2.0 / n)
    assert abs(stats.kurtosis(z64)) < N_SIGMA * math.sqrt(24.0 / n)
    assert stats.kstest(z64, "norm").pvalue > 1e-3
    # The two halves (cos and sin of one pair) are uncorrelated.
    half = n // 2
    assert abs(np.corrcoef(z64[:half], z64[half : 2 * half])[0, 1]) < N_SIGMA / math.sqrt(half)


# --- parallel determinism ----------------------------------------------------------------
BANDED_SHAPE = (700, 1024)  # 256-row bands: 3 bands, the last one short


def _star_over_band_edge(params: DetectorParameters) -> np.ndarray:
    """Irradiance (BANDED_SHAPE): a sky of dark current, a textured target and one over-full
    pixel at row 250 whose blooming spills across the band edge at row 256."""
    rng = np.random.default_rng(30)
    irradiance = np.zeros(BANDED_SHAPE)
    irradiance[100:600, 100:500] = rng.uniform(0.2, 1.0, (500, 400)) * _irradiance_for_electrons(
        params, 2e5, 1.0
    )
    irradiance[250, 800] = _irradiance_for_electrons(params, 41 * params.full_well_e, 1.0)
    return irradiance


def test_detector_same_bytes_for_any_thread_count() -> None:
    params = DetectorParameters()
    irradiance = _star_over_band_edge(params)

    def frame(threads: int, seed: int = 5) -> bytes:
        rng = np.random.default_rng(seed)
        return simulate_detector(
            irradiance, 1.0, params, BAND_NM, rng, 12, threads=threads
        ).tobytes()

    one = frame(1)
    assert frame(2) == one
    assert frame(3) == one
    assert frame(1) == one
    assert frame(2, seed=6) != one
    e = np.full(BANDED_SHAPE, 1e4)
    reads = [read_out_dn(e, params, np.random.default_rng(8), threads=k) for k in (1, 2)]
    assert reads[0].tobytes() == reads[1].tobytes()
    shots = [shot_noise_electrons(e, np.random.default_rng(9), threads=k) for k in (1, 2)]
    assert shots[0].tobytes() == shots[1].tobytes()
    maps = [_draw_camera_maps(BANDED_SHAPE, 0.01, 1.0, 0.5, 3, k) for k in (1, 2)]
    assert maps[0][0].tobytes() == maps[1][0].tobytes()
    assert maps[0][1].tobytes() == maps[1][1].tobytes()


def test_blooming_across_a_band_edge_is_read_out() -> None:
    # 41 full wells in one pixel: 20 full wells spill up and 20 down, 41 full pixels in
    # rows 230..270 of column 800; rows 256..270 lie in a band with no over-full pixel of its
    # own, which must be read out again after the blooming.
    params = dataclasses.replace(NO_FPN, read_noise_e=0.0)
    dn = simulate_detector(
        _star_over_band_edge(params), 1.0, params, BAND_NM, np.random.default_rng(31), 0
    )
    column = dn[:, 800].astype(np.float64)
    full = np.flatnonzero(column > params.full_well_dn - 1)
    np.testing.assert_array_equal(full, np.arange(230, 271))
    assert np.all(column[:229] <= params.bias_dn + 1)
    assert np.all(column[272:] <= params.bias_dn + 1)
    assert np.all(dn <= params.full_well_dn + 1)
