"""One frame through the camera: rendered radiance (+ stars) -> optics -> detector -> DN.

The renderer gives radiance towards the camera in three channels (each the in-band light
reflected with that channel's reflectance, docs/design.md "Radiometry and units"). The
detector is panchromatic over the band, so the channels are first combined into one in-band
radiance with the weights of the band's three equal sub-bands in the solar spectrum (blue:
short third, green: middle, red: long), the reading in which each channel's reflectance
holds over its third of the band; each third's photons are counted at its own
photon-weighted wavelength. Then, in the detector's physical order:

1. optics: the camera equation E = pi L tau (1 - eps^2) / (4 N^2) (``satsight.sensor.optics``),
   then the blur of the system OTF (diffraction of the obscured aperture over the band,
   pixel aperture, jitter, defocus) by a kernel designed for the renderer's sub-pixel
   sampling (``satsight.sensor.psf.frame_kernel``), convolved where there is signal, with
   the margin ring the renderer adds around the frame (``satsight.sensor.convolution``);
2. stars: their photons, each through the same optics at its exact sub-pixel position
   (``satsight.sensor.star_field``), added to the focal plane;
3. exposure: a fixed time, or the time that fills a chosen fraction of full well with the
   target's bright end (``satsight.sensor.exposure_rule.ExposureRule``);
4. detector: photons, QE, fixed pattern, dark current, shot noise, full well and blooming,
   read noise, gain, bias and ADC (``satsight.sensor.exposure.simulate_detector``).

Reflected sunlight keeps the Sun's spectrum within each channel's third of the band
(materials are grey there), so each channel's photons are its power over h c / lambda_c,
lambda_c the solar photon-weighted wavelength of its third. The detector counts photons at
one energy, h c / lambda_eff (lambda_eff of the whole band), so each channel's power is
weighted by lambda_c / lambda_eff first: the irradiance handed to the detector is
"photon-equivalent", equal to the true power for grey surfaces. Star photons are counted per
star from its own spectrum and handed to the detector the same way, so their count is exact.

Quantum efficiency: the detector turns photons into electrons with one eta, ``SensorChain.
quantum_efficiency``: the detector's scalar override, or its QE curve's photon-weighted mean
over the band in the sunlight spectrum (``satsight.sensor.band_qe``; 0.8127 for the
CCD231-84 curve and E-490 over 450-900 nm). The curve's mean over each third differs (0.904,
0.886 and 0.627 for 450-600, 600-750 and 750-900 nm), and the materials' channel
reflectances are already weighted by the curve within each third
(``satsight.scene.band_reflectance``), so each channel's photons are weighted by
eta_c / eta as well: the detector then counts sum_c eta_c N_c electrons, the integral of
reflectance x photons x QE over the band (exact for reflectances flat within each third),
and a grey surface still reads its photon-weighted mean eta (the weights
``channel_detected_weights`` sum to 1 to ~1e-7). Each star's photons are weighted by
eta_star / eta, eta_star the curve's mean over the star's black body
(``star_quantum_efficiency_ratio``). With a scalar override every ratio is 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import (
    Spectrum,
    check_band_nm,
    photon_weighted_wavelength_m,
    spectral_weights,
)
from satsight.render.buffers import RadianceImage, margin_pixels_xy, within_box
from satsight.sensor.convolution import apply_optics
from satsight.sensor.detector import DetectorParameters, mean_photon_energy_j
from satsight.sensor.exposure import exposure_for_fill, mean_electrons_image, simulate_detector
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.mtf import band_wavelengths_m, check_render_sampling
from satsight.sensor.optics import Optics, focal_plane_irradiance_w_m2
from satsight.sensor.psf import frame_kernel

#: Side of the kernel applied to rendered frames, pixels (odd). The kernel's response is the
#: system OTF over the pixel Nyquist square, fitted on R = 20 taps each side: within 0.6 %
#: along the axes up to and including Nyquist (``frame_kernel``). A defocus blur disc and
#: jitter widen it (``psf_size_px``).
PSF_SIZE_PX = 41


def blur_radius_px(optics: Optics, pixel_pitch_m: float) -> int:
    """Pixels the defocus disc (its radius) and the jitter (4 sigma) add to a PSF's reach."""
    radius_m = 0.5 * optics.defocus_blur_diameter_m + 4.0 * optics.jitter_rms_m
    return math.ceil(radius_m / pixel_pitch_m)


def psf_size_px(optics: Optics, pixel_pitch_m: float) -> int:
    """Side (odd, pixels) of the PSF kernel: ``PSF_SIZE_PX`` widened by the defocus disc and
    the jitter, so that neither is cut off."""
    return PSF_SIZE_PX + 2 * blur_radius_px(optics, pixel_pitch_m)


#: Largest number of target pixels the auto exposure takes its percentile over.
EXPOSURE_SAMPLE_PIXELS = 1 << 20

#: Percentile of a region's mean signal that its exposure label reports (``region_fill``).
REGION_FILL_PERCENTILE = 99.0


def exposure_regions(object_mask: np.ndarray, background_mask: np.ndarray | None) -> dict:
    """The parts of a frame whose exposure the labels report apart: {"target", "earth",
    "moon": (H, W) bool, or None where the region is empty}, from the object mask and
    ``RadianceImage.background_id`` (0 space, 1 the Earth, 2 the Moon behind the target;
    None when no body is in view: the Earth and the Moon are then empty, and no full-frame
    mask is made for them)."""
    if background_mask is None:
        return {"target": object_mask, "earth": None, "moon": None}
    return {"target": object_mask, "earth": background_mask == 1, "moon": background_mask == 2}


def _percentile_of(values: np.ndarray, percentile: float) -> float | None:
    """The percentile of ``values``, over an evenly strided subset of at most
    ``EXPOSURE_SAMPLE_PIXELS`` of them (None when empty)."""
    if values.size == 0:
        return None
    if values.size > EXPOSURE_SAMPLE_PIXELS:
        values = values[:: -(-values.size // EXPOSURE_SAMPLE_PIXELS)]
    return float(np.percentile(values, percentile))


@dataclass(frozen=True)
class DnImage:
    """What the detector reads out for one frame.

    dn: (H, W) uint16 digital numbers (bias included). exposure_time_s: integration time.
    saturated_pixel_count: pixels within 3 read-noise sigma (+1 DN) of the full-well level,
    or at the ADC's top code.
    star_count: stars drawn on the frame. bias_dn and full_well_dn: the camera's offset and
    the mean output at full well, for display stretches.
    """

    dn: np.ndarray
    exposure_time_s: float
    saturated_pixel_count: int
    star_count: int
    bias_dn: float
    full_well_dn: float

    def labels(self) -> dict:
        """The frame's sensor labels, JSON-ready."""
        return {
            "exposure_time_s": self.exposure_time_s,
            "saturated_pixel_count": self.saturated_pixel_count,
            "star_count": self.star_count,
        }


@dataclass(frozen=True)
class SensorChain:
    """A camera's optics and detector, prepared once and applied to every frame.

    camera: the pinhole camera (focal length, pixel pitch, image size). optics, detector:
    the telescope and CCD. band_nm: the detected band (nm). spectrum: the solar spectrum of
    the reflected light. exposure: the exposure rule. camera_seed: fixes the detector's
    PRNU and DSNU maps. supersampling, samples_per_pixel: the renderer's sub-pixel sampling
    (``RenderSettings``), for which the blur kernel ``psf`` is designed (``frame_kernel``).
    exposure_factor: a factor on the time the exposure rule gives (a randomised sensor's;
    the result stays within the rule's bounds).

    Derived: quantum_efficiency, the eta of sunlit light over the band, and
    quantum_efficiency_source, where it comes from (``DetectorParameters.
    band_quantum_efficiency``); channel_quantum_efficiency, (3,) RGB, each third's eta;
    channel_photon_weights, (3,) RGB, each channel's power weight times lambda_c /
    lambda_eff; channel_detected_weights, those times eta_c / eta (see the module doc).
    """

    camera: PinholeCamera
    optics: Optics
    detector: DetectorParameters
    band_nm: tuple[float, float]
    spectrum: Spectrum = "astm_e490"
    exposure: ExposureRule = field(default_factory=ExposureRule)
    camera_seed: int = 0
    supersampling: int = 1
    samples_per_pixel: int = 1
    exposure_factor: float = 1.0
    psf: np.ndarray = field(init=False, repr=False)
    channel_weights: np.ndarray = field(init=False, repr=False)
    channel_photon_weights: np.ndarray = field(init=False, repr=False)
    channel_quantum_efficiency: np.ndarray = field(init=False, repr=False)
    channel_detected_weights: np.ndarray = field(init=False, repr=False)
    effective_wavelength_m: float = field(init=False)
    quantum_efficiency: float = field(init=False)
    quantum_efficiency_source: str = field(init=False)

    def __post_init__(self) -> None:
        lo, hi = check_band_nm(self.band_nm)
        if not (math.isfinite(self.exposure_factor) and self.exposure_factor > 0):
            raise SatsightError(f"exposure_factor must be > 0, got {self.exposure_factor!r}")
        if abs(self.optics.focal_length_m - self.camera.focal_length_m) > 1e-9:
            raise SatsightError(
                f"the optics' focal length ({self.optics.focal_length_m:g} m) differs from the "
                f"camera's ({self.camera.focal_length_m:g} m); build both from one config"
            )
        if abs(self.detector.pixel_pitch_m - self.camera.pixel_pitch_m) > 1e-12:
            raise SatsightError(
                f"the detector's pixel pitch ({self.detector.pixel_pitch_m:g} m) differs from "
                f"the camera's ({self.camera.pixel_pitch_m:g} m); build both from one config"
            )
        s, spp = check_render_sampling(self.supersampling, self.samples_per_pixel)
        psf = frame_kernel(
            self.optics,
            band_wavelengths_m((lo, hi)),
            None,
            self.camera.pixel_pitch_m,
            psf_size_px(self.optics, self.camera.pixel_pitch_m),
            s,
            spp,
        )
        edges = np.linspace(lo, hi, 4)
        blue, green, red = spectral_weights(edges, self.spectrum)
        lam_eff = photon_weighted_wavelength_m((lo, hi), self.spectrum)
        lam_rgb = [
            photon_weighted_wavelength_m((float(a), float(b)), self.spectrum)
            for a, b in zip(edges[2::-1], edges[3:0:-1], strict=True)
        ]
        power = np.array([red, green, blue])
        photon_weights = power * np.array(lam_rgb) / lam_eff
        eta = self.detector.band_quantum_efficiency((lo, hi), self.spectrum)
        eta_rgb = np.array(
            [
                self.detector.band_quantum_efficiency((float(a), float(b)), self.spectrum)
                for a, b in zip(edges[2::-1], edges[3:0:-1], strict=True)
            ]
        )
        object.__setattr__(self, "band_nm", (lo, hi))
        object.__setattr__(self, "psf", psf.astype(np.float32))
        object.__setattr__(self, "channel_weights", power.astype(np.float32))
        object.__setattr__(self, "channel_photon_weights", photon_weights.astype(np.float32))
        object.__setattr__(self, "channel_quantum_efficiency", eta_rgb)
        object.__setattr__(
            self, "channel_detected_weights", (photon_weights * eta_rgb / eta).astype(np.float32)
        )
        object.__setattr__(self, "effective_wavelength_m", lam_eff)
        object.__setattr__(self, "quantum_efficiency", eta)
        object.__setattr__(
            self,
            "quantum_efficiency_source",
            self.detector.quantum_efficiency_source((lo, hi), self.spectrum),
        )

    def star_quantum_efficiency_ratio(self, temperature_k: np.ndarray) -> np.ndarray:
        """(N,) eta_star / eta for stars at ``temperature_k`` (N,) K: the factor that makes
        a star's photons, added to the focal plane like reflected light, give its own
        electrons (``DetectorParameters.star_quantum_efficiency``; 1 with a scalar override)."""
        eta_star = self.detector.star_quantum_efficiency(self.band_nm, temperature_k)
        return eta_star / self.quantum_efficiency

    @property
    def photon_energy_j(self) -> float:
        """Mean photon energy of reflected sunlight in the band, h c / lambda_eff (J)."""
        return mean_photon_energy_j(self.band_nm, self.effective_wavelength_m)

    def band_radiance_w_m2_sr(self, radiance_rgb_w_m2_sr: np.ndarray) -> np.ndarray:
        """(H, W) float32 in-band radiance from the (H, W, 3) rendered channels."""
        radiance = np.asarray(radiance_rgb_w_m2_sr, dtype=np.float32)
        if radiance.ndim != 3 or radiance.shape[2] != 3:
            raise SatsightError(
                f"radiance must be (H, W, 3) W m^-2 sr^-1, got shape {radiance.shape}"
            )
        return radiance @ self.channel_weights

    @property
    def margin_px(self) -> int:
        """Width (px) of the ring around the frame whose light the kernel spreads into the
        frame: the kernel's radius. Render with ``Renderer.render(..., margin_px=this)``."""
        return self.psf.shape[0] // 2

    def focal_plane_irradiance_w_m2(self, image: RadianceImage) -> np.ndarray:
        """(H, W) float32 photon-equivalent in-band irradiance on the detector from the
        rendered scene, after the camera equation and the blur (W m^-2, pixel-averaged).

        "Photon-equivalent": each channel's power is weighted by its photons, lambda_c /
        lambda_eff, and by its quantum efficiency, eta_c / eta, so the detector's single
        photon energy h c / lambda_eff and single eta count every channel's electrons right
        (exact power for grey surfaces, whose weights sum to 1).
        Only the bounding box of the non-zero radiance (frame and margin ring) is combined
        (the renderer's background is 0; with supersampling, edge pixels whose centre misses
        the target still carry light), with the camera equation folded into the channel
        weights: E = sum_c w_c (lambda_c / lambda_eff) (eta_c / eta) L_c pi tau (1 - eps^2)
        / (4 N^2).

        The blur reaches ``margin_px`` pixels across the frame's edge. When the image carries
        the radiance of a ring at least that wide around the frame
        (``RadianceImage.margin_radiance_w_m2_sr``, from ``Renderer.render(...,
        margin_px=chain.margin_px)``), the edge pixels get the light from beyond the frame
        and a uniform scene reads uniform to the corners. Without a ring (or with a narrower
        one) the frame is taken as dark beyond it: edge pixels of a scene that fills the
        frame then read low, by 10-12 % on the edge rows and 19-22 % in the corners with the
        default kernel at f/7 and f/10.
        """
        radiance = image.radiance_w_m2_sr
        if radiance.ndim != 3 or radiance.shape[2] != 3:
            raise SatsightError(
                f"radiance must be (H, W, 3) W m^-2 sr^-1, got shape {radiance.shape}"
            )
        h, w = radiance.shape[:2]
        ring = image.margin_radiance_w_m2_sr
        m = int(image.margin_px) if ring is not None else 0
        factor = float(focal_plane_irradiance_w_m2(1.0, self.optics))
        weights = (self.channel_detected_weights * np.float32(factor)).astype(np.float32)
        # The frame and its ring on one (H + 2m, W + 2m) grid; np.zeros maps pages lazily,
        # so the empty parts cost nothing.
        focal = np.zeros((h + 2 * m, w + 2 * m), dtype=np.float32)
        boxes = []
        rows = np.flatnonzero(radiance.reshape(h, -1).max(axis=1, initial=0.0) > 0)
        if rows.size:
            band = radiance[rows[0] : rows[-1] + 1]
            # Column maxima over the rows first (a contiguous reduction), then over channels.
            cols = np.flatnonzero(band.max(axis=0).max(axis=1) > 0)
            r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
            frame_box = (slice(r0 + m, r1 + m), slice(c0 + m, c1 + m))
            np.matmul(
                radiance[r0:r1, c0:c1].astype(np.float32, copy=False),
                weights,
                out=focal[frame_box],
            )
            boxes.append((r0 + m, r1 + m, c0 + m, c1 + m))
        if m:
            ring = np.asarray(ring, dtype=np.float32)
            x, y = margin_pixels_xy(w, h, m)
            if ring.shape != (x.size, 3):
                raise SatsightError(
                    f"the margin ring of a {w} x {h} frame, {m} px wide, holds {x.size} pixels "
                    f"(n, 3); got radiance of shape {ring.shape}"
                )
            values = ring @ weights  # (n,), > 0 where any channel is (the weights are)
            # The ring in row-major order of the padded frame: m full rows on top, two
            # m-wide strips beside each frame row, m full rows below.
            top, beside = m * (w + 2 * m), 2 * m * h
            sides = values[top : top + beside].reshape(h, 2 * m)
            focal[:m] = values[:top].reshape(m, w + 2 * m)
            focal[m + h :] = values[top + beside :].reshape(m, w + 2 * m)
            focal[m : m + h, :m] = sides[:, :m]
            focal[m : m + h, m + w :] = sides[:, m:]
            lit = values > 0
            if lit.any():
                ys, xs = y[lit] + m, x[lit] + m
                boxes.append((int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1))
        if not boxes:
            return np.zeros((h, w), dtype=np.float32)
        signal_box = (
            min(b[0] for b in boxes),
            max(b[1] for b in boxes),
            min(b[2] for b in boxes),
            max(b[3] for b in boxes),
        )
        return apply_optics(focal, self.psf, signal_box=signal_box, margin_px=m)

    def still_exposure(
        self, image: RadianceImage, irradiance_w_m2: np.ndarray | None = None
    ) -> tuple[float, np.ndarray | None]:
        """The exposure rule's time for a rendered still (s), and the still's focal-plane
        irradiance when the rule needed it (``irradiance_w_m2`` when given, else made here;
        None for a fixed exposure)."""
        if self.exposure.mode == "fixed":
            return self._rule_time_s, None
        if irradiance_w_m2 is None:
            irradiance_w_m2 = self.focal_plane_irradiance_w_m2(image)
        return self.exposure_time_s(irradiance_w_m2, image.object_mask), irradiance_w_m2

    @property
    def longest_exposure_s(self) -> float:
        """The longest time the exposure rule gives (s): the fixed time (with the exposure
        factor); for the auto rule ``max_time_s``, or its time for a frame without lit
        target pixels where that is longer."""
        if self.exposure.mode == "fixed":
            return self._rule_time_s
        return max(self.exposure.max_time_s, self._rule_time_s)

    @property
    def _rule_time_s(self) -> float:
        """The rule's fixed time (s), or the auto rule's time for a frame without lit
        target pixels."""
        return self.exposure.time_s * self.exposure_factor

    def exposure_time_s(self, irradiance_w_m2: np.ndarray, object_mask: np.ndarray) -> float:
        """The frame's exposure time under the exposure rule (s).

        The percentile is taken over the lit target pixels, or over an evenly strided
        subset of at most ``EXPOSURE_SAMPLE_PIXELS`` of them on large targets (its rank
        error, ~1 / sqrt(n) ~ 0.1 %, is far below what the rule needs).
        """
        rule = self.exposure
        if rule.mode == "fixed":
            return self._rule_time_s
        if irradiance_w_m2.shape[:2] != object_mask.shape:
            raise SatsightError(
                f"the irradiance image {irradiance_w_m2.shape[:2]} and the object mask "
                f"{object_mask.shape} must have the same size"
            )
        box, inside = within_box(object_mask)
        lit = irradiance_w_m2[box][inside]
        if lit.size > EXPOSURE_SAMPLE_PIXELS:
            lit = lit[:: -(-lit.size // EXPOSURE_SAMPLE_PIXELS)]
        level = _percentile_of(lit[lit > 0], rule.percentile)
        if level is None:
            return self._rule_time_s
        t = exposure_for_fill(
            level,
            self.detector,
            self.band_nm,
            rule.fill_fraction,
            self.effective_wavelength_m,
            quantum_efficiency=self.quantum_efficiency,
        )
        return float(np.clip(t * self.exposure_factor, rule.min_time_s, rule.max_time_s))

    def region_fill(
        self, irradiance_w_m2: np.ndarray, exposure_time_s: float, region: np.ndarray | None
    ) -> float | None:
        """The ``REGION_FILL_PERCENTILE`` percentile of the mean signal of the pixels in
        ``region`` ((H, W) bool), as a fraction of full well: electrons from the irradiance
        and the dark current over the exposure, before noise, fixed pattern and the well's
        limit (so above 1 where the region saturates). None for an empty region (or None)."""
        if region is None:
            return None
        level = _percentile_of(irradiance_w_m2[region], REGION_FILL_PERCENTILE)
        if level is None:
            return None
        d = self.detector
        rate_e_per_s = (
            self.quantum_efficiency * level * d.pixel_area_m2 / self.photon_energy_j
            + d.dark_current_e_per_s
        )
        return rate_e_per_s * exposure_time_s / d.full_well_e

    def saturated(self, dn: np.ndarray) -> np.ndarray:
        """(H, W) bool: pixels within 3 read-noise sigma (+1 DN) of the full-well level, or
        at the ADC's top code."""
        d = self.detector
        full_well_dn = min(d.full_well_dn, float(d.adc_max_dn))
        # A pixel at full well reads full_well_dn give or take its read noise.
        noise_dn = d.read_noise_e / d.conversion_gain_e_per_dn
        return dn >= min(full_well_dn - 3.0 * noise_dn - 1.0, d.adc_max_dn)

    def photons_as_irradiance_w_m2(self, photons: np.ndarray, exposure_time_s: float) -> np.ndarray:
        """Mean photons per pixel over the exposure as the in-band irradiance (W m^-2) the
        detector turns back into exactly those photons (at ``photon_energy_j``)."""
        scale = self.photons_to_irradiance_factor(exposure_time_s)
        return np.asarray(photons, dtype=np.float32) * np.float32(scale)

    def photons_to_irradiance_factor(self, exposure_time_s: float) -> float:
        """W m^-2 of focal-plane irradiance per mean photon per pixel over the exposure."""
        return self.photon_energy_j / (self.detector.pixel_area_m2 * exposure_time_s)

    def mean_electrons(self, irradiance_w_m2: np.ndarray, exposure_time_s: float) -> np.ndarray:
        """(H, W) float64 noise-free mean electrons per pixel of a focal-plane irradiance
        image (W m^-2) over ``exposure_time_s``: what ``read_out`` draws its shot noise
        around, before the full well (eta PRNU E A t / <E_ph> + (D + DSNU) t)."""
        return mean_electrons_image(
            irradiance_w_m2,
            exposure_time_s,
            self.detector,
            self.band_nm,
            self.camera_seed,
            self.effective_wavelength_m,
            quantum_efficiency=self.quantum_efficiency,
        )

    def read_out(
        self,
        irradiance_w_m2: np.ndarray,
        exposure_time_s: float,
        rng: np.random.Generator,
        star_count: int = 0,
    ) -> DnImage:
        """The detector's exposure of a focal-plane irradiance image (W m^-2)."""
        dn = simulate_detector(
            irradiance_w_m2,
            exposure_time_s,
            self.detector,
            self.band_nm,
            rng,
            self.camera_seed,
            self.effective_wavelength_m,
            quantum_efficiency=self.quantum_efficiency,
        )
        full_well_dn = min(self.detector.full_well_dn, float(self.detector.adc_max_dn))
        return DnImage(
            dn=dn,
            exposure_time_s=float(exposure_time_s),
            saturated_pixel_count=int(np.count_nonzero(self.saturated(dn))),
            star_count=int(star_count),
            bias_dn=self.detector.bias_dn,
            full_well_dn=full_well_dn,
        )
