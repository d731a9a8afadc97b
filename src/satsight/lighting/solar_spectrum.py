"""The Sun's spectrum outside the atmosphere and its in-band irradiance.

Two spectra are offered:

* ``"astm_e490"``: the ASTM E-490-00a air-mass-zero solar spectral irradiance at 1 AU
  (ASTM E490-00a(2006), *Standard Solar Constant and Zero Air Mass Solar Spectral Irradiance
  Tables*, ASTM International; table as published by NREL's Renewable Resource Data Center,
  https://www.nrel.gov/grid/solar-resource/spectra-astm-e490.html). 1697 samples from
  119.5 nm to 1 mm; its integral is the E-490 solar constant, 1366.1 W m^-2. Between
  samples the spectrum is taken as linear, so band integrals are the exact integrals of
  the linear interpolant (the trapezoid rule with the band edges interpolated).
* ``"blackbody_5778k"``: a Planck spectrum at ``temperature_k`` (default 5778 K, the
  value the paper uses; the IAU 2015 Resolution B3 nominal solar effective temperature is
  5772 K) scaled so that its total over all wavelengths is ``total_w_m2`` (default
  1366.1 W m^-2). The total uses the Stefan-Boltzmann law ``sigma T^4`` in closed form;
  the band uses numerical quadrature of Planck's law.

Over the paper's 450-900 nm band at 1 AU the E-490 table gives 671.5 W m^-2 (satsight's
``DEFAULT_SUN_IRRADIANCE_W_M2``) and the scaled 5778 K black body 648.7 W m^-2 (the paper
quotes 647.7 W m^-2).

Units: wavelengths are metres inside (``wavelength_m``); bands are given in nanometres
(``band_nm``) because that is how they are quoted. Spectral irradiance is in W m^-2 per
metre of wavelength (``spectral_irradiance_w_m2_per_m``); irradiance in W m^-2 on a
surface facing the Sun.
"""

from __future__ import annotations

import hashlib
import itertools
import math
from functools import lru_cache
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Literal

import numpy as np

from satsight.constants import AU_M, DEFAULT_BAND_NM, STEFAN_BOLTZMANN_W_M2_K4
from satsight.errors import SatsightError
from satsight.lighting.blackbody import planck_exitance_w_m2_per_m

Spectrum = Literal["astm_e490", "blackbody_5778k"]
SPECTRA: tuple[str, ...] = ("astm_e490", "blackbody_5778k")

# The solar constant of ASTM E-490-00a, W m^-2 (the integral of its table).
E490_SOLAR_CONSTANT_W_M2 = 1366.1

# The paper's solar temperature, K; IAU 2015 Resolution B3 gives the nominal solar
# effective temperature 5772 K.
PAPER_SUN_TEMPERATURE_K = 5778.0
IAU_2015_NOMINAL_SUN_TEFF_K = 5772.0


E490_FILE = "astm_e490_am0.csv"
# SHA-256 of the data file, with line endings normalised to "\n".
E490_SHA256 = "0f740c626b6c34fef5274b03a70f413a440bd06fea59ec3e86f17cc34e6db5df"
E490_ROWS = 1697
_E490_COLUMNS = "wavelength_nm,spectral_irradiance_w_m2_nm"

_NM = 1e-9  # metres per nanometre


def _read_verified(path: Traversable | Path) -> str:
    """The text of the E-490 data file at ``path``, after checking its SHA-256."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SatsightError(
            f"the ASTM E-490 spectrum file {E490_FILE} cannot be read ({exc}); reinstall satsight"
        ) from exc
    raw = raw.replace(b"\r\n", b"\n")
    digest = hashlib.sha256(raw).hexdigest()
    if digest != E490_SHA256:
        raise SatsightError(
            f"the ASTM E-490 spectrum file {path} is damaged: its SHA-256 is {digest}, "
            f"expected {E490_SHA256}; reinstall satsight"
        )
    return raw.decode("ascii")


def e490_path() -> Traversable:
    """Where the E-490 data file lies in the installed package."""
    return resources.files("satsight.lighting") / "data" / E490_FILE


def _parse_e490(text: str) -> tuple[np.ndarray, np.ndarray]:
    lines = [s for s in text.splitlines() if s.strip() and not s.startswith("#")]
    if not lines or lines[0].strip() != _E490_COLUMNS:
        raise SatsightError(f"{E490_FILE}: expected the column header '{_E490_COLUMNS}'")
    table = np.array([[float(v) for v in s.split(",")] for s in lines[1:]], dtype=np.float64)
    if table.shape != (E490_ROWS, 2):
        raise SatsightError(f"{E490_FILE}: expected {E490_ROWS} rows of 2 values")
    return table[:, 0], table[:, 1]


@lru_cache(maxsize=1)
def _e490_cached() -> tuple[np.ndarray, np.ndarray]:
    wavelength_nm, irradiance_w_m2_nm = _parse_e490(_read_verified(e490_path()))
    wavelength_m = wavelength_nm * _NM
    irradiance_w_m2_per_m = irradiance_w_m2_nm / _NM
    wavelength_m.setflags(write=False)
    irradiance_w_m2_per_m.setflags(write=False)
    return wavelength_m, irradiance_w_m2_per_m


def load_e490() -> tuple[np.ndarray, np.ndarray]:
    """The ASTM E-490-00a air-mass-zero solar spectrum at 1 AU.

    Returns ``(wavelength_m, spectral_irradiance_w_m2_per_m)``: two (1697,) float64
    arrays, wavelength in m (increasing, 119.5 nm to 1 mm) and spectral irradiance on a
    surface facing the Sun at 1 AU in W m^-2 m^-1. The arrays are read-only.

    The data file's SHA-256 is checked on first use; a damaged or edited file raises
    :class:`~satsight.errors.SatsightError`.
    """
    return _e490_cached()


def _integrate_piecewise_linear(x: np.ndarray, y: np.ndarray, lo: float, hi: float) -> float:
    """Exact integral over [lo, hi] of the linear interpolant through (x, y)."""
    inside = (x > lo) & (x < hi)
    xs = np.concatenate(([lo], x[inside], [hi]))
    ys = np.concatenate(([np.interp(lo, x, y)], y[inside], [np.interp(hi, x, y)]))
    return float(np.sum(0.5 * (ys[1:] + ys[:-1]) * np.diff(xs)))


def solar_constant_w_m2() -> float:
    """Total solar irradiance at 1 AU from the E-490 table, W m^-2 (about 1366.1).

    The integral of the whole table (trapezoid rule, the table taken as linear between
    samples).
    """
    wavelength_m, irradiance = load_e490()
    return _integrate_piecewise_linear(
        wavelength_m, irradiance, float(wavelength_m[0]), float(wavelength_m[-1])
    )


def _planck_band_w_m2(lo_m: float, hi_m: float, temperature_k: float) -> float:
    """Integral of the black-body exitance over [lo_m, hi_m], W m^-2.

    Composite Gauss-Legendre quadrature in ln(lambda) (panels at most 0.05 wide, 8 nodes
    each); the integrand is smooth, so the result is exact to rounding.
    """
    a, b = math.log(lo_m), math.log(hi_m)
    n_panels = max(1, math.ceil((b - a) / 0.05))
    nodes, weights = np.polynomial.legendre.leggauss(8)
    edges = np.linspace(a, b, n_panels + 1)
    half = 0.5 * np.diff(edges)[:, None]
    u = 0.5 * (edges[1:] + edges[:-1])[:, None] + half * nodes[None, :]
    lam = np.exp(u)
    integrand = planck_exitance_w_m2_per_m(lam, temperature_k) * lam
    return float(np.sum(half * weights[None, :] * integrand))


def check_band_nm(band_nm: tuple[float, float]) -> tuple[float, float]:
    """A spectral band (lo, hi) in nm as two floats with 0 < lo < hi, or SatsightError."""
    try:
        lo, hi = (float(v) for v in band_nm)
    except (TypeError, ValueError) as exc:
        raise SatsightError(
            f"band_nm must be two wavelengths (lo, hi) in nm, got {band_nm!r}"
        ) from exc
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SatsightError(
            f"band_nm must satisfy 0 < lo < hi (nm), got ({lo:g}, {hi:g}); "
            "give the band's short-wavelength edge first"
        )
    return lo, hi


def _check_distance_au(distance_au: float) -> float:
    d = float(distance_au)
    if not (math.isfinite(d) and d > 0.0):
        raise SatsightError(f"distance_au must be finite and > 0 AU, got {distance_au}")
    return d


def _band_irradiance_1au_w_m2(
    lo_nm: float, hi_nm: float, spectrum: str, temperature_k: float, total_w_m2: float
) -> float:
    if spectrum == "astm_e490":
        wavelength_m, irradiance = load_e490()
        first_nm, last_nm = wavelength_m[0] / _NM, wavelength_m[-1] / _NM
        if lo_nm < first_nm * (1 - 1e-12) or hi_nm > last_nm * (1 + 1e-12):
            raise SatsightError(
                f"band ({lo_nm:g}, {hi_nm:g}) nm lies outside the ASTM E-490 table, which "
                f"covers {first_nm:g} nm to {last_nm:g} nm"
            )
        lo_m = max(lo_nm * _NM, float(wavelength_m[0]))
        hi_m = min(hi_nm * _NM, float(wavelength_m[-1]))
        return _integrate_piecewise_linear(wavelength_m, irradiance, lo_m, hi_m)
    if spectrum == "blackbody_5778k":
        t = float(temperature_k)
        if not (math.isfinite(t) and t > 0.0):
            raise SatsightError(f"temperature_k must be finite and > 0 K, got {temperature_k}")
        if not (math.isfinite(total_w_m2) and total_w_m2 >= 0.0):
            raise SatsightError(f"total_w_m2 must be finite and >= 0 W m^-2, got {total_w_m2}")
        band = _planck_band_w_m2(lo_nm * _NM, hi_nm * _NM, t)
        fraction = band / (STEFAN_BOLTZMANN_W_M2_K4 * t**4)
        return float(total_w_m2) * fraction
    raise SatsightError(f"unknown spectrum '{spectrum}'; choose one of {', '.join(SPECTRA)}")


def band_irradiance_w_m2(
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    spectrum: Spectrum = "astm_e490",
    distance_au: float = 1.0,
    *,
    temperature_k: float = PAPER_SUN_TEMPERATURE_K,
    total_w_m2: float = E490_SOLAR_CONSTANT_W_M2,
) -> float:
    """In-band solar irradiance on a surface facing the Sun, W m^-2.

    ``E(d) = E_1AU (1 AU / d)^2`` with ``E_1AU`` the integral of the spectral irradiance
    over ``band_nm = (lo, hi)`` (nm), integrated exactly up to the band edges.

    spectrum: ``"astm_e490"`` (the E-490 table; the band must lie within 119.5 nm to 1 mm)
    or ``"blackbody_5778k"`` (Planck at ``temperature_k``, default the paper's 5778 K,
    scaled to a total of ``total_w_m2``, default 1366.1 W m^-2; ``temperature_k`` and
    ``total_w_m2`` apply to this spectrum only).
    distance_au: Sun-observer distance in astronomical units (1 AU = 149 597 870 700 m,
    IAU 2012 Resolution B2).
    """
    lo, hi = check_band_nm(band_nm)
    d = _check_distance_au(distance_au)
    e_1au = _band_irradiance_1au_w_m2(lo, hi, spectrum, temperature_k, total_w_m2)
    return e_1au / d**2


def irradiance_at_distance_w_m2(irradiance_at_1_au_w_m2: float, sun_distance_m: float) -> float:
    """The Sun's irradiance (W m^-2, any band) at ``sun_distance_m`` from it, from its value
    at 1 AU by the inverse-square law: ``E(d) = E_1AU (AU / d)^2``."""
    return irradiance_at_1_au_w_m2 * (AU_M / sun_distance_m) ** 2


def spectral_weights(
    edges_nm: tuple[float, ...] | np.ndarray,
    spectrum: Spectrum = "astm_e490",
    *,
    temperature_k: float = PAPER_SUN_TEMPERATURE_K,
) -> np.ndarray:
    """Fraction of the irradiance between ``edges_nm[0]`` and ``edges_nm[-1]`` in each sub-band.

    edges_nm: (K + 1,) increasing wavelengths in nm delimiting K consecutive sub-bands
    (e.g. the pass bands of colour channels). Returns (K,) float64 fractions summing to 1;
    dimensionless and independent of the distance to the Sun.
    """
    edges = np.asarray(edges_nm, dtype=np.float64).reshape(-1)
    if edges.size < 2:
        raise SatsightError(f"edges_nm needs at least two wavelengths, got {edges.tolist()}")
    if not np.all(np.diff(edges) > 0.0):
        raise SatsightError(f"edges_nm must be strictly increasing (nm), got {edges.tolist()}")
    parts = np.array(
        [
            band_irradiance_w_m2((lo, hi), spectrum, temperature_k=temperature_k, total_w_m2=1.0)
            for lo, hi in itertools.pairwise(edges.tolist())
        ]
    )
    total = float(np.sum(parts))
    if total <= 0.0:
        raise SatsightError(
            f"the spectrum has no irradiance between {edges[0]:g} and {edges[-1]:g} nm"
        )
    return parts / total


def photon_weighted_wavelength_m(
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    spectrum: Spectrum = "astm_e490",
    *,
    temperature_k: float = PAPER_SUN_TEMPERATURE_K,
) -> float:
    """Photon-weighted mean wavelength of sunlight in ``band_nm``, m.

    ``lambda_eff = int E_lambda lambda d lambda / int E_lambda d lambda`` over the band, so
    that in-band irradiance E carries ``E lambda_eff / (h c)`` photons per second and square
    metre: the mean photon energy is ``h c / lambda_eff``. Light reflected
    by grey surfaces keeps this spectrum. For ``"astm_e490"`` both integrals are taken over the
    table's linear interpolant (``E lambda`` interpolated linearly between samples, which
    differs from the exact product by far less than 1e-6 relative over 1-nm spacing); for the
    black body, Gauss-Legendre quadrature in ln(lambda).
    """
    lo, hi = check_band_nm(band_nm)
    lo_m, hi_m = lo * _NM, hi * _NM
    if spectrum == "astm_e490":
        wavelength_m, irradiance = load_e490()
        energy = _band_irradiance_1au_w_m2(lo, hi, spectrum, temperature_k, 1.0)
        weighted = _integrate_piecewise_linear(wavelength_m, irradiance * wavelength_m, lo_m, hi_m)
        return weighted / energy
    if spectrum == "blackbody_5778k":
        a, b = math.log(lo_m), math.log(hi_m)
        nodes, weights = np.polynomial.legendre.leggauss(64)
        lam = np.exp(0.5 * (b - a) * nodes + 0.5 * (a + b))
        exitance = planck_exitance_w_m2_per_m(lam, float(temperature_k)) * lam
        return float(np.sum(weights * exitance * lam) / np.sum(weights * exitance))
    raise SatsightError(f"unknown spectrum '{spectrum}'; choose one of {', '.join(SPECTRA)}")
