"""Draw docs/images/smooth_normals.png: a procedural dish with flat and with smooth
normals, and a textured solar wing (cell grid, busbars) beside the radiator strips of the bus.

Usage: python benchmarks/smooth_normals_figure.py [OUTPUT.png]

Renders the ``two_wings_dish`` satellite of seed 3 under the Sun alone (no environment,
no inter-reflection), 3 x 3 rays per pixel. The two dish panels share one brightness
scale; each image is scaled so that its 99.5th percentile of lit pixels is white, then
gamma-encoded (2.2) for display.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.procedural import generate_satellite

SIDE_PX = 300
SETTINGS = RenderSettings(environment="off", bounces=0, supersampling=3)
SUN_IRRADIANCE_W_M2 = 671.5


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _render(mesh, camera_body_m, target_body_m, focal_m, sun_direction, up=(0.0, 0.0, 1.0)):
    camera = PinholeCamera(focal_m, 15e-6, SIDE_PX, SIDE_PX)
    pose = look_at_cam_from_body(
        np.asarray(camera_body_m), np.asarray(target_body_m), up_hint_body=np.asarray(up)
    )
    light = LightField.sun_only(_unit(sun_direction), SUN_IRRADIANCE_W_M2)
    return Renderer(mesh, SETTINGS).render(camera, pose, light).radiance_w_m2_sr


def _display(radiance: np.ndarray, white: float) -> np.ndarray:
    return np.clip(radiance / white, 0.0, 1.0) ** (1.0 / 2.2)


def _white(*images: np.ndarray) -> float:
    lit = np.concatenate([im[im.max(axis=-1) > 0].ravel() for im in images])
    return float(np.percentile(lit, 99.5))


def main(output: Path) -> None:
    flat = generate_satellite("two_wings_dish", 3)
    rich = generate_satellite("two_wings_dish", 3, smooth_normals=True, textures=True)
    dish = rich.vertices_m[
        rich.faces[rich.face_part_index == rich.part_names.index("antenna_dish")]
    ]
    dish_centre = dish.reshape(-1, 3).mean(axis=0)
    # The dish looks along -x: view it from there, a little off axis, Sun grazing.
    eye = dish_centre + 9.0 * _unit([-1.0, -0.35, 0.3])
    sun = [-0.45, 0.8, 0.4]
    dish_flat = _render(flat, eye, dish_centre, 0.011, sun)
    dish_smooth = _render(rich, eye, dish_centre, 0.011, sun)
    white = _white(dish_flat, dish_smooth)

    def centre(name: str) -> np.ndarray:
        index = rich.part_names.index(name)
        return rich.vertices_m[np.unique(rich.faces[rich.face_part_index == index])].mean(axis=0)

    # The wing root and the bus beside it, seen from the cells' side (the cells lie on the
    # substrate's side away from it), lit from that side.
    cell_side = _unit(centre("wing_1_cells") - centre("wing_1_substrate"))
    target = np.array([0.0, 1.0, 0.0]) + 0.3 * cell_side
    eye_wing = target + 4.5 * _unit(cell_side + np.array([0.7, -0.5, 0.0]))
    sun_wing = cell_side + np.array([0.9, -0.3, 0.3])
    wing = _render(rich, eye_wing, target, 0.01, sun_wing, up=(0.0, 1.0, 0.0))

    fig, axes = plt.subplots(1, 3, figsize=(9.0, 3.35), dpi=100)
    panels = [
        (_display(dish_flat, white), "flat triangles"),
        (_display(dish_smooth, white), "smooth normals (crease 30°)"),
        (_display(wing, _white(wing)), "textured cells and radiator strips"),
    ]
    for ax, (image, title) in zip(axes, panels, strict=True):
        ax.imshow(image, interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout(pad=0.6)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=100, pil_kwargs={"optimize": True})
    print(f"wrote {output} ({output.stat().st_size / 1024:.0f} kB)")


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[1] / "docs" / "images" / "smooth_normals.png"
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
