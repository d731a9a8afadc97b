"""Per-frame random draws of a CCD exposure: shot noise, read noise and quantisation.

* ``shot_noise_electrons``: the Poisson count of photo- and dark electrons around their
  mean (exact below ``SHOT_NOISE_NORMAL_MIN_MEAN_E``, its normal limit above);
* ``read_out_dn``: Gaussian read noise, division by the conversion gain, the bias, rounding
  to whole DN (the quantisation noise, 1/12 DN^2) and the ADC clip.

These are the temporal noise terms of the EMVA 1288 R4.0 linear model (see
``satsight.sensor.detector``); they change from frame to frame. Randomness comes only from
the ``np.random.Generator`` passed in.

Speed and reproducibility. A full 4096 x 4112 frame is processed in row bands of about
``BAND_PIXELS`` pixels on a thread pool (numpy's generators and ufuncs release the GIL).
The bands are fixed by the image width and height alone, and each band draws from its own
generator, spawned from one ``np.random.SeedSequence`` whose entropy is four 64-bit words
taken from the caller's generator. So the output depends only on the generator's state (and
the camera seed), never on the number of threads. Normal draws in float32 use a Box-Muller
transform on the bit generator's raw words (``_standard_normal_f32``).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.errors import SatsightError
from satsight.sensor.detector import (
    DetectorParameters,
    _check_image_2d,
    _check_nonnegative_image,
)
from satsight.sensor.threads import check_threads, run_jobs

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
# Generators, row bands and normal draws
# --------------------------------------------------------------------------------------
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
# Shot noise
# --------------------------------------------------------------------------------------
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
# Measurement and readout
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
