"""Commands about surface materials: materials (the spectral library) and fit-brdf
(reflection models fitted to measured BRDFs)."""

from __future__ import annotations

import json
from pathlib import Path

import click
from rich.table import Table

from satsight.commands.shell import console, report_folder_option
from satsight.commands.tables import print_tables, prints_tables
from satsight.errors import SatsightError


def _band_nm(text: str) -> tuple[float, float]:
    """'LO,HI' in nm -> (lo, hi); a clear error otherwise."""
    try:
        lo, hi = (float(part) for part in text.split(","))
    except ValueError:
        raise SatsightError(
            f"--band must be two wavelengths in nm, 'LO,HI', got {text!r}"
        ) from None
    return lo, hi


@prints_tables
@click.command()
@click.option(
    "--band",
    "band_text",
    default="450,900",
    show_default=True,
    help="sensor band LO,HI in nm; its thirds are the blue, green and red channels",
)
@click.option(
    "--qe",
    default="ccd231_84",
    show_default=True,
    type=click.Choice(["ccd231_84", "flat"]),
    help="detector quantum efficiency curve that weights the band integration",
)
@report_folder_option("out/materials", "materials.json and material_spectra.png")
def materials(band_text: str, qe: str, out_dir: Path) -> None:
    """List the spectral material library with each material's in-band RGB reflectance,
    and plot the spectra (400-1800 nm)."""
    from satsight.lighting.solar_spectrum import check_band_nm
    from satsight.scene.material_plot import materials_report, plot_library_spectra

    band = check_band_nm(_band_nm(band_text))
    rows = materials_report(band, qe)
    table = Table(
        title=f"material library: in-band reflectance over {band[0]:g}-{band[1]:g} nm "
        f"(thirds as b, g, r; photon- and {qe} QE-weighted); M metallic, R roughness"
    )
    for column in ("material", "category", "r", "g", "b", "M", "R", "IOR"):
        left = column in ("material", "category")
        table.add_column(column, justify="left" if left else "right", no_wrap=left)
    table.add_column("spectrum")
    for row in rows:
        r, g, b = row["rgb"]
        table.add_row(
            row["name"],
            row["category"],
            f"{r:.3f}",
            f"{g:.3f}",
            f"{b:.3f}",
            f"{row['metallic']:.2f}",
            f"{row['roughness']:.2f}",
            f"{row['ior']:.3g}",
            row["spectrum"],
        )
    print_tables([table])
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / "materials.json"
    document = {"band_nm": list(band), "quantum_efficiency": qe, "materials": rows}
    json_path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    png_path = plot_library_spectra(out_dir / "material_spectra.png", band)
    console.print(f"wrote {json_path} (with each spectrum's source) and {png_path}")


@click.command("fit-brdf")
@click.argument("measurements", type=click.Path(path_type=Path))
@click.option(
    "--model",
    required=True,
    type=click.Choice(["improved_phong", "phong", "ggx"]),
    help="reflection model to fit (paper Eq. 17, Eq. 16, or the GGX material model)",
)
@report_folder_option(
    "out/brdf_fit", "the fitted parameters (YAML) and the plane-of-incidence plot"
)
def fit_brdf(measurements: Path, model: str, out_dir: Path) -> None:
    """Fit a reflection model to the measured BRDF samples in MEASUREMENTS (CSV: theta_i_deg,
    phi_i_deg, theta_o_deg, phi_o_deg, wavelength_nm or band, brdf_per_sr); print the
    parameters with their uncertainties, MSE, PSNR and angular error."""
    from satsight.brdf.fit_files import fit_brdf_command

    with console.status(f"fitting {model} to {measurements}"):
        report = fit_brdf_command(measurements, model, out_dir)
    click.echo(report.table())
