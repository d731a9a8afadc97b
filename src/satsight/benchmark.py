"""Render-stage benchmark: median seconds per frame at several image sizes (JSON).

The target (a procedural ``two_wings`` satellite) is placed so that it covers about half
of the frame. Each size renders one warm-up frame (JIT compilation, or a load from Dr.Jit's
disk cache, and the first touch of the image buffers), then ``frames`` timed frames from
different azimuths, so per-frame values change and any recompilation would show.
"""

from __future__ import annotations

import json
import math
import platform
import resource
import statistics
import sys
import time

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.poses.views import View
from satsight.render.buffers import SunLight
from satsight.render.direct import DirectRenderer
from satsight.scene.procedural import generate_satellite

DEFAULT_SIZES_PX = ((1024, 1024), (2048, 2048), (4096, 4112))
TARGET_COVERAGE = 0.5
_SUN = SunLight(np.array([0.5, -0.4, 0.75]), 671.5)


def _view(distance_m: float, k: int) -> View:
    return View(distance_m, math.radians(-70.0 + 7.0 * k), math.radians(25.0))


def _distance_for_coverage(renderer: DirectRenderer, camera: PinholeCamera) -> float:
    """Distance at which the target covers about TARGET_COVERAGE of the frame."""
    probe_side = 256
    scale = max(camera.width_px, camera.height_px) / probe_side
    probe = PinholeCamera(
        camera.focal_length_m,
        camera.pixel_pitch_m * scale,
        max(1, round(camera.width_px / scale)),
        max(1, round(camera.height_px / scale)),
    )
    radius = renderer.mesh.bounding_radius_m
    distance = 2.0 * radius / (probe.sensor_width_m / probe.focal_length_m)
    for _ in range(6):
        image = renderer.render(
            probe, _view(distance, 0).cam_from_body(renderer.mesh.center_m), _SUN
        )
        fraction = max(image.object_mask.mean(), 1e-4)
        distance *= math.sqrt(fraction / TARGET_COVERAGE)
    return distance


def run_render_benchmark(sizes_px=DEFAULT_SIZES_PX, frames: int = 5, variant: str = "auto") -> dict:
    """Time the direct-light render stage; returns a JSON-ready dict."""
    mesh = generate_satellite("two_wings", seed=1)
    t0 = time.perf_counter()
    renderer = DirectRenderer(mesh, variant)
    setup_s = time.perf_counter() - t0
    results = []
    for width, height in sizes_px:
        camera = PinholeCamera.high_resolution().with_size(width, height)
        distance = _distance_for_coverage(renderer, camera)
        times, coverage = [], []
        for k in range(frames + 1):
            pose = _view(distance, k).cam_from_body(mesh.center_m)
            _kernel_history(clear=True)
            start = time.perf_counter()
            image = renderer.render(camera, pose, _SUN)
            times.append(time.perf_counter() - start)
            coverage.append(float(image.object_mask.mean()))
            if k == 0:
                compile_s, compiled, from_disk = _kernel_history()
        median = statistics.median(times[1:])
        results.append(
            {
                "stage": "render_direct_sun",
                "width_px": width,
                "height_px": height,
                "frames_timed": frames,
                "median_s": median,
                "min_s": min(times[1:]),
                "max_s": max(times[1:]),
                "first_frame_s": times[0],
                "warmup_overhead_s": max(0.0, times[0] - median),  # JIT + first-touch memory
                "jit_compile_s": compile_s,
                "kernels_compiled": compiled,
                "kernels_from_disk_cache": from_disk,
                "primary_rays_per_s": width * height / median,
                "target_coverage_mean": statistics.fmean(coverage[1:]),
                "distance_m": distance,
            }
        )
    return {
        "benchmark": "render",
        "variant": renderer.variant,
        "machine": {"cpu_count": _cpu_count(), "platform": platform.platform()},
        "target": {"name": mesh.name, "triangles": len(mesh.faces)},
        "renderer_setup_s": setup_s,
        "results": results,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def parse_sizes_px(text: str) -> list[tuple[int, int]]:
    """Parse "1024x1024,4096x4112" into [(1024, 1024), (4096, 4112)]."""
    try:
        sizes = [tuple(int(v) for v in item.lower().split("x")) for item in text.split(",")]
        if any(len(size) != 2 or min(size) < 1 for size in sizes):
            raise ValueError
    except ValueError:
        raise SatsightError(f"--sizes must look like 1024x1024,4096x4112; got '{text}'") from None
    return sizes


def _kernel_history(clear: bool = False) -> tuple[float, int, int]:
    """(compile seconds, kernels compiled, kernels loaded from Dr.Jit's disk cache) since
    the last call; a warm disk cache makes the first frame nearly as fast as the rest."""
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    history = [k for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
    if clear:
        return 0.0, 0, 0
    compile_ms = sum(k.get("codegen_time", 0.0) + k.get("backend_time", 0.0) for k in history)
    compiled = sum(1 for k in history if not k.get("cache_hit"))
    from_disk = sum(1 for k in history if k.get("cache_disk"))
    return compile_ms / 1e3, compiled, from_disk


def _cpu_count() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5, help="timed frames per size (>= 5)")
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--sizes", default="1024x1024,2048x2048,4096x4112")
    args = parser.parse_args(argv)
    if args.frames < 5:
        parser.error("--frames must be at least 5 (the median needs several frames)")
    try:
        result = run_render_benchmark(parse_sizes_px(args.sizes), args.frames, args.variant)
    except SatsightError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    print(json.dumps(result, indent=2))
