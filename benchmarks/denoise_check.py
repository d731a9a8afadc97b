"""What filtering the Monte Carlo part of a one-path render does to fireflies and radiometry
(JSON). A measurement for choosing a route to clean images, not a feature.

Usage: python benchmarks/denoise_check.py [--example fly_around] [--size 512]
       [--settings default|example] [--seeds 32] [--reference-seeds 256]
       [--oidn-quality fast|balanced|high]

Each of three frames (first, middle, last) is rendered at one path per pixel with
``seeds`` seeds. Its *deterministic* part, the direct Sun at the pixel centre's surface
(the same render with no bounces, no environment and no sunlit-surface samples: at one
path per pixel every seed gives it alike), is kept; the rest, the Monte Carlo part, is
filtered by:

* ``spread``: pixels whose Monte Carlo luminance exceeds 4x the mean of the other target
  pixels of their 5 x 5 window give the excess (their colour kept) in equal shares to the
  target pixels of that window: the target's sum is conserved exactly.
* ``oidn``: Intel Open Image Denoise (``pyoidn``, HDR, with the parts' base colours as
  albedo and the camera-frame normals, both noise-free), where it is installed
  (``pip install pyoidn``; it is not a satsight dependency).

Per frame and filter: ``firefly_excess_percent`` (target pixels above 4x the median of
their 5 x 5 neighbourhood that are not so in the reference, the mean of ``reference-seeds``
renders; as ``firefly_check.py``), ``target_mean_ratio`` (filtered over unfiltered target
luminance, summed over the seeds), ``local_bias_percentiles`` (the filtered image's mean
over the seeds minus the unfiltered mean, paired seed by seed so that the noise cancels,
over the reference, at the 1, 10, 50, 90 and 99th percentiles of the target pixels above
1 % of the median) and ``seconds`` per frame.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from firefly_check import LUMINANCE_RGB, _mean_render, firefly_mask, scenario_at_size
from scipy import ndimage

from satsight.pipeline import FrameEngine, frame_light, frame_seed
from satsight.render.renderer import Renderer

SPREAD_FACTOR = 4.0
SPREAD_WINDOW_PX = 5


def _box_sum(values: np.ndarray) -> np.ndarray:
    size = SPREAD_WINDOW_PX
    return ndimage.uniform_filter(values, size=size, mode="constant") * size * size


def spread(radiance: np.ndarray, exact_lum: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The ``spread`` filter (module docstring) of an (H, W, 3) radiance image."""
    lum = radiance @ LUMINANCE_RGB
    mc = np.where(mask, np.maximum(lum - exact_lum, 0.0), 0.0)
    count = _box_sum(mask.astype(np.float64))
    others = (_box_sum(mc) - mc) / np.maximum(count - 1.0, 1.0)
    flagged = mask & (mc > SPREAD_FACTOR * others) & (count > 1)
    excess = np.where(flagged, mc - SPREAD_FACTOR * others, 0.0)
    removed = radiance * np.where(flagged, excess / np.maximum(lum, 1e-30), 0.0)[..., None]
    share = removed / np.maximum(count, 1.0)[..., None]
    added = np.stack([_box_sum(share[..., c]) for c in range(3)], axis=-1) * mask[..., None]
    return radiance - removed + added


def oidn_filter(quality: str):
    try:
        import pyoidn
    except ImportError:
        return None

    def run(mc: np.ndarray, albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
        return pyoidn.denoise(mc, albedo, normal, hdr=True, clean_aux=True, quality=quality)

    return run


def check(args) -> list[dict]:
    scenario, settings = scenario_at_size(args.example, args.size, args.settings == "default")
    engine = FrameEngine(scenario)
    variant = scenario.render.variant
    renderer = Renderer(engine.mesh, settings, variant)
    deterministic = Renderer(
        engine.mesh,
        settings.with_(bounces=0, environment="off", sunlit_sampling=False, light_samples=1),
        variant,
    )
    materials = [engine.mesh.part_material(i) for i in range(len(engine.mesh.part_names))]
    base_rgb = np.array([(0.0, 0.0, 0.0)] + [m.base_color_rgb for m in materials], np.float32)
    denoise = oidn_filter(args.oidn_quality)
    records = []
    for frame_index in sorted({0, engine.frame_count // 2, engine.frame_count - 1}):
        plan = int(engine.plan_indices[frame_index])
        view = (engine.camera, engine.track.cam_from_body(plan))
        light = frame_light(scenario, engine.track, plan)
        seed = frame_seed(scenario.seed, plan)
        reference = _mean_render(
            renderer, (*view, light), range(seed + 1000, seed + 1000 + args.reference_seeds), 0
        )
        mask = reference.object_mask
        ref_lum = reference.radiance_w_m2_sr @ LUMINANCE_RGB
        ref_fireflies = firefly_mask(reference.radiance_w_m2_sr, mask)
        exact = deterministic.render(*view, light, seed=seed).radiance_w_m2_sr.astype(np.float64)
        exact_lum = exact @ LUMINANCE_RGB
        albedo = base_rgb[reference.part_id]
        normal = reference.normals_cam.astype(np.float32)
        filters = {
            "none": lambda rad: rad,
            "spread": lambda rad, e=exact_lum, m=mask: spread(rad, e, m),
        }
        if denoise is not None:

            def oidn(rad, e=exact, a=albedo, n=normal):
                return e + denoise(np.clip(rad - e, 0.0, None).astype(np.float32), a, n)

            filters["oidn"] = oidn
        sums = {name: 0.0 for name in filters}
        fireflies = {name: [] for name in filters}
        seconds = {name: 0.0 for name in filters}
        for k in range(args.seeds):
            raw = renderer.render(*view, light, seed=seed + k).radiance_w_m2_sr.astype(np.float64)
            for name, run in filters.items():
                start = time.perf_counter()
                out = run(raw)
                seconds[name] += (time.perf_counter() - start) / args.seeds
                sums[name] = sums[name] + out
                excess = firefly_mask(out, mask) & ~ref_fireflies
                fireflies[name].append(excess.sum() / mask.sum())
        bright = mask & (ref_lum > 0.01 * np.median(ref_lum[mask]))
        raw_mean = sums["none"] @ LUMINANCE_RGB / args.seeds
        for name in filters:
            mean = sums[name] @ LUMINANCE_RGB / args.seeds
            local = (mean - raw_mean)[bright] / ref_lum[bright]
            records.append(
                {
                    "frame_index": int(frame_index),
                    "filter": name,
                    "firefly_excess_percent": 100 * float(np.mean(fireflies[name])),
                    "target_mean_ratio": float(mean[mask].sum() / raw_mean[mask].sum()),
                    "local_bias_percentiles": np.percentile(local, [1, 10, 50, 90, 99]).tolist(),
                    "seconds": seconds[name],
                }
            )
    return records


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--example", default="fly_around")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--settings", choices=("example", "default"), default="default")
    parser.add_argument("--seeds", type=int, default=32)
    parser.add_argument("--reference-seeds", type=int, default=256)
    parser.add_argument("--oidn-quality", default="fast")
    args = parser.parse_args(argv)
    print(json.dumps(check(args), indent=1))


if __name__ == "__main__":
    main()
