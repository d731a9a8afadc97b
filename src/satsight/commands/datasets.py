"""Commands that write or read datasets: demo, generate, merge, validate, stats, export."""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import click
from rich.progress import Progress

from satsight.commands.shell import Interrupted, console, example_scenario_path, progress_bar
from satsight.commands.tables import print_tables, prints_tables, stdout_console
from satsight.errors import SatsightError


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
    from satsight.dataset.staging import check_dataset_folder

    if overwrite and resume:
        raise SatsightError("give --overwrite or --resume, not both")
    check_dataset_folder(out_dir, overwrite, resume)  # at once, before the scenario loads

    import shlex

    from satsight.config.outputs import parse_outputs_option
    from satsight.config.scenario import load_scenario, parse_scenario
    from satsight.run.generation import generate_dataset
    from satsight.run.interrupt import StopFlag, stop_on_sigint
    from satsight.run.shard import Shard

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
    with progress_bar() as progress, stop_on_sigint(stop):
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
            render_processes="auto",
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
        f"{summary.variant}"
        + (f" in {n} render processes" if (n := summary.render_processes) > 1 else "")
        + (f"; stage medians: {stages}" if stages else "")
        + ")"
    )
    if shard is None and (summary.out_dir / "contact_sheet.png").is_file():
        console.print(f"look first at {summary.out_dir / 'contact_sheet.png'}")


_OUT_OPTION = click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="dataset folder (created; an existing dataset needs --resume or --overwrite)",
)


@click.command()
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


@click.command()
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
@click.option(
    "--memory-gb",
    default=None,
    type=click.FloatRange(min=0.0, min_open=True),
    help="memory the run may use, GB: frames are made one at a time (slower) where two in "
    "flight would need more; default: the machine's available memory "
    "(SATSIGHT_MEMORY_LIMIT_GB)",
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
    memory_gb: float | None,
) -> None:
    """Render the scenario in CONFIG (YAML) into a dataset folder, frame by frame.

    Ctrl-C stops after the frames in flight; --resume finishes the dataset later.
    """
    if workers is not None and scheduler is not None:
        raise SatsightError("give --workers or --scheduler, not both")
    if scheduler is not None:
        from satsight.run.scheduler_address import scheduler_address

        scheduler = scheduler_address(scheduler)  # at once, before the scenario loads
    if memory_gb is not None and not math.isfinite(memory_gb):
        raise click.BadParameter(
            f"{memory_gb} is not a finite number of GB", param_hint="--memory-gb"
        )
    with _memory_limit(memory_gb):
        _generate(config, out_dir, overwrite, resume, shard, workers, scheduler, outputs, crop_px)


@contextmanager
def _memory_limit(memory_gb: float | None) -> Iterator[None]:
    """Within the block, ``SATSIGHT_MEMORY_LIMIT_GB`` is ``memory_gb`` (unchanged if None):
    the frame-size check, the frames in flight and local Dask workers (which inherit the
    environment) all count on it."""
    from satsight.frame_memory import MEMORY_LIMIT_VARIABLE

    if memory_gb is None:
        yield
        return
    previous = os.environ.get(MEMORY_LIMIT_VARIABLE)
    os.environ[MEMORY_LIMIT_VARIABLE] = repr(float(memory_gb))
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(MEMORY_LIMIT_VARIABLE, None)
        else:
            os.environ[MEMORY_LIMIT_VARIABLE] = previous


@click.command()
@click.argument("shards", nargs=-1, required=True, type=click.Path(path_type=Path))
@_OUT_OPTION
@click.option("--move", is_flag=True, help="move the shards' files instead of copying them")
def merge(shards: tuple[Path, ...], out_dir: Path, move: bool) -> None:
    """Join complete shard folders (generate --shard K/N) into one dataset in --out."""
    from satsight.dataset.merge import merge_shards

    count = merge_shards(list(shards), out_dir, move=move)
    console.print(f"merged {len(shards)} shards into {out_dir} ({count} frames)")


@prints_tables
@click.command()
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
    from satsight.dataset.validate import validate_dataset
    from satsight.dataset.validation_report import omitted_line, summary_table

    # Transient: the bar shows while frames are checked, then gives way to the report.
    with Progress(*progress_bar().columns, console=console, transient=True) as progress:
        task = progress.add_task("validating", total=None)
        report = validate_dataset(
            dataset,
            hashes=hashes,
            allow_incomplete=allow_incomplete,
            on_frame_done=lambda done, total: progress.update(task, completed=done, total=total),
        )
    out = stdout_console()
    for problem in report.findings.problems:
        out.print(str(problem), markup=False)
    if (more := omitted_line(report)) is not None:
        out.print(more, markup=False)
    print_tables([summary_table(report)])
    if not report.ok:
        sys.exit(1)


@prints_tables
@click.command()
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
    print_tables(stats_tables(numbers))
    json_path, png_path = write_stats(numbers, out)
    console.print(f"wrote {json_path} and {png_path}")


@click.command("export")
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["bop", "speedplus", "coco"]),
    required=True,
    help="bop: BOP scene-wise layout; speedplus: the SPEED+ layout; coco: COCO instances "
    "(boxes, RLE masks, keypoints)",
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
@click.option(
    "--image",
    "image_mode",
    type=click.Choice(["dn16", "raw16", "linear8", "preview"]),
    default="dn16",
    show_default=True,
    help="dn16: 16-bit DN above the bias; raw16: DN as read out; linear8: 8-bit, linear "
    "in DN with one gain (--white-dn); preview: the 8-bit display stretch (not linear)",
)
@click.option(
    "--white-dn",
    type=float,
    default=None,
    help="linear8: DN above the bias that reads 255 [default: the detector's saturation]",
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
    image_mode: str,
    white_dn: float | None,
    overwrite: bool,
) -> None:
    """Export DATASET to the BOP, SPEED+ or COCO format with a seeded train/val/test split.

    The images are the detector's DN, linearly scaled (--image); satsight_export.json
    in the export says how to turn them back into DN."""
    from satsight.dataset.export import export_dataset
    from satsight.dataset.export.splits import SplitRule, parse_split

    rule = SplitRule(parse_split(split_text), seed)
    summary = export_dataset(
        dataset, out_dir, fmt, rule, crop, overwrite, domain, image_mode, white_dn
    )
    console.print(summary.line(), highlight=False)
