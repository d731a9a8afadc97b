"""Commands that measure the renderer: ablate (the paper's Table 4) and bench (timings)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from satsight.commands.shell import console, progress_bar
from satsight.commands.tables import print_tables, prints_tables
from satsight.errors import SatsightError


@prints_tables
@click.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    required=True,
    help="folder for ablation.csv, ablation.png and phong_fits.json (created; must be empty "
    "unless --overwrite)",
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
    """Ablate the radiative model on CONFIG's frames (paper Table 4): MSE, PSNR, angle.

    improved_phong and phong use coefficients fitted to each part's GGX material;
    the *_mapped variants the heuristic mapping from the GGX parameters."""
    from rich.table import Table

    from satsight.config.scenario import load_scenario
    from satsight.dataset.staging import check_output_folder, staged_folder
    from satsight.tools.ablation import VARIANTS, fit_rows, run_ablation, write_csv, write_figure

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

    with progress_bar() as progress:
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
        (root / "phong_fits.json").write_text(
            json.dumps(
                {
                    "kind": "model-to-model fits of the Phong models to each part's GGX "
                    "material (satsight.brdf.reference_fit), not measurements",
                    "fits": fit_rows(result.fits),
                },
                indent=2,
            ),
            encoding="utf-8",
        )
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
    print_tables([table])
    console.print(
        "improved_phong, phong: coefficients fitted to each part's GGX material; "
        "*_mapped: derived from the GGX parameters by the heuristic mapping"
    )
    console.print(
        f"wrote {out_dir / 'ablation.csv'}, {out_dir / 'ablation.png'} and "
        f"{out_dir / 'phong_fits.json'}"
    )


@click.command()
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
    "--cluster-scaling",
    "cluster_frames",
    default=None,
    type=click.IntRange(min=3),
    help="instead: N frames at 1024x1024 on a Dask LocalCluster of one worker held to one "
    "core, then of one worker per core (needs satsight[dask])",
)
@click.option(
    "--warm-kernels",
    is_flag=True,
    help="with --dataset or --cluster-scaling: keep the Dr.Jit kernel cache of earlier runs "
    "(default: each case compiles its kernels, as a first dataset of new views does)",
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
    cluster_frames: int | None,
    warm_kernels: bool,
) -> None:
    """Time the render stage (or, with --dataset, whole datasets; with --cluster-scaling,
    a local Dask cluster's speed-up); prints JSON."""
    if dataset_frames is not None and cluster_frames is not None:
        raise click.UsageError("choose --dataset or --cluster-scaling, not both")
    cache = "warm" if warm_kernels else "cold"
    if cluster_frames is not None:
        from satsight.tools.dataset_benchmark import run_cluster_scaling

        click.echo(json.dumps(run_cluster_scaling(cluster_frames, kernel_cache=cache), indent=2))
        return
    if dataset_frames is not None:
        from satsight.tools.dataset_benchmark import run_dataset_benchmark

        click.echo(json.dumps(run_dataset_benchmark(dataset_frames, kernel_cache=cache), indent=2))
        return
    from satsight.tools.render_benchmark import parse_sizes_px, run_render_benchmark

    radiative = [] if radiative_sizes == "none" else parse_sizes_px(radiative_sizes)
    result = run_render_benchmark(
        parse_sizes_px(sizes), frames, variant, radiative, scaling=not no_scaling
    )
    click.echo(json.dumps(result, indent=2))
