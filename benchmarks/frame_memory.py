"""Measure the peak memory of a run against its frame size; prints JSON.

Usage: python benchmarks/frame_memory.py [--sizes 1024,2048,4096] [--frames 6]
    [--outputs "dn,preview,radiance,depth,normals,masks;dn,masks"] [--overrides JSON]
    [--in-flight 1,2]

Each case runs ``satsight generate`` on a copy of the bundled example scenario (the
procedural two-wing satellite, its render settings) with ``--frames`` frames at 0.8 km and
the camera made ``size x size`` pixels and ``--in-flight`` frames in flight (what
``satsight.frame_memory.frames_in_flight`` would choose, set here whatever the machine's
memory), in a fresh process, and reads that process's peak
resident set size (``VmHWM`` of /proc/self/status: its own, where ``ru_maxrss`` would
carry over a larger parent's across exec). A straight line
through the peaks against the pixel count gives the fixed cost (interpreter, Mitsuba,
Dr.Jit's compiled kernels, the mesh) and the bytes per pixel that
``satsight.frame_memory`` uses, for each number of frames in flight.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile

_CHILD = """
import json, sys, time
from pathlib import Path
import satsight.run.generation
from satsight.api import load_scenario
from satsight.cli import example_scenario_path
from satsight.run.generation import generate_dataset

size, outputs, out = int(sys.argv[1]), sys.argv[2].split(","), Path(sys.argv[3])
in_flight = int(sys.argv[6])
satsight.run.generation.frames_in_flight = lambda width, height: (in_flight, None)
frames = [{"distance_km": 0.8, "azimuth_deg": 20.0 + 30.0 * k, "elevation_deg": 25.0}
          for k in range(int(sys.argv[5]))]
scenario = load_scenario(example_scenario_path(), {
    "camera.width_px": size, "camera.height_px": size, "frames": frames,
    "outputs.files": outputs, **json.loads(sys.argv[4]),
})
start = time.perf_counter()
generate_dataset(scenario, out)
seconds = time.perf_counter() - start
status = Path("/proc/self/status").read_text().splitlines()
peak = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:")) * 1024
print(peak, seconds)
"""


def peak_bytes(
    size: int, outputs: str, overrides: str, frames: int, in_flight: int
) -> tuple[int, float]:
    """Peak RSS (bytes) and wall time (s) of a ``generate`` of ``frames`` frames at
    size x size with ``in_flight`` frames in flight."""
    with tempfile.TemporaryDirectory() as folder:
        result = subprocess.run(
            [
                sys.executable,
                "-c",
                _CHILD,
                str(size),
                outputs,
                os.path.join(folder, "ds"),
                overrides,
                str(frames),
                str(in_flight),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
    peak, seconds = result.stdout.split()[-2:]
    return int(peak), float(seconds)


def fit(points: list[tuple[int, int]]) -> tuple[float, float]:
    """Least-squares line peak = fixed + per_pixel * pixels: (fixed bytes, bytes/pixel)."""
    n = len(points)
    mean_x = sum(p for p, _ in points) / n
    mean_y = sum(b for _, b in points) / n
    sxx = sum((p - mean_x) ** 2 for p, _ in points)
    sxy = sum((p - mean_x) * (b - mean_y) for p, b in points)
    slope = sxy / sxx
    return mean_y - slope * mean_x, slope


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="512,1024,2048")
    parser.add_argument("--outputs", default="dn,preview,radiance,depth,normals,masks;dn,masks")
    parser.add_argument(
        "--frames",
        type=int,
        default=6,
        help="frames per run: more than a run keeps in flight (rendering one while the one "
        "before is sensed and written), so the peak is that of a long run",
    )
    parser.add_argument(
        "--in-flight",
        default="1,2",
        help="frames in flight, each a case (comma-separated)",
    )
    parser.add_argument(
        "--overrides",
        default="{}",
        help="more scenario overrides as JSON, e.g. '{\"render.supersampling\": 2}'",
    )
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if len(set(sizes)) < 2:
        parser.error("--sizes needs at least two different sizes to fit a line")
    report = {
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "frames": args.frames,
        "overrides": json.loads(args.overrides),
        "cases": [],
    }
    for outputs in args.outputs.split(";"):
        for in_flight in (int(n) for n in args.in_flight.split(",")):
            points = []
            for size in sizes:
                peak, seconds = peak_bytes(size, outputs, args.overrides, args.frames, in_flight)
                points.append((size * size, peak))
                case = {"outputs": outputs, "in_flight": in_flight, "size_px": size}
                report["cases"].append({**case, "peak_rss_bytes": peak, "seconds": seconds})
            fixed, per_pixel = fit(points)
            report.setdefault("fits", []).append(
                {
                    "outputs": outputs,
                    "in_flight": in_flight,
                    "fixed_bytes": round(fixed),
                    "bytes_per_pixel": round(per_pixel, 1),
                }
            )
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
