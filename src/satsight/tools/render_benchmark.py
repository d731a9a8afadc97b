"""Render-stage benchmark: median seconds per frame at several image sizes (JSON).

The target (a procedural ``two_wings`` satellite) is placed so that it covers about half
of the frame. Each size renders one warm-up frame (JIT compilation, or a load from Dr.Jit's
disk cache, and the first touch of the image buffers), then ``frames`` timed frames from
different azimuths, so per-frame values change and any recompilation would show.

Stages: ``render_direct_sun`` (sun and shadow rays only) at every size; the radiative
frames ``sun_unshadowed_sh_1_bounce`` and ``sun_sampled_sh_2_bounces`` (Sun + SH
earthshine of a target 500 km above the day side) at the radiative sizes; and, at the
first radiative size, how the time grows with bounces and samples per pixel.
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
from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.errors import SatsightError
from satsight.lighting.bodies import environment_light_field
from satsight.lighting.light_field import LightField
from satsight.poses.views import View
from satsight.render.renderer import Renderer
from satsight.render.settings import DIRECT_SUN_ONLY, RenderSettings
from satsight.scene.procedural import generate_satellite

DEFAULT_SIZES_PX = ((1024, 1024), (2048, 2048), (4096, 4112))
DEFAULT_RADIATIVE_SIZES_PX = ((1024, 1024), (4096, 4112))
TARGET_COVERAGE = 0.5
_SUN_DIRECTION = np.array([0.5, -0.4, 0.75])
_SUN_W_M2 = 671.5
RADIATIVE_STAGES = {
    "sun_unshadowed_sh_1_bounce": RenderSettings(environment="unshadowed", bounces=1),
    "sun_sampled_sh_2_bounces": RenderSettings(environment="sampled", bounces=2),
}


def _light() -> LightField:
    """Sun plus earthshine for a target 500 km above the day side (Earth along -z)."""
    sun = _SUN_DIRECTION / np.linalg.norm(_SUN_DIRECTION)
    earth = -(EARTH_MEAN_RADIUS_M + 500e3) * np.array([0.0, 0.0, 1.0])
    return environment_light_field(sun, _SUN_W_M2, earth_center_from_target_m=earth)


def _view(distance_m: float, k: int) -> View:
    return View(distance_m, math.radians(-70.0 + 7.0 * k), math.radians(25.0))


def _distance_for_coverage(renderer: Renderer, camera: PinholeCamera, light) -> float:
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
            probe, _view(distance, 0).cam_from_body(renderer.mesh.center_m), light
        )
        fraction = max(image.object_mask.mean(), 1e-4)
        distance *= math.sqrt(fraction / TARGET_COVERAGE)
    return distance


def _time_stage(renderer: Renderer, stage: str, size_px, frames: int, light) -> dict:
    """Median seconds per frame of one renderer at one size, and what came with it."""
    width, height = size_px
    camera = PinholeCamera.high_resolution().with_size(width, height)
    distance = _distance_for_coverage(renderer, camera, light)
    times, coverage = [], []
    for k in range(frames + 1):
        pose = _view(distance, k).cam_from_body(renderer.mesh.center_m)
        _kernel_history(clear=True)
        start = time.perf_counter()
        image = renderer.render(camera, pose, light, seed=k)
        times.append(time.perf_counter() - start)
        coverage.append(float(image.object_mask.mean()))
        if k == 0:
            compile_s, compiled, from_disk = _kernel_history()
    median = statistics.median(times[1:])
    s = renderer.settings
    return {
        "stage": stage,
        "width_px": width,
        "height_px": height,
        "environment": s.environment,
        "bounces": s.bounces,
        "samples_per_pixel": s.samples_per_pixel,
        "brdf": s.brdf,
        "frames_timed": frames,
        "median_s": median,
        "min_s": min(times[1:]),
        "max_s": max(times[1:]),
        "first_frame_s": times[0],
        "warmup_overhead_s": max(0.0, times[0] - median),  # JIT + first-touch memory
        "jit_compile_s": compile_s,
        "kernels_compiled": compiled,
        "kernels_from_disk_cache": from_disk,
        "primary_rays_per_s": width * height * s.passes / median,
        "target_coverage_mean": statistics.fmean(coverage[1:]),
        "distance_m": distance,
    }


def run_render_benchmark(
    sizes_px=DEFAULT_SIZES_PX,
    frames: int = 5,
    variant: str = "auto",
    radiative_sizes_px=DEFAULT_RADIATIVE_SIZES_PX,
    scaling: bool = True,
) -> dict:
    """Time the render stage; returns a JSON-ready dict (see the module docstring)."""
    mesh = generate_satellite("two_wings", seed=1)
    light = _light()
    sun_only = LightField.sun_only(light.sun_direction_body, light.sun_irradiance_w_m2)
    t0 = time.perf_counter()
    direct = Renderer(mesh, DIRECT_SUN_ONLY, variant)
    setup_s = time.perf_counter() - t0
    results = [
        _time_stage(direct, "render_direct_sun", size, frames, sun_only) for size in sizes_px
    ]
    for stage, settings in RADIATIVE_STAGES.items():
        renderer = Renderer(mesh, settings, variant)
        results += [
            _time_stage(renderer, stage, size, frames, light) for size in radiative_sizes_px
        ]
    if scaling and radiative_sizes_px:
        size = radiative_sizes_px[0]
        base = RADIATIVE_STAGES["sun_sampled_sh_2_bounces"]
        for bounces in (0, 1, 3, 4):
            renderer = Renderer(mesh, base.with_(bounces=bounces), variant)
            results.append(_time_stage(renderer, "scaling_bounces", size, frames, light))
        for spp in (2, 4, 8):
            renderer = Renderer(mesh, base.with_(samples_per_pixel=spp), variant)
            results.append(_time_stage(renderer, "scaling_samples", size, frames, light))
    return {
        "benchmark": "render",
        "variant": direct.variant,
        "machine": {"cpu_count": _cpu_count(), "platform": platform.platform()},
        "target": {"name": mesh.name, "triangles": len(mesh.faces)},
        "light": {
            "sun_irradiance_w_m2": light.sun_irradiance_w_m2,
            "earthshine": "Earth 500 km below (-z), albedo 0.30, SH order 4",
        },
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
    parser.add_argument(
        "--radiative-sizes",
        default="1024x1024,4096x4112",
        help="sizes for the radiative stages ('none' to skip them)",
    )
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling stages")
    args = parser.parse_args(argv)
    if args.frames < 5:
        parser.error("--frames must be at least 5 (the median needs several frames)")
    try:
        radiative = [] if args.radiative_sizes == "none" else parse_sizes_px(args.radiative_sizes)
        result = run_render_benchmark(
            parse_sizes_px(args.sizes), args.frames, args.variant, radiative, not args.no_scaling
        )
    except SatsightError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    print(json.dumps(result, indent=2))
