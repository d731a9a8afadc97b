"""Time ``satsight generate`` end to end: wall seconds per frame, CPU use and peak memory.

Each case renders the bundled RSSF example (``rssf_dataset.yaml``, its first N frames, all
seven distance intervals) into a fresh folder, in a child process of its own, so that its
peak resident memory and CPU time are its own. Reported per case:

* ``seconds_per_frame``: the run's wall time over its frame count, start-up (scenario,
  plan, star catalogue, first kernel compilation) and the closing (labels.json, contact
  sheet) included: what a user waits;
* ``steady_seconds_per_frame``: the time between the first and the last frame's commit
  over the frames in between: what each further frame of a long dataset costs;
* ``cpu_percent``: CPU time (user + system, all threads, and the render processes' when
  the run started them) over wall time, in % of one core;
* ``peak_rss_mb``: the child's peak resident memory, plus its render processes' (their
  largest peak times their number, an upper bound);
* ``render_processes``: the local render processes that made the frames (1: the child
  itself; ``satsight.run.processes``: several for long runs of small frames);
* ``stage_median_s``: median seconds per frame of the render, sensor and file stages (they
  overlap in the pipeline, so they do not add up to the wall time);
* ``megabytes_per_frame``: bytes written per frame.

Kernels: by default each case starts with an empty Dr.Jit kernel cache (``DRJIT_CACHE_DIR``
in a fresh folder), as a user's first dataset of new views does; with the user's own
cache (``kernel_cache="warm"``, ``--warm-kernels``) the kernels compiled by earlier runs of
the same frames are read from disk, which hides what compiling costs.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

import yaml

from satsight.errors import SatsightError

#: (name, image size WIDTHxHEIGHT, outputs) of the default cases.
DEFAULT_CASES = (
    ("4k_all", (4096, 4112), "all"),
    ("4k_lean", (4096, 4112), "lean"),
    ("1k_all", (1024, 1024), "all"),
    ("1k_lean", (1024, 1024), "lean"),
)
#: The paper's own figures (seconds per frame, end to end) for comparison.
PAPER_SECONDS_PER_FRAME = {"sspt": 1.67, "rssf": 2.86}


def _scenario(size_px: tuple[int, int], outputs: str, frames: int) -> dict:
    from satsight.config.outputs import parse_outputs_option

    path = resources.files("satsight") / "examples" / "rssf_dataset.yaml"
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data["sampler"]["frame_count"] = frames
    data["camera"] = {**data.get("camera", {}), "width_px": size_px[0], "height_px": size_px[1]}
    data["outputs"] = {"files": list(parse_outputs_option(outputs))}
    return data


def run_case(
    size_px: tuple[int, int],
    outputs: str,
    frames: int,
    out_dir: Path,
    workers: int | None = None,
    cores: int | None = None,
) -> dict:
    """One case in this process: generate the dataset and time it (see module docstring).
    workers: on a LocalCluster of that many workers (``--workers``). cores: first hold this
    process (and the workers it starts) to that many of its cores."""
    from satsight.config.scenario import parse_scenario
    from satsight.run.generation import generate_dataset

    if cores is not None:
        os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:cores])
    scenario = parse_scenario(_scenario(size_px, outputs, frames), "benchmark")
    commits: list[float] = []
    cpu0, t0 = os.times(), time.perf_counter()
    summary = generate_dataset(
        scenario,
        out_dir,
        workers=workers,
        on_frame_done=lambda d, n: commits.append(time.perf_counter()),
        render_processes="auto",  # as ``satsight generate``
    )
    wall = time.perf_counter() - t0
    cpu1 = os.times()
    cpu = sum(getattr(cpu1, f) - getattr(cpu0, f) for f in _CPU_FIELDS)
    commits = commits[1:]  # the first call reports the frames already there (none)
    written = sum(p.stat().st_size for p in out_dir.rglob("*") if p.is_file())
    return {
        "frames": summary.rendered,
        "image_size_px": list(size_px),
        "outputs": outputs,
        "seconds_per_frame": wall / summary.rendered,
        "steady_seconds_per_frame": (commits[-1] - commits[0]) / (len(commits) - 1),
        "wall_s": wall,
        "cpu_percent": 100.0 * cpu / wall,
        "peak_rss_mb": _peak_rss_mb(summary.render_processes),
        "stage_median_s": {
            name: statistics.median(times) for name, times in summary.stage_seconds.items()
        },
        "megabytes_per_frame": written / summary.rendered / 1e6,
        "variant": summary.variant,
        "render_processes": summary.render_processes,
        "workers": workers,
        "cores": len(os.sched_getaffinity(0)),
    }


#: ``os.times`` fields of this process and of its ended children (render processes).
_CPU_FIELDS = ("user", "system", "children_user", "children_system")


def _peak_rss_mb(render_processes: int) -> float:
    """Peak resident memory (MB) of this process, plus that of its largest ended child
    times ``render_processes`` when it had render processes (an upper bound: their peaks
    need not coincide)."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    if render_processes <= 1:
        return own
    return own + render_processes * resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0


def _child(arguments: list[str], env: dict | None = None) -> dict:
    command = [sys.executable, "-m", "satsight.tools.dataset_benchmark", *arguments]
    done = subprocess.run(command, capture_output=True, text=True, check=False, env=env)
    if done.returncode != 0:
        raise SatsightError(f"benchmark case failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout)


def run_cluster_scaling(
    frames: int = 40, size_px: tuple[int, int] = (1024, 1024), kernel_cache: str = "cold"
) -> dict:
    """A Dask LocalCluster of one worker against one worker per core, each worker rendering
    on one thread (``SATSIGHT_RENDER_THREADS=1``); the one-worker run (its client, the
    scheduler and the worker) is held to one core, the other has them all. The speed-up
    is what more machines give. Steady rates (from the first to the last commit) leave the
    cluster's start-up out. CPU use and peak memory are the client's alone (the workers
    are other processes), so they are left out."""
    if frames < 3:
        raise SatsightError("the cluster benchmark needs at least 3 frames per case")
    cores = len(os.sched_getaffinity(0))
    size = f"{size_px[0]}x{size_px[1]}"
    results = {}
    with tempfile.TemporaryDirectory(prefix="satsight-bench-") as tmp:
        for workers in sorted({1, cores}):
            out = str(Path(tmp) / f"w{workers}")
            env = {
                **_kernel_cache_env(kernel_cache, Path(tmp) / f"w{workers}-kernels"),
                "SATSIGHT_LOCAL_WORKERS": "always",
                "SATSIGHT_RENDER_THREADS": "1",
            }
            case = _child(
                ["--case", size, "lean", str(frames), out, "--case-workers", str(workers),
                 "--case-cores", str(workers)],
                env,
            )  # fmt: skip
            for client_only in ("cpu_percent", "peak_rss_mb"):
                case.pop(client_only)
            results[f"{workers}_workers"] = case
    one, many = results["1_workers"], results[f"{cores}_workers"]
    return {
        "benchmark": "cluster_scaling",
        "scenario": "examples/rssf_dataset.yaml (first N frames), lean outputs",
        "kernel_cache": kernel_cache,
        "machine": {"cpu_count": cores, "platform": platform.platform()},
        "cases": results,
        "speedup_steady": one["steady_seconds_per_frame"] / many["steady_seconds_per_frame"],
        "speedup_end_to_end": one["seconds_per_frame"] / many["seconds_per_frame"],
    }


def _kernel_cache_env(kernel_cache: str, folder: Path) -> dict[str, str]:
    """The environment of a case's child: ``"cold"``, an empty Dr.Jit kernel cache in
    ``folder``; ``"warm"``, the user's own."""
    if kernel_cache not in ("cold", "warm"):
        raise SatsightError(f"kernel_cache must be 'cold' or 'warm', got {kernel_cache!r}")
    if kernel_cache == "warm":
        return dict(os.environ)
    folder.mkdir(parents=True, exist_ok=False)
    return {**os.environ, "DRJIT_CACHE_DIR": str(folder)}


def run_dataset_benchmark(
    frames: int = 21,
    cases: tuple = DEFAULT_CASES,
    work_dir: Path | None = None,
    kernel_cache: str = "cold",
) -> dict:
    """Every case in a child process of its own; JSON-ready results. kernel_cache: "cold"
    (each case compiles its kernels, module docstring) or "warm"."""
    if frames < 3:
        raise SatsightError("the dataset benchmark needs at least 3 frames per case")
    results = {}
    with tempfile.TemporaryDirectory(prefix="satsight-bench-", dir=work_dir) as tmp:
        for name, size_px, outputs in cases:
            out = Path(tmp) / name
            env = _kernel_cache_env(kernel_cache, Path(tmp) / f"{name}-kernels")
            command = [
                sys.executable, "-m", "satsight.tools.dataset_benchmark", "--case",
                f"{size_px[0]}x{size_px[1]}", outputs, str(frames), str(out),
            ]  # fmt: skip
            done = subprocess.run(command, capture_output=True, text=True, check=False, env=env)
            if done.returncode != 0:
                raise SatsightError(f"benchmark case {name} failed:\n{done.stderr[-2000:]}")
            results[name] = json.loads(done.stdout)
    return {
        "benchmark": "dataset",
        "scenario": "examples/rssf_dataset.yaml (first N frames of the RSSF plan)",
        "kernel_cache": kernel_cache,
        "machine": {
            "cpu_count": len(os.sched_getaffinity(0)),
            "platform": platform.platform(),
            "python": platform.python_version(),
        },
        "paper_seconds_per_frame": PAPER_SECONDS_PER_FRAME,
        "cases": results,
    }


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--frames", type=int, help="frames per case (>= 3; default 21, 40 with --cluster-scaling)"
    )
    parser.add_argument(
        "--cases",
        default=",".join(name for name, _, _ in DEFAULT_CASES),
        help="comma list of cases to run",
    )
    parser.add_argument(
        "--cluster-scaling",
        action="store_true",
        help="instead: a LocalCluster of 1 worker on 1 core against 1 worker per core",
    )
    parser.add_argument(
        "--warm-kernels",
        action="store_true",
        help="keep the user's Dr.Jit kernel cache (default: each case starts with an empty "
        "one and compiles its kernels, as a first dataset of new views does)",
    )
    parser.add_argument(
        "--case", nargs=4, metavar=("SIZE", "OUTPUTS", "FRAMES", "OUT"), help=argparse.SUPPRESS
    )
    parser.add_argument("--case-workers", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--case-cores", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    try:
        if args.case:
            size, outputs, frames, out = args.case
            width, height = (int(v) for v in size.split("x"))
            result = run_case(
                (width, height), outputs, int(frames), Path(out), args.case_workers,
                args.case_cores,
            )  # fmt: skip
        elif args.cluster_scaling:
            result = run_cluster_scaling(
                args.frames or 40, kernel_cache="warm" if args.warm_kernels else "cold"
            )
        else:
            chosen = args.cases.split(",")
            unknown = set(chosen) - {name for name, _, _ in DEFAULT_CASES}
            if unknown:
                parser.error(f"unknown case(s) {', '.join(sorted(unknown))}")
            cases = tuple(case for case in DEFAULT_CASES if case[0] in chosen)
            result = run_dataset_benchmark(
                args.frames or 21, cases, kernel_cache="warm" if args.warm_kernels else "cold"
            )
    except SatsightError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
