"""Independent oracles for the detector's quantum efficiency over a band.

The ASTM E-490 table and the CCD231-84 QE table are read straight from their data files;
every factor is taken as linear between its samples (as the library does) and the integrals
are trapezoid sums on a fine uniform grid (0.05 nm), not on the tables' own nodes. The
library sums the product at the tables' nodes (the E-490 table is 1 nm apart here); the two
quadratures of the same integrand differ by the trapezoid error of that product between
nodes: measured < 3e-6 relative for the solar QE over 450-900 nm and its thirds, < 1e-6 for
black bodies from 3000 to 30000 K.
"""

from __future__ import annotations

from importlib import resources

import numpy as np

H_PLANCK_J_S = 6.62607015e-34
C_M_S = 299_792_458.0
K_BOLTZMANN_J_K = 1.380649e-23
_STEP_NM = 0.05


def table(package: str, name: str) -> np.ndarray:
    """(N, 2) rows of a bundled CSV table (comments and the header line skipped)."""
    text = (resources.files(package) / "data" / name).read_text(encoding="utf-8")
    rows = [s for s in text.splitlines() if s.strip() and not s.startswith("#")][1:]
    return np.array([[float(v) for v in s.split(",")] for s in rows])


def _grid_nm(lo_nm: float, hi_nm: float) -> np.ndarray:
    return np.linspace(lo_nm, hi_nm, round((hi_nm - lo_nm) / _STEP_NM) + 1)


def qe_curve(wavelength_nm: np.ndarray) -> np.ndarray:
    """The CCD231-84 QE table, linear between its samples."""
    qe = table("satsight.camera", "ccd231_84_astro_multi2_qe.csv")
    return np.interp(wavelength_nm, qe[:, 0], qe[:, 1])


def solar_photon_integrals(lo_nm: float, hi_nm: float) -> tuple[float, float, float]:
    """(int E dl, int E l / (h c) dl, int E l QE / (h c) dl) of E-490 over [lo, hi] nm:
    W m^-2, photons s^-1 m^-2 and photo-electrons s^-1 m^-2 at 1 AU."""
    e490 = table("satsight.lighting", "astm_e490_am0.csv")  # nm, W m^-2 nm^-1
    wl = _grid_nm(lo_nm, hi_nm)
    power = np.interp(wl, e490[:, 0], e490[:, 1])
    photons = power * wl * 1e-9 / (H_PLANCK_J_S * C_M_S)
    return (
        float(np.trapezoid(power, wl)),
        float(np.trapezoid(photons, wl)),
        float(np.trapezoid(photons * qe_curve(wl), wl)),
    )


def solar_qe(lo_nm: float, hi_nm: float) -> float:
    """Photon-weighted mean QE of E-490 sunlight over [lo, hi] nm."""
    _, photons, electrons = solar_photon_integrals(lo_nm, hi_nm)
    return electrons / photons


def blackbody_qe(lo_nm: float, hi_nm: float, temperature_k: np.ndarray) -> np.ndarray:
    """(N,) photon-weighted mean QE over [lo, hi] nm of black bodies at temperature_k."""
    wl = _grid_nm(lo_nm, hi_nm)
    t = np.atleast_1d(np.asarray(temperature_k, dtype=np.float64))[:, None]
    x = H_PLANCK_J_S * C_M_S / (K_BOLTZMANN_J_K * wl[None, :] * 1e-9 * t)
    photons = wl[None, :] ** -4 / np.expm1(x)  # B_lambda lambda, up to a constant
    return np.trapezoid(photons * qe_curve(wl), wl, axis=1) / np.trapezoid(photons, wl, axis=1)
