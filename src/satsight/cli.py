"""Command line: ``satsight demo | generate | merge | validate | stats | export | plan |
camera | ablate | bench | satellite``.

A thin shell over ``satsight.generation``, ``satsight.dataset`` and the other stages: user
errors print a message and exit with status 2, never a traceback; a run stopped by Ctrl-C
exits with 130 after saying how to resume it.
"""

from __future__ import annotations

import json
import sys
from importlib import resources
from pathlib import Path

import click
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from satsight.errors import SatsightError

console = Console(stderr=True, soft_wrap=True)


def example_scenario_path() -> Path:
    """Path of the bundled example scenario."""
    return Path(str(resources.files("satsight") / "examples" / "first_light.yaml"))


def _progress() -> Progress:
    """A progress bar on standard error: description, bar, done/total, elapsed time."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )


class Interrupted(SatsightError):
    """The user stopped a run; committed frames are kept (exit status 130)."""


def _generate(
    config_path: Path,
    out_dir: Path,
    overwrite: bool = False,
    resume: bool = False,
    shard: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    outputs: str | None = None,
    crop_px: int | None = None,
) -> None:
    import shlex

    from satsight.config.outputs import parse_outputs_option
    from satsight.config.scenario import load_scenario, parse_scenario
    from satsight.generation import Shard, StopFlag, generate_dataset, stop_on_sigint

    if overwrite and resume:
        raise SatsightError("give --overwrite or --resume, not both")
    scenario = load_scenario(config_path)
    if outputs is not None or crop_px is not None:
        data = scenario.model_dump(mode="json")
        if outputs is not None:
            data["outputs"]["files"] = list(parse_outputs_option(outputs))
        if crop_px is not None:
            data["outputs"]["crop"] = {**(data["outputs"]["crop"] or {}), "size_px": crop_px}
        scenario = parse_scenario(data, str(config_path))
    shard_spec = None if shard is None else Shard.parse(shard)
    console.print(f"[bold]satsight[/bold]: scenario '{scenario.name}'")
    stop = StopFlag()
    with _progress() as progress, stop_on_sigint(stop):
        task = progress.add_task("frames", total=None)
        summary = generate_dataset(
            scenario,
            out_dir,
            overwrite=overwrite,
            resume=resume,
            shard=shard_spec,
            workers=workers,
            scheduler=scheduler,
            on_frame_done=lambda done, total: progress.update(task, completed=done, total=total),
            stop=stop,
        )
    if summary.interrupted:
        demo = config_path == example_scenario_path()
        args = ["demo"] if demo else ["generate", str(config_path)]
        args += ["--out", str(out_dir), "--resume"]
        args += [] if shard is None else ["--shard", shard]
        args += [] if outputs is None else ["--outputs", outputs]
        args += [] if crop_px is None else ["--crop-px", str(crop_px)]
        raise Interrupted(
            f"stopped: {summary.committed_before + summary.rendered} of {summary.frame_count} "
            f"frames committed in {out_dir}; resume with: satsight " + shlex.join(args)
        )
    if summary.rendered == 0 and summary.complete:
        console.print(f"{out_dir} is already complete ({summary.frame_count} frames)")
        return
    stages = ", ".join(
        f"{name} {sorted(times)[len(times) // 2]:.3f} s"
        for name, times in summary.stage_seconds.items()
        if times
    )
    per_frame = summary.total_seconds / max(summary.rendered, 1)
    what = f"frames of shard {shard}" if shard else "frames"
    before = f", {summary.committed_before} were there" if summary.committed_before else ""
    console.print(
        f"wrote {summary.rendered} {what} to {summary.out_dir}{before} in "
        f"{summary.total_seconds:.1f} s ({per_frame:.2f} s/frame end to end, "
        f"{summary.variant}" + (f"; stage medians: {stages}" if stages else "") + ")"
    )
    if shard is None and (summary.out_dir / "contact_sheet.png").is_file():
        console.print(f"look first at {summary.out_dir / 'contact_sheet.png'}")


@click.group()
@click.version_option(package_name="satsight")
def cli() -> None:
    """satsight: physically based optical images of space objects with exact labels."""


_OUT_OPTION = click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="dataset folder (created; an existing dataset needs --resume or --overwrite)",
)


@cli.command()
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=Path("out/demo"),
    show_default=True,
    help="output folder",
)
@click.option("--overwrite", is_flag=True, help="replace the dataset in the folder")
@click.option("--resume", is_flag=True, help="finish an interrupted demo dataset")
def demo(out_dir: Path, overwrite: bool, resume: bool) -> None:
    """Render the bundled example scenario."""
    _generate(example_scenario_path(), out_dir, overwrite, resume)


@cli.command()
@click.argument("config", type=click.Path(path_type=Path))
@_OUT_OPTION
@click.option("--overwrite", is_flag=True, help="replace the dataset in the folder")
@click.option(
    "--resume", is_flag=True, help="finish the interrupted dataset in the folder (same scenario)"
)
@click.option("--shard", default=None, help="render shard K of N only (K/N); join with merge")
@click.option(
    "--workers",
    default=None,
    type=click.IntRange(min=1),
    help="render on a local Dask cluster of N worker processes (needs satsight[dask])",
)
@click.option(
    "--scheduler", default=None, help="render on the Dask scheduler at ADDRESS (tcp://host:port)"
)
@click.option(
    "--outputs",
    default=None,
    help="files per frame: all, lean (dn,masks) or a comma list of "
    "dn,preview,radiance,depth,normals,masks (overrides the scenario's outputs.files)",
)
@click.option(
    "--crop-px",
    default=None,
    type=click.IntRange(min=16),
    help="also write a crop of this size centred on the target (scenario: outputs.crop)",
)
def generate(
    config: Path,
    out_dir: Path,
    overwrite: bool,
    resume: bool,
    shard: str | None,
    workers: int | None,
    scheduler: str | None,
    outputs: str | None,
    crop_px: int | None,
) -> None:
    """Render the scenario in CONFIG (YAML) into a dataset folder, frame by frame.

    Ctrl-C stops after the frames in flight; --resume finishes the dataset later.
    """
    if workers is not None and scheduler is not None:
        raise SatsightError("give --workers or --scheduler, not both")
    _generate(config, out_dir, overwrite, resume, shard, workers, scheduler, outputs, crop_px)


@cli.command()
@click.argument("shards", nargs=-1, required=True, type=click.Path(path_type=Path))
@_OUT_OPTION
@click.option("--move", is_flag=True, help="move the shards' files instead of copying them")
def merge(shards: tuple[Path, ...], out_dir: Path, move: bool) -> None:
    """Join complete shard folders (generate --shard K/N) into one dataset in --out."""
    from satsight.dataset.merge import merge_shards

    count = merge_shards(list(shards), out_dir, move=move)
    console.print(f"merged {len(shards)} shards into {out_dir} ({count} frames)")


# Rows of the printed plan shown in full; longer plans show their head and tail.
_PLAN_ROWS_SHOWN = 40


@cli.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=Path("out/plan"),
    show_default=True,
    help="folder for plan.csv and the plots (created; files of the same name are replaced)",
)
@click.option("--no-plots", is_flag=True, help="write plan.csv only")
def plan(config: Path, out_dir: Path, no_plots: bool) -> None:
    """Print the frame plan of CONFIG without rendering, and plot it."""
    from rich.table import Table

    from satsight.config.scenario import load_scenario
    from satsight.pipeline import build_target
    from satsight.poses.plan import frames_to_render, plan_track
    from satsight.poses.plan_plots import plan_table_rows, write_plan_csv, write_plan_plots

    scenario = load_scenario(config)
    mesh = build_target(scenario.target)
    track = plan_track(scenario, mesh.center_m, mesh.bounding_radius_m)
    rendered = frames_to_render(scenario, track)
    rows = plan_table_rows(track, with_epoch=False)
    since = f", time after {scenario.epoch_utc}" if scenario.epoch_utc else ""
    table = Table(title=f"frame plan of '{scenario.name}'{since}")
    for column in rows[0]:
        table.add_column(column, justify="right", no_wrap=True)
    shown = range(len(rows))
    if len(rows) > _PLAN_ROWS_SHOWN:
        half = _PLAN_ROWS_SHOWN // 2
        shown = [*range(half), -1, *range(len(rows) - half, len(rows))]
    for i in shown:
        if i < 0:
            table.add_row(*(["..."] * len(rows[0])))
        else:
            table.add_row(*(str(value) for value in rows[i].values()))
    Console().print(table)
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


@cli.command()
@click.argument("config", type=click.Path(path_type=Path), required=False)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=Path("out/camera"),
    show_default=True,
    help="folder for camera.json and system_mtf.png (created; files of the same name are replaced)",
)
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
    Console().print(table)
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


@cli.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="folder for ablation.csv and ablation.png (created; must be empty unless --overwrite)",
)
@click.option("--overwrite", is_flag=True, help="replace the output folder if it exists")
@click.option(
    "--spp",
    default=16,
    show_default=True,
    type=click.IntRange(min=1),
    help="samples per pixel of the variants",
)
@click.option(
    "--reference-spp",
    default=256,
    show_default=True,
    type=click.IntRange(min=1),
    help="reference samples per pixel",
)
@click.option(
    "--width",
    "width_px",
    default=384,
    show_default=True,
    type=click.IntRange(min=8),
    help="image width in pixels (same field of view as the scenario's camera)",
)
@click.option(
    "--bounces",
    default=0,
    show_default=True,
    type=click.IntRange(min=0, max=16),
    help="inter-reflections in every run (they add noise common to all variants)",
)
@click.option(
    "--max-frames", default=None, type=click.IntRange(min=1), help="use the first N frames only"
)
def ablate(
    config: Path,
    out_dir: Path,
    overwrite: bool,
    spp: int,
    reference_spp: int,
    width_px: int,
    bounces: int,
    max_frames: int | None,
) -> None:
    """Ablate the radiative model on CONFIG's frames (paper Table 4): MSE, PSNR, angle."""
    from rich.table import Table

    from satsight.ablation import VARIANTS, run_ablation, write_csv, write_figure
    from satsight.config.scenario import load_scenario
    from satsight.dataset.staging import check_output_folder, staged_folder

    scenario = load_scenario(config)
    check_output_folder(out_dir, overwrite)
    if overwrite and out_dir.is_dir() and any(out_dir.iterdir()):
        if not (out_dir / "ablation.csv").is_file():
            raise SatsightError(
                f"--overwrite replaces only ablation folders, and {out_dir} holds no "
                "ablation.csv; choose an empty or new folder"
            )
    if reference_spp < spp:
        raise SatsightError(f"--reference-spp ({reference_spp}) must be >= --spp ({spp})")
    planned: list[int] = []

    def on_plan(count: int) -> None:
        planned.append(count)
        progress.update(task, total=count * (len(VARIANTS) + 1))

    with _progress() as progress:
        task = progress.add_task("ablation renders", total=None)
        result = run_ablation(
            scenario,
            samples_per_pixel=spp,
            reference_samples_per_pixel=reference_spp,
            width_px=width_px,
            max_frames=max_frames,
            bounces=bounces,
            on_plan=on_plan,
            on_render=lambda name, index: progress.update(
                task, advance=1, description=f"ablation: {name}"
            ),
        )
    frames = planned[0]
    with staged_folder(out_dir, overwrite) as root:
        write_csv(root / "ablation.csv", result.rows)
        write_figure(
            root / "ablation.png",
            result,
            f"{scenario.name}: ablation against the reference ({reference_spp} spp), "
            f"variants at {spp} spp, {bounces} bounce(s), {frames} frame(s)",
        )
    table = Table(title=f"ablation of '{scenario.name}' ({frames} frames, {width_px} px wide)")
    for column in ("variant", "MSE (W m^-2 sr^-1)^2", "PSNR (dB)", "mean angle (deg)"):
        table.add_column(column, justify="right")
    for row in result.rows:
        table.add_row(
            row["variant"],
            f"{row['mse_w2_m4_sr2']:.4g}",
            f"{row['psnr_db']:.2f}",
            f"{row['mean_angular_error_deg']:.3f}",
        )
    Console().print(table)
    console.print(f"wrote {out_dir / 'ablation.csv'} and {out_dir / 'ablation.png'}")


@cli.command()
@click.option(
    "--frames",
    default=5,
    show_default=True,
    type=click.IntRange(min=5),
    help="timed frames per size",
)
@click.option(
    "--sizes",
    default="1024x1024,2048x2048,4096x4112",
    show_default=True,
    help="comma-separated WIDTHxHEIGHT list",
)
@click.option(
    "--radiative-sizes",
    default="1024x1024,4096x4112",
    show_default=True,
    help="sizes for the radiative stages (sun + SH earthshine + bounces), or 'none'",
)
@click.option("--no-scaling", is_flag=True, help="skip the bounces / samples scaling stages")
@click.option(
    "--dataset",
    "dataset_frames",
    default=None,
    type=click.IntRange(min=3),
    help="instead: time 'generate' end to end on N frames of the RSSF example "
    "(4096x4112 and 1024x1024, all outputs and lean), in child processes",
)
@click.option(
    "--variant",
    default="auto",
    show_default=True,
    type=click.Choice(["auto", "llvm_ad_rgb", "cuda_ad_rgb"]),
)
def bench(
    frames: int,
    sizes: str,
    radiative_sizes: str,
    no_scaling: bool,
    variant: str,
    dataset_frames: int | None,
) -> None:
    """Time the render stage (or, with --dataset, whole datasets); prints JSON."""
    if dataset_frames is not None:
        from satsight.dataset_benchmark import run_dataset_benchmark

        click.echo(json.dumps(run_dataset_benchmark(dataset_frames), indent=2))
        return
    from satsight.benchmark import parse_sizes_px, run_render_benchmark

    radiative = [] if radiative_sizes == "none" else parse_sizes_px(radiative_sizes)
    result = run_render_benchmark(
        parse_sizes_px(sizes), frames, variant, radiative, scaling=not no_scaling
    )
    click.echo(json.dumps(result, indent=2))


@cli.command()
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


@cli.command()
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option(
    "--hashes/--no-hashes",
    default=True,
    show_default=True,
    help="compare every file's SHA-256 with its frame's checksums (sizes are always compared)",
)
@click.option(
    "--allow-incomplete",
    is_flag=True,
    help="check the committed frames of a dataset that has no complete.json yet",
)
def validate(dataset: Path, hashes: bool, allow_incomplete: bool) -> None:
    """Check DATASET's files, checksums and labels; exit status 1 when problems are found."""
    from satsight.dataset.validate import omitted_line, summary_table, validate_dataset

    # Transient: the bar shows while frames are checked, then gives way to the report.
    with Progress(*_progress().columns, console=console, transient=True) as progress:
        task = progress.add_task("validating", total=None)
        report = validate_dataset(
            dataset,
            hashes=hashes,
            allow_incomplete=allow_incomplete,
            on_frame_done=lambda done, total: progress.update(task, completed=done, total=total),
        )
    out = Console(soft_wrap=True, highlight=False)
    for problem in report.findings.problems:
        out.print(str(problem), markup=False)
    if (more := omitted_line(report)) is not None:
        out.print(more, markup=False)
    Console().print(summary_table(report))
    if not report.ok:
        sys.exit(1)


@cli.command()
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=None,
    help="folder for stats.json and stats.png, outside the dataset (created; files of the "
    "same name are replaced)  [default: out/stats/DATASET_NAME]",
)
def stats(dataset: Path, out_dir: Path | None) -> None:
    """Count DATASET's frames per distance interval, target class and visibility flag, and
    plot its ranges, phase angles, visible fractions, exposure times and saturation."""
    from satsight.dataset.reader import open_dataset
    from satsight.dataset.stats import dataset_stats, output_folder, stats_tables, write_stats

    opened = open_dataset(dataset)
    out = output_folder(dataset, out_dir or Path("out/stats") / dataset.resolve().name)
    numbers = dataset_stats(opened)
    for table in stats_tables(numbers):
        Console().print(table)
    json_path, png_path = write_stats(numbers, out)
    console.print(f"wrote {json_path} and {png_path}")


@cli.command("export")
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["bop", "speedplus"]),
    required=True,
    help="bop: BOP scene-wise layout; speedplus: the SPEED+ layout",
)
@click.option(
    "--out", "out_dir", type=click.Path(path_type=Path), required=True, help="export folder"
)
@click.option(
    "--split",
    "split_text",
    default="0.8,0.1,0.1",
    show_default=True,
    help="fractions of the frames in train,val,test (sum 1)",
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=click.IntRange(min=0),
    help="seed of the split's frame order",
)
@click.option("--crop", is_flag=True, help="export the crops around the target")
@click.option(
    "--domain",
    default="synthetic",
    show_default=True,
    help="SPEED+ image domain folder",
)
@click.option("--overwrite", is_flag=True, help="replace an earlier export in --out")
def export(
    dataset: Path,
    fmt: str,
    out_dir: Path,
    split_text: str,
    seed: int,
    crop: bool,
    domain: str,
    overwrite: bool,
) -> None:
    """Export DATASET to the BOP or SPEED+ format with a seeded train/val/test split."""
    from satsight.dataset.export import export_dataset
    from satsight.dataset.export.splits import SplitRule, parse_split

    rule = SplitRule(parse_split(split_text), seed)
    summary = export_dataset(dataset, out_dir, fmt, rule, crop, overwrite, domain)
    console.print(summary.line(), highlight=False)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``satsight`` command."""
    try:
        cli.main(args=argv, standalone_mode=False)
    except click.exceptions.Abort:
        console.print("aborted")
        sys.exit(130)
    except Interrupted as error:
        console.print(str(error), highlight=False)
        sys.exit(130)
    except KeyboardInterrupt:
        console.print(
            "interrupted; the frames committed so far are kept: run the same command with "
            "--resume to finish"
        )
        sys.exit(130)
    except click.ClickException as error:
        error.show()
        sys.exit(error.exit_code)
    except SatsightError as error:
        console.print(f"[red]error:[/red] {error}", highlight=False)
        sys.exit(2)
    except OSError as error:
        where = f": {error.filename}" if error.filename else ""
        console.print(f"[red]error:[/red] {error.strerror or error}{where}", highlight=False)
        sys.exit(2)
