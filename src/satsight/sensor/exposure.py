"""One CCD exposure: focal-plane irradiance (W m^-2) to digital numbers (uint16).

The chain follows the physical order of a CCD exposure (Janesick, *Photon Transfer*,
SPIE Press, 2007, ch. 2-5), one small pure function per stage:

1. photon collection: ``photons_per_pixel`` (``satsight.sensor.detector``);
2. charge generation: ``expected_electrons`` (``satsight.sensor.detector``) with the
   camera's ``fixed_pattern_maps`` (``satsight.sensor.fixed_pattern``), then
   ``shot_noise_electrons`` (``satsight.sensor.noise``) draws the Poisson count;
3. charge collection: ``saturate_electrons`` caps each pixel at its full well, optionally
   spilling the excess along the column (blooming);
4. measurement and readout: ``read_out_dn`` (``satsight.sensor.noise``) adds Gaussian read
   noise, divides by the conversion gain, adds the bias, rounds to whole DN and clips to
   the ADC range.

``simulate_detector`` runs the whole chain, fused per row band in float32 (electrons up to
~1.6e7 are exact integers there, 46 x the full well); ``mean_electrons_image`` gives its
noise-free mean before saturation and ``exposure_for_fill`` the exposure time that fills
the well to a fraction. Randomness comes only from the ``np.random.Generator`` passed in
(temporal noise) or from ``camera_seed`` (fixed pattern); the result never depends on the
thread count (see ``satsight.sensor.noise``).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.constants import DEFAULT_BAND_NM
from satsight.errors import SatsightError
from satsight.sensor.detector import (
    DetectorParameters,
    _check_exposure_s,
    _check_image_2d,
    _check_nonnegative_image,
    _finite,
    expected_electrons,
    mean_photon_energy_j,
    photons_per_pixel,
)
from satsight.sensor.fixed_pattern import _camera_maps, fixed_pattern_maps
from satsight.sensor.noise import (
    MAX_POISSON_MEAN_E,
    SHOT_NOISE_NORMAL_MIN_MEAN_E,
    _band_seeds,
    _check_rng,
    _read_out_band,
    _row_bands,
    _shot_noise_band,
)
from satsight.sensor.threads import check_threads, run_jobs


def resolve_qe(
    params: DetectorParameters, band_nm: tuple[float, float], quantum_efficiency: float | None
) -> float:
    """The eta an exposure uses: ``quantum_efficiency`` when given (checked to lie in
    (0, 1]), else the detector's for sunlight over the band,
    ``params.band_quantum_efficiency(band_nm)`` (its override or its curve's E-490
    photon-weighted mean)."""
    if quantum_efficiency is None:
        return params.band_quantum_efficiency(band_nm)
    if not (_finite(quantum_efficiency) and 0.0 < float(quantum_efficiency) <= 1.0):
        raise SatsightError(
            f"quantum_efficiency must be in (0, 1] electrons per photon, got "
            f"{quantum_efficiency!r}; give a fraction or None for the detector's own"
        )
    return float(quantum_efficiency)


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
    *,
    quantum_efficiency: float | None = None,
) -> np.ndarray:
    """Noise-free mean electrons per pixel (H, W, e-, float64), before saturation.

    Photon collection and the mean of charge generation, with this camera's fixed
    pattern: eta PRNU E A t / <E_ph> + (D + DSNU) t. eta is ``quantum_efficiency`` when
    given, else ``params.band_quantum_efficiency(band_nm)`` (see ``resolve_qe``).
    """
    irradiance = _check_nonnegative_image("irradiance_w_m2", irradiance_w_m2, "W m^-2")
    _check_image_2d("irradiance_w_m2", irradiance)
    photon_energy_j = mean_photon_energy_j(band_nm, effective_wavelength_m)
    photons = photons_per_pixel(irradiance, params.pixel_area_m2, exposure_time_s, photon_energy_j)
    prnu, dsnu = fixed_pattern_maps(irradiance.shape, params, camera_seed)
    return expected_electrons(
        photons,
        resolve_qe(params, band_nm, quantum_efficiency),
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
    quantum_efficiency: float | None = None,
) -> np.ndarray:
    """One exposure: in-band focal-plane irradiance (H, W, W m^-2) to raw DN (H, W, uint16).

    The stages of ``mean_electrons_image`` (photon collection, charge generation means with
    the fixed pattern of ``camera_seed``), ``shot_noise_electrons``, ``saturate_electrons``
    (with ``params.blooming``) and ``read_out_dn``, fused per row band in float32:
    mu_e = (eta PRNU E A / <E_ph> + D_ij) t, then the shot-noise draw, the full-well cap and
    the readout. Blooming needs whole columns: bands holding over-full pixels wait, the
    affected columns bloom, and every band whose electrons changed is read out again from
    the same read-noise draws. Temporal noise comes only from ``rng``: the same generator
    state gives the same bytes, whatever ``threads`` (default: all cores). eta is
    ``quantum_efficiency`` when given, else ``params.band_quantum_efficiency(band_nm)``.
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
    eta = resolve_qe(params, band_nm, quantum_efficiency)
    rate_per_w_m2 = eta * params.pixel_area_m2 / photon_energy_j
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
    *,
    quantum_efficiency: float | None = None,
) -> float:
    """Exposure time (s) that puts a pixel at ``irradiance_w_m2`` at fill_fraction x full well.

    Closed form from the mean signal (PRNU = 1, DSNU = 0):
    t = f FW / (eta E A / <E_ph> + D). Pass the target's peak irradiance, or a high
    percentile of it (e.g. ``np.percentile(irr[mask], 99)``) to let a few glints saturate.
    eta is ``quantum_efficiency`` when given, else ``params.band_quantum_efficiency(band_nm)``.
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
    eta = resolve_qe(params, band_nm, quantum_efficiency)
    rate_e_per_s = (
        eta * float(irradiance_w_m2) * params.pixel_area_m2
    ) / photon_energy_j + params.dark_current_e_per_s
    if rate_e_per_s <= 0:
        raise SatsightError(
            "no signal: irradiance_w_m2 is 0 and the dark current is 0, so no exposure "
            "fills the well; pass the target's irradiance"
        )
    return float(fill_fraction) * params.full_well_e / rate_e_per_s
