"""Star field: positions against astropy, occlusion, the photons image through the PSF and
the detector, limiting magnitudes checked by Monte Carlo."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.constants as const

from qe_oracle import blackbody_qe
from satsight.camera.pinhole import PinholeCamera
from satsight.ephemeris.time import parse_epoch_utc
from satsight.errors import SatsightError
from satsight.sensor import detector as det
from satsight.sensor import exposure as ex
from satsight.sensor import limiting_magnitude as lm
from satsight.sensor import noise
from satsight.sensor import star_field as sf
from satsight.sensor import star_stamps as st
from satsight.sensor.mtf import band_wavelengths_m, diffraction_mtf
from satsight.sensor.optics import Optics
from satsight.sensor.star_astrometry import directions_icrs, unit_vectors
from satsight.sensor.star_catalog import load_star_catalog

EPOCH = "2026-03-20T12:00:00Z"
BAND = (450.0, 900.0)
R_SAT_M = np.array([4_100e3, -4_900e3, 2_800e3])  # LEO, |r| ~ 6980 km
V_SAT_M_S = np.array([5_600e3, 3_300e3, -2_400e3]) / 1e3  # ~7.0 km/s
PIXEL_M = 15e-6
MAS = math.pi / (180 * 3600e3)


@pytest.fixture(scope="module")
def catalog():
    return load_star_catalog(9.95)


def look_at(boresight_gcrs: np.ndarray) -> np.ndarray:
    """R_cam_from_gcrs with +z along the boresight, +x towards increasing RA."""
    z = boresight_gcrs / np.linalg.norm(boresight_gcrs)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def astropy_pixels(catalog, source_ids, R, camera, epoch_utc, r_m, v_m_s):
    """Independent projection: astropy space motion + GCRS (aberration, light deflection)."""
    import astropy.units as u
    from astropy.coordinates import GCRS, CartesianRepresentation, SkyCoord
    from astropy.time import Time
    from astropy.utils import iers
    from erfa import ErfaWarning

    k = np.searchsorted(catalog.source_id, source_ids, sorter=np.argsort(catalog.source_id))
    k = np.argsort(catalog.source_id)[k]
    assert np.all(catalog.source_id[k] == source_ids)
    t = Time(epoch_utc.rstrip("Z"), scale="utc")
    with iers.conf.set_temp("auto_download", False), warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=ErfaWarning, message=".*distance overridden")
        coord = SkyCoord(
            ra=catalog.ra_rad[k] * u.rad,
            dec=catalog.dec_rad[k] * u.rad,
            pm_ra_cosdec=catalog.pm_ra_cosdec_rad_per_yr[k] * u.rad / u.yr,
            pm_dec=catalog.pm_dec_rad_per_yr[k] * u.rad / u.yr,
            frame="icrs",
            obstime=Time(2016.0, format="jyear"),
        ).apply_space_motion(new_obstime=t)
        frame = GCRS(
            obstime=t,
            obsgeoloc=CartesianRepresentation(r_m * u.m),
            obsgeovel=CartesianRepresentation(v_m_s * u.m / u.s),
        )
        moved = SkyCoord(ra=coord.ra, dec=coord.dec, frame="icrs")  # infinitely distant
        apparent = moved.transform_to(frame)
    d = unit_vectors(apparent.ra.rad, apparent.dec.rad) @ R.T
    return camera.focal_length_px * d[:, :2] / d[:, 2:] + [camera.cx_px, camera.cy_px]


@pytest.mark.parametrize(
    ("camera", "target_hip", "min_stars"),
    [
        (PinholeCamera.wide_field(), None, 300),  # Cygnus star cloud
        (PinholeCamera.high_resolution(), 104214, 10),  # 61 Cyg A, 5.2 arcsec/yr
    ],
)
def test_positions_match_astropy(catalog, camera, target_hip, min_stars):
    """Pixel positions agree with astropy (apply_space_motion, then GCRS with the observer's
    geocentric position and velocity: aberration and solar light deflection) to < 0.02 px
    (measured 0.0016 px wide field, 0.0077 px high resolution)."""
    t = parse_epoch_utc(EPOCH)
    if target_hip is None:
        boresight = unit_vectors(np.radians(305.0), np.radians(40.0))
    else:
        k = np.flatnonzero(catalog.hip_id == target_hip)
        sub = sf._subset(catalog, k)
        boresight = directions_icrs(sub, sf.julian_year_tt(t))[0] + [2e-3, -1e-3, 0]
    R = look_at(np.asarray(boresight))
    stars = sf.stars_in_view(catalog, R, camera, EPOCH, V_SAT_M_S, margin_px=0.0)
    assert len(stars) >= min_stars
    if target_hip is not None:
        assert -target_hip in stars.source_id or np.any(
            np.isin(stars.source_id, catalog.source_id[catalog.hip_id == target_hip])
        )
    ref = astropy_pixels(catalog, stars.source_id, R, camera, EPOCH, R_SAT_M, V_SAT_M_S)
    dev = np.hypot(stars.x_px - ref[:, 0], stars.y_px - ref[:, 1])
    print(f"{camera.focal_length_m} m: {len(stars)} stars, max deviation {dev.max():.4f} px")
    assert dev.max() < 0.02


def test_proper_motion_moves_61_cyg_by_the_right_amount(catalog):
    """61 Cyg A moves ~5.28 arcsec/yr: ~53 arcsec (~51 px at f = 3 m) from J2016 to 2026."""
    k = np.flatnonzero(catalog.hip_id == 104214)
    sub = sf._subset(catalog, k)
    u0 = directions_icrs(sub, 2016.0)[0]
    u1 = directions_icrs(sub, 2026.0)[0]
    moved_arcsec = 2 * math.asin(0.5 * np.linalg.norm(u1 - u0)) / MAS / 1e3
    assert moved_arcsec == pytest.approx(52.8, abs=1.0)


def test_julian_year_and_earth_velocity():
    t = parse_epoch_utc("2000-01-01T11:58:55.816Z")  # J2000.0 = 12:00 TT
    assert sf.julian_year_tt(t) == pytest.approx(2000.0, abs=1e-9)
    v = sf.earth_velocity_bcrs_m_s(parse_epoch_utc(EPOCH))
    assert v.shape == (3,) and 29.0e3 < np.linalg.norm(v) < 30.5e3
    with pytest.raises(SatsightError, match="skyfield Time"):
        sf.earth_velocity_bcrs_m_s("2026-01-01")


# --- occlusion -------------------------------------------------------------------------------


def _field(catalog, **kwargs):
    R = look_at(unit_vectors(np.radians(305.0), np.radians(40.0)))
    cam = PinholeCamera.wide_field()
    return cam, sf.stars_in_view(catalog, R, cam, EPOCH, V_SAT_M_S, margin_px=0.0, **kwargs)


def test_sphere_hides_exactly_the_stars_within_its_angular_radius(catalog):
    cam, all_stars = _field(catalog)
    dirs = cam.ray_directions_cam(np.stack([all_stars.x_px, all_stars.y_px], 1))
    centre_dir = np.array([0.01, -0.005, 1.0])
    centre_dir /= np.linalg.norm(centre_dir)
    distance_m, angular_radius = 384_400e3, math.radians(1.0)
    sphere = (centre_dir * distance_m, distance_m * math.sin(angular_radius))
    _, shown = _field(catalog, occluding_spheres_cam=[sphere])
    angle = np.arccos(np.clip(dirs @ centre_dir, -1, 1))
    expected_hidden = set(all_stars.source_id[angle < angular_radius].tolist())
    hidden = set(all_stars.source_id.tolist()) - set(shown.source_id.tolist())
    assert hidden == expected_hidden and len(hidden) > 10
    assert shown.n_hidden_by_spheres == len(hidden)
    # A sphere behind the camera hides nothing; a camera inside a sphere sees nothing.
    _, behind = _field(catalog, occluding_spheres_cam=[(-centre_dir * distance_m, 1e6)])
    assert len(behind) == len(all_stars)
    _, inside = _field(catalog, occluding_spheres_cam=[(np.zeros(3) + 10.0, 100.0)])
    assert len(inside) == 0


def test_mask_pixel_hides_the_star_on_it(catalog):
    cam, all_stars = _field(catalog)
    j = int(np.argmin(all_stars.v_mag))
    mask = np.zeros((cam.height_px, cam.width_px), dtype=bool)
    mask[int(np.rint(all_stars.y_px[j])), int(np.rint(all_stars.x_px[j]))] = True
    _, shown = _field(catalog, object_mask=mask)
    assert shown.n_hidden_by_mask == 1
    assert all_stars.source_id[j] not in shown.source_id
    assert len(shown) == len(all_stars) - 1


# --- photons image ---------------------------------------------------------------------------


def one_star(x: float, y: float, v: float = 6.0, t: float = 5772.0) -> sf.StarsInView:
    from satsight.sensor.star_photometry import star_photon_flux_m2_s

    flux = star_photon_flux_m2_s(np.array([v]), np.array([t]), BAND)
    return sf.StarsInView(
        np.array([x]),
        np.array([y]),
        np.array([v]),
        np.array([t]),
        flux,
        np.array([1]),
        0,
        0,
        BAND,
    )


def test_photon_count_closed_form():
    optics = Optics.for_preset("high_resolution")
    star = one_star(30.0, 30.0)
    n = sf.star_photon_counts(star.photon_flux_m2_s, optics, 0.1)[0]
    expected = star.photon_flux_m2_s[0] * math.pi * 0.3**2 / 4 * 0.8 * 0.1
    assert n == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("preset", ["high_resolution", "wide_field"])
def test_image_conserves_photons_and_clips_at_edges(preset):
    optics = Optics.for_preset(preset)
    star = one_star(30.27, 25.61)
    n = sf.star_photon_counts(star.photon_flux_m2_s, optics, 0.05)[0]
    img = st.star_photons_image(star, (64, 80), optics, PIXEL_M, 0.05, BAND)
    assert img.dtype == np.float32 and img.shape == (64, 80)
    assert img.sum(dtype=np.float64) == pytest.approx(n, rel=1e-6)  # enclosed fraction 1
    # A star near the corner: only the in-frame part of its stamp lands.
    edge = one_star(-1.3, 2.2)
    img = st.star_photons_image(edge, (64, 80), optics, PIXEL_M, 0.05, BAND)
    stamp = st.psf_stamps(
        np.array([-0.3]), np.array([0.2]), np.array([5772.0]), optics, PIXEL_M, BAND
    )[0]
    inside = stamp[8 - 2 :, 8 + 1 :].sum()  # rows y >= 0 (centre row 2), columns x >= 0
    assert img.sum(dtype=np.float64) == pytest.approx(n * inside, rel=1e-6)
    assert 0.005 < inside < 0.1  # its centre is 1.3 px left of the frame


def test_psf_stamp_matches_pixel_integrated_airy():
    """Core of the stamp vs the Airy PSF integrated over pixels (psf.psf_kernel, 9 x 9
    sub-pixels of 5 x 5 samples each), band-weighted by the same photon spectrum: agree to
    the ~1 % of the wings that psf_kernel renormalises into its core."""
    from satsight.sensor.psf import psf_kernel

    optics = Optics.for_preset("high_resolution")
    lam = band_wavelengths_m(BAND, 16)
    w = lam**-4 / np.expm1(const.h * const.c / (lam * const.k * 5772.0))
    kernel = psf_kernel(optics, lam, w, PIXEL_M / 9, 17 * 9, subsamples=5)
    binned = kernel.reshape(17, 9, 17, 9).sum(axis=(1, 3))
    stamp = st.psf_stamps(np.zeros(1), np.zeros(1), np.array([5772.0]), optics, PIXEL_M, BAND)[0]
    core = np.s_[6:11, 6:11]
    assert np.allclose(stamp[core], binned[core], rtol=0.02, atol=2e-4)
    assert stamp[8, 8] == pytest.approx(binned[8, 8], rel=0.015)


def test_defocused_star_stamp_spreads_its_light_over_the_blur_disc():
    """A 6-pixel (90 um) geometric blur disc through the stamps' OTF: each stamp still sums to
    1, the centre pixel falls from ~0.84 to about the pixel's share of the disc,
    p^2 / (pi d^2 / 4) = 0.0354 (times the ~97 % of the light in the disc's core), and the
    stamp agrees with the spatial-domain kernel (psf.psf_kernel, Airy averaged over 5 x 5
    points in each of 9 x 9 sub-pixels, convolved with the area-averaged disc) to the ~1 % of
    the wings that psf_kernel renormalises into its core."""
    from satsight.sensor.psf import psf_kernel

    d_m = 6 * PIXEL_M
    sharp = Optics.for_preset("high_resolution")
    optics = Optics.for_preset("high_resolution", defocus_blur_diameter_m=d_m)
    t = np.array([5772.0, 5772.0])
    focused = st.psf_stamps(np.array([0.0, 0.3]), np.array([0.0, -0.2]), t, sharp, PIXEL_M, BAND)
    stamps = st.psf_stamps(np.array([0.0, 0.3]), np.array([0.0, -0.2]), t, optics, PIXEL_M, BAND)
    np.testing.assert_allclose(stamps.sum(axis=(1, 2)), 1.0, rtol=0, atol=1e-12)
    assert focused[0, 8, 8] > 0.8
    share = PIXEL_M**2 / (math.pi * d_m**2 / 4)
    assert 0.95 * share < stamps[0, 8, 8] < share
    assert stamps[:, 8, 8].max() < 0.05 * focused[:, 8, 8].min()
    # the sub-pixel shift still moves the light: first moment of the shifted stamp
    y, x = np.mgrid[-8:9, -8:9]
    assert (stamps[1] * x).sum() == pytest.approx(0.3, abs=0.02)
    assert (stamps[1] * y).sum() == pytest.approx(-0.2, abs=0.02)
    lam = band_wavelengths_m(BAND, 16)
    w = lam**-4 / np.expm1(const.h * const.c / (lam * const.k * 5772.0))
    kernel = psf_kernel(optics, lam, w, PIXEL_M / 9, 17 * 9, subsamples=5)
    binned = kernel.reshape(17, 9, 17, 9).sum(axis=(1, 3))
    core = np.s_[4:13, 4:13]
    assert np.allclose(stamps[0][core], binned[core], rtol=0.015, atol=5e-4)


def test_centroid_equals_position_for_a_well_sampled_symmetric_psf():
    """With 1 px rms jitter (OTF ~ 0 at 1/p) the first moment equals the sub-pixel position
    to < 0.01 px."""
    optics = Optics.for_preset("high_resolution", jitter_rms_rad=PIXEL_M / 3.0)
    y, x = np.mgrid[-16:17, -16:17]
    for dx, dy in [(0.0, 0.0), (0.3, -0.2), (-0.5, 0.45), (0.12, 0.37)]:
        s = st.psf_stamps(
            np.array([dx]),
            np.array([dy]),
            np.array([5772.0]),
            optics,
            PIXEL_M,
            BAND,
            stamp_radius_px=16,
        )[0]
        assert (s * x).sum() == pytest.approx(dx, abs=0.01)
        assert (s * y).sum() == pytest.approx(dy, abs=0.01)


def test_centroid_bias_of_undersampled_psf_matches_aliasing_theory():
    """Undersampled (diffraction-limited) PSF: the pixel first moment is
    x0 + (1/pi) sum_k (-1)^k OTF(k/p) sin(2 pi k x0) / k (Poisson summation of the sampled,
    pixel-integrated PSF); checks the sub-pixel phase and the aliasing of the stamps."""
    optics = Optics.for_preset("high_resolution")
    lam = band_wavelengths_m(BAND, 16)
    w = lam**-4 / np.expm1(const.h * const.c / (lam * const.k * 5772.0))
    w /= w.sum()
    x = np.arange(-24, 25)
    for x0 in (0.1, 0.3, -0.45):
        s = st.psf_stamps(
            np.array([x0]),
            np.zeros(1),
            np.array([5772.0]),
            optics,
            PIXEL_M,
            BAND,
            stamp_radius_px=24,
        )[0]
        k = np.arange(1, 8)
        otf = sum(
            wi * diffraction_mtf(k / PIXEL_M, li, optics.f_number)
            for li, wi in zip(lam, w, strict=True)
        )
        theory = x0 + np.sum((-1.0) ** k * otf * np.sin(2 * math.pi * k * x0) / k) / math.pi
        assert (s.sum(0) * x).sum() == pytest.approx(theory, abs=0.005)
        assert abs(theory - x0) > 0.02  # the bias is real


def test_isolated_star_dn_reproduces_photon_count():
    """Photons image -> detector chain (expected_electrons, Poisson, saturation, read-out
    with noise and rounding) averaged over K seeds: sum(DN - bias) g / QE = N within 2 %,
    QE the curve's photon-weighted mean over the star's black body (oracle from the data
    files)."""
    optics = Optics.for_preset("wide_field")
    params = det.DetectorParameters()
    star = one_star(20.4, 19.8, v=7.0)
    qe = float(blackbody_qe(*BAND, star.temperature_k)[0])
    t = 0.05
    photons = st.star_photons_image(star, (40, 40), optics, PIXEL_M, t, BAND).astype(np.float64)
    n_true = sf.star_photon_counts(star.photon_flux_m2_s, optics, t)[0]
    assert photons.max() * qe < 0.5 * params.full_well_e
    mean_e = det.expected_electrons(photons, qe, 1.0, params.dark_current_e_per_s, 0.0, t)
    n_px = photons.size
    var_sum = mean_e.sum() + n_px * (
        params.read_noise_e**2 + params.conversion_gain_e_per_dn**2 / 12
    )
    k = 200
    sd_rel = math.sqrt(var_sum / k) / (qe * n_true)
    assert 4 * sd_rel < 0.005  # statistical error well below the 2 % tolerance
    rng = np.random.default_rng(np.random.SeedSequence([2026, 3]))
    sums = []
    for _ in range(k):
        e = noise.shot_noise_electrons(mean_e, rng)
        e = ex.saturate_electrons(e, params.full_well_e, params.blooming)
        dn = noise.read_out_dn(e, params, rng).astype(np.float64)
        sums.append((dn - params.bias_dn).sum() * params.conversion_gain_e_per_dn)
    dark = n_px * params.dark_current_e_per_s * t
    recovered = (np.mean(sums) - dark) / qe
    print(f"N = {n_true:.1f} photons, recovered {recovered:.1f}")
    assert recovered == pytest.approx(n_true, rel=0.02)


# --- limiting magnitude ----------------------------------------------------------------------


@pytest.mark.parametrize("preset", ["high_resolution", "wide_field"])
def test_limiting_magnitude_monte_carlo(preset):
    """At the limiting magnitude, simulated stamps (Poisson photo-electrons, dark, Gaussian
    read noise, rounding to DN) measured in the chosen aperture give SNR = 5. With K trials
    the estimate mean/std has relative sd sqrt(1/(K SNR^2) + 1/(2K)); 4 sd tolerance."""
    optics = Optics.for_preset(preset)
    params = det.DetectorParameters()
    t = 0.1
    res = lm.limiting_magnitude_details(optics, params, t, BAND, snr=5.0)
    assert res.v_mag == pytest.approx(lm.limiting_magnitude(optics, params, t, BAND))
    # The star's QE: the curve's photon-weighted mean over a 5772 K black body (the oracle's
    # fine-grid quadrature agrees with the library's to < 1e-6).
    qe = float(blackbody_qe(*BAND, np.array([5772.0]))[0])
    assert res.quantum_efficiency == pytest.approx(qe, rel=1e-5)
    k = 20_000
    photons = np.tile(res.fraction * res.photons, (k, 1))  # (K S, S)
    rng = np.random.default_rng(np.random.SeedSequence([5, k]))
    mean_e = det.expected_electrons(photons, qe, 1.0, params.dark_current_e_per_s, 0.0, t)
    dn = noise.read_out_dn(noise.shot_noise_electrons(mean_e, rng), params, rng).astype(np.float64)
    s = res.fraction.shape[0]
    signal_e = ((dn - params.bias_dn) * params.conversion_gain_e_per_dn).reshape(k, s, s)
    signal_e = (
        signal_e[:, res.aperture].sum(axis=1) - res.n_pixels * params.dark_current_e_per_s * t
    )
    snr = signal_e.mean() / signal_e.std(ddof=1)
    tol = 4 * math.sqrt(1 / (k * 25.0) + 1 / (2 * k))
    print(f"{preset}: V_lim {res.v_mag:.2f}, n = {res.n_pixels} px, MC SNR {snr:.3f}")
    assert snr == pytest.approx(5.0, rel=tol)
    assert signal_e.mean() == pytest.approx(res.signal_e, rel=4 / (5 * math.sqrt(k)))


@pytest.mark.parametrize("temperature_k", [3500.0, 5772.0, 15000.0])
def test_limiting_magnitude_moves_with_the_stars_own_qe(temperature_k):
    """The SNR fixes the electrons x in the aperture, so the photons N = x / (eta F_n) and
    V = -2.5 log10 N + const: a scalar eta = 0.9 against the curve's mean over the star's
    black body moves the limit by exactly 2.5 log10(0.9 / eta_star), +0.11 mag at 5772 K."""
    optics = Optics.for_preset("wide_field")

    def v_lim(params: det.DetectorParameters) -> float:
        return lm.limiting_magnitude(optics, params, 0.1, BAND, temperature_k=temperature_k)

    curve = v_lim(det.DetectorParameters())
    scalar = v_lim(det.DetectorParameters(quantum_efficiency=0.9))
    eta_star = float(blackbody_qe(*BAND, np.array([temperature_k]))[0])
    assert scalar - curve == pytest.approx(2.5 * math.log10(0.9 / eta_star), abs=1e-5)


def test_limiting_magnitude_scaling():
    """Fainter with longer exposures: per decade of exposure the limit moves by 2.5 mag when
    read noise dominates (SNR ~ N) and by 1.25 mag when the star's shot noise does
    (SNR ~ sqrt N); at SNR 5 and 5 e- read noise the steps lie between."""
    params = det.DetectorParameters()
    for preset in ("high_resolution", "wide_field"):
        optics = Optics.for_preset(preset)
        v = [lm.limiting_magnitude(optics, params, t) for t in (1e-3, 1e-2, 1e-1, 1.0)]
        steps = np.diff(v)
        assert np.all(steps > 1.2) and np.all(steps < 2.6)


# --- bad input -------------------------------------------------------------------------------


def test_bad_input_raises(catalog):
    cam = PinholeCamera.wide_field()
    R = np.eye(3)
    optics = Optics.for_preset("wide_field")
    star = one_star(10.0, 10.0)
    with pytest.raises(SatsightError, match="3, 3"):
        sf.stars_in_view(catalog, np.eye(2), cam, EPOCH, V_SAT_M_S)
    with pytest.raises(SatsightError, match="proper rotation"):
        sf.stars_in_view(catalog, 2 * R, cam, EPOCH, V_SAT_M_S)
    with pytest.raises(SatsightError, match="camera_velocity"):
        sf.stars_in_view(catalog, R, cam, EPOCH, [np.nan, 0, 0])
    with pytest.raises(SatsightError, match="ISO"):
        sf.stars_in_view(catalog, R, cam, "yesterday", V_SAT_M_S)
    with pytest.raises(SatsightError, match="band_nm"):
        sf.stars_in_view(catalog, R, cam, EPOCH, V_SAT_M_S, band_nm=(900, 450))
    with pytest.raises(SatsightError, match="occluding_spheres_cam"):
        sf.stars_in_view(
            catalog, R, cam, EPOCH, V_SAT_M_S, occluding_spheres_cam=[(np.zeros(3), -1.0)]
        )
    with pytest.raises(SatsightError, match="object_mask"):
        sf.stars_in_view(catalog, R, cam, EPOCH, V_SAT_M_S, object_mask=np.zeros((3, 3), bool))
    with pytest.raises(SatsightError, match="exposure_time_s"):
        st.star_photons_image(star, (20, 20), optics, PIXEL_M, -1.0, BAND)
    with pytest.raises(SatsightError, match="band"):
        st.star_photons_image(star, (20, 20), optics, PIXEL_M, 1.0, (400, 700))
    with pytest.raises(SatsightError, match="shape_hw"):
        st.star_photons_image(star, (20,), optics, PIXEL_M, 1.0, BAND)
    with pytest.raises(SatsightError, match="one per star"):
        st.star_photons_image(star, (20, 20), optics, PIXEL_M, 1.0, BAND, scale=np.ones(2))
    with pytest.raises(SatsightError, match="scale must be"):
        st.star_photons_image(star, (20, 20), optics, PIXEL_M, 1.0, BAND, scale=-1.0)
    with pytest.raises(SatsightError, match="exposure_time_s"):
        lm.limiting_magnitude(optics, det.DetectorParameters(), 0.0)
    with pytest.raises(SatsightError, match="snr"):
        lm.limiting_magnitude(optics, det.DetectorParameters(), 1.0, snr=-1)
