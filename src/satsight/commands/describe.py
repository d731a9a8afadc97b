"""Commands that describe a scenario's parts without rendering a dataset: plan, camera,
satellite, lightcurve."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from satsight.commands.shell import console, example_scenario_path, report_folder_option
from satsight.commands.tables import print_tables, prints_tables

# Rows of the printed plan shown in full; longer plans show their head and tail.
_PLAN_ROWS_SHOWN = 40


@prints_tables
@click.command()
@click.argument("config", type=click.Path(path_type=Path))
@report_folder_option("out/plan", "plan.csv and the plots")
@click.option("--no-plots", is_flag=True, help="write plan.csv only")
def plan(config: Path, out_dir: Path, no_plots: bool) -> None:
    """Print the frame plan of CONFIG without rendering, and plot it."""
    from rich.table import Table

    from satsight.config.scenario import load_scenario
    from satsight.poses.plan import frames_to_render, plan_track
    from satsight.poses.plan_plots import write_plan_plots
    from satsight.poses.plan_table import plan_table_rows, write_plan_csv

    scenario = load_scenario(config)
    mesh = scenario.target.build(scenario.sun.band_nm)
    request = scenario.plan_request()
    track = plan_track(request, mesh.center_m, mesh.bounding_radius_m)
    rendered = frames_to_render(request, track)
    shown = list(range(len(track)))
    if len(track) > _PLAN_ROWS_SHOWN:
        half = _PLAN_ROWS_SHOWN // 2
        shown = [*range(half), -1, *range(len(track) - half, len(track))]
    # Rows only for the frames printed: a long plan's table is its first and last rows.
    rows = plan_table_rows(track, with_epoch=False, frames=[i for i in shown if i >= 0])
    since = f", time after {scenario.epoch_utc}" if scenario.epoch_utc else ""
    table = Table(title=f"frame plan of '{scenario.name}'{since}")
    for column in rows[0]:
        table.add_column(column, justify="right", no_wrap=True)
    rows_in_order = iter(rows)
    for i in shown:
        if i < 0:
            table.add_row(*(["..."] * len(rows[0])))
        else:
            table.add_row(*(str(value) for value in next(rows_in_order).values()))
    print_tables([table])
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / "plan.csv"
    write_plan_csv(track, csv_path)
    written = [csv_path]
    if not no_plots:
        written += write_plan_plots(track, out_dir, f"{scenario.name}: frame plan")
    visible = int(track.visible.sum())
    console.print(
        f"{len(track)} frames planned, {visible} pass the visibility tests, "
        f"{len(rendered)} would be rendered (on_fail: "
        f"{scenario.visibility.on_fail if scenario.sampler is not None else 'n/a'}); "
        f"range {track.range_m.min() / 1e3:.3g} to {track.range_m.max() / 1e3:.3g} km"
    )
    console.print("wrote " + ", ".join(str(p) for p in written))


@prints_tables
@click.command()
@click.argument("config", type=click.Path(path_type=Path), required=False)
@report_folder_option("out/camera", "camera.json and system_mtf.png")
def camera(config: Path | None, out_dir: Path) -> None:
    """Describe the camera of CONFIG (default: the bundled example): optics, sampling,
    exposure and limiting magnitude at SNR 5; plot its system MTF."""
    from rich.table import Table

    from satsight.config.scenario import load_scenario
    from satsight.pipeline import build_sensor
    from satsight.sensor.camera_report import SNR_LIMIT, camera_report
    from satsight.sensor.mtf import band_wavelengths_m
    from satsight.sensor.mtf_plot import plot_system_mtf

    scenario = load_scenario(config or example_scenario_path())
    sensor = build_sensor(scenario)
    report = camera_report(sensor)
    table = Table(title=f"camera of '{scenario.name}' ({scenario.camera.preset})")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    rows = [
        ("focal length / aperture", f"{report['focal_length_m']:g} m / "
         f"{report['aperture_diameter_m']:g} m (f/{report['f_number']:.3g})"),
        ("IFOV", f"{report['ifov_urad']:.3g} urad/px"),
        ("field of view", "{:.3f} x {:.3f} deg".format(*report["fov_deg"])),
        ("Airy radius at lambda_eff", f"{report['airy_radius_px']:.2f} px "
         f"({report['effective_wavelength_nm']:.0f} nm)"),
        ("reference exposure", f"{report['reference_exposure']['exposure_time_s'] * 1e3:.3g} ms"),
        (f"limiting V at SNR {SNR_LIMIT:g}, reference exposure",
         f"{report['reference_exposure']['v_mag']:.2f}"),
    ]  # fmt: skip
    rows += [
        (f"limiting V at SNR {SNR_LIMIT:g}, {row['exposure_time_s'] * 1e3:g} ms",
         f"{row['v_mag']:.2f}")
        for row in report["limiting_magnitude_snr5"]
    ]  # fmt: skip
    for name, value in rows:
        table.add_row(name, value)
    print_tables([table])
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / "camera.json"
    json_path.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    mtf_path = plot_system_mtf(
        sensor.optics,
        sensor.camera.pixel_pitch_m,
        sensor.band_nm,
        out_dir / "system_mtf.png",
        n_wavelengths=len(band_wavelengths_m(sensor.band_nm)),
    )
    console.print(f"wrote {json_path}, {mtf_path}")


@click.command()
@click.argument("satellite_class")
@click.option("--seed", default=0, show_default=True, type=int)
@click.option(
    "--out",
    "out_path",
    type=click.Path(path_type=Path),
    required=True,
    help="OBJ file to write (an .mtl is written beside it)",
)
def satellite(satellite_class: str, seed: int, out_path: Path) -> None:
    """Write a procedural satellite of SATELLITE_CLASS as OBJ + MTL."""
    from satsight.scene.obj_export import write_obj
    from satsight.scene.procedural import generate_satellite

    mesh = generate_satellite(satellite_class, seed)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    obj, mtl = write_obj(mesh, out_path)
    console.print(
        f"wrote {obj} and {mtl}: {len(mesh.part_names)} parts, {len(mesh.faces)} triangles"
    )


@click.command()
@click.argument("config", type=click.Path(path_type=Path))
@report_folder_option("out/lightcurve", "lightcurve.csv and lightcurve.png")
@click.option(
    "--size-px",
    default=96,
    show_default=True,
    type=click.IntRange(min=16, max=1024),
    help="side of the small render of each frame (the target fills 80 % of it)",
)
@click.option(
    "--spp",
    default=None,
    type=click.IntRange(min=1),
    help="samples per pixel (default: the scenario's)",
)
def lightcurve(config: Path, out_dir: Path, size_px: int, spp: int | None) -> None:
    """Render CONFIG's frames small and plot the target's in-band irradiance at the observer
    and its V-equivalent magnitude over time; write CSV."""
    from satsight.commands.shell import progress_bar
    from satsight.config.scenario import load_scenario
    from satsight.tools.lightcurve import plot_lightcurve, run_lightcurve, write_csv

    scenario = load_scenario(config)
    with progress_bar() as progress:
        task = progress.add_task("light curve", total=None)
        curve = run_lightcurve(
            scenario,
            size_px=size_px,
            samples_per_pixel=spp,
            on_frame=lambda done, total: progress.update(task, completed=done, total=total),
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(curve, out_dir / "lightcurve.csv")
    png_path = plot_lightcurve(curve, out_dir / "lightcurve.png")
    magnitudes = curve.column("v_magnitude_equivalent")
    lit = magnitudes[np.isfinite(magnitudes)]
    span = f"V {lit.min():.2f} to {lit.max():.2f}" if lit.size else "no lit frame"
    console.print(f"{len(curve.rows)} frames, {span}; wrote {csv_path} and {png_path}")
