"""Figures and tables of the spectral material library.

``plot_library_spectra(path)`` draws the library's reflectance spectra from 400 to 1800 nm
in four panels by category, in the manner of the paper's Fig. 9: (a) MLI, films and solar
cells, (b) paints, (c) metals and OSR, (d) CFRP, films and others, with the sensor band
shaded. ``materials_report(band_nm)`` returns one row per material (name, category,
in-band RGB, metallic, roughness, IOR, a summary of the sources) for a printed table.
"""

from __future__ import annotations

from pathlib import Path

from satsight.camera.quantum_efficiency import DEFAULT_QE, QuantumEfficiency
from satsight.constants import DEFAULT_BAND_NM
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.scene.band_reflectance import material_rgb_reflectance
from satsight.scene.material_library import CATEGORIES, entry_spectrum, load_library

PANEL_TITLES = {
    "films_and_cells": "(a) MLI, films and solar cells",
    "paints": "(b) paints",
    "metals_and_osr": "(c) metals and OSR",
    "others": "(d) CFRP, films and others",
}


def plot_library_spectra(path: str | Path, band_nm: tuple[float, float] = DEFAULT_BAND_NM) -> Path:
    """Write a 2 x 2 figure of every library spectrum (reflectance vs wavelength, nm) to
    ``path`` (PNG or any format matplotlib knows), the band ``band_nm`` shaded. Returns
    the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lo, hi = check_band_nm(band_nm)
    library = load_library()
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5), sharex=True, sharey=True)
    for ax, category in zip(axes.ravel(), CATEGORIES, strict=True):
        ax.axvspan(lo, hi, color="0.9", zorder=0, label=f"sensor band {lo:g}-{hi:g} nm")
        for entry in library.values():
            if entry.category != category:
                continue
            wl, refl = entry_spectrum(entry)
            style = "-" if entry.spectrum_kind == "computed" else "--"
            ax.plot(wl, refl, style, lw=1.4, label=entry.name)
        ax.set_title(PANEL_TITLES[category])
        ax.set_xlim(400, 1800)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    for ax in axes[1]:
        ax.set_xlabel("wavelength (nm)")
    for ax in axes[:, 0]:
        ax.set_ylabel("reflectance (normal incidence)")
    fig.suptitle(
        "satsight material library: solid = computed from optical constants, dashed = tabulated"
    )
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _summary(text: str, limit: int = 70) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def materials_report(
    band_nm: tuple[float, float] = DEFAULT_BAND_NM, qe: str | QuantumEfficiency = DEFAULT_QE
) -> list[dict]:
    """One row per library material, for a printed table.

    Keys: name, category, rgb (r, g, b in-band reflectance over the thirds of ``band_nm``,
    weighted by detected photons with QE ``qe``), metallic, roughness, ior, spectrum
    ('computed' or 'table'), source (a short summary of the spectrum's source).
    """
    rows = []
    for entry in load_library().values():
        r, g, b = material_rgb_reflectance(entry, band_nm, qe)
        rows.append(
            {
                "name": entry.name,
                "category": entry.category,
                "rgb": (round(r, 3), round(g, 3), round(b, 3)),
                "metallic": entry.brdf["metallic"].value,
                "roughness": entry.brdf["roughness"].value,
                "ior": entry.brdf["ior"].value,
                "spectrum": entry.spectrum_kind,
                "source": _summary(entry.spectrum_source),
            }
        )
    return rows


def format_report(rows: list[dict]) -> str:
    """The rows of :func:`materials_report` as a fixed-width text table."""
    header = (
        f"{'name':26s} {'category':16s} {'r':>6s} {'g':>6s} {'b':>6s} "
        f"{'M':>4s} {'R':>5s} {'IOR':>5s}  source"
    )
    lines = [header, "-" * len(header)]
    for row in rows:
        r, g, b = row["rgb"]
        lines.append(
            f"{row['name']:26s} {row['category']:16s} {r:6.3f} {g:6.3f} {b:6.3f} "
            f"{row['metallic']:4.2f} {row['roughness']:5.2f} {row['ior']:5.2f}  {row['source']}"
        )
    return "\n".join(lines)
