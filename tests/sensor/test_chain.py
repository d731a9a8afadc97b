"""The frame's sensor chain: channel weights, exposure rule, photon bookkeeping, readout."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from kernel_taps import edge_and_corner_loss, frame_kernel_taps
from qe_oracle import blackbody_qe, solar_photon_integrals, solar_qe
from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import band_irradiance_w_m2
from satsight.render.buffers import RadianceImage, margin_pixels_xy, mask_box, within_box
from satsight.sensor.chain import SensorChain, exposure_regions
from satsight.sensor.detector import DetectorParameters, photons_per_pixel
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.mtf import band_wavelengths_m
from satsight.sensor.optics import Optics
from satsight.sensor.star_field import StarsInView, star_photon_counts
from satsight.sensor.star_stamps import star_photons_image

BAND_NM = (450.0, 900.0)
H_PLANCK_J_S = 6.62607015e-34
C_M_S = 299_792_458.0
#: The CCD231-84 curve's mean over the band for E-490 sunlight, from the data files.
SOLAR_QE = solar_qe(*BAND_NM)
#: Relative tolerance of the QE-weighted counts: the oracle's fine-grid quadrature against
#: the library's node sums (< 3e-6, see qe_oracle) plus float32 rounding of the weights and
#: the irradiance (~1e-7 each).
QE_RTOL = 1e-5
#: A detector without fixed pattern or dark current: its mean electrons are eta x photons.
CLEAN = {"prnu_fraction": 0.0, "dsnu_e_per_s": 0.0, "dark_current_e_per_s": 0.0}


def _chain(
    exposure: ExposureRule | None = None, size_px: tuple[int, int] = (96, 80), **detector
) -> SensorChain:
    camera = PinholeCamera.high_resolution().with_size(*size_px)
    return SensorChain(
        camera=camera,
        optics=Optics.for_preset("high_resolution"),
        detector=DetectorParameters(pixel_pitch_m=camera.pixel_pitch_m, **detector),
        band_nm=BAND_NM,
        exposure=exposure or ExposureRule(),
        camera_seed=3,
    )


def _image(radiance_rgb: np.ndarray) -> RadianceImage:
    h, w = radiance_rgb.shape[:2]
    hit = radiance_rgb.any(axis=2)
    return RadianceImage(
        radiance_w_m2_sr=radiance_rgb.astype(np.float32),
        depth_m=np.where(hit, np.float32(1000.0), np.float32(0.0)),
        part_id=hit.astype(np.uint16),
        normals_cam=np.zeros((h, w, 3), np.float32),
    )


def test_channel_weights_are_the_solar_thirds_of_the_band() -> None:
    chain = _chain()
    thirds = [band_irradiance_w_m2((450.0 + 150.0 * k, 600.0 + 150.0 * k)) for k in range(3)]
    blue, green, red = np.array(thirds) / sum(thirds)
    np.testing.assert_allclose(chain.channel_weights, [red, green, blue], rtol=1e-6)
    # A grey surface: every channel equal, so the band radiance is that value.
    grey = np.full((4, 5, 3), 7.5, np.float32)
    np.testing.assert_allclose(chain.band_radiance_w_m2_sr(grey), 7.5, rtol=1e-6)


def test_effective_wavelength_is_inside_the_band_and_sets_the_photon_energy() -> None:
    chain = _chain()
    assert 450e-9 < chain.effective_wavelength_m < 900e-9
    assert chain.photon_energy_j == pytest.approx(
        H_PLANCK_J_S * C_M_S / chain.effective_wavelength_m, rel=1e-12
    )


def test_photons_as_irradiance_round_trips_through_the_detector() -> None:
    chain = _chain()
    photons = np.random.default_rng(1).uniform(0.0, 5e4, size=(6, 7)).astype(np.float32)
    t = 0.004
    irradiance = chain.photons_as_irradiance_w_m2(photons, t)
    back = photons_per_pixel(irradiance, chain.detector.pixel_area_m2, t, chain.photon_energy_j)
    np.testing.assert_allclose(back, photons, rtol=1e-6)


def test_auto_exposure_fills_the_chosen_fraction_at_the_percentile() -> None:
    chain = _chain(ExposureRule(fill_fraction=0.6, percentile=50.0))
    irradiance = np.zeros((80, 96), np.float32)
    irradiance[10:30, 10:60] = 0.25
    irradiance[30:50, 10:60] = 0.5  # the median of the lit target is between the two
    irradiance[50:52, 10:60] = 400.0  # a glint, far above
    mask = irradiance > 0
    t = chain.exposure_time_s(irradiance, mask)
    level = float(np.percentile(irradiance[mask], 50.0))
    d = chain.detector
    rate_e_per_s = SOLAR_QE * level * d.pixel_area_m2 / chain.photon_energy_j
    assert t == pytest.approx(
        0.6 * d.full_well_e / (rate_e_per_s + d.dark_current_e_per_s), rel=QE_RTOL
    )


def test_exposure_rule_falls_back_and_clips() -> None:
    irradiance = np.full((80, 96), 1e-9, np.float32)
    mask = np.zeros((80, 96), bool)
    # No target on the frame: the configured time.
    assert _chain(ExposureRule(time_s=0.02)).exposure_time_s(irradiance, mask) == 0.02
    # A very faint target: the longest time allowed.
    mask[:5, :5] = True
    clipped = _chain(ExposureRule(max_time_s=2.0)).exposure_time_s(irradiance, mask)
    assert clipped == 2.0
    # Fixed mode ignores the scene.
    fixed = _chain(ExposureRule(mode="fixed", time_s=0.5)).exposure_time_s(irradiance, mask)
    assert fixed == 0.5


def test_uniform_patch_reads_the_closed_form_dn() -> None:
    """A large grey patch: inside it, mean DN = bias + QE E A t / (h c / lambda_eff) / g with
    E = pi L tau / (4 N^2); the sky beyond the blur's reach reads the bias. "Inside" and
    "beyond" are farther than the kernel's radius (20 px) from the patch's edge: nearer, the
    Airy wings carry light out of the patch (~0.5 % at 8 px inside it)."""
    chain = _chain(ExposureRule(mode="fixed", time_s=0.002), size_px=(180, 140))
    radiance = np.zeros((140, 180, 3), np.float32)
    radiance[40:120, 30:150] = 30.0
    image = _image(radiance)
    irradiance = chain.focal_plane_irradiance_w_m2(image)
    dn = chain.read_out(irradiance, 0.002, np.random.default_rng(5)).dn
    d, optics = chain.detector, chain.optics
    e_w_m2 = math.pi * 30.0 * optics.transmission / (4.0 * optics.f_number**2)
    electrons = SOLAR_QE * e_w_m2 * d.pixel_area_m2 * 0.002 / chain.photon_energy_j
    inner = dn[61:99, 51:129].astype(np.float64)
    # Per-pixel spread: shot noise, 1 % PRNU, read noise and quantisation, in DN.
    sigma_dn = math.sqrt(electrons + (0.01 * electrons) ** 2 + d.read_noise_e**2) / (
        d.conversion_gain_e_per_dn
    )
    sem = math.hypot(sigma_dn, math.sqrt(1 / 12)) / math.sqrt(inner.size)
    expected = d.bias_dn + electrons / d.conversion_gain_e_per_dn
    assert abs(inner.mean() - expected) < 5 * sem
    sky = dn[:19, :].astype(np.float64)
    assert abs(sky.mean() - d.bias_dn) < 5 * 1.0 / math.sqrt(sky.size) + 0.01


def test_same_seed_same_bytes_other_seed_other_bytes() -> None:
    chain = _chain()
    irradiance = np.full((80, 96), 0.3, np.float32)
    a = chain.read_out(irradiance, 0.001, np.random.default_rng(9)).dn
    b = chain.read_out(irradiance, 0.001, np.random.default_rng(9)).dn
    c = chain.read_out(irradiance, 0.001, np.random.default_rng(10)).dn
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()


def test_saturated_pixels_are_counted() -> None:
    chain = _chain(blooming=False)
    irradiance = np.zeros((80, 96), np.float32)
    irradiance[:3, :4] = 1e6  # far beyond full well in any exposure
    out = chain.read_out(irradiance, 0.01, np.random.default_rng(2))
    assert out.saturated_pixel_count == 12
    assert out.exposure_time_s == 0.01
    assert out.labels()["saturated_pixel_count"] == 12


def test_optics_and_camera_must_agree() -> None:
    camera = PinholeCamera.high_resolution()
    with pytest.raises(SatsightError, match="focal length"):
        SensorChain(
            camera=camera,
            optics=Optics.for_preset("wide_field"),
            detector=DetectorParameters(),
            band_nm=BAND_NM,
        )
    with pytest.raises(SatsightError, match="pixel pitch"):
        SensorChain(
            camera=camera,
            optics=Optics.for_preset("high_resolution"),
            detector=DetectorParameters(pixel_pitch_m=10e-6),
            band_nm=BAND_NM,
        )


def test_psf_kernel_grows_with_the_defocus_blur_disc() -> None:
    camera = PinholeCamera.high_resolution().with_size(96, 80)
    focused = _chain()
    blurred = SensorChain(
        camera=camera,
        optics=Optics.for_preset("high_resolution", defocus_blur_diameter_m=300e-6),
        detector=DetectorParameters(),
        band_nm=BAND_NM,
    )
    assert focused.psf.shape == (41, 41)
    assert focused.margin_px == 20
    # A 20-pixel disc fits inside the kernel with the diffraction margin kept.
    assert blurred.psf.shape == (61, 61)
    assert blurred.margin_px == 30
    assert float(blurred.psf.sum()) == pytest.approx(1.0, abs=1e-6)
    # The disc's light is spread: the centre holds about one disc pixel's share.
    assert float(blurred.psf.max()) == pytest.approx(4 / (math.pi * 20**2), rel=0.1)


@pytest.mark.parametrize("channel", [0, 1, 2], ids=["red", "green", "blue"])
def test_a_coloured_patch_counts_the_electrons_of_its_own_third(channel) -> None:
    """Light in one channel only: a Lambertian plate whose reflectance rho_c holds over that
    third of the band and is 0 elsewhere, under E-490 sunlight at 1 AU. Its channel radiance
    is rho_c E_band / pi; its electrons are rho_c tau A t / (4 N^2 h c) int_third E l QE dl:
    the third's photons at its own photon-weighted wavelength (not the band's, which would
    miscount red light by +27 % and blue light by -19 %) and at its own QE (0.904, 0.886,
    0.627 from blue to red; the band's 0.813 would miscount red light by +30 %)."""
    chain = _chain(ExposureRule(mode="fixed", time_s=0.002), size_px=(140, 120), **CLEAN)
    radiance = np.zeros((120, 140, 3), np.float32)
    radiance[20:100, 20:120, channel] = 40.0
    irradiance = chain.focal_plane_irradiance_w_m2(_image(radiance))
    lo, hi = {0: (750.0, 900.0), 1: (600.0, 750.0), 2: (450.0, 600.0)}[channel]
    band_w_m2 = solar_photon_integrals(*BAND_NM)[0]
    electrons_per_m2_s = solar_photon_integrals(lo, hi)[2]
    optics, d = chain.optics, chain.detector
    rho = 40.0 * math.pi / band_w_m2
    expected = (rho * optics.transmission / (4 * optics.f_number**2) * electrons_per_m2_s) * (
        d.pixel_area_m2 * 0.002
    )
    got = chain.mean_electrons(irradiance, 0.002)
    # Inside the patch, beyond the kernel's reach (20 px) from its edges.
    np.testing.assert_allclose(got[41:79, 41:99], expected, rtol=QE_RTOL)
    assert chain.channel_quantum_efficiency[channel] == pytest.approx(solar_qe(lo, hi), rel=QE_RTOL)


def test_a_grey_lambert_plate_counts_the_photon_weighted_qe_of_sunlight() -> None:
    """A grey Lambertian plate of albedo rho facing the Sun at 1 AU: every channel holds
    rho E_band / pi, and its mean electrons per pixel are rho tau A t / (4 N^2 h c) int E l QE
    dl over the band, the curve's photon-weighted mean (0.8127) times its photons. The
    chain's eta is that mean, and the channel weights of a grey surface sum to 1."""
    chain = _chain(size_px=(140, 120), **CLEAN)
    band_w_m2, photons_per_m2_s, electrons_per_m2_s = solar_photon_integrals(*BAND_NM)
    rho, t = 0.3, 0.004
    radiance = np.zeros((120, 140, 3), np.float32)
    radiance[20:100, 20:120] = rho * band_w_m2 / math.pi
    got = chain.mean_electrons(chain.focal_plane_irradiance_w_m2(_image(radiance)), t)
    optics, d = chain.optics, chain.detector
    scale = rho * optics.transmission / (4 * optics.f_number**2) * d.pixel_area_m2 * t
    np.testing.assert_allclose(got[41:79, 41:99], scale * electrons_per_m2_s, rtol=QE_RTOL)
    assert chain.quantum_efficiency == pytest.approx(
        electrons_per_m2_s / photons_per_m2_s, rel=QE_RTOL
    )
    assert 0.81 < chain.quantum_efficiency < 0.815
    assert float(chain.channel_detected_weights.sum()) == pytest.approx(1.0, abs=1e-6)
    assert "CCD231-84 curve" in chain.quantum_efficiency_source
    assert "[450, 900] nm" in chain.quantum_efficiency_source


def test_a_scalar_quantum_efficiency_overrides_the_curve_everywhere() -> None:
    """quantum_efficiency = 0.7: eta is 0.7 for every channel and every star, so a plate's
    electrons are 0.7 x its photons, whatever its colour, and the source says so."""
    chain = _chain(size_px=(140, 120), quantum_efficiency=0.7, **CLEAN)
    assert chain.quantum_efficiency == 0.7
    assert chain.quantum_efficiency_source == "scalar override"
    np.testing.assert_array_equal(chain.channel_quantum_efficiency, [0.7, 0.7, 0.7])
    np.testing.assert_allclose(chain.channel_detected_weights, chain.channel_photon_weights)
    np.testing.assert_array_equal(
        chain.star_quantum_efficiency_ratio(np.array([3000.0, 30000.0])), [1.0, 1.0]
    )
    band_w_m2, photons_per_m2_s, _ = solar_photon_integrals(*BAND_NM)
    _, red_photons_per_m2_s, _ = solar_photon_integrals(750.0, 900.0)
    radiance = np.zeros((120, 140, 3), np.float32)
    radiance[20:100, 20:70] = 0.3 * band_w_m2 / math.pi  # grey
    radiance[20:100, 70:120, 0] = 0.3 * band_w_m2 / math.pi  # red only
    got = chain.mean_electrons(chain.focal_plane_irradiance_w_m2(_image(radiance)), 0.004)
    optics, d = chain.optics, chain.detector
    scale = 0.3 * optics.transmission / (4 * optics.f_number**2) * d.pixel_area_m2 * 0.004
    # Grey: 1e-5 as above; red: the chain's wavelength of the third (exact integrals of the
    # E-490 interpolant) against the fine-grid oracle, and float32 weights.
    np.testing.assert_allclose(got[41:79, 41:49], 0.7 * scale * photons_per_m2_s, rtol=QE_RTOL)
    np.testing.assert_allclose(got[41:79, 91:99], 0.7 * scale * red_photons_per_m2_s, rtol=QE_RTOL)


@pytest.mark.parametrize("temperature_k", [3000.0, 5772.0, 20000.0])
def test_an_isolated_stars_electrons_follow_its_own_black_body_qe(temperature_k) -> None:
    """A star's photons, added to the focal plane as the pipeline does (photons to
    irradiance, times eta_star / eta), give eta_star N electrons in all, eta_star the
    curve's photon-weighted mean over its black body: 0.737 at 3000 K, 0.809 at 5772 K,
    0.846 at 20000 K, none of them the sunlight's 0.813."""
    chain = _chain(size_px=(64, 64), **CLEAN)
    flux = np.array([2e7])  # photons s^-1 m^-2
    temperature = np.array([temperature_k])
    stars = StarsInView(
        x_px=np.array([31.3]),
        y_px=np.array([32.6]),
        v_mag=np.array([5.0]),
        temperature_k=temperature,
        photon_flux_m2_s=flux,
        source_id=np.array([1]),
        n_hidden_by_spheres=0,
        n_hidden_by_mask=0,
        band_nm=BAND_NM,
    )
    t = 0.01
    irradiance = np.zeros((64, 64), np.float32)
    scale = chain.photons_to_irradiance_factor(t) * chain.star_quantum_efficiency_ratio(temperature)
    star_photons_image(
        stars, (64, 64), chain.optics, chain.camera.pixel_pitch_m, t, BAND_NM,
        out=irradiance, scale=scale,
    )  # fmt: skip
    photons = float(star_photon_counts(flux, chain.optics, t)[0])
    eta_star = float(blackbody_qe(*BAND_NM, temperature)[0])
    # The stamp (17 x 17 px) lies inside the frame and sums to 1; float32 sums over it.
    assert float(chain.mean_electrons(irradiance, t).sum()) == pytest.approx(
        eta_star * photons, rel=QE_RTOL
    )
    assert abs(eta_star - SOLAR_QE) > 0.003


def test_light_outside_the_object_mask_is_kept() -> None:
    """With supersampling a pixel whose centre misses the target still carries light; a
    target smaller than a pixel may leave the mask empty. Its light must reach the detector."""
    chain = _chain()
    radiance = np.zeros((80, 96, 3), np.float32)
    radiance[40, 50] = 70.0  # no surface at any pixel centre: depth 0, part 0
    image = RadianceImage(
        radiance_w_m2_sr=radiance,
        depth_m=np.zeros((80, 96), np.float32),
        part_id=np.zeros((80, 96), np.uint16),
        normals_cam=np.zeros((80, 96, 3), np.float32),
    )
    assert not image.object_mask.any()
    irradiance = chain.focal_plane_irradiance_w_m2(image)
    optics = chain.optics
    expected = 70.0 * math.pi * optics.transmission / (4 * optics.f_number**2)
    # The kernel spreads it; the sum over the frame keeps it (far from the edges): the dips
    # of its negative side lobes (8.9 % of the power at f/10) are taken back from the pixels
    # around them, not clipped (which read this lone pixel 8.9 % bright). Bound: float32
    # round-off of the sums, 1e-5.
    kernel = chain.psf.astype(np.float64)
    assert kernel.sum() == pytest.approx(1.0, abs=1e-6)
    assert float(-kernel[kernel < 0].sum()) > 0.07
    assert irradiance.min() >= 0.0
    assert float(irradiance.sum()) == pytest.approx(expected, rel=1e-5)


def _with_ring(radiance_rgb: np.ndarray, margin_px: int) -> RadianceImage:
    """A frame whose radiance comes from the middle of a larger (H + 2m, W + 2m, 3) scene,
    with the rest as its margin ring (the renderer's ``margin_pixels_xy`` order)."""
    m = margin_px
    h, w = radiance_rgb.shape[0] - 2 * m, radiance_rgb.shape[1] - 2 * m
    x, y = margin_pixels_xy(w, h, m)
    inner = _image(radiance_rgb[m : m + h, m : m + w])
    return dataclasses.replace(
        inner, margin_px=m, margin_radiance_w_m2_sr=radiance_rgb[y + m, x + m].astype(np.float32)
    )


def test_a_scene_filling_the_frame_reads_uniform_to_the_corners_with_the_margin() -> None:
    # Every frame pixel's kernel footprint lies on the uniform scene, so each reads the
    # camera equation's irradiance exactly, up to float32 rounding (~1e-7; bound 1e-5).
    # Without the ring the frame is dark beyond its edge and the edge pixels read low.
    chain = _chain()
    m = chain.margin_px
    scene = np.full((80 + 2 * m, 96 + 2 * m, 3), 25.0, np.float32)
    optics = chain.optics
    expected = 25.0 * math.pi * optics.transmission / (4.0 * optics.f_number**2)
    irradiance = chain.focal_plane_irradiance_w_m2(_with_ring(scene, m))
    assert irradiance.shape == (80, 96)
    np.testing.assert_allclose(irradiance, expected, rtol=1e-5)
    bare = chain.focal_plane_irradiance_w_m2(_image(scene[m:-m, m:-m]))
    # The expected losses are the taps beyond the frame's edge, from the taps' defining
    # integral (kernel_taps.edge_and_corner_loss). The designed taps differ from those by
    # < 3e-6 each (test_psf), so a sum of at most 41 x 20 taps by < 2.5e-3; float32 FFT
    # round-off adds ~1e-6. Tolerance 2.5e-3.
    edge, corner = edge_and_corner_loss(
        frame_kernel_taps(optics, band_wavelengths_m(BAND_NM), chain.camera.pixel_pitch_m, 41)
    )
    assert chain.psf.shape == (41, 41)
    assert bare[40, 0] / expected == pytest.approx(1 - edge, abs=2.5e-3)  # edge rows: -12.0 %
    assert bare[0, 0] / expected == pytest.approx(1 - corner, abs=2.5e-3)  # corners: -21.8 %
    # A wider ring than the kernel needs changes nothing.
    wide = np.full((80 + 2 * (m + 7), 96 + 2 * (m + 7), 3), 25.0, np.float32)
    irradiance = chain.focal_plane_irradiance_w_m2(_with_ring(wide, m + 7))
    np.testing.assert_allclose(irradiance, expected, rtol=1e-5)


def test_light_only_in_the_margin_ring_reaches_the_frame_edge() -> None:
    chain = _chain()
    m = chain.margin_px
    scene = np.zeros((80 + 2 * m, 96 + 2 * m, 3), np.float32)
    scene[m + 30 : m + 50, m - 3 : m - 1] = 60.0  # a strip just left of the frame
    with_ring = chain.focal_plane_irradiance_w_m2(_with_ring(scene, m))
    assert with_ring[33:47, 0].min() > 0.0
    assert not with_ring[:, 40:].any()  # beyond the kernel's reach: exactly 0
    # The same frame pixels as blurring the whole scene without a ring.
    camera = PinholeCamera.high_resolution().with_size(96 + 2 * m, 80 + 2 * m)
    whole = dataclasses.replace(chain, camera=camera).focal_plane_irradiance_w_m2(_image(scene))
    np.testing.assert_allclose(with_ring, whole[m:-m, m:-m], rtol=0, atol=1e-6 * whole.max())
    bad = dataclasses.replace(_with_ring(scene, m), margin_radiance_w_m2_sr=np.zeros((5, 3)))
    with pytest.raises(SatsightError, match="margin ring"):
        chain.focal_plane_irradiance_w_m2(bad)


def test_the_kernel_follows_the_render_sampling() -> None:
    camera = PinholeCamera.high_resolution().with_size(96, 80)
    optics = Optics.for_preset("high_resolution")

    def chain(s: int, spp: int) -> SensorChain:
        return SensorChain(camera, optics, DetectorParameters(), BAND_NM, supersampling=s,
                           samples_per_pixel=spp)  # fmt: skip

    one, four, jittered = chain(1, 1), chain(2, 1), chain(1, 16)
    # Averaged sub-pixel samples blur already: the kernel sharpens less of the frame.
    assert one.psf[20, 20] < four.psf[20, 20] < jittered.psf[20, 20]
    with pytest.raises(SatsightError, match="supersampling"):
        chain(0, 1)
    with pytest.raises(SatsightError, match="samples_per_pixel"):
        chain(1, 0)


def test_exposure_labels_tell_the_target_and_a_bright_earth_apart() -> None:
    """The auto exposure serves the target; the Earth behind it, 20 x brighter, is reported
    at 20 x the target's fill and all its pixels saturated, the target's none."""
    chain = _chain(ExposureRule(fill_fraction=0.7, percentile=99.0), blooming=False)
    target = np.zeros((80, 96), bool)
    target[20:50, 30:70] = True
    background = np.zeros((80, 96), np.uint8)
    background[60:, :] = 1  # the Earth below the target
    irradiance = np.where(target, np.float32(0.2), np.float32(0.0))
    irradiance[background == 1] = 4.0
    t = chain.exposure_time_s(irradiance, target)
    regions = exposure_regions(target, background)
    assert not regions["moon"].any()
    fill = {name: chain.region_fill(irradiance, t, where) for name, where in regions.items()}
    assert fill["target"] == pytest.approx(0.7, rel=1e-6)
    d = chain.detector
    rate_e_per_s = SOLAR_QE * 4.0 * d.pixel_area_m2 / chain.photon_energy_j
    assert fill["earth"] == pytest.approx(
        (rate_e_per_s + d.dark_current_e_per_s) * t / d.full_well_e, rel=QE_RTOL
    )
    assert fill["earth"] == pytest.approx(14.0, rel=1e-3)  # 0.7 x 20, the dark current ~0
    assert fill["moon"] is None
    dn = chain.read_out(irradiance, t, np.random.default_rng(4)).dn
    saturated = chain.saturated(dn)
    assert not (saturated & regions["target"]).any()
    assert np.count_nonzero(saturated & regions["earth"]) == np.count_nonzero(background == 1)
    # Without a body in view (background None) the Earth and the Moon are empty regions,
    # with no mask made, and no fill.
    empty = exposure_regions(target, None)
    assert empty["target"] is target and empty["earth"] is None and empty["moon"] is None
    assert chain.region_fill(irradiance, t, None) is None
    assert chain.region_fill(irradiance, t, np.zeros_like(target)) is None


def test_a_region_cut_to_its_box_gives_its_pixels_in_the_frames_order() -> None:
    rng = np.random.default_rng(12)
    image = rng.uniform(size=(64, 80)).astype(np.float32)
    for mask in (
        np.zeros((64, 80), bool),
        rng.uniform(size=(64, 80)) > 0.999,  # a few scattered pixels
        np.pad(rng.uniform(size=(9, 5)) > 0.3, ((20, 35), (40, 35))),  # a small blob
        np.ones((64, 80), bool),
    ):
        box, inside = within_box(mask)
        np.testing.assert_array_equal(image[box][inside], image[mask])
        assert np.count_nonzero(inside) == np.count_nonzero(mask)
        if mask.any():
            rows, columns = mask_box(mask)
            assert mask[rows.start].any() and mask[rows.stop - 1].any()
            assert mask[:, columns.start].any() and mask[:, columns.stop - 1].any()
            assert not mask[: rows.start].any() and not mask[:, columns.stop :].any()
        else:
            assert mask_box(mask) is None and inside.size == 0


def test_the_object_mask_is_made_once_and_read_only() -> None:
    image = _image(np.zeros((6, 7, 3), np.float32))
    image = dataclasses.replace(image, part_id=np.array([[0, 1, 2, 3, 0, 0, 0]] * 6, np.uint16))
    mask = image.object_mask
    assert image.object_mask is mask and not mask.flags.writeable
    np.testing.assert_array_equal(mask, image.part_id > 0)
    # Other objects' parts (past the target's) are not the target.
    others = dataclasses.replace(image, target_part_count=2)
    np.testing.assert_array_equal(others.object_mask, (image.part_id > 0) & (image.part_id <= 2))


def test_an_image_without_its_radiance_keeps_its_mask() -> None:
    image = _image(np.ones((4, 5, 3), np.float32))
    mask = image.object_mask
    lean = image.without_radiance()
    assert lean.radiance_w_m2_sr is None and lean.margin_radiance_w_m2_sr is None
    assert lean.object_mask is mask
    assert _image(np.ones((4, 5, 3), np.float32)).without_radiance().object_mask.all()


def test_a_stills_exposure_is_the_rule_on_its_irradiance() -> None:
    chain = _chain(ExposureRule(percentile=99.0, fill_fraction=0.7))
    radiance = np.zeros((80, 96, 3), np.float32)
    radiance[30:45, 40:60] = np.linspace(1.0, 30.0, 15 * 20 * 3).reshape(15, 20, 3)
    image = _image(radiance)
    irradiance = chain.focal_plane_irradiance_w_m2(image)
    t, made = chain.still_exposure(image)
    np.testing.assert_array_equal(made, irradiance)
    assert t == chain.exposure_time_s(irradiance, image.object_mask)
    assert chain.exposure.min_time_s < t < chain.exposure.max_time_s  # not at a clip
    t_given, given = chain.still_exposure(image, irradiance)
    assert t_given == t and given is irradiance  # a given irradiance is used, not made again
    assert chain.longest_exposure_s == chain.exposure.max_time_s


def test_a_fixed_exposure_carries_the_exposure_factor() -> None:
    # A randomised frame scales the rule's time by its exposure factor, the fixed time
    # too; the motion over the exposure is found for that time (FrameEngine.exposure_motion).
    chain = dataclasses.replace(
        _chain(ExposureRule(mode="fixed", time_s=0.25)), exposure_factor=2.0
    )
    image = _image(np.full((80, 96, 3), 5.0, np.float32))
    assert chain.longest_exposure_s == 0.5
    assert chain.still_exposure(image) == (0.5, None)
    assert chain.exposure_time_s(np.zeros((80, 96)), image.object_mask) == 0.5
