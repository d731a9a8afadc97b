"""Rendered frames blur as the camera's system MTF says: ISO 12233 slanted-edge measurements.

The estimator (``satsight.sensor.slanted_edge``) is first checked on edges with a known MTF
(a Gaussian-blurred edge sampled at the pixel centres, in closed form). Then a real render:
a large Lambertian plate with a straight edge 5.19 deg (slope 1/11) from the pixel columns,
lit by the Sun only (no environment, no bounces, so every lit pixel has the same radiance),
one sample at each pixel centre (the default render settings), through the sensor chain to
noise-free DN. The measured MTF must be ``system_mtf`` up to the pixel Nyquist frequency at
both camera presets.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from kernel_taps import edge_and_corner_loss, frame_kernel_taps
from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts
from satsight.sensor.chain import SensorChain
from satsight.sensor.convolution import apply_optics
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.exposure import exposure_for_fill
from satsight.sensor.mtf import band_wavelengths_m, system_mtf
from satsight.sensor.optics import Optics
from satsight.sensor.psf import psf_kernel
from satsight.sensor.slanted_edge import slanted_edge_mtf

BAND_NM = (450.0, 900.0)
PITCH_M = 15e-6
PHASES = 11  # edge slope 1/11: 5.19 deg from the pixel columns
WIDTH_PX, HEIGHT_PX = 176, 220  # +-64 px of ESF on every row, 20 phase cycles
#: Camera distance over focal length: both presets see the same plate at the same scale.
DISTANCE_OVER_FOCAL = 1000.0
SUN = LightField.sun_only(np.array([0.3, 0.2, 1.0]), 1000.0)
NOISE_FREE = DetectorParameters(
    read_noise_e=0.0,
    full_well_e=1e10,
    conversion_gain_e_per_dn=1e10 / 60000.0,
    dark_current_e_per_s=0.0,
    dsnu_e_per_s=0.0,
    prnu_fraction=0.0,
    blooming=False,
)


def _edge(h: int, w: int, slope: float, x0: float, sigma_px: float) -> np.ndarray:
    """A straight edge x = x0 + slope (y - h / 2) blurred by a Gaussian of sigma_px (its
    ESF, the normal's erf, sampled at the pixel centres)."""
    y, x = np.indices((h, w)).astype(np.float64)
    distance = (x - (x0 + slope * (y - h / 2))) / math.hypot(1.0, slope)
    return 3.0 + 50.0 * (1.0 + erf(distance / (sigma_px * math.sqrt(2.0))))


# --- the estimator on edges of known MTF -------------------------------------------------------


@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize("sigma_px", [0.6, 0.9])
def test_per_phase_bins_read_a_gaussian_edge_exactly(sign, sigma_px):
    # Per-phase bins of a smooth ESF, first-differenced: the Gaussian's MTF times the
    # difference's box, sinc(nu cos(theta) / N). The Hann window (L = 128 px) multiplies the
    # LSF by ~1 - pi^2 x^2 / L^2, which moves the MTF by ~pi^2 sigma^2 / L^2 ~ 5e-4 at most.
    img = _edge(HEIGHT_PX, WIDTH_PX, sign / PHASES, WIDTH_PX / 2 + 0.37, sigma_px)
    result = slanted_edge_mtf(img, phases_per_px=PHASES)
    assert result.phases_per_px == PHASES
    assert math.degrees(result.angle_rad) == pytest.approx(sign * 5.194428907734806, abs=1e-12)
    f = result.frequency_cyc_per_px
    expected = np.exp(-2 * math.pi**2 * sigma_px**2 * f**2)
    expected *= np.sinc(f * math.cos(result.angle_rad) / PHASES)
    band = f <= 0.5
    np.testing.assert_allclose(result.mtf[band], expected[band], rtol=0, atol=5e-4)


@pytest.mark.parametrize("x_offset_px", [0.0, 0.37, 0.71])
def test_iso_bins_read_a_gaussian_edge_at_five_degrees(x_offset_px):
    # ISO 4x bins with the bin and derivative responses divided out: within 0.004 of the
    # Gaussian's MTF up to Nyquist, the residue of the uneven spread of the rows' phases over
    # the bins, which moves with the edge's offset (bound: 0.006).
    sigma = 0.6
    img = _edge(HEIGHT_PX, WIDTH_PX, math.tan(math.radians(5.0)), WIDTH_PX / 2 + x_offset_px, sigma)
    result = slanted_edge_mtf(img)
    assert result.phases_per_px is None
    assert math.degrees(result.angle_rad) == pytest.approx(5.0, abs=1e-3)
    f = result.frequency_cyc_per_px
    band = f <= 0.5
    expected = np.exp(-2 * math.pi**2 * sigma**2 * f[band] ** 2)
    np.testing.assert_allclose(result.mtf[band], expected, rtol=0, atol=0.006)


def test_the_estimator_refuses_what_it_cannot_measure():
    edge = _edge(HEIGHT_PX, WIDTH_PX, 1 / PHASES, WIDTH_PX / 2, 0.6)
    with pytest.raises(SatsightError, match="1/12"):
        slanted_edge_mtf(edge, phases_per_px=12)
    with pytest.raises(SatsightError, match="deg from the pixel columns"):
        slanted_edge_mtf(_edge(HEIGHT_PX, WIDTH_PX, 0.0, WIDTH_PX / 2, 0.6))
    with pytest.raises(SatsightError, match="widen the image"):
        slanted_edge_mtf(edge[:, 40:136], phases_per_px=PHASES)
    with pytest.raises(SatsightError, match="cross the edge"):
        slanted_edge_mtf(np.ones((40, 60)))


# --- rendered frames ---------------------------------------------------------------------------


def _view(camera: PinholeCamera):
    """The camera's pose above the plate (plane z = 0, body frame), and the body-frame
    corners of a triangle whose left side draws the edge u = u0 + (v - cy) / 11 in the
    image (u0 puts every pixel centre half a phase from the edge) and whose other sides lie
    far outside the frame and its margin. The image-to-plate map is the same for both
    presets (distance / focal length fixed), so both see the same triangle."""
    distance_m = camera.focal_length_m * DISTANCE_OVER_FOCAL
    pose = look_at_cam_from_body(
        np.array([0.0, 0.0, distance_m]), np.zeros(3), up_hint_body=(0.0, 1.0, 0.0)
    )
    cx, cy = camera.cx_px, camera.cy_px
    u0 = (round(WIDTH_PX / 2 * PHASES - cy) + 0.5 + cy) / PHASES
    corners_px = [
        (u0 + (-3 * HEIGHT_PX - cy) / PHASES, -3 * HEIGHT_PX),
        (u0 + (4 * HEIGHT_PX - cy) / PHASES, 4 * HEIGHT_PX),
        (u0 + 50 * WIDTH_PX, cy),
    ]
    metres_per_px = camera.pixel_pitch_m * DISTANCE_OVER_FOCAL
    body_from_cam = pose.inverse()
    corners = np.array(
        [
            body_from_cam.apply(
                np.array([(u - cx) * metres_per_px, (v - cy) * metres_per_px, distance_m])
            )
            for u, v in corners_px
        ]
    )
    return pose, corners


@pytest.fixture(scope="module")
def edge_renderer(llvm_variant) -> Renderer:
    corners = _view(PinholeCamera.wide_field().with_size(WIDTH_PX, HEIGHT_PX))[1]
    grey = Material("grey_lambert", (0.5, 0.5, 0.5), metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", grey.name, corners, np.array([[0, 1, 2]]))], {grey.name: grey})
    return Renderer(mesh, RenderSettings(environment="off", bounces=0), llvm_variant)


def _camera(preset: str, width_px: int = WIDTH_PX, height_px: int = HEIGHT_PX) -> PinholeCamera:
    return getattr(PinholeCamera, preset)().with_size(width_px, height_px)


def _noise_free_dn(chain: SensorChain, irradiance_w_m2: np.ndarray) -> np.ndarray:
    """DN above the bias of a noise-free exposure filling half the (10^10 e-) full well: no
    read noise, dark signal or fixed pattern; shot noise 1.4e-5 and the ADC step 3e-5 of the
    signal, far below the 3 % tested."""
    t = exposure_for_fill(
        float(irradiance_w_m2.max()), NOISE_FREE, BAND_NM, 0.5, chain.effective_wavelength_m
    )
    dn = chain.read_out(irradiance_w_m2, t, np.random.default_rng(0)).dn
    return dn.astype(np.float64) - NOISE_FREE.bias_dn


@pytest.mark.parametrize("preset", ["wide_field", "high_resolution"])
def test_rendered_edge_blurs_as_the_system_mtf_says(edge_renderer, preset):
    # Tolerance 3 %: the kernel's cut at 20 px lifts its response by up to 1.8 % at Nyquist
    # and 0.3-0.5 % elsewhere (Airy wings renormalised into it; the LSF's Hann window does
    # the same); the estimator adds < 0.1 % (first test above), the detector ~1e-4. The
    # measurement gives 0.6 % (f/7) and 0.7 % (f/10). Directions: the normal is 5.2 deg off
    # the rows, where the 2-D system OTF differs from system_mtf by < 0.08 % (pixel sinc).
    camera = _camera(preset)
    optics = Optics.for_preset(preset)
    chain = SensorChain(camera, optics, NOISE_FREE, BAND_NM)
    pose = _view(camera)[0]
    image = edge_renderer.render(camera, pose, SUN, seed=1, margin_px=chain.margin_px)
    lit = image.radiance_w_m2_sr[image.object_mask]
    assert lit.max() - lit.min() < 1e-4 * lit.max()  # one radiance on the whole plate
    dn = _noise_free_dn(chain, chain.focal_plane_irradiance_w_m2(image))
    result = slanted_edge_mtf(dn, phases_per_px=PHASES)
    f = result.frequency_cyc_per_px
    band = f <= 0.5
    assert f[band][-1] > 0.49
    expected = system_mtf(f[band] / PITCH_M, optics, PITCH_M, band_wavelengths_m(BAND_NM))
    np.testing.assert_allclose(result.mtf[band], expected, rtol=0.03)
    # The spatially sampled PSF that rendered frames were blurred with before: it treats a
    # pixel's single sample as the pixel's average, so the frame kept the pixel sinc it had
    # not got: 0.88 (f/7) and 0.83 (f/10) at Nyquist where the system has 0.52 and 0.47.
    old = psf_kernel(optics, band_wavelengths_m(BAND_NM), None, PITCH_M, 15)
    band_radiance = chain.band_radiance_w_m2_sr(image.radiance_w_m2_sr)
    before = slanted_edge_mtf(apply_optics(band_radiance, old), phases_per_px=PHASES)
    assert before.mtf[band][-1] > 1.5 * expected[-1]


@pytest.mark.parametrize("preset", ["wide_field", "high_resolution"])
def test_a_rendered_scene_filling_the_frame_reads_uniform_to_the_corners(edge_renderer, preset):
    # The camera looks at the plate far inside its lit side, so the plate fills the frame
    # and its margin ring: every pixel reads the plate's irradiance, edges and corners
    # included, up to float32 rounding (~1e-7; bound 1e-5). Without the ring the edge rows
    # read 10-12 % low and the corners 19-22 % (the kernel's reach beyond the frame).
    camera = _camera(preset, 96, 80)
    camera = PinholeCamera(
        camera.focal_length_m,
        camera.pixel_pitch_m,
        96,
        80,
        cx_px=camera.cx_px - 400.0,  # the frame 400 px right of the edge's side
        cy_px=camera.cy_px,
    )
    optics = Optics.for_preset(preset)
    chain = SensorChain(camera, optics, NOISE_FREE, BAND_NM)
    pose = _view(_camera(preset))[0]
    image = edge_renderer.render(camera, pose, SUN, seed=1, margin_px=chain.margin_px)
    assert image.object_mask.all() and image.margin_radiance_w_m2_sr.min() > 0
    irradiance = chain.focal_plane_irradiance_w_m2(image)
    plate = float(np.median(irradiance))
    np.testing.assert_allclose(irradiance, plate, rtol=1e-5)
    bare = chain.focal_plane_irradiance_w_m2(
        edge_renderer.render(camera, pose, SUN, seed=1)  # no margin ring
    )
    # The expected losses are the taps beyond the frame's edge, from the taps' defining
    # integral (kernel_taps.edge_and_corner_loss). The designed taps differ from those by
    # < 3e-6 each (test_psf), so a sum of at most 41 x 20 taps by < 2.5e-3; float32 FFT
    # and rendering round-off add ~1e-5 (the ring test above). Tolerance 2.5e-3.
    edge, corner = edge_and_corner_loss(
        frame_kernel_taps(optics, band_wavelengths_m(BAND_NM), camera.pixel_pitch_m, 41)
    )
    assert chain.psf.shape == (41, 41)
    assert 1 - bare[40, 0] / plate == pytest.approx(edge, abs=2.5e-3)
    assert 1 - bare[0, 0] / plate == pytest.approx(corner, abs=2.5e-3)
