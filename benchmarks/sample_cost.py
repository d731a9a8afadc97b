"""Render time of an example's frames against the light paths per pixel and the
sampling of sunlit parts (JSON).

Usage: python benchmarks/sample_cost.py [--example fly_around] [--frame 36]
       [--size 4096] [--spp 1,4,16,64] [--repeats 3] [--variant auto]

Renders one frame of the example at ``size`` px wide (field of view kept: the pixel pitch
grows by 4096 / size) with its own render settings, for every count of paths per pixel in
``--spp``, with ``sunlit_sampling`` on and off, and prints the median seconds of
``repeats`` renders after one that compiles the kernels, and the target's pixel count.
Compare the rows of one run: the machines are noisy.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from firefly_check import scenario_at_size

from satsight.pipeline import FrameEngine, frame_light, frame_seed
from satsight.render.renderer import Renderer


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--example", default="fly_around")
    parser.add_argument("--frame", type=int, default=36)
    parser.add_argument("--size", type=int, default=4096)
    parser.add_argument("--spp", default="1,4,16,64")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variant", default="auto")
    args = parser.parse_args(argv)
    scenario, settings = scenario_at_size(args.example, args.size, False)
    engine = FrameEngine(scenario)
    plan = int(engine.plan_indices[args.frame])
    pose = engine.track.cam_from_body(plan)
    light = frame_light(scenario, engine.track, plan)
    seed = frame_seed(scenario.seed, plan)
    rows = []
    for spp in (int(v) for v in args.spp.split(",")):
        for sunlit in (True, False):
            renderer = Renderer(
                engine.mesh,
                settings.with_(samples_per_pixel=spp, sunlit_sampling=sunlit),
                args.variant,
            )
            image = renderer.render(engine.camera, pose, light, seed=seed)  # compiles
            times = []
            for k in range(args.repeats):
                start = time.perf_counter()
                renderer.render(engine.camera, pose, light, seed=seed + 1 + k)
                times.append(time.perf_counter() - start)
            rows.append(
                {
                    "samples_per_pixel": spp,
                    "sunlit_sampling": sunlit,
                    "render_s": statistics.median(times),
                    "target_pixels": int(image.object_mask.sum()),
                }
            )
    print(
        json.dumps(
            {
                "example": args.example,
                "frame": args.frame,
                "size_px": [engine.camera.width_px, engine.camera.height_px],
                "variant": renderer.variant,
                "rows": rows,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
