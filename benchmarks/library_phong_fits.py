"""Improved Phong and Phong fitted to every library material's GGX BRDF (a Table 3 analogue).

Usage: python benchmarks/library_phong_fits.py [--band 450,900] [--markdown PATH]

For each material of the spectral library (``satsight.scene.material_library``), its
renderer ``Material`` for the band (``scene.band_reflectance.material_from_entry``) is
fitted by ``satsight.brdf.reference_fit.fit_phong_to_ggx``: the GGX BRDF is sampled on a
fixed hemispherical grid and weighted by cos^2(theta_i) cos(theta_o) (the radiance error
of a randomly oriented facet). These are MODEL-TO-MODEL fits (Phong forms against the GGX
model that defines the materials), not fits to measurements.

Prints JSON (one record per material: both fits' coefficients and metrics, seconds) and a
markdown table: improved Phong kd and ks (means over R, G, B), g, a, b, c, PSNR (dB, on
the grid, against the largest GGX value), weighted spectral angle (deg) and weighted
relative RMS;
Phong g, PSNR and weighted relative RMS. ``--markdown PATH`` also writes the table there.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from satsight.brdf.reference_fit import fit_phong_to_ggx
from satsight.constants import DEFAULT_BAND_NM
from satsight.scene.band_reflectance import material_from_entry
from satsight.scene.material_library import list_materials


def fit_library(band_nm: tuple[float, float]) -> list[dict]:
    records = []
    for name in list_materials():
        material = material_from_entry(name, band_nm)
        start = time.perf_counter()
        result = fit_phong_to_ggx(material)
        seconds = time.perf_counter() - start
        record = {
            "material": name,
            "ggx": {
                "base_color_rgb": list(material.base_color_rgb),
                "metallic": material.metallic,
                "roughness": material.roughness,
                "ior": material.ior,
            },
            "geometries": result.n_geometries,
            "seconds": round(seconds, 3),
        }
        for model, fit in result.fits.items():
            record[model] = {
                **fit.summary(),
                "max_directional_albedo": fit.fit.max_albedo,
                "at_bounds": list(fit.fit.at_bounds),
            }
        records.append(record)
    return records


def _mean(values) -> float:
    return sum(values) / len(values)


def markdown_table(records: list[dict], band_nm: tuple[float, float]) -> str:
    lines = [
        f"Model-to-model fits (not measurements): improved Phong and Phong fitted to each "
        f"library material's GGX BRDF, band {band_nm[0]:g}-{band_nm[1]:g} nm; kd, ks are "
        "means over R, G, B; PSNR against the largest GGX value on the fit grid; angle: "
        "spectral angle between GGX and fit, weighted by W |f|; rel. RMS: "
        "sqrt(sum W df^2 / sum W f^2) with the fit's weights W.",
        "",
        "| material | iP kd | iP ks | iP g | iP a | iP b | iP c | iP PSNR (dB) "
        "| iP angle (deg) | iP rel. RMS | Phong g | Phong PSNR (dB) | Phong rel. RMS |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        ip, p = r["improved_phong"], r["phong"]
        lines.append(
            f"| {r['material']} | {_mean(ip['kd_rgb']):.3f} | {_mean(ip['ks_rgb']):.3f} "
            f"| {ip['g']:.4g} | {ip['a']:.2f} | {ip['b']:.2f} | {ip['c']:.2f} "
            f"| {ip['psnr_db']:.1f} | {ip['weighted_spectral_angle_deg']:.2f} "
            f"| {ip['weighted_relative_rms']:.3f} | {p['g']:.4g} | {p['psnr_db']:.1f} "
            f"| {p['weighted_relative_rms']:.3f} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--band", default=",".join(f"{v:g}" for v in DEFAULT_BAND_NM))
    parser.add_argument("--markdown", type=Path, default=None)
    args = parser.parse_args()
    lo, hi = (float(v) for v in args.band.split(","))
    records = fit_library((lo, hi))
    print(json.dumps({"band_nm": [lo, hi], "kind": "model-to-model", "fits": records}, indent=2))
    table = markdown_table(records, (lo, hi))
    print(table)
    if args.markdown is not None:
        args.markdown.write_text(table, encoding="utf-8")


if __name__ == "__main__":
    main()
