"""Monte Carlo noise and fireflies of the target at an example's render settings (JSON).

Usage: python benchmarks/firefly_check.py [--examples fly_around,approach] [--frames 3]
       [--size 512] [--reference-spp 1024] [--reference-supersampling 1]
       [--settings example|default] [--samples-per-pixel N] [--sunlit-sampling on|off]
       [--reference paths|seeds]

Each example is rendered at ``size`` px wide (field of view kept: the pixel pitch grows by
4096 / size) at ``frames`` frames spread evenly over its frame list, with its own render
settings (``--settings example``) or the package defaults (``--settings default``), twice
(two seeds), and once at ``reference-spp`` paths per pixel (a third seed) as the converged
reference. With ``--reference-supersampling s`` the reference's paths are spread over s x s
strata (reference-spp / s^2 paths each): its texture lookups then use the mip level of an
s times smaller footprint, so it tends to the render of the full-size textures rather than
that of the level the settings look up (mip-mapped normal and metallic-roughness maps are
not linear in the radiance). Per frame:

* ``firefly_fraction``: target pixels (object mask) whose luminance exceeds 4x the median
  of the target pixels in their 5 x 5 neighbourhood; ``firefly_fraction_reference``: the
  same on the reference, where it counts real structure (lit edges and glints against
  shadow); ``firefly_excess_fraction``: pixels flagged at the settings but not in the
  reference, i.e. the Monte Carlo outliers.
* ``mean_radiance_ratio``: the target's mean luminance at the settings over the reference's,
  over the object mask grown by 2 px (partly covered edge pixels included, so that
  pixel-centre and pixel-area sampling of the edges compare); its Monte Carlo standard
  error ``mean_radiance_ratio_se`` from the two seeds.
* ``mc_over_shot_rms``: per target pixel, the Monte Carlo noise of the electrons the
  detector collects (the two seeds' difference / sqrt 2, after the optics' blur, at the
  frame's exposure from the sensor chain) over the photon shot noise sqrt(electrons) of the
  reference, as the root mean square of the ratio over the target; ``..._p90`` its 90th
  percentile. Below 1 the render's noise is under the noise the detector adds anyway.
* ``render_s``: seconds per frame at the settings (median of the two seeds' renders).

``--samples-per-pixel`` and ``--sunlit-sampling`` change those two settings (the reference
keeps its own path count). ``--reference seeds`` makes the reference the mean of
reference-spp / paths renders at the settings themselves with other seeds: at one path per
pixel they all sample the pixel centres, so the comparison leaves out the aliasing between
centre and area sampling and counts the Monte Carlo outliers alone.

Runs the package found on ``sys.path``: point PYTHONPATH at another checkout's ``src`` to
measure that code.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import binary_dilation

from satsight.api import load_scenario
from satsight.pipeline import FrameEngine, frame_light, frame_seed
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings

EXAMPLES = Path(__file__).resolve().parents[1] / "src" / "satsight" / "examples"
# Rec. 709 luminance weights of the linear RGB channels (ITU-R BT.709-6, item 3.2).
LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
FIREFLY_FACTOR = 4.0
WINDOW_PX = 5
PRESET_WIDTH_PX, PRESET_HEIGHT_PX, PRESET_PITCH_UM = 4096, 4112, 15.0


def firefly_mask(radiance: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: target pixels brighter than FIREFLY_FACTOR x the median luminance of the
    target pixels in their WINDOW_PX x WINDOW_PX neighbourhood (themselves included)."""
    lum = np.where(mask, radiance @ LUMINANCE_RGB, np.nan)
    h = WINDOW_PX // 2
    window = sliding_window_view(np.pad(lum, h, constant_values=np.nan), (WINDOW_PX,) * 2)
    ys, xs = np.nonzero(mask)
    median = np.nanmedian(window[ys, xs].reshape(len(ys), -1), axis=1)
    out = np.zeros(mask.shape, dtype=bool)
    out[ys, xs] = lum[ys, xs] > FIREFLY_FACTOR * median
    return out


def scenario_at_size(name: str, size_px: int, default_settings: bool, changes: dict | None = None):
    """The example scenario at size_px wide (field of view kept) and its render settings
    (the example's or the defaults), with ``changes`` applied."""
    overrides = {
        "camera.width_px": size_px,
        "camera.height_px": round(size_px * PRESET_HEIGHT_PX / PRESET_WIDTH_PX),
        "camera.pixel_pitch_um": PRESET_PITCH_UM * PRESET_WIDTH_PX / size_px,
    }
    scenario = load_scenario(EXAMPLES / f"{name}.yaml", overrides)
    settings = RenderSettings() if default_settings else scenario.render.settings()
    return scenario, settings.with_(**(changes or {}))


def _mean_render(renderer: Renderer, view: tuple, seeds, margin_px: int):
    """The frame rendered with each seed, its radiance (and margin ring) averaged."""
    total = ring = first = None
    count = 0
    for seed in seeds:
        image = renderer.render(*view, seed=seed, margin_px=margin_px)
        rad = image.radiance_w_m2_sr.astype(np.float64)
        total = rad if total is None else total + rad
        if image.margin_radiance_w_m2_sr is not None:
            margin = image.margin_radiance_w_m2_sr.astype(np.float64)
            ring = margin if ring is None else ring + margin
        first = first or image
        count += 1
    return dataclasses.replace(
        first,
        radiance_w_m2_sr=(total / count).astype(np.float32),
        margin_radiance_w_m2_sr=None if ring is None else (ring / count).astype(np.float32),
    )


def check_example(
    name: str,
    frames: int,
    size_px: int,
    reference_spp: int,
    default_settings: bool,
    reference_supersampling: int = 1,
    changes: dict | None = None,
    reference_mode: str = "paths",
) -> dict:
    scenario, settings = scenario_at_size(name, size_px, default_settings, changes)
    engine = FrameEngine(scenario)
    sensor = engine.sensor
    renderer = Renderer(engine.mesh, settings, scenario.render.variant)
    s = reference_supersampling
    reference = Renderer(
        engine.mesh,
        settings.with_(samples_per_pixel=max(1, reference_spp // s**2), supersampling=s),
    )
    picks = np.unique(np.linspace(0, engine.frame_count - 1, frames).round().astype(int))
    records = []
    for frame_index in picks:
        plan = int(engine.plan_indices[frame_index])
        pose = engine.track.cam_from_body(plan)
        light = frame_light(scenario, engine.track, plan)
        seed = frame_seed(scenario.seed, plan)
        margin = sensor.margin_px
        images, times = [], []
        for k in range(2):
            start = time.perf_counter()
            images.append(
                renderer.render(engine.camera, pose, light, seed=seed + k, margin_px=margin)
            )
            times.append(time.perf_counter() - start)
        start = time.perf_counter()
        if reference_mode == "paths":
            ref = reference.render(engine.camera, pose, light, seed=seed + 2, margin_px=margin)
        else:  # the mean of renders at the settings themselves, other seeds
            ref = _mean_render(
                renderer,
                (engine.camera, pose, light),
                range(seed + 100, seed + 100 + max(1, reference_spp // settings.passes)),
                margin,
            )
        reference_s = time.perf_counter() - start
        mask = ref.object_mask
        if not mask.any():
            continue
        fireflies = firefly_mask(images[0].radiance_w_m2_sr, mask)
        fireflies_ref = firefly_mask(ref.radiance_w_m2_sr, mask)
        # Over the mask grown by 2 px, so that pixels the target covers in part count for
        # both (one pixel-centre path and 1024 paths over the pixel see its edge apart).
        near = binary_dilation(mask, iterations=2)
        means = [float((im.radiance_w_m2_sr[near] @ LUMINANCE_RGB).mean()) for im in images]
        mean_ref = float((ref.radiance_w_m2_sr[near] @ LUMINANCE_RGB).mean())
        # Electrons at the frame's exposure (set by the reference, as the dataset sets it).
        irradiance_ref = sensor.focal_plane_irradiance_w_m2(ref)
        exposure_s = sensor.exposure_time_s(irradiance_ref, mask)
        electrons = [
            sensor.mean_electrons(sensor.focal_plane_irradiance_w_m2(im), exposure_s)
            for im in (*images, ref)
        ]
        lit = mask & (electrons[2] > 1.0)
        mc_sigma = (electrons[0] - electrons[1])[lit] / np.sqrt(2.0)
        ratio = np.abs(mc_sigma) / np.sqrt(electrons[2][lit])
        records.append(
            {
                "frame_index": int(frame_index),
                "target_pixels": int(mask.sum()),
                "firefly_fraction": float(fireflies.sum() / mask.sum()),
                "firefly_fraction_reference": float(fireflies_ref.sum() / mask.sum()),
                "firefly_excess_fraction": float((fireflies & ~fireflies_ref).sum() / mask.sum()),
                "mean_radiance_ratio": means[0] / mean_ref,
                "mean_radiance_ratio_se": abs(means[0] - means[1]) / np.sqrt(2.0) / mean_ref,
                "exposure_s": exposure_s,
                "electrons_target_median": float(np.median(electrons[2][mask])),
                "mc_over_shot_rms": float(np.sqrt(np.mean(ratio**2))) if lit.any() else None,
                "mc_over_shot_p90": float(np.percentile(ratio, 90)) if lit.any() else None,
                "render_s": statistics.median(times),
                "reference_s": reference_s,
            }
        )
    keys = ("firefly_fraction", "firefly_excess_fraction", "mean_radiance_ratio")
    return {
        "example": name,
        "size_px": [engine.camera.width_px, engine.camera.height_px],
        "settings": settings.__dict__,
        "reference_spp": reference_spp,
        "reference_supersampling": reference_supersampling,
        "frames": records,
        "median": {k: statistics.median(r[k] for r in records) for k in keys} if records else {},
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", default="fly_around,approach")
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--reference-supersampling", type=int, default=1)
    parser.add_argument("--settings", choices=("example", "default"), default="example")
    parser.add_argument("--samples-per-pixel", type=int, default=None)
    parser.add_argument("--sunlit-sampling", choices=("on", "off"), default=None)
    parser.add_argument("--reference", choices=("paths", "seeds"), default="paths")
    args = parser.parse_args(argv)
    changes = {}
    if args.samples_per_pixel is not None:
        changes["samples_per_pixel"] = args.samples_per_pixel
    if args.sunlit_sampling is not None:
        changes["sunlit_sampling"] = args.sunlit_sampling == "on"
    result = [
        check_example(
            name,
            args.frames,
            args.size,
            args.reference_spp,
            args.settings == "default",
            args.reference_supersampling,
            changes,
            args.reference,
        )
        for name in args.examples.split(",")
    ]
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
