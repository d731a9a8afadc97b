"""CCD detector parameters and the mean signal they give: photons and electrons per pixel.

``DetectorParameters`` holds the electro-optical figures of a CCD (pixel pitch, quantum
efficiency, dark current, read noise, full well, conversion gain, bias, ADC bits, fixed-
pattern spreads). The noise-free first stages of an exposure (Janesick, *Photon Transfer*,
SPIE Press, 2007, ch. 2-5) are here too:

1. photon collection: ``photons_per_pixel`` = E A t / <E_ph>, mean photons per pixel, with
   ``mean_photon_energy_j`` = h c / lambda_eff;
2. charge generation, its mean: ``expected_electrons`` = eta PRNU n_ph + (D + DSNU) t, mean
   photo-electrons plus dark electrons.

The other stages live beside this module: ``satsight.sensor.fixed_pattern`` (PRNU and DSNU
maps, drawn once per ``camera_seed``), ``satsight.sensor.noise`` (the per-frame random
draws: shot noise, read noise and quantisation in ``read_out_dn``) and
``satsight.sensor.exposure`` (full-well saturation and blooming, and ``simulate_detector``,
the whole exposure from irradiance to DN).

This is the linear camera model of EMVA Standard 1288 Release 4.0 (2021), section 2:
mean signal mu_y = K (eta mu_p + mu_d) + bias with K = 1 / conversion gain (DN per
electron), and temporal variance sigma_y^2 = K^2 (sigma_d^2 + mu_e) + sigma_q^2 with the
quantisation variance sigma_q^2 = 1/12 DN^2. Here sigma_d is the read noise and mu_e the
total (photo + dark) electrons, whose shot noise is Poisson. Fixed-pattern noise (PRNU,
DSNU) is spatial, the same in every frame of one camera; it is drawn once per
``camera_seed``.

Units: SI inside. Irradiance ``_w_m2``, times ``_s``, lengths ``_m``, energies ``_j``,
charges ``_e`` (electrons), ``_e_per_s``, ``_dn`` (digital numbers), ``_e_per_dn``. Images
are (H, W) arrays, row 0 at the top; a CCD column is an image column (axis 0 runs along
it).

Defaults describe a Teledyne e2v CCD231-84 back-illuminated sensor (datasheet
"CCD231-84 Back Illuminated Scientific CCD Sensor, 4096 x 4112 pixels, 4-side buttable",
Teledyne e2v); values not on the datasheet are marked "assumption".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.constants import DEFAULT_BAND_NM, PLANCK_J_S, SPEED_OF_LIGHT_M_S
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import Spectrum, check_band_nm
from satsight.sensor.band_qe import blackbody_weighted_qe, solar_weighted_qe


# --------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------
def _finite(value: object) -> bool:
    try:
        return not isinstance(value, bool) and math.isfinite(float(value))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


@dataclass(frozen=True)
class DetectorParameters:
    """Electro-optical parameters of a CCD231-84-class back-illuminated CCD.

    pixel_pitch_m: pixel size (square pixels), 15 um. Source: CCD231-84 datasheet.
    quantum_efficiency: None (default) or a scalar override eta in (0, 1], electrons per
        incident photon. None takes eta from the CCD231-84 astro multi-2 curve
        (``satsight.camera.quantum_efficiency``, the curve the material library's band
        integration weights by too), photon-weighted over the band by the light's own
        spectrum (``satsight.sensor.band_qe``): 0.813 for sunlight (ASTM E-490) over
        450-900 nm, 0.74-0.85 for stars from 3000 K to 20000 K (see
        ``band_quantum_efficiency`` and ``star_quantum_efficiency``). A number is used as
        it is for every spectrum and wavelength.
    dark_current_e_per_s: mean dark current per pixel, 3 e-/pixel/hour = 8.3e-4 e-/s.
        Source: CCD231-84 datasheet, dark signal of a few e-/pixel/hour at -100 C
        (3 e-/pixel/hour chosen).
    read_noise_e: read noise, rms electrons per pixel per read, 5 e-. Assumption: the
        datasheet gives ~2-3 e- rms at low (~50 kHz) pixel rates; 5 e- is assumed for a
        ~1 MHz readout of a full frame in a few seconds.
    full_well_e: pixel full-well capacity (linear saturation), 350 ke-. Source: datasheet
        (image-area peak signal, 350 ke-/pixel typical).
    conversion_gain_e_per_dn: electrons per digital number (1/K in EMVA 1288),
        350e3 / 60000 = 5.83 e-/DN. Assumption: chosen so the full well maps to 60000 DN
        above the bias, near the top of a 16-bit ADC.
    bias_dn: electronic offset added before digitisation, 1000 DN. Assumption.
    adc_bits: ADC resolution, 16 bits (output range 0 .. 65535). Assumption (usual for
        scientific CCD controllers).
    prnu_fraction: photo-response non-uniformity, the rms of the per-pixel gain map
        (relative), 1 %. Assumption (typical for back-illuminated CCDs, Janesick 2007,
        ch. 6).
    dsnu_e_per_s: dark-signal non-uniformity, the rms over pixels of the per-pixel dark
        current, 1.5 e-/pixel/hour = 4.2e-4 e-/s. Assumption (half the mean dark current).
    blooming: if True, charge above full well spills up and down the column into
        neighbouring pixels (see ``saturate_electrons``); if False it is lost (clipped).
        Default True: the CCD231-84 has no anti-blooming structure (datasheet).
    """

    pixel_pitch_m: float = 15e-6
    quantum_efficiency: float | None = None
    dark_current_e_per_s: float = 3.0 / 3600.0
    read_noise_e: float = 5.0
    full_well_e: float = 350e3
    conversion_gain_e_per_dn: float = 350e3 / 60000.0
    bias_dn: float = 1000.0
    adc_bits: int = 16
    prnu_fraction: float = 0.01
    dsnu_e_per_s: float = 1.5 / 3600.0
    blooming: bool = True

    def __post_init__(self) -> None:
        def need(ok: bool, what: str, value: object, fix: str) -> None:
            if not ok:
                raise SatsightError(f"{what}; got {value!r}. {fix}")

        qe = self.quantum_efficiency
        if qe is not None:
            need(
                _finite(qe) and 0.0 < float(qe) <= 1.0,  # type: ignore[arg-type]
                "quantum_efficiency must be None (the detector's QE curve) or a number in "
                "(0, 1] electrons per photon",
                qe,
                "Give a fraction, e.g. 0.8 for 80 %, or leave it unset for the curve.",
            )
            object.__setattr__(self, "quantum_efficiency", float(qe))  # type: ignore[arg-type]
        for name in (
            "pixel_pitch_m",
            "dark_current_e_per_s",
            "read_noise_e",
            "full_well_e",
            "conversion_gain_e_per_dn",
            "bias_dn",
            "prnu_fraction",
            "dsnu_e_per_s",
        ):
            value = getattr(self, name)
            need(_finite(value), f"{name} must be a finite number", value, "Give a real value.")
            object.__setattr__(self, name, float(value))
        need(
            self.pixel_pitch_m > 0,
            "pixel_pitch_m must be > 0 m",
            self.pixel_pitch_m,
            "Give the pixel size in metres (15e-6 for 15 um).",
        )
        need(
            self.dark_current_e_per_s >= 0,
            "dark_current_e_per_s must be >= 0",
            self.dark_current_e_per_s,
            "Give electrons per pixel per second (3 e-/h = 3/3600).",
        )
        need(
            self.read_noise_e >= 0,
            "read_noise_e must be >= 0 e- rms",
            self.read_noise_e,
            "Give the rms read noise in electrons.",
        )
        need(
            self.full_well_e > 0,
            "full_well_e must be > 0 e-",
            self.full_well_e,
            "Give the full-well capacity in electrons (350e3 for a CCD231-84).",
        )
        need(
            self.conversion_gain_e_per_dn > 0,
            "conversion_gain_e_per_dn must be > 0 e-/DN",
            self.conversion_gain_e_per_dn,
            "Give electrons per digital number.",
        )
        need(
            isinstance(self.adc_bits, int | np.integer)
            and not isinstance(self.adc_bits, bool)
            and 1 <= int(self.adc_bits) <= 16,
            "adc_bits must be a whole number from 1 to 16 (output is uint16)",
            self.adc_bits,
            "Give the ADC resolution in bits, e.g. 16.",
        )
        object.__setattr__(self, "adc_bits", int(self.adc_bits))
        need(
            0.0 <= self.bias_dn < self.adc_max_dn,
            f"bias_dn must be in [0, {self.adc_max_dn}) DN",
            self.bias_dn,
            "Give an offset inside the ADC range, e.g. 1000 DN.",
        )
        need(
            0.0 <= self.prnu_fraction <= 0.2,
            "prnu_fraction must be in [0, 0.2] (relative rms gain spread)",
            self.prnu_fraction,
            "Give a fraction, e.g. 0.01 for 1 %; 0 switches PRNU off.",
        )
        need(
            self.dsnu_e_per_s >= 0,
            "dsnu_e_per_s must be >= 0",
            self.dsnu_e_per_s,
            "Give the rms of the dark current over pixels in e-/s; 0 switches DSNU off.",
        )
        need(
            self.dsnu_e_per_s == 0 or self.dark_current_e_per_s > 0,
            "dsnu_e_per_s > 0 needs dark_current_e_per_s > 0 (DSNU is the spread of a "
            "positive dark current)",
            (self.dark_current_e_per_s, self.dsnu_e_per_s),
            "Set a dark current or set dsnu_e_per_s to 0.",
        )
        need(
            isinstance(self.blooming, bool | np.bool_),
            "blooming must be True or False",
            self.blooming,
            "Give a boolean.",
        )
        object.__setattr__(self, "blooming", bool(self.blooming))

    @property
    def pixel_area_m2(self) -> float:
        """Pixel area (m^2), pitch squared (100 % fill factor of a back-illuminated CCD)."""
        return self.pixel_pitch_m**2

    def band_quantum_efficiency(
        self, band_nm: tuple[float, float] = DEFAULT_BAND_NM, spectrum: Spectrum = "astm_e490"
    ) -> float:
        """Mean electrons per photon of sunlit light over ``band_nm``: the scalar override,
        or the QE curve's photon-weighted mean over the band in ``spectrum``
        (:func:`satsight.sensor.band_qe.solar_weighted_qe`; 0.8127 for E-490 over 450-900 nm)."""
        if self.quantum_efficiency is not None:
            check_band_nm(band_nm)
            return self.quantum_efficiency
        return solar_weighted_qe(check_band_nm(band_nm), spectrum)

    def star_quantum_efficiency(
        self, band_nm: tuple[float, float], temperature_k: np.ndarray | float
    ) -> np.ndarray:
        """(N,) mean electrons per photon of stars (black bodies at ``temperature_k``, (N,)
        K) over ``band_nm``: the scalar override, or the QE curve's photon-weighted mean in
        each star's spectrum (:func:`satsight.sensor.band_qe.blackbody_weighted_qe`)."""
        band = check_band_nm(band_nm)
        if self.quantum_efficiency is None:
            return blackbody_weighted_qe(band, temperature_k)
        t = np.atleast_1d(np.asarray(temperature_k, dtype=np.float64))
        return np.full(t.shape, self.quantum_efficiency)

    def quantum_efficiency_source(
        self, band_nm: tuple[float, float] = DEFAULT_BAND_NM, spectrum: Spectrum = "astm_e490"
    ) -> str:
        """Where ``band_quantum_efficiency`` comes from, in words (for labels)."""
        if self.quantum_efficiency is not None:
            return "scalar override"
        lo, hi = check_band_nm(band_nm)
        names = {"astm_e490": "ASTM E-490", "blackbody_5778k": "5778 K black body"}
        light = names.get(spectrum, spectrum)
        return (
            f"CCD231-84 curve, solar-photon weighted ({light}) over [{lo:g}, {hi:g}] nm; "
            "stars: their own black body"
        )

    @property
    def adc_max_dn(self) -> int:
        """Largest ADC output code, 2^bits - 1 (65535 for 16 bits)."""
        return (1 << self.adc_bits) - 1

    @property
    def full_well_dn(self) -> float:
        """Mean output of a pixel at full well, bias + full_well / gain (DN), before ADC clip."""
        return self.bias_dn + self.full_well_e / self.conversion_gain_e_per_dn


# --------------------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------------------
def _check_exposure_s(exposure_time_s: float) -> float:
    if not (_finite(exposure_time_s) and float(exposure_time_s) >= 0.0):
        raise SatsightError(
            f"exposure_time_s must be finite and >= 0 s, got {exposure_time_s!r}; "
            "give the integration time in seconds (0 gives a bias frame)"
        )
    return float(exposure_time_s)


def _check_nonnegative_image(name: str, image: np.ndarray | float, unit: str) -> np.ndarray:
    array = np.asarray(image, dtype=np.float64)
    if array.size == 0:
        return array
    # min and max propagate NaN, so two reductions check finiteness and sign without
    # allocating a full-size temporary.
    lo, hi = float(array.min()), float(array.max())
    if not (math.isfinite(lo) and math.isfinite(hi) and lo >= 0.0):
        raise SatsightError(
            f"{name} must be finite and >= 0 {unit} everywhere; got values from {lo:g} to "
            f"{hi:g}. Fix the upstream stage that made it."
        )
    return array


def _check_image_2d(name: str, image: np.ndarray) -> None:
    if image.ndim != 2 or 0 in image.shape:
        raise SatsightError(
            f"{name} must be a non-empty (H, W) image; got shape {image.shape}. "
            "Pass one single-band image."
        )


# --------------------------------------------------------------------------------------
# 1. Photon collection
# --------------------------------------------------------------------------------------
def mean_photon_energy_j(
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    effective_wavelength_m: float | None = None,
) -> float:
    """Mean energy per photon over the band, <E_ph> = h c / lambda_eff (J).

    For in-band irradiance E (W m^-2) the photon flux is E / <E_ph>. If the spectral
    irradiance is flat across [lo, hi], the photon flux is
    int (E / (hi - lo)) lambda / (h c) d lambda = E lambda_mean / (h c), so lambda_eff is the
    band's mean wavelength (lo + hi) / 2; that is the default. For another spectrum pass its
    photon-weighted effective wavelength, lambda_eff = int E_lambda lambda d lambda /
    int E_lambda d lambda (e.g. from the solar spectrum times the optics' transmission),
    which must lie inside the band. h and c are the exact SI (CODATA 2018) values.
    """
    lo_nm, hi_nm = check_band_nm(band_nm)
    if effective_wavelength_m is None:
        wavelength_m = 0.5 * (lo_nm + hi_nm) * 1e-9
    else:
        if not _finite(effective_wavelength_m):
            raise SatsightError(
                f"effective_wavelength_m must be a finite number of metres, got "
                f"{effective_wavelength_m!r}"
            )
        wavelength_m = float(effective_wavelength_m)
        if not (lo_nm * 1e-9 <= wavelength_m <= hi_nm * 1e-9):
            raise SatsightError(
                f"effective_wavelength_m must lie in the band [{lo_nm:g}, {hi_nm:g}] nm; got "
                f"{wavelength_m * 1e9:g} nm. Give it in metres (550e-9 for 550 nm)."
            )
    return PLANCK_J_S * SPEED_OF_LIGHT_M_S / wavelength_m


def photons_per_pixel(
    irradiance_w_m2: np.ndarray | float,
    pixel_area_m2: float,
    exposure_time_s: float,
    photon_energy_j: float,
) -> np.ndarray:
    """Mean number of photons reaching each pixel, n_ph = E A t / <E_ph>.

    irradiance_w_m2: in-band focal-plane irradiance per pixel, (H, W) or scalar, W m^-2.
    pixel_area_m2: light-collecting pixel area (m^2). exposure_time_s: integration time (s).
    photon_energy_j: mean photon energy (J), from ``mean_photon_energy_j``.
    Returns float64 photons per pixel, same shape as the irradiance (EMVA 1288 R4.0, eq. 1).
    """
    irradiance = _check_nonnegative_image("irradiance_w_m2", irradiance_w_m2, "W m^-2")
    t = _check_exposure_s(exposure_time_s)
    if not (_finite(pixel_area_m2) and pixel_area_m2 > 0):
        raise SatsightError(
            f"pixel_area_m2 must be > 0 m^2, got {pixel_area_m2!r}; (15e-6)**2 for 15 um"
        )
    if not (_finite(photon_energy_j) and photon_energy_j > 0):
        raise SatsightError(
            f"photon_energy_j must be > 0 J, got {photon_energy_j!r}; "
            "use mean_photon_energy_j(band_nm)"
        )
    return irradiance * (float(pixel_area_m2) * t / float(photon_energy_j))


# --------------------------------------------------------------------------------------
# 2. Charge generation: the mean
# --------------------------------------------------------------------------------------
def expected_electrons(
    photons: np.ndarray | float,
    quantum_efficiency: float,
    prnu_map: np.ndarray | float,
    dark_current_e_per_s: float,
    dsnu_e_per_s_map: np.ndarray | float,
    exposure_time_s: float,
) -> np.ndarray:
    """Mean electrons per pixel, mu_e = eta PRNU n_ph + (D + DSNU) t (e-, float64).

    photons: mean photons per pixel (H, W). quantum_efficiency: eta, electrons per photon.
    prnu_map: relative response (H, W) or 1.0. dark_current_e_per_s: mean dark current D.
    dsnu_e_per_s_map: per-pixel dark-current offset (H, W) or 0.0. exposure_time_s: t (s).
    The mean of the linear model of EMVA 1288 R4.0, eq. 6 (mu_d = D t).
    """
    photons = np.asarray(photons, dtype=np.float64)
    t = _check_exposure_s(exposure_time_s)
    if not (_finite(quantum_efficiency) and 0 < quantum_efficiency <= 1):
        raise SatsightError(
            f"quantum_efficiency must be in (0, 1], got {quantum_efficiency!r}; give a fraction"
        )
    if not (_finite(dark_current_e_per_s) and dark_current_e_per_s >= 0):
        raise SatsightError(
            f"dark_current_e_per_s must be >= 0, got {dark_current_e_per_s!r}; give e-/s"
        )
    prnu = np.asarray(prnu_map, dtype=np.float64)
    dsnu = np.asarray(dsnu_e_per_s_map, dtype=np.float64)
    try:
        shape = np.broadcast_shapes(photons.shape, prnu.shape, dsnu.shape)
    except ValueError as exc:
        raise SatsightError(
            f"photons {photons.shape}, prnu_map {prnu.shape} and dsnu_e_per_s_map "
            f"{dsnu.shape} must have the same (H, W) shape (or be scalars)"
        ) from exc
    # In place, one full-size allocation: large frames are dominated by memory traffic.
    mean_e = np.empty(shape)
    np.multiply(photons, prnu, out=mean_e)
    if t > 0:
        # (eta PRNU n_ph / t + D + DSNU) t
        mean_e *= float(quantum_efficiency) / t
        mean_e += dsnu
        mean_e += float(dark_current_e_per_s)
        mean_e *= t
    else:
        mean_e *= float(quantum_efficiency)
    # A DSNU map is built so that D + DSNU >= 0; guard against hand-made maps that are not.
    return _check_nonnegative_image("expected electrons", mean_e, "e-")
