"""The detector's quantum efficiency over the band, weighted by the light it sees.

A CCD's electrons per incident photon depend on wavelength, QE(lambda)
(``satsight.camera.quantum_efficiency``, the curve the material library's band integration
uses too). Over a band the mean that turns photons into electrons is the photon-weighted one,

    <QE> = int N(l) QE(l) dl / int N(l) dl,    N(l) = E(l) l / (h c)

(EMVA Standard 1288 Release 4.0 (2021), Sec. 2: the mean signal is eta mu_p for each
wavelength), with E the light's spectral irradiance: the ASTM E-490 Sun (or the 5778 K black
body) for sunlit surfaces and earthshine, a star's own black body for stars. Every factor is
taken as linear between its samples; the integrals are trapezoid sums over the union of the
E-490, QE-curve and band-edge wavelengths (black bodies: that grid refined to <= 1 nm).
"""

from __future__ import annotations

import functools

import numpy as np

from satsight.camera.quantum_efficiency import DEFAULT_QE, load_quantum_efficiency
from satsight.errors import SatsightError
from satsight.lighting.blackbody import planck_shape_per_m5
from satsight.lighting.solar_spectrum import (
    PAPER_SUN_TEMPERATURE_K,
    Spectrum,
    check_band_nm,
    load_e490,
)
from satsight.quadrature import trapezoid

_NM = 1e-9


def _grid_nm(lo: float, hi: float, curve_name: str, fine: bool) -> np.ndarray:
    e_wl_nm = load_e490()[0] / _NM
    curve = load_quantum_efficiency(curve_name)
    parts = [np.array([lo, hi]), e_wl_nm[(e_wl_nm > lo) & (e_wl_nm < hi)]]
    parts.append(curve.wavelength_nm[(curve.wavelength_nm > lo) & (curve.wavelength_nm < hi)])
    if fine:
        parts.append(np.linspace(lo, hi, int(np.ceil(hi - lo)) + 1))
    return np.unique(np.concatenate(parts))


@functools.lru_cache(maxsize=32)
def solar_weighted_qe(
    band_nm: tuple[float, float],
    spectrum: Spectrum = "astm_e490",
    curve_name: str = DEFAULT_QE,
) -> float:
    """Photon-weighted mean QE of sunlight over ``band_nm`` (nm): ~0.81 for the CCD231-84
    curve over 450-900 nm with E-490 (its plain mean over the band is ~0.80)."""
    lo, hi = check_band_nm(band_nm)
    curve = load_quantum_efficiency(curve_name)
    if spectrum == "astm_e490":
        wl = _grid_nm(lo, hi, curve_name, fine=False)
        e_wl, e_val = load_e490()
        photons = np.interp(wl * _NM, e_wl, e_val) * wl
    elif spectrum == "blackbody_5778k":
        wl = _grid_nm(lo, hi, curve_name, fine=True)
        photons = planck_shape_per_m5(wl * _NM, PAPER_SUN_TEMPERATURE_K) * wl
    else:
        raise SatsightError(f"unknown spectrum '{spectrum}'; choose astm_e490 or blackbody_5778k")
    return trapezoid(photons * curve(wl), wl) / trapezoid(photons, wl)


def blackbody_weighted_qe(
    band_nm: tuple[float, float],
    temperature_k: np.ndarray,
    curve_name: str = DEFAULT_QE,
) -> np.ndarray:
    """(N,) photon-weighted mean QE over ``band_nm`` of black bodies at ``temperature_k``
    (N,) K: the QE a star of that temperature sees."""
    lo, hi = check_band_nm(band_nm)
    t = np.atleast_1d(np.asarray(temperature_k, dtype=np.float64))
    if not np.all(np.isfinite(t) & (t > 0)):
        raise SatsightError("temperature_k must be positive, finite temperatures in K")
    curve = load_quantum_efficiency(curve_name)
    wl = _grid_nm(lo, hi, curve_name, fine=True)
    photons = planck_shape_per_m5(wl[None, :] * _NM, t[:, None]) * wl[None, :]
    dx = np.diff(wl)
    weights = np.zeros(wl.size)
    weights[:-1] += 0.5 * dx
    weights[1:] += 0.5 * dx  # trapezoid weights
    return (photons * curve(wl)) @ weights / (photons @ weights)
