"""Detector model: focal-plane irradiance (W m^-2) to a CCD's digital numbers (uint16).

The chain follows the physical order of a CCD exposure (Janesick, *Photon Transfer*,
SPIE Press, 2007, ch. 2-5), one small pure function per stage:

1. photon collection: ``photons_per_pixel`` = E A t / <E_ph>, mean photons per pixel;
2. charge generation: ``expected_electrons`` = eta PRNU n_ph + (D + DSNU) t, mean
   photo-electrons plus dark electrons; ``shot_noise_electrons`` draws the Poisson count
   (exact below ``SHOT_NOISE_NORMAL_MIN_MEAN_E``, its normal limit above);
3. charge collection: ``saturate_electrons`` caps each pixel at its full well, optionally
   spilling the excess along the column (blooming);
4. measurement and readout: ``read_out_dn`` adds Gaussian read noise, divides by the
   conversion gain, adds the bias, rounds to whole DN and clips to the ADC range.

This is the linear camera model of EMVA Standard 1288 Release 4.0 (2021), section 2:
mean signal mu_y = K (eta mu_p + mu_d) + bias with K = 1 / conversion gain (DN per
electron), and temporal variance sigma_y^2 = K^2 (sigma_d^2 + mu_e) + sigma_q^2 with the
quantisation variance sigma_q^2 = 1/12 DN^2. Here sigma_d is the read noise and mu_e the
total (photo + dark) electrons, whose shot noise is Poisson. Fixed-pattern noise (PRNU,
DSNU) is spatial, the same in every frame of one camera; it is drawn once per
``camera_seed``.

Speed and reproducibility. A full 4096 x 4112 frame is processed in row bands of about
``BAND_PIXELS`` pixels on a thread pool (numpy's generators and ufuncs release the GIL).
The bands are fixed by the image width and height alone, and each band draws from its own
generator, spawned from one ``np.random.SeedSequence`` whose entropy is four 64-bit words
taken from the caller's generator. So the output depends only on the generator's state (and
the camera seed), never on the number of threads. ``simulate_detector`` works in float32
(electrons up to ~1.6e7 are exact integers there, 46 x the full well), fused per band.

Units: SI inside. Irradiance ``_w_m2``, times ``_s``, lengths ``_m``, energies ``_j``,
charges ``_e`` (electrons), ``_e_per_s``, ``_dn`` (digital numbers), ``_e_per_dn``. Images
are (H, W) arrays, row 0 at the top; a CCD column is an image column (axis 0 runs along
it). Randomness comes only from the ``np.random.Generator`` passed in (temporal noise) or
from ``camera_seed`` (fixed pattern).

Defaults describe a Teledyne e2v CCD231-84 back-illuminated sensor (datasheet
"CCD231-84 Back Illuminated Scientific CCD Sensor, 4096 x 4112 pixels, 4-side buttable",
Teledyne e2v); values not on the datasheet are marked "assumption".
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.constants as const

from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.sensor.threads import check_threads, run_jobs

#: Planck constant h (J s), CODATA 2018 exact value (scipy.constants).
PLANCK_J_S: float = const.h
#: Speed of light in vacuum c (m s^-1), exact.
SPEED_OF_LIGHT_M_S: float = const.c
#: The paper's default pass band (nm).
DEFAULT_BAND_NM: tuple[float, float] = (450.0, 900.0)
#: Largest mean the Poisson sampler accepts (numpy's limit is about 9.2e18); far above any
#: physical pixel (a full well is ~1e5-1e6 e-).
MAX_POISSON_MEAN_E: float = 1e15
#: Shot-noise means (e-) at or above this are drawn from the normal limit of the Poisson
#: distribution, rint(mu + sqrt(mu - 1/12) z), z standard normal: mean mu and variance mu
#: (the 1/12 removes the variance of the rounding to whole electrons, Sheppard's
#: correction, exact to ~exp(-2 pi^2 mu)), skewness 0 instead of 1/sqrt(mu) <= 0.032 and
#: excess kurtosis 0 instead of 1/mu <= 0.001; the largest difference between the two
#: cumulative distributions is 0.0021 at mu = 1000 (0.0007 at 1e4) and shrinks as
#: 1/sqrt(mu). Below it the exact Poisson sampler is used.
SHOT_NOISE_NORMAL_MIN_MEAN_E: float = 1000.0
#: Shot-noise means (e-) below this (dark-current-only empty space: ~1e-3 e- in 1 s) are
#: drawn exactly by thinning: Poisson(mu_max) candidate counts on every pixel of a band,
#: each candidate kept with probability mu / mu_max, which gives independent Poisson(mu)
#: counts (Poisson thinning theorem). Its cost is ~mu_max per pixel, not one draw per pixel.
SHOT_NOISE_SPARSE_MAX_MEAN_E: float = 0.1
#: Pixels per row band of the parallel stages (64 rows of a 4096-pixel-wide frame). The
#: bands depend only on the image size, so results do not depend on the thread count.
BAND_PIXELS: int = 1 << 18


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
    quantum_efficiency: band-averaged quantum efficiency eta over the pass band (0-1),
        electrons per incident photon; 0.9. Assumption: band average over 450-900 nm of
        the datasheet's "astro multi-2" coating curve (above 90 % from ~450 to ~800 nm,
        falling towards 900 nm).
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
    quantum_efficiency: float = 0.9
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

        for name in (
            "pixel_pitch_m",
            "quantum_efficiency",
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
            0.0 < self.quantum_efficiency <= 1.0,
            "quantum_efficiency must be in (0, 1] electrons per photon",
            self.quantum_efficiency,
            "Give a fraction, e.g. 0.9 for 90 %.",
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


def _check_rng(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise SatsightError(
            f"rng must be a numpy.random.Generator, got {type(rng).__name__}; "
            "create one with numpy.random.default_rng(seed)"
        )
    return rng


def _row_bands(height: int, width: int) -> list[tuple[int, int]]:
    """Row ranges [r0, r1) of about BAND_PIXELS pixels each; a function of the size only."""
    rows = max(1, BAND_PIXELS // max(width, 1))
    return [(r0, min(r0 + rows, height)) for r0 in range(0, height, rows)]


def _standard_normal_f32(gen: np.random.Generator, out: np.ndarray) -> np.ndarray:
    """Fill ``out`` ((n,) float32, contiguous) with independent standard normal draws.

    Box-Muller transform (Box & Muller, Ann. Math. Stat. 29, 610, 1958): for independent
    uniforms u1 in (0, 1] and u2 in [0, 1), sqrt(-2 ln u1) (cos 2 pi u2, sin 2 pi u2) are two
    independent standard normals. The uniforms are 32-bit words of ``gen``'s bit generator,
    u1 = (k + 1) 2^-32 and u2 = k' 2^-32, so draws reach |z| = sqrt(64 ln 2) = 6.66 (a radius
    beyond that has probability 2.3e-10 per pair). With float32 vectorised ufuncs this is
    2-3x faster than numpy's float32 ziggurat (normal draws dominate a full frame's cost);
    both are Gaussian to float32 resolution. Returns ``out``.
    """
    n = out.size
    half = (n + 1) // 2
    words = gen.bit_generator.random_raw(half).view(np.uint32)  # 2 * half 32-bit words
    radius = np.multiply(words[:half], np.float32(2.0**-32), dtype=np.float32)
    radius += np.float32(2.0**-32)
    np.log(radius, out=radius)
    radius *= np.float32(-2.0)
    np.sqrt(radius, out=radius)
    angle = np.multiply(words[half:], np.float32(2.0 * math.pi * 2.0**-32), dtype=np.float32)
    first, second = out[:half], out[half:]
    np.cos(angle, out=first)
    first *= radius
    np.sin(angle[: n - half], out=second)
    second *= radius[: n - half]
    return out


def _standard_normal(gen: np.random.Generator, out: np.ndarray) -> np.ndarray:
    """Standard normal draws into ``out`` (n,): Box-Muller in float32, numpy's in float64."""
    if out.dtype == np.float32:
        return _standard_normal_f32(gen, out)
    return gen.standard_normal(dtype=np.float64, out=out)


def _band_seeds(rng: np.random.Generator, count: int) -> list[np.random.SeedSequence]:
    """``count`` independent seed sequences, from four 64-bit words drawn from ``rng``.

    Always consumes the same four draws, so the caller's generator advances the same way
    whatever the image size or thread count.
    """
    words = rng.integers(0, 2**64, size=4, dtype=np.uint64)
    return np.random.SeedSequence([int(w) for w in words]).spawn(count)


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
# 2. Charge generation
# --------------------------------------------------------------------------------------
def fixed_pattern_maps(
    shape: tuple[int, int], params: DetectorParameters, camera_seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel fixed-pattern maps of one camera: (prnu_gain_map, dsnu_e_per_s_map).

    prnu_gain_map: (H, W) float32, dimensionless relative response, 1 + prnu_fraction z with
        z standard normal, clipped at 0 (a 5-sigma event at the largest allowed 20 %).
        Mean 1, rms spread prnu_fraction.
    dsnu_e_per_s_map: (H, W) float32, e-/s, the per-pixel dark current minus its mean. The
        per-pixel dark current D_ij is lognormal with mean dark_current_e_per_s and rms
        dsnu_e_per_s (a positive, right-skewed distribution, as measured dark currents are;
        Janesick 2007, ch. 7), so the map has mean 0 and D + map >= 0 everywhere.
    Both are drawn from ``np.random.SeedSequence(camera_seed)`` (one child stream each, split
    into fixed row bands), so they depend only on the camera seed, the shape and the two
    spreads, never on the temporal-noise generator or the thread count; switching one off
    leaves the other unchanged. float32 holds them to 6e-8 relative, far below their 1 %
    spread. The maps of the two most recent cameras are cached (PRNU and the per-pixel dark
    current, 2 x 67 MB for a 4096 x 4112 frame; drawing them costs ~0.08 s on 2 cores); the arrays
    returned are read-only.
    """
    prnu, dark_e_per_s = _camera_maps(shape, params, camera_seed)
    h, w = int(shape[0]), int(shape[1])
    if prnu is None:
        prnu = np.ones((h, w), dtype=np.float32)
    if dark_e_per_s is None:
        dsnu = np.zeros((h, w), dtype=np.float32)
    else:
        dsnu = dark_e_per_s - np.float32(params.dark_current_e_per_s)
    prnu.setflags(write=False)
    dsnu.setflags(write=False)
    return prnu, dsnu


_CAMERA_MAPS: OrderedDict[tuple, tuple[np.ndarray | None, np.ndarray | None]] = OrderedDict()
_CAMERA_MAPS_LOCK = threading.Lock()
_CAMERA_MAPS_KEPT = 2


def _camera_maps(
    shape: tuple[int, int],
    params: DetectorParameters,
    camera_seed: int,
    threads: int | None = None,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Cached (prnu_gain_map, dark_current_e_per_s_map) of one camera, float32 (H, W).

    None stands for a switched-off map (PRNU 1 everywhere; dark current D everywhere).
    The dark-current map is D_ij = D + DSNU_ij >= 0. Thread count does not change values.
    """
    if len(shape) != 2 or not all(isinstance(n, int | np.integer) and n > 0 for n in shape):
        raise SatsightError(f"shape must be (H, W) with positive whole numbers, got {shape!r}")
    if not isinstance(camera_seed, int | np.integer) or camera_seed < 0:
        raise SatsightError(f"camera_seed must be a non-negative whole number, got {camera_seed!r}")
    key = (
        (int(shape[0]), int(shape[1])),
        params.prnu_fraction,
        params.dark_current_e_per_s,
        params.dsnu_e_per_s,
        int(camera_seed),
    )
    with _CAMERA_MAPS_LOCK:
        if key in _CAMERA_MAPS:
            _CAMERA_MAPS.move_to_end(key)
            return _CAMERA_MAPS[key]
        maps = _draw_camera_maps(*key, check_threads(threads))
        _CAMERA_MAPS[key] = maps
        while len(_CAMERA_MAPS) > _CAMERA_MAPS_KEPT:
            _CAMERA_MAPS.popitem(last=False)
        return maps


def _draw_camera_maps(
    shape: tuple[int, int],
    prnu_fraction: float,
    dark_current_e_per_s: float,
    dsnu_e_per_s: float,
    camera_seed: int,
    threads: int,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    prnu_seq, dsnu_seq = np.random.SeedSequence(int(camera_seed)).spawn(2)
    bands = _row_bands(*shape)
    prnu = dark = None
    if prnu_fraction > 0:
        prnu = np.empty(shape, dtype=np.float32)
        prnu_seeds = prnu_seq.spawn(len(bands))

        def draw_prnu(i: int) -> None:
            band = prnu[bands[i][0] : bands[i][1]]
            _standard_normal_f32(np.random.default_rng(prnu_seeds[i]), band.reshape(-1))
            band *= np.float32(prnu_fraction)
            band += np.float32(1.0)
            np.maximum(band, np.float32(0.0), out=band)

        run_jobs(draw_prnu, len(bands), threads)
        prnu.setflags(write=False)
    if dsnu_e_per_s > 0:
        # Lognormal with mean D and rms s: sigma_ln^2 = ln(1 + (s / D)^2), mu_ln = ln D -
        # sigma_ln^2 / 2.
        mean = dark_current_e_per_s
        sigma_ln = math.sqrt(math.log1p((dsnu_e_per_s / mean) ** 2))
        dark = np.empty(shape, dtype=np.float32)
        dsnu_seeds = dsnu_seq.spawn(len(bands))

        def draw_dark(i: int) -> None:
            band = dark[bands[i][0] : bands[i][1]]
            _standard_normal_f32(np.random.default_rng(dsnu_seeds[i]), band.reshape(-1))
            band *= np.float32(sigma_ln)
            band += np.float32(math.log(mean) - 0.5 * sigma_ln**2)
            np.exp(band, out=band)

        run_jobs(draw_dark, len(bands), threads)
        dark.setflags(write=False)
    return prnu, dark


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


def shot_noise_electrons(
    mean_electrons_e: np.ndarray,
    rng: np.random.Generator,
    *,
    threads: int | None = None,
    normal_min_mean_e: float = SHOT_NOISE_NORMAL_MIN_MEAN_E,
) -> np.ndarray:
    """Collected electrons including shot noise: a Poisson draw per pixel (e-, float64).

    mean_electrons_e: mean electrons (H, W) (or any shape), >= 0 and <= MAX_POISSON_MEAN_E.
    Photon arrival and dark generation are Poisson processes, and so is the photo-electron
    count after the binomial QE selection (Janesick 2007, ch. 3; EMVA 1288 R4.0, sec. 2.2:
    sigma_e^2 = mu_e). Each pixel is drawn in one of three ways, by its mean mu:

    * mu < ``SHOT_NOISE_SPARSE_MAX_MEAN_E`` (0.1 e-): exact Poisson by thinning (see there);
    * up to ``normal_min_mean_e`` (default ``SHOT_NOISE_NORMAL_MIN_MEAN_E``, 1000 e-):
      numpy's exact Poisson sampler;
    * from ``normal_min_mean_e`` on: rint(mu + sqrt(mu - 1/12) z), the normal limit with the
      same mean and variance (``SHOT_NOISE_NORMAL_MIN_MEAN_E`` states the error).
      ``normal_min_mean_e=math.inf`` draws exact Poisson counts everywhere.

    Every result is a whole number of electrons. Row bands of the image draw from their own
    generators (see the module docstring), so ``threads`` (default: all cores) does not
    change the result.
    """
    rng = _check_rng(rng)
    n_threads = check_threads(threads)
    mean = _check_nonnegative_image("mean_electrons_e", mean_electrons_e, "e-")
    try:
        normal_min_mean_e = float(normal_min_mean_e)
    except (TypeError, ValueError):
        normal_min_mean_e = math.nan
    if not normal_min_mean_e >= 1.0:
        raise SatsightError(
            f"normal_min_mean_e must be a number >= 1 e- (math.inf for exact Poisson "
            f"everywhere), got {normal_min_mean_e!r}"
        )
    if mean.size and float(mean.max()) > MAX_POISSON_MEAN_E:
        raise SatsightError(
            f"mean electrons per pixel must be <= {MAX_POISSON_MEAN_E:g} e-; got "
            f"{float(mean.max()):g}. Shorten the exposure or check the irradiance units "
            "(W m^-2)."
        )
    out = np.empty(mean.shape, dtype=np.float64)
    if mean.size == 0:
        return out
    flat_mean, flat_out = np.ascontiguousarray(mean).reshape(-1), out.reshape(-1)
    width = mean.shape[-1] if mean.ndim else 1
    bands = [(r0 * width, r1 * width) for r0, r1 in _row_bands(mean.size // width, width)]
    seeds = _band_seeds(rng, len(bands))

    def job(i: int) -> None:
        a, b = bands[i]
        _shot_noise_band(
            flat_mean[a:b], np.random.default_rng(seeds[i]), flat_out[a:b], normal_min_mean_e
        )

    run_jobs(job, len(bands), n_threads)
    return out


def _shot_noise_band(
    mean: np.ndarray, gen: np.random.Generator, out: np.ndarray, normal_min_mean_e: float
) -> None:
    """Shot-noise draws for one band: ``mean`` (n,) float >= 0 into ``out`` (n,), in place.

    The draws happen in a fixed order (normal, Poisson, thinning), so the result depends only
    on ``gen``'s state and the means.
    """
    n = mean.size
    dtype = out.dtype.type
    big = mean >= normal_min_mean_e
    n_big = int(np.count_nonzero(big))
    if n_big == n:  # fully lit band: no gathering
        _standard_normal(gen, out)
        sigma = np.subtract(mean, dtype(1.0 / 12.0), dtype=dtype)
        np.sqrt(sigma, out=sigma)
        out *= sigma
        out += mean
        np.rint(out, out=out)
        return
    out.fill(0)
    if n_big:
        lit = mean[big].astype(dtype, copy=False)
        draws = _standard_normal(gen, np.empty(n_big, dtype=dtype))
        sigma = lit - dtype(1.0 / 12.0)
        np.sqrt(sigma, out=sigma)
        draws *= sigma
        draws += lit
        np.rint(draws, out=draws)
        out[big] = draws
    small = mean < SHOT_NOISE_SPARSE_MAX_MEAN_E
    n_small = int(np.count_nonzero(small))
    if n_big + n_small < n:
        mid = ~(big | small)
        out[mid] = gen.poisson(mean[mid])
    if n_small:
        _add_thinned_poisson(mean if n_small == n else np.where(small, mean, 0), gen, out)


def _add_thinned_poisson(rate: np.ndarray, gen: np.random.Generator, out: np.ndarray) -> None:
    """Add independent Poisson(rate_i) counts to ``out`` (both (n,)), by thinning.

    With mu_max = max(rate): draw N ~ Poisson(n mu_max) candidates and place each on a pixel
    drawn uniformly, which gives every pixel an independent Poisson(mu_max) number of
    candidates (Poisson splitting); keep each candidate with probability rate_i / mu_max,
    which leaves independent Poisson(rate_i) counts (Poisson thinning; e.g. Ross,
    *Stochastic Processes*, 2nd ed., 1996, sec. 2.3). Exact, and costs ~n mu_max draws.
    """
    mu_max = float(rate.max())
    if mu_max <= 0.0:
        return
    n_candidates = int(gen.poisson(mu_max * rate.size))
    if n_candidates == 0:
        return
    where = gen.integers(0, rate.size, size=n_candidates)
    keep = gen.random(n_candidates) * mu_max < rate[where]
    np.add.at(out, where[keep], 1)


# --------------------------------------------------------------------------------------
# 3. Charge collection
# --------------------------------------------------------------------------------------
def _spill(column: np.ndarray, start: int, step: int, charge_e: float, full_well_e: float) -> None:
    """Put ``charge_e`` into ``column`` from index ``start`` on in direction ``step`` (+1/-1),
    filling each pixel to full well in turn; full pixels pass the charge on. What reaches
    the end of the column leaves it (lost over the frame edge)."""
    if charge_e <= 0:
        return
    stop = len(column) if step > 0 else -1
    if start == stop:
        return
    view = column[start:stop:step] if step > 0 else column[start::-1]
    # Pixels already at or above full well (a later over-full run) take nothing.
    room = np.maximum(full_well_e - view, 0.0)
    filled = np.cumsum(room)
    k = int(np.searchsorted(filled, charge_e, side="left"))
    if k >= len(view):
        view += room
        return
    view[:k] += room[:k]
    view[k] += charge_e - (filled[k - 1] if k > 0 else 0.0)


def saturate_electrons(electrons_e: np.ndarray, full_well_e: float, blooming: bool) -> np.ndarray:
    """Collected charge after the pixel wells saturate (e-, float64, (H, W); a new array).

    Without blooming, charge above ``full_well_e`` is lost: min(e, full_well).
    With blooming (a CCD without anti-blooming drain, Janesick 2007, ch. 10), excess charge
    flows along the column (axis 0) only, not across the channel stops to other columns.
    Model: in each column, each run of consecutive over-full pixels is set to full well
    and its total excess is split equally, half spilled upwards from the run's top and half
    downwards from its bottom; a spill fills neighbouring pixels to full well one after the
    other and passes through pixels already full. Runs are handled top to bottom. Charge
    reaching the top or bottom edge of the frame leaves it; otherwise each column's total
    charge is conserved exactly (to rounding), and no pixel ends above full well.
    """
    e = _check_nonnegative_image("electrons_e", electrons_e, "e-")
    _check_image_2d("electrons_e", e)
    if not (_finite(full_well_e) and full_well_e > 0):
        raise SatsightError(f"full_well_e must be > 0 e-, got {full_well_e!r}")
    fw = float(full_well_e)
    if not blooming:
        return np.minimum(e, fw)
    out = e.copy()
    for j in np.flatnonzero((out > fw).any(axis=0)):
        column = out[:, j].copy()
        _bloom_column(column, fw)
        out[:, j] = column
    return out


def _bloom_column(column: np.ndarray, full_well_e: float) -> None:
    """Blooming of one CCD column (1-D float64 electrons), in place (see saturate_electrons)."""
    over = column > full_well_e
    flags = np.concatenate(([False], over, [False]))
    edges = np.flatnonzero(flags[1:] != flags[:-1])
    for top, end in zip(edges[0::2], edges[1::2], strict=True):
        excess = float(np.sum(column[top:end] - full_well_e))
        column[top:end] = full_well_e
        _spill(column, top - 1, -1, 0.5 * excess, full_well_e)
        _spill(column, end, +1, 0.5 * excess, full_well_e)


# --------------------------------------------------------------------------------------
# 4. Measurement and readout
# --------------------------------------------------------------------------------------
def read_out_dn(
    electrons_e: np.ndarray,
    params: DetectorParameters,
    rng: np.random.Generator,
    *,
    threads: int | None = None,
) -> np.ndarray:
    """Digitised image: DN = clip(round((e + n_read) / g + bias), 0, 2^bits - 1), uint16.

    electrons_e: collected electrons (H, W). n_read: Gaussian read noise, rms
    ``read_noise_e`` electrons, independent per pixel (output amplifier and CDS noise,
    Janesick 2007, ch. 4). g: ``conversion_gain_e_per_dn``. Rounding to the nearest integer
    adds the quantisation variance 1/12 DN^2 (EMVA 1288 R4.0, eq. 9); the ADC clips below
    0 and above 2^bits - 1. Computed in float32 (6e-8 relative, < 0.004 DN below 65536 DN),
    in row bands with their own generators: ``threads`` (default: all cores) does not change
    the result.
    """
    rng = _check_rng(rng)
    n_threads = check_threads(threads)
    e = np.asarray(electrons_e)
    if not np.issubdtype(e.dtype, np.floating):
        e = e.astype(np.float64)
    _check_image_2d("electrons_e", e)
    dn = np.empty(e.shape, dtype=np.uint16)
    bands = _row_bands(*e.shape)
    seeds = _band_seeds(rng, len(bands))

    def job(i: int) -> None:
        r0, r1 = bands[i]
        _read_out_band(e[r0:r1], params, np.random.default_rng(seeds[i]), dn[r0:r1])

    run_jobs(job, len(bands), n_threads)
    return dn


def _read_out_band(
    electrons_e: np.ndarray,
    params: DetectorParameters,
    gen: np.random.Generator,
    out_dn: np.ndarray,
) -> None:
    """Read noise, gain, bias, rounding and ADC clip of one band, into ``out_dn`` (uint16)."""
    g = params.conversion_gain_e_per_dn
    signal = np.multiply(electrons_e, 1.0 / g, dtype=np.float32)
    if params.read_noise_e > 0:
        noise = _standard_normal_f32(gen, np.empty(signal.size, dtype=np.float32))
        noise *= np.float32(params.read_noise_e / g)
        signal += noise.reshape(signal.shape)
    signal += np.float32(params.bias_dn)
    np.rint(signal, out=signal)
    np.clip(signal, np.float32(0.0), np.float32(params.adc_max_dn), out=signal)
    np.copyto(out_dn, signal, casting="unsafe")


# --------------------------------------------------------------------------------------
# The chain
# --------------------------------------------------------------------------------------
def _check_irradiance(irradiance_w_m2: np.ndarray) -> np.ndarray:
    """The irradiance as a float32/float64 (H, W) array, checked finite and >= 0; no copy."""
    image = np.asarray(irradiance_w_m2)
    if image.dtype not in (np.float32, np.float64):
        image = image.astype(np.float64)
    if image.size:
        lo, hi = float(image.min()), float(image.max())
        if not (math.isfinite(lo) and math.isfinite(hi) and lo >= 0.0):
            raise SatsightError(
                f"irradiance_w_m2 must be finite and >= 0 W m^-2 everywhere; got values from "
                f"{lo:g} to {hi:g}. Fix the upstream stage that made it."
            )
    _check_image_2d("irradiance_w_m2", image)
    return image


def mean_electrons_image(
    irradiance_w_m2: np.ndarray,
    exposure_time_s: float,
    params: DetectorParameters,
    band_nm: tuple[float, float],
    camera_seed: int,
    effective_wavelength_m: float | None = None,
) -> np.ndarray:
    """Noise-free mean electrons per pixel (H, W, e-, float64), before saturation.

    Photon collection and the mean of charge generation, with this camera's fixed
    pattern: eta PRNU E A t / <E_ph> + (D + DSNU) t.
    """
    irradiance = _check_nonnegative_image("irradiance_w_m2", irradiance_w_m2, "W m^-2")
    _check_image_2d("irradiance_w_m2", irradiance)
    photon_energy_j = mean_photon_energy_j(band_nm, effective_wavelength_m)
    photons = photons_per_pixel(irradiance, params.pixel_area_m2, exposure_time_s, photon_energy_j)
    prnu, dsnu = fixed_pattern_maps(irradiance.shape, params, camera_seed)
    return expected_electrons(
        photons,
        params.quantum_efficiency,
        prnu,
        params.dark_current_e_per_s,
        dsnu,
        exposure_time_s,
    )


def simulate_detector(
    irradiance_w_m2: np.ndarray,
    exposure_time_s: float,
    params: DetectorParameters,
    band_nm: tuple[float, float],
    rng: np.random.Generator,
    camera_seed: int,
    effective_wavelength_m: float | None = None,
    *,
    threads: int | None = None,
) -> np.ndarray:
    """One exposure: in-band focal-plane irradiance (H, W, W m^-2) to raw DN (H, W, uint16).

    The stages of ``mean_electrons_image`` (photon collection, charge generation means with
    the fixed pattern of ``camera_seed``), ``shot_noise_electrons``, ``saturate_electrons``
    (with ``params.blooming``) and ``read_out_dn``, fused per row band in float32:
    mu_e = (eta PRNU E A / <E_ph> + D_ij) t, then the shot-noise draw, the full-well cap and
    the readout. Blooming needs whole columns: bands holding over-full pixels wait, the
    affected columns bloom, and every band whose electrons changed is read out again from
    the same read-noise draws. Temporal noise comes only from ``rng``: the same generator
    state gives the same bytes, whatever ``threads`` (default: all cores).
    A half-lit 4096 x 4112 frame takes ~0.1 s on 2 cores, plus ~0.08 s for a camera's first
    frame (its fixed-pattern maps); ``benchmarks/sensor_bench.py`` measures it.
    """
    rng = _check_rng(rng)
    n_threads = check_threads(threads)
    irradiance = _check_irradiance(irradiance_w_m2)
    t = _check_exposure_s(exposure_time_s)
    photon_energy_j = mean_photon_energy_j(band_nm, effective_wavelength_m)
    prnu, dark_e_per_s = _camera_maps(irradiance.shape, params, camera_seed, n_threads)
    h, w = irradiance.shape
    # Photo-electrons per second per W m^-2: eta A / <E_ph>.
    rate_per_w_m2 = params.quantum_efficiency * params.pixel_area_m2 / photon_energy_j
    fw = np.float32(params.full_well_e)
    electrons = np.empty((h, w), dtype=np.float32)
    dn = np.empty((h, w), dtype=np.uint16)
    bands = _row_bands(h, w)
    shot_seeds, read_seeds = zip(*(s.spawn(2) for s in _band_seeds(rng, len(bands))), strict=True)

    def expose(i: int) -> np.ndarray | None:
        """Mean, shot noise, saturation and (unless blooming waits) readout of band i.

        Returns the columns holding over-full pixels when blooming must wait, else None.
        """
        r0, r1 = bands[i]
        mean = np.multiply(irradiance[r0:r1], rate_per_w_m2, dtype=np.float32)
        if prnu is not None:
            mean *= prnu[r0:r1]
        if dark_e_per_s is not None:
            mean += dark_e_per_s[r0:r1]
        else:
            mean += np.float32(params.dark_current_e_per_s)
        mean *= np.float32(t)
        if float(mean.max()) > MAX_POISSON_MEAN_E:
            raise SatsightError(
                f"mean electrons per pixel must be <= {MAX_POISSON_MEAN_E:g} e-; got "
                f"{float(mean.max()):g}. Shorten the exposure or check the irradiance units "
                "(W m^-2)."
            )
        band_e = electrons[r0:r1]
        _shot_noise_band(
            mean.reshape(-1),
            np.random.default_rng(shot_seeds[i]),
            band_e.reshape(-1),
            SHOT_NOISE_NORMAL_MIN_MEAN_E,
        )
        if not params.blooming:
            np.minimum(band_e, fw, out=band_e)
        elif float(band_e.max()) > fw:
            return np.flatnonzero((band_e > fw).any(axis=0))
        _read_out_band(band_e, params, np.random.default_rng(read_seeds[i]), dn[r0:r1])
        return None

    waiting = run_jobs(expose, len(bands), n_threads)
    if any(cols is not None for cols in waiting):
        redo = np.array([cols is not None for cols in waiting])
        changed_rows = np.zeros(h, dtype=bool)
        for j in np.unique(np.concatenate([c for c in waiting if c is not None])):
            before = electrons[:, j].copy()
            column = before.astype(np.float64)
            _bloom_column(column, float(params.full_well_e))
            after = column.astype(np.float32)
            changed = np.flatnonzero(after != before)
            if changed.size:
                changed_rows[changed[0] : changed[-1] + 1] = True
            electrons[:, j] = after
        for i, (r0, r1) in enumerate(bands):
            redo[i] |= bool(changed_rows[r0:r1].any())

        def read_again(i: int) -> None:
            r0, r1 = bands[i]
            gen = np.random.default_rng(read_seeds[i])  # the same read noise as a first read
            _read_out_band(electrons[r0:r1], params, gen, dn[r0:r1])

        again = np.flatnonzero(redo)
        run_jobs(lambda k: read_again(int(again[k])), again.size, n_threads)
    return dn


def exposure_for_fill(
    irradiance_w_m2: float,
    params: DetectorParameters,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    fill_fraction: float = 0.7,
    effective_wavelength_m: float | None = None,
) -> float:
    """Exposure time (s) that puts a pixel at ``irradiance_w_m2`` at fill_fraction x full well.

    Closed form from the mean signal (PRNU = 1, DSNU = 0):
    t = f FW / (eta E A / <E_ph> + D). Pass the target's peak irradiance, or a high
    percentile of it (e.g. ``np.percentile(irr[mask], 99)``) to let a few glints saturate.
    """
    if not (_finite(irradiance_w_m2) and irradiance_w_m2 >= 0):
        raise SatsightError(
            f"irradiance_w_m2 must be a finite scalar >= 0 W m^-2, got {irradiance_w_m2!r}; "
            "pass the target's peak (or a percentile of its) in-band irradiance"
        )
    if not (_finite(fill_fraction) and 0 < fill_fraction <= 1):
        raise SatsightError(
            f"fill_fraction must be in (0, 1], got {fill_fraction!r}; e.g. 0.7 for 70 % "
            "of full well"
        )
    photon_energy_j = mean_photon_energy_j(band_nm, effective_wavelength_m)
    rate_e_per_s = (
        params.quantum_efficiency * float(irradiance_w_m2) * params.pixel_area_m2
    ) / photon_energy_j + params.dark_current_e_per_s
    if rate_e_per_s <= 0:
        raise SatsightError(
            "no signal: irradiance_w_m2 is 0 and the dark current is 0, so no exposure "
            "fills the well; pass the target's irradiance"
        )
    return float(fill_fraction) * params.full_well_e / rate_e_per_s
