"""The CUDA variant against the LLVM one, on a machine that may have only one of them.

Step 1, on a machine with libLLVM (``llvm_ad_rgb``): render the reference scenes and save
them::

    python benchmarks/cuda_check.py save reference.npz

Step 2, on a machine with an NVIDIA GPU (``cuda_ad_rgb``): render the same scenes, compare
pixel by pixel and print JSON (fractions of pixels that agree, per output and scene, and
the median seconds per 4096 x 4112 frame, which ``save`` prints for LLVM)::

    python benchmarks/cuda_check.py compare reference.npz

The scenes are a procedural satellite (256 x 256 px, Sun + earthshine) under four render
settings: the Sun alone, the renderer's default (sampled earthshine and bodies, two
bounces), unshadowed earthshine with one bounce, and 2 x 2 supersampling. The two
backends run the same random streams, so a pixel agrees unless float rounding changes a
branch: part id and depth to 1e-5, radiance to 1e-4 relative
(``tests/render/test_backend.py`` uses the same tolerances where both variants are
present).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.lighting.bodies import environment_light_field
from satsight.poses.views import View
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.procedural import generate_satellite

SETTINGS = {
    "sun_only": RenderSettings(environment="off", bounces=0),
    "default": RenderSettings(),
    "unshadowed_1_bounce": RenderSettings(environment="unshadowed", bounces=1),
    "supersampling_2": RenderSettings(supersampling=2),
}
SIDE_PX = 256
FULL_FRAME_PX = (4096, 4112)
RADIANCE_RTOL = 1e-4
DEPTH_RTOL = 1e-5


def _scene(size_px: tuple[int, int] = (SIDE_PX, SIDE_PX)):
    """The satellite across 80 % of the frame's width, Sun and earthshine."""
    mesh = generate_satellite("two_wings_dish", seed=5)
    pitch = 15e-6
    distance_m = 1500.0
    focal = 0.8 * size_px[0] * pitch * distance_m / (2.0 * mesh.bounding_radius_m)
    camera = PinholeCamera(focal, pitch, *size_px)
    pose = View(distance_m, math.radians(35.0), math.radians(25.0)).cam_from_body(mesh.center_m)
    sun = np.array([0.5, -0.4, 0.75])
    earth = -(EARTH_MEAN_RADIUS_M + 500e3) * np.array([0.0, 0.0, 1.0])
    light = environment_light_field(
        sun / np.linalg.norm(sun), 671.5, earth_center_from_target_m=earth
    )
    return mesh, camera, pose, light


def render_all(variant: str) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """{setting/output: array} and {setting: seconds of its second render} on ``variant``."""
    mesh, camera, pose, light = _scene()
    arrays: dict[str, np.ndarray] = {}
    seconds: dict[str, float] = {}
    for name, settings in SETTINGS.items():
        renderer = Renderer(mesh, settings, variant)
        renderer.render(camera, pose, light, seed=11)  # compiles the kernels
        start = time.perf_counter()
        image = renderer.render(camera, pose, light, seed=11)
        seconds[name] = time.perf_counter() - start
        arrays[f"{name}/radiance_w_m2_sr"] = image.radiance_w_m2_sr
        arrays[f"{name}/depth_m"] = image.depth_m
        arrays[f"{name}/part_id"] = image.part_id
    return arrays, seconds


def time_full_frames(variant: str, frames: int = 5) -> dict[str, float]:
    """Median seconds per 4096 x 4112 frame (after one that compiles the kernels), for the
    Sun alone and the default settings."""
    mesh, camera, pose, light = _scene(FULL_FRAME_PX)
    medians = {}
    for name in ("sun_only", "default"):
        renderer = Renderer(mesh, SETTINGS[name], variant)
        renderer.render(camera, pose, light, seed=0)
        times = []
        for k in range(frames):
            start = time.perf_counter()
            renderer.render(camera, pose, light, seed=k + 1)
            times.append(time.perf_counter() - start)
        medians[name] = float(np.median(times))
    return medians


def agreement(test: dict[str, np.ndarray], reference: dict[str, np.ndarray]) -> dict:
    """Per setting: fractions of pixels where part id, depth and radiance agree."""
    out = {}
    for name in SETTINGS:
        part_t, part_r = test[f"{name}/part_id"], reference[f"{name}/part_id"]
        depth_t, depth_r = test[f"{name}/depth_m"], reference[f"{name}/depth_m"]
        rad_t, rad_r = test[f"{name}/radiance_w_m2_sr"], reference[f"{name}/radiance_w_m2_sr"]
        both = (part_t > 0) & (part_r > 0)
        depth_ok = np.where(
            both,
            np.abs(depth_t - depth_r) <= DEPTH_RTOL * np.maximum(depth_r, 1.0),
            depth_t == depth_r,
        )
        floor = 1e-6 * float(rad_r.max())
        close = np.abs(rad_t - rad_r) <= RADIANCE_RTOL * np.maximum(np.abs(rad_r), floor)
        sum_t, sum_r = float(rad_t.sum()), float(rad_r.sum())
        out[name] = {
            "target_pixels": int(both.sum()),
            "part_id_agree_fraction": float(np.mean(part_t == part_r)),
            "depth_agree_fraction": float(np.mean(depth_ok)),
            "radiance_agree_fraction": float(np.mean(close.all(axis=-1))),
            "radiance_sum_relative_difference": (sum_t - sum_r) / sum_r if sum_r else 0.0,
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=["save", "compare"])
    parser.add_argument("reference", help="the .npz of LLVM renders (written by 'save')")
    args = parser.parse_args(argv)
    if args.action == "save":
        arrays, seconds = render_all("llvm_ad_rgb")
        np.savez_compressed(args.reference, **arrays)
        report = {
            "variant": "llvm_ad_rgb",
            "seconds": seconds,
            "full_frame_median_s": time_full_frames("llvm_ad_rgb"),
        }
        print(json.dumps(report, indent=2))
        return 0
    with np.load(args.reference) as data:
        reference = {key: data[key] for key in data.files}
    arrays, seconds = render_all("cuda_ad_rgb")
    report = {
        "variant": "cuda_ad_rgb",
        "size_px": [SIDE_PX, SIDE_PX],
        "seconds": seconds,
        "agreement": agreement(arrays, reference),
        "full_frame_median_s": time_full_frames("cuda_ad_rgb"),
    }
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
