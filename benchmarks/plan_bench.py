"""Benchmark frame planning; prints JSON (median seconds per plan and per frame).

Usage: python benchmarks/plan_bench.py [--repeats 5] [--frames 1000]

Plans each bundled orbital example as it is, and each again with ``--frames`` frames
(ephemeris, propagation of both spacecraft with RK4 at 1 s, attitude, pointing,
visibility). The target mesh is built once per example, outside the timing.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from satsight.cli import example_scenario_path
from satsight.config.scenario import load_scenario
from satsight.poses.plan import plan_track

EXAMPLES = ("fly_around", "fly_by", "approach", "rssf_dataset")


def _time(scenario, center, repeats: int) -> tuple[float, int]:
    plan_track(scenario.plan_request(), center)  # first call: ephemeris file opened and cached
    seconds = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        track = plan_track(scenario.plan_request(), center)
        seconds.append(time.perf_counter() - t0)
    return statistics.median(seconds), len(track)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed plans per case (>= 3)")
    parser.add_argument("--frames", type=int, default=1000, help="frames of the large plans")
    args = parser.parse_args()
    if args.repeats < 3 or args.frames < 1:
        parser.error("need --repeats >= 3 and --frames >= 1")
    results = []
    for name in EXAMPLES:
        scenario = load_scenario(example_scenario_path().parent / f"{name}.yaml")
        center = scenario.target.build().center_m
        sampler = scenario.sampler
        large = sampler.model_copy(
            update={"frame_count": args.frames, "step_s": None, "step_deg": None}
        )
        for label, case in (
            ("example", scenario),
            ("large", scenario.model_copy(update={"sampler": large})),
        ):
            median_s, frames = _time(case, center, args.repeats)
            results.append(
                {
                    "scenario": name,
                    "case": label,
                    "frames": frames,
                    "median_s": median_s,
                    "median_per_frame_s": median_s / frames,
                }
            )
    print(json.dumps({"benchmark": "plan", "repeats": args.repeats, "results": results}, indent=2))


if __name__ == "__main__":
    main()
