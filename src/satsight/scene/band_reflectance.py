"""In-band colour of a reflectance spectrum, and library entries as renderer materials.

The sensor band ``(lo, hi)`` nm is split into three equal thirds, the convention of
``satsight.sensor.chain`` and ``satsight.lighting.solar_spectrum``: blue = the short third,
green = the middle, red = the long. Each channel's reflectance is the mean of the spectrum
weighted by what the detector counts from sunlight, photo-electrons::

    rho_c = int rho(l) E(l) l QE(l) dl / int E(l) l QE(l) dl     over the channel's third

with E the ASTM E-490 solar spectral irradiance (``load_e490``), ``E l / (h c)`` its photon
flux, and QE(l) the detector's quantum efficiency (``satsight.camera.quantum_efficiency``;
``"flat"`` gives the photon-weighted mean). All factors are taken as linear between their
samples; the integrals are trapezoid sums over the union of the E-490, spectrum and QE
sample wavelengths inside the third (the E-490 table is 1 nm apart here, the spectra 5 nm).

A library entry becomes a :class:`satsight.scene.materials.Material` by
:func:`material_from_entry`: the base colour is the in-band reflectance, mapped by the
entry's metallic value M (paper Eq. 18):

* M = 1 (metals, second-surface mirrors, metallised films): the base colour *is* the
  normal-incidence reflectance F0 (``ks = base``).
* M = 0 (paints, cloth, composites, cells): the directional albedo at normal incidence of
  the model is ``F0 + base (1 - F0)(1 - F_h)`` (the specular part reflects F0; the
  diffuse part enters through the interface and leaves through it, losing the
  hemispherical Fresnel fraction ``F_h``), so ``base = (R - F0) / ((1 - F0)(1 - F_h))``,
  clamped to [0, 1]. For 0 < M < 1 the same balance gives
  ``base = (R - (1 - M) F0) / (M + (1 - M)(1 - F0)(1 - F_h))``.

The rough-specular lobe reflects a little less than F0 at normal incidence (masking); the
mapping neglects that (a few per cent of F0).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import replace

import numpy as np

from satsight.camera.quantum_efficiency import (
    DEFAULT_QE,
    QuantumEfficiency,
    resolve_quantum_efficiency,
)
from satsight.constants import DEFAULT_BAND_NM
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import check_band_nm, load_e490
from satsight.quadrature import trapezoid
from satsight.scene.material_library import (
    LIBRARY_PREFIX,
    LibraryEntry,
    entry_spectrum,
    list_materials,
    load_entry,
)
from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.spectra import hemispherical_fresnel

_NM = 1e-9


def channel_edges_nm(band_nm: tuple[float, float] = DEFAULT_BAND_NM) -> np.ndarray:
    """(4,) edges of the blue, green and red thirds of ``band_nm``, nm."""
    lo, hi = check_band_nm(band_nm)
    return np.linspace(lo, hi, 4)


def _e490_nm() -> tuple[np.ndarray, np.ndarray]:
    wavelength_m, irradiance_w_m2_per_m = load_e490()
    return wavelength_m / _NM, irradiance_w_m2_per_m * _NM  # nm, W m^-2 nm^-1


def _nodes(lo: float, hi: float, *grids: np.ndarray) -> np.ndarray:
    pts = [np.array([lo, hi])]
    pts += [g[(g > lo) & (g < hi)] for g in grids]
    return np.unique(np.concatenate(pts))


def detected_weights(
    wavelength_nm: np.ndarray, qe: str | QuantumEfficiency = DEFAULT_QE
) -> np.ndarray:
    """The weight ``E(l) l QE(l)`` at ``wavelength_nm`` (nm): the photo-electron spectral
    rate per unit area, up to the factor 1 / (h c)."""
    e_wl, e_val = _e490_nm()
    curve = resolve_quantum_efficiency(qe)
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    return np.interp(wl, e_wl, e_val) * wl * curve(wl)


def band_mean(
    wavelength_nm: np.ndarray,
    reflectance: np.ndarray,
    lo_nm: float,
    hi_nm: float,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> float:
    """Detected-photon-weighted mean of a spectrum over [lo_nm, hi_nm] (see module doc)."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    refl = np.asarray(reflectance, dtype=np.float64)
    if lo_nm < wl[0] or hi_nm > wl[-1]:
        raise SatsightError(
            f"the spectrum covers {wl[0]:g}-{wl[-1]:g} nm, not the band {lo_nm:g}-{hi_nm:g} nm"
        )
    curve = resolve_quantum_efficiency(qe)
    e_wl, _ = _e490_nm()
    x = _nodes(lo_nm, hi_nm, e_wl, wl, curve.wavelength_nm)
    w = detected_weights(x, curve)
    den = trapezoid(w, x)
    if not den > 0.0:
        raise SatsightError(
            f"the detector sees no sunlight between {lo_nm:g} and {hi_nm:g} nm (QE is 0 there)"
        )
    return float(trapezoid(w * np.interp(x, wl, refl), x) / den)


def channel_reflectance(
    wavelength_nm: np.ndarray,
    reflectance: np.ndarray,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> tuple[float, float, float]:
    """(r, g, b): the spectrum's detected-photon-weighted mean over the long, middle and
    short third of ``band_nm``. wavelength_nm, reflectance: (W,) arrays, nm and [0, 1]."""
    edges = channel_edges_nm(band_nm)
    blue, green, red = (
        band_mean(wavelength_nm, reflectance, edges[i], edges[i + 1], qe) for i in range(3)
    )
    return red, green, blue


def _entry(material: str | LibraryEntry) -> LibraryEntry:
    return material if isinstance(material, LibraryEntry) else load_entry(material)


def material_rgb_reflectance(
    material: str | LibraryEntry,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> tuple[float, float, float]:
    """(r, g, b) in-band reflectance of a library material (name or entry)."""
    wl, refl = entry_spectrum(_entry(material))
    return channel_reflectance(wl, refl, band_nm, qe)


def solar_weighted_reflectance(
    wavelength_nm: np.ndarray, reflectance: np.ndarray, band_nm: Sequence[float] = (400, 1800)
) -> float:
    """Energy-weighted mean reflectance under the E-490 Sun over ``band_nm`` (nm).

    ``1 -`` this is the solar absorptance *restricted to the band*; published solar
    absorptances integrate over about 250-2500 nm, so they differ by the light outside.
    """
    e_wl, e_val = _e490_nm()
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    lo, hi = float(band_nm[0]), float(band_nm[1])
    x = _nodes(lo, hi, e_wl, wl)
    w = np.interp(x, e_wl, e_val)
    return float(trapezoid(w * np.interp(x, wl, reflectance), x) / trapezoid(w, x))


def base_colour_from_reflectance(
    rgb_reflectance: Sequence[float], metallic: float, ior: float
) -> tuple[float, float, float]:
    """Base colour that makes the GGX model's normal-incidence albedo equal the measured
    in-band reflectance (see the module docstring), clamped to [0, 1]."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    f_h = hemispherical_fresnel(ior)
    m = float(metallic)
    denominator = m + (1.0 - m) * (1.0 - f0) * (1.0 - f_h)
    out = [(float(r) - (1.0 - m) * f0) / denominator for r in rgb_reflectance]
    r, g, b = (min(max(v, 0.0), 1.0) for v in out)
    return r, g, b


def material_from_entry(
    material: str | LibraryEntry,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> Material:
    """The renderer's Material for a library entry, its base colour from the band integral."""
    entry = _entry(material)
    v = {k: sv.value for k, sv in entry.brdf.items()}
    rgb = material_rgb_reflectance(entry, band_nm, qe)
    base = base_colour_from_reflectance(rgb, v["metallic"], v["ior"])
    lo, hi = check_band_nm(band_nm)
    curve = resolve_quantum_efficiency(qe)
    source = (
        f"library '{entry.name}': base colour = in-band reflectance over {lo:g}-{hi:g} nm "
        f"(QE '{curve.name}'), spectrum: {entry.spectrum_source}; "
        + "; ".join(f"{k}: {sv.source}" for k, sv in entry.brdf.items())
    )
    optional = {
        k: v[k]
        for k in ("gloss_exponent_g", "fresnel_exponent_a", "lobe_decay_b", "diffuse_exponent_c")
        if k in v
    }
    return Material(
        name=entry.name,
        base_color_rgb=base,
        metallic=v["metallic"],
        roughness=v["roughness"],
        ior=v["ior"],
        alpha=v["alpha"],
        source=source,
        **optional,
    )


def library_materials(
    names: Iterable[str],
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> dict[str, Material]:
    """{``library:NAME``: its Material for ``band_nm``} for each requested library name (with
    or without the ``library:`` prefix); the Material is named with the prefix, as the
    scenario refers to it."""
    out = {}
    for raw in names:
        name = raw.removeprefix(LIBRARY_PREFIX)
        key = LIBRARY_PREFIX + name
        out[key] = replace(material_from_entry(name, band_nm, qe), name=key)
    return out


#: The library material that stands for each built-in part material of the procedural
#: satellites (``target.procedural.materials: library``). Built-ins without a counterpart
#: (panel substrate, black metal, lens, instrument grey, the ideal Lambertian white) keep
#: their values.
BUILTIN_LIBRARY_MATCH: dict[str, str] = {
    "mli_gold": "mli_aluminised_kapton",
    "mli_silver": "aluminium_teflon",
    "solar_cell": "gaas_solar_cell",
    "white_paint": "white_paint_az93",
    "antenna_white": "white_paint_az93",
    "black_crinkle": "black_paint_z306",
    "brushed_aluminium": "aluminium",
    "titanium_hinge": "titanium",
    "cfrp": "cfrp",
}


class BandMaterials(Mapping[str, Material]):
    """The materials of one sensor band, by name: every built-in name (with the library's
    material where ``BUILTIN_LIBRARY_MATCH`` has one, named as the built-in, so meshes keep
    their part materials; the built-in values elsewhere) and every library material as
    ``library:NAME``. Each library material is integrated over the band when first looked
    up (a few ms to 0.8 s each), so holding them all costs nothing until used."""

    def __init__(
        self,
        band_nm: tuple[float, float] = DEFAULT_BAND_NM,
        qe: str | QuantumEfficiency = DEFAULT_QE,
    ) -> None:
        self.band_nm = check_band_nm(band_nm)
        self.qe = qe
        self._names = list(FIRST_MATERIALS) + [LIBRARY_PREFIX + name for name in list_materials()]
        self._known = set(self._names)
        self._made: dict[str, Material] = {}

    def __getitem__(self, key: str) -> Material:
        if key not in self._known:
            raise KeyError(key)
        if key not in self._made:
            if key in BUILTIN_LIBRARY_MATCH:
                entry = material_from_entry(BUILTIN_LIBRARY_MATCH[key], self.band_nm, self.qe)
                self._made[key] = replace(entry, name=key)
            elif key.startswith(LIBRARY_PREFIX):
                self._made.update(library_materials([key], self.band_nm, self.qe))
            else:
                self._made[key] = FIRST_MATERIALS[key]
        return self._made[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __contains__(self, key: object) -> bool:
        return key in self._known


def builtins_from_library(
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    qe: str | QuantumEfficiency = DEFAULT_QE,
) -> BandMaterials:
    """The materials of ``band_nm`` (``BandMaterials``): the built-in names with the
    library's materials where ``BUILTIN_LIBRARY_MATCH`` has one, the built-in values
    elsewhere, and every library material as ``library:NAME``."""
    return BandMaterials(band_nm, qe)
