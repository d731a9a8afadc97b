"""One scenario end to end: target -> poses -> render -> labels -> files.

``run_scenario`` is what ``satsight generate`` and ``satsight demo`` call; the CLI is a thin
shell over it.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from satsight import __version__
from satsight.config.scenario import Scenario, TargetConfig
from satsight.dataset.labels import frame_labels
from satsight.dataset.preview import crop_box_xyxy_px, thumbnail, write_contact_sheet
from satsight.dataset.staging import check_output_folder, staged_folder
from satsight.dataset.writer import LABELS_FORMAT, write_frame, write_labels
from satsight.errors import SatsightError
from satsight.lighting.bodies import environment_light_field
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.scene.loading import load_mesh
from satsight.scene.mesh import TargetMesh
from satsight.scene.obj_export import write_obj
from satsight.scene.procedural import generate_satellite

CONVENTIONS = {
    "units": "SI; names carry non-SI units",
    "quaternion": "scalar-first [qw, qx, qy, qz], Hamilton, qw >= 0",
    "pose": "x_cam = R(q_cam_from_body) @ x_body + t_cam_from_body_m",
    "camera_frame": "OpenCV: +x right, +y down, +z boresight",
    "pixel_origin": "(0, 0) is the centre of the top-left pixel",
    "depth": "metres along +z_cam; 0 where no surface",
    "part_mask": "0 background; part id = part index + 1",
    "keypoints": "8 bounding-box corners (bit 0: x, bit 1: y, bit 2: z; 0 min, 1 max), then "
    "the box centre",
}


def is_dataset(folder: Path) -> bool:
    """Whether ``folder`` holds a dataset written by satsight (its labels.json says so)."""
    try:
        document = json.loads((Path(folder) / "labels.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(document, dict) and document.get("format") == LABELS_FORMAT


def build_target(config: TargetConfig) -> TargetMesh:
    """The target mesh a scenario asks for (procedural or loaded from a file)."""
    if config.procedural is not None:
        return generate_satellite(config.procedural.satellite_class, config.procedural.seed)
    return load_mesh(config.mesh.path, scale_m=config.mesh.scale_m)


def build_light_field(scenario: Scenario) -> LightField:
    """The light at the target: the Sun, plus earthshine and moonshine when configured."""
    sun = scenario.sun.build()
    earth, moon = scenario.earth, scenario.moon
    return environment_light_field(
        sun.direction_body,
        sun.irradiance_w_m2,
        earth_center_from_target_m=None if earth is None else earth.center_from_target_m(),
        earth_albedo=0.30 if earth is None else earth.albedo,
        moon_center_from_target_m=None if moon is None else moon.center_from_target_m(),
        moon_albedo=0.12 if moon is None else moon.albedo,
        l_max=scenario.render.sh_order,
    )


def frame_seed(scenario_seed: int, frame_index: int) -> int:
    """The render seed of one frame, independent of which other frames are rendered."""
    state = np.random.SeedSequence([scenario_seed, frame_index]).generate_state(2, np.uint32)
    return int(state[0]) << 32 | int(state[1])


@dataclass(frozen=True)
class RunSummary:
    out_dir: Path
    frame_count: int
    render_seconds: list[float]
    total_seconds: float
    variant: str


ProgressCallback = Callable[[int, int], None]
# Frames whose files are written in the background while the next one renders.
_WRITER_THREADS = 2


def run_scenario(
    scenario: Scenario,
    out_dir: Path,
    overwrite: bool = False,
    on_frame_done: ProgressCallback | None = None,
) -> RunSummary:
    """Render every frame of ``scenario`` and write the dataset to ``out_dir``.

    The dataset is built in a temporary folder and moved into place only when complete.
    ``on_frame_done(done, total)`` is called after each frame (for progress bars).
    """
    out_dir = Path(out_dir)
    check_output_folder(out_dir, overwrite)
    if overwrite and out_dir.is_dir() and any(out_dir.iterdir()) and not is_dataset(out_dir):
        raise SatsightError(
            f"--overwrite replaces only satsight datasets, and {out_dir} holds no satsight "
            "labels.json; choose an empty or new folder"
        )
    started = time.perf_counter()
    mesh = build_target(scenario.target)
    camera = scenario.camera.build()
    sun = scenario.sun.build()
    light = build_light_field(scenario)
    renderer = Renderer(mesh, scenario.render.settings(), scenario.render.variant)
    frames, thumbs, titles, render_seconds = [], [], [], []
    with (
        staged_folder(out_dir, overwrite) as root,
        ThreadPoolExecutor(max_workers=_WRITER_THREADS) as writers,
    ):
        # The model goes first: a mesh that cannot be written fails before any rendering.
        (root / "model").mkdir()
        write_obj(mesh, root / "model" / "target.obj")
        writes: list[Future] = []
        for index, frame in enumerate(scenario.frames):
            view = frame.build()
            cam_from_body = view.cam_from_body(mesh.center_m)
            t0 = time.perf_counter()
            image = renderer.render(
                camera, cam_from_body, light, seed=frame_seed(scenario.seed, index)
            )
            render_seconds.append(time.perf_counter() - t0)
            labels = frame_labels(mesh, camera, cam_from_body, sun, image)
            # Files are compressed and written in the background while the next frame
            # renders; waiting on older writes bounds the frames held in memory.
            writes.append(writers.submit(write_frame, root, index, image))
            if index >= _WRITER_THREADS:
                writes[index - _WRITER_THREADS].result()
            frames.append({"frame_index": index, "view": frame.model_dump(), **labels})
            x0, y0, x1, y1 = crop_box_xyxy_px(labels["bbox_xyxy_px"], image.shape)
            thumbs.append(thumbnail(image.radiance_w_m2_sr[y0:y1, x0:x1]))
            titles.append(
                f"#{index}  {frame.distance_km:g} km, az {frame.azimuth_deg:g}°, "
                f"el {frame.elevation_deg:g}°, phase {labels['phase_angle_deg']:.0f}°\n"
                f"{labels['object_pixel_count']} px on target; crop {x1 - x0} px wide"
            )
            del image
            if on_frame_done is not None:
                on_frame_done(index + 1, len(scenario.frames))
        for record, write in zip(frames, writes, strict=True):
            record.update(write.result())
        (root / "scenario.yaml").write_text(
            yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False), encoding="utf-8"
        )
        write_contact_sheet(
            root / "contact_sheet.png",
            thumbs,
            titles,
            f"{scenario.name}: {mesh.name}, {camera.width_px}x{camera.height_px} px, "
            f"f = {camera.focal_length_m:g} m",
        )
        write_labels(
            root,
            {
                "satsight_version": __version__,
                "scenario": scenario.name,
                "render_variant": renderer.variant,
                "conventions": CONVENTIONS,
                "camera": {
                    "focal_length_m": camera.focal_length_m,
                    "pixel_pitch_m": camera.pixel_pitch_m,
                    "image_size_px": [camera.width_px, camera.height_px],
                    "K": camera.K.tolist(),
                    "fov_x_deg": float(np.degrees(camera.fov_x_rad)),
                    "fov_y_deg": float(np.degrees(camera.fov_y_rad)),
                },
                "sun": {
                    "direction_body": sun.direction_body.tolist(),
                    "irradiance_w_m2": sun.irradiance_w_m2,
                    "spectrum": scenario.sun.spectrum,
                    "band_nm": list(scenario.sun.band_nm),
                },
                "render_settings": dataclasses.asdict(renderer.settings),
                "environment_light": {
                    "description": "earthshine and moonshine as real SH, index l(l+1)+m, "
                    "body frame, direction towards the source",
                    "sh_order": light.l_max,
                    "sh_radiance_w_m2_sr": light.sh_radiance_w_m2_sr.tolist(),
                },
                "target": {
                    **mesh.summary(),
                    "model_obj": "model/target.obj",
                    "keypoints_body_m": mesh.keypoints_body_m.tolist(),
                },
                "frames": frames,
            },
        )
    return RunSummary(
        out_dir=out_dir,
        frame_count=len(frames),
        render_seconds=render_seconds,
        total_seconds=time.perf_counter() - started,
        variant=renderer.variant,
    )
