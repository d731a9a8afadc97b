"""Render time against the target's triangle count (JSON): the render bench's two_wings
satellite, each triangle split into four at its edge midpoints again and again (the same
shape, flat-shaded, 4x the triangles per step), timed as ``satsight bench`` times a stage.

Usage: python benchmarks/mesh_scaling.py [--steps 4] [--frames 3] [--size 4096x4112]
       [--stage sun_unshadowed_sh_1_bounce|sun_sampled_sh_2_bounces|render_direct_sun]

Per step: triangles, the renderer's build time (its tables and Embree's BVH), the median
render time over ``frames`` frames after a warm-up one, and that median over the first
step's.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from satsight.render.renderer import Renderer
from satsight.scene.mesh import TargetMesh
from satsight.scene.procedural import generate_satellite
from satsight.tools.render_benchmark import (
    DIRECT_SUN_ONLY,
    RADIATIVE_STAGES,
    _light,
    _time_stage,
    parse_sizes_px,
)


def split_in_four(mesh: TargetMesh) -> TargetMesh:
    """Each triangle as four (corners and edge midpoints; the midpoints are not shared
    between neighbours, which changes no surface), flat-shaded, untextured."""
    v = mesh.vertices_m[mesh.faces]  # (M, 3, 3)
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    tris = np.stack(
        [
            np.stack([a, ab, ca], axis=1),
            np.stack([ab, b, bc], axis=1),
            np.stack([ca, bc, c], axis=1),
            np.stack([ab, bc, ca], axis=1),
        ],
        axis=1,
    ).reshape(-1, 3, 3)
    vertices = tris.reshape(-1, 3)
    faces = np.arange(len(vertices)).reshape(-1, 3)
    return dataclasses.replace(
        mesh,
        vertices_m=vertices,
        faces=faces,
        face_part_index=np.repeat(mesh.face_part_index, 4),
        corner_normals=None,
        corner_uv=None,
        part_textures=(),
    )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--size", default="4096x4112")
    parser.add_argument(
        "--stage",
        default="sun_unshadowed_sh_1_bounce",
        choices=[*RADIATIVE_STAGES, "render_direct_sun"],
    )
    args = parser.parse_args(argv)
    (size,) = parse_sizes_px(args.size)
    settings = RADIATIVE_STAGES.get(args.stage, DIRECT_SUN_ONLY)
    mesh = generate_satellite("two_wings", seed=1)
    mesh = dataclasses.replace(mesh, corner_normals=None, corner_uv=None, part_textures=())
    light = _light()
    rows = []
    for step in range(args.steps + 1):
        start = time.perf_counter()
        renderer = Renderer(mesh, settings)
        build_s = time.perf_counter() - start
        timed = _time_stage(renderer, args.stage, size, args.frames, light)
        rows.append(
            {
                "triangles": len(mesh.faces),
                "renderer_build_s": build_s,
                "median_s": timed["median_s"],
                "min_s": timed["min_s"],
                "max_s": timed["max_s"],
                "target_coverage_mean": timed["target_coverage_mean"],
            }
        )
        if step < args.steps:
            mesh = split_in_four(mesh)
    for row in rows:
        row["over_first"] = row["median_s"] / rows[0]["median_s"]
    print(json.dumps({"stage": args.stage, "size_px": list(size), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
