"""How bright the catalogue's stars are: colours, V magnitudes, temperatures, photon flux.

* ``g_minus_v``: Johnson V from Gaia G and BP - RP (Riello et al. 2021, Table C.2);
* ``fit_colour_relations``: B - V from BP - RP and V - Hp from B - V, fitted on the stars
  paired in Gaia and Hipparcos when the catalogue is built;
* ``temperature_from_b_minus_v``: a blackbody effective temperature (Ballesteros 2012);
* ``star_photon_flux_m2_s``: the in-band photon flux of a star at the aperture.

Photometry: a star's spectrum is a blackbody at its temperature scaled to its V magnitude at
545 nm with the V zero point f_lambda = 3.631e-11 W m^-2 nm^-1 (Bessell, Castelli & Plez
1998, A&A 333, 231, Table A2); see :func:`star_photon_flux_m2_s`.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from satsight.constants import PLANCK_J_S, SPEED_OF_LIGHT_M_S
from satsight.errors import SatsightError
from satsight.lighting.blackbody import planck_shape_per_m5
from satsight.lighting.solar_spectrum import check_band_nm

GV_CITATION = "Riello et al. 2021, A&A 649, A3, Table C.2 (G - V from BP - RP)"
TEFF_CITATION = "Ballesteros 2012, EPL 97, 34008 (T_eff from B - V)"
ZERO_POINT_CITATION = "Bessell, Castelli & Plez 1998, A&A 333, 231, Table A2 (V zero point)"

SOLAR_TEMPERATURE_K = 5772.0
"""Nominal solar effective temperature (IAU 2015 Resolution B3), used without a colour."""
GV_COEFFS = (-0.02704, 0.01424, -0.2156, 0.01426)
"""G - V as a polynomial in c = BP - RP, increasing powers (Riello et al. 2021, Table C.2)."""
GV_COLOUR_RANGE = (-0.5, 2.75)
"""Range of BP - RP where the G - V polynomial is valid; c is clipped to it."""
BV_CLIP_FOR_TEMPERATURE = (-0.4, 2.0)
"""B - V is clipped to this range before the Ballesteros (2012) formula."""
V_EFFECTIVE_WAVELENGTH_NM = 545.0
"""Effective wavelength of the Johnson V band (Bessell et al. 1998, Table A2), nm."""
V_ZERO_POINT_W_M2_NM = 3.631e-11
"""Spectral flux density f_lambda of a V = 0 star at 545 nm (Bessell et al. 1998, Table A2:
363.1e-11 erg cm^-2 s^-1 A^-1), W m^-2 nm^-1."""
V_HP_FIT_RANGE_BV = (-0.4, 2.0)
"""Range of B - V over which V - Hp is fitted on the paired stars, and to which B - V is
clipped when that fit gives the V of a star known to Hipparcos only."""
_NODES_PER_PANEL = 16
_PANEL_WIDTH_NM = 100.0


@functools.cache
def _gauss_legendre() -> tuple[np.ndarray, np.ndarray]:
    """The nodes and weights of one panel's Gauss-Legendre rule on [-1, 1] (read-only),
    made once: numpy's takes 0.4 ms, once a frame."""
    x, w = np.polynomial.legendre.leggauss(_NODES_PER_PANEL)
    x.flags.writeable = w.flags.writeable = False
    return x, w


# --- colours and magnitudes ------------------------------------------------------------------


def g_minus_v(bp_minus_rp: np.ndarray) -> np.ndarray:
    """G - V (mag) from BP - RP (Riello et al. 2021, Table C.2), c clipped to [-0.5, 2.75]."""
    c = np.clip(np.asarray(bp_minus_rp, dtype=np.float64), *GV_COLOUR_RANGE)
    return np.polynomial.polynomial.polyval(c, GV_COEFFS)


def temperature_from_b_minus_v(b_minus_v: np.ndarray) -> np.ndarray:
    """Blackbody effective temperature (K) from B - V (Ballesteros 2012, Eq. 14).

    T = 4600 K (1 / (0.92 (B - V) + 1.7) + 1 / (0.92 (B - V) + 0.62)), B - V clipped to
    [-0.4, 2.0] (about 21 700 K to 3 200 K); NaN gives the solar 5772 K.
    """
    bv = np.asarray(b_minus_v, dtype=np.float64)
    x = np.clip(np.nan_to_num(bv, nan=0.0), *BV_CLIP_FOR_TEMPERATURE)
    t = 4600.0 * (1.0 / (0.92 * x + 1.7) + 1.0 / (0.92 * x + 0.62))
    return np.where(np.isnan(bv), SOLAR_TEMPERATURE_K, t)


def _clipped_polyfit(x: np.ndarray, y: np.ndarray, degree: int) -> tuple[np.ndarray, float, int]:
    """Least-squares polynomial (increasing powers) with three 5-sigma clipping passes;
    returns (coefficients, rms of the kept residuals, number kept)."""
    keep = np.ones(x.shape, dtype=bool)
    for _ in range(3):
        coeffs = np.polynomial.polynomial.polyfit(x[keep], y[keep], degree)
        resid = y - np.polynomial.polynomial.polyval(x, coeffs)
        keep = np.abs(resid) <= 5.0 * np.std(resid[keep])
    coeffs = np.polynomial.polynomial.polyfit(x[keep], y[keep], degree)
    resid = y[keep] - np.polynomial.polynomial.polyval(x[keep], coeffs)
    return coeffs, float(np.sqrt(np.mean(resid**2))), int(keep.sum())


def fit_colour_relations(
    bp_minus_rp: np.ndarray, b_minus_v: np.ndarray, v_gaia: np.ndarray, hp_mag: np.ndarray
) -> dict[str, Any]:
    """Fit, on stars paired in Gaia and Hipparcos, B - V as a cubic in BP - RP (for
    c in [-0.5, 2.75]) and V - Hp as a quadratic in B - V (for B - V in [-0.4, 2.0]).

    All inputs (K,) for the K paired stars with both colours known. Returns a dict with
    ``bv_from_bprp`` / ``v_minus_hp_from_bv`` coefficients (increasing powers), their rms
    residuals (mag) and the number of stars kept after clipping.
    """
    in_c = (bp_minus_rp >= GV_COLOUR_RANGE[0]) & (bp_minus_rp <= GV_COLOUR_RANGE[1])
    bv_coeffs, bv_rms, bv_n = _clipped_polyfit(bp_minus_rp[in_c], b_minus_v[in_c], 3)
    in_bv = (b_minus_v >= V_HP_FIT_RANGE_BV[0]) & (b_minus_v <= V_HP_FIT_RANGE_BV[1]) & in_c
    dv_coeffs, dv_rms, dv_n = _clipped_polyfit(b_minus_v[in_bv], v_gaia[in_bv] - hp_mag[in_bv], 2)
    return {
        "bv_from_bprp": tuple(float(c) for c in bv_coeffs),
        "bv_from_bprp_rms_mag": bv_rms,
        "bv_from_bprp_n": bv_n,
        "v_minus_hp_from_bv": tuple(float(c) for c in dv_coeffs),
        "v_minus_hp_from_bv_rms_mag": dv_rms,
        "v_minus_hp_from_bv_n": dv_n,
    }


# --- photon flux -----------------------------------------------------------------------------


def _check_stars(v_mag: np.ndarray, temperature_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.atleast_1d(np.asarray(v_mag, dtype=np.float64))
    t = np.atleast_1d(np.asarray(temperature_k, dtype=np.float64))
    try:
        v, t = np.broadcast_arrays(v, t)
    except ValueError as exc:
        raise SatsightError(
            f"v_mag {v.shape} and temperature_k {t.shape} must have the same (N,) shape"
        ) from exc
    if v.ndim != 1:
        raise SatsightError(f"v_mag and temperature_k must be (N,) arrays; got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise SatsightError("v_mag must be finite V magnitudes; got NaN or inf")
    if not np.all((t >= 1000.0) & (t <= 1e5)):
        raise SatsightError(
            "temperature_k must be blackbody temperatures from 1000 to 100000 K; got "
            f"values from {np.nanmin(t) if t.size else 0:g} to {np.nanmax(t) if t.size else 0:g}"
        )
    return v, t


def star_photon_flux_m2_s(
    v_mag: np.ndarray, temperature_k: np.ndarray, band_nm: tuple[float, float]
) -> np.ndarray:
    """In-band photon flux of stars at the top of the aperture, photons s^-1 m^-2, (N,).

    v_mag: (N,) Johnson V magnitudes. temperature_k: (N,) blackbody temperatures (K).
    band_nm: (lo, hi) pass band in nm. The spectrum is a blackbody B_lambda(T) scaled so that
    f_lambda(545 nm) = 3.631e-11 W m^-2 nm^-1 x 10^(-0.4 V) (Bessell, Castelli & Plez 1998,
    Table A2), counted as photons (lambda / (h c)) and integrated over the band with
    composite Gauss-Legendre quadrature (16 nodes per <= 100 nm panel; relative error
    < 1e-12 for T >= 1000 K). A V = 0 star delivers ~1.0e8 photons s^-1 m^-2 nm^-1 near
    545 nm. Extinction-free: no atmosphere in space.
    """
    lo, hi = check_band_nm(band_nm)
    v, t = _check_stars(v_mag, temperature_k)
    panels = max(1, math.ceil((hi - lo) / _PANEL_WIDTH_NM))
    x, w = _gauss_legendre()
    edges = np.linspace(lo, hi, panels + 1)
    half = 0.5 * np.diff(edges)
    lam_nm = ((edges[:-1] + half)[:, None] + half[:, None] * x[None, :]).ravel()
    weights_nm = (half[:, None] * w[None, :]).ravel()
    lam_m = lam_nm * 1e-9
    shape = planck_shape_per_m5(lam_m[None, :], t[:, None])  # (N, nodes)
    ref = planck_shape_per_m5(np.array([V_EFFECTIVE_WAVELENGTH_NM * 1e-9]), t)  # (N,)
    f_v = V_ZERO_POINT_W_M2_NM * 10.0 ** (-0.4 * v)  # W m^-2 nm^-1 at 545 nm
    photons_per_nm = (shape / ref[:, None]) * (lam_m / (PLANCK_J_S * SPEED_OF_LIGHT_M_S))[None, :]
    return f_v * (photons_per_nm @ weights_nm)
