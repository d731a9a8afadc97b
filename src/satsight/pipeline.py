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
from satsight.dataset.preview import (
    DN_PREVIEW_STRETCH,
    crop_box_xyxy_px,
    thumbnail,
    write_contact_sheet,
)
from satsight.dataset.staging import check_output_folder, staged_folder
from satsight.dataset.writer import LABELS_FORMAT, write_frame, write_labels
from satsight.ephemeris.orbits import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.sun_moon import AU_M
from satsight.errors import SatsightError
from satsight.lighting.bodies import MOON_MEAN_RADIUS_M, environment_light_field
from satsight.lighting.light_field import LightField
from satsight.poses.plan import frames_to_render, plan_track
from satsight.poses.track import PoseTrack
from satsight.render.buffers import RadianceImage, SunLight
from satsight.render.renderer import Renderer
from satsight.scene.loading import load_mesh
from satsight.scene.mesh import TargetMesh
from satsight.scene.obj_export import write_obj
from satsight.scene.procedural import generate_satellite
from satsight.sensor.chain import DnImage, SensorChain, blur_radius_px

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


def frame_light(scenario: Scenario, track: PoseTrack, index: int) -> tuple[LightField, SunLight]:
    """The light at the target in frame ``index`` of the plan, in the body frame.

    The Sun's in-band irradiance is the scenario's value at 1 AU scaled by the inverse square
    of the frame's Sun distance; the Earth and the Moon are lit by all of it, the target by
    its ``sunlit_fraction`` (partly or wholly in the Earth's shadow). Earthshine and moonshine
    are included when the scenario has ``earth`` / ``moon`` sections.
    """
    R_body_from_cam = track.cam_from_body(index).R_a_from_b.T
    sun_config = scenario.sun
    if scenario.sampler is None:
        irradiance = sun_config.in_band_irradiance_w_m2
    else:
        at_1_au = sun_config.model_copy(update={"distance_au": 1.0}).in_band_irradiance_w_m2
        irradiance = at_1_au * (AU_M / track.sun_distance_m[index]) ** 2
    sun_body = R_body_from_cam @ track.sun_from_target_cam[index]
    at_target = irradiance * float(track.sunlit_fraction[index])

    def center_body(direction_cam: np.ndarray, distance_m: float) -> np.ndarray:
        return R_body_from_cam @ (direction_cam * distance_m)

    earth, moon = scenario.earth, scenario.moon
    light = environment_light_field(
        sun_body,
        irradiance,
        earth_center_from_target_m=None
        if earth is None
        else center_body(track.earth_from_target_cam[index], track.earth_distance_m[index]),
        earth_albedo=0.30 if earth is None else earth.albedo,
        moon_center_from_target_m=None
        if moon is None
        else center_body(track.moon_from_target_cam[index], track.moon_distance_m[index]),
        moon_albedo=0.12 if moon is None else moon.albedo,
        l_max=scenario.render.sh_order,
        sun_irradiance_at_target_w_m2=at_target,
    )
    return light, SunLight(sun_body, at_target)


def planned_frames(scenario: Scenario, mesh: TargetMesh) -> tuple[PoseTrack, np.ndarray]:
    """The scenario's frame plan and the indices of the frames to render."""
    track = plan_track(scenario, mesh.center_m, mesh.bounding_radius_m)
    indices = frames_to_render(scenario, track)
    if indices.size == 0:
        raise SatsightError(
            f"none of the {len(track)} planned frames passes the visibility tests, and "
            "visibility.on_fail is 'skip'; run 'satsight plan' to see why, then change the "
            "scenario or set on_fail to 'flag'"
        )
    return track, indices


def frame_seed(scenario_seed: int, frame_index: int) -> int:
    """The render seed of one frame, independent of which other frames are rendered."""
    state = np.random.SeedSequence([scenario_seed, frame_index]).generate_state(2, np.uint32)
    return int(state[0]) << 32 | int(state[1])


def sensor_noise_rng(scenario_seed: int, frame_index: int) -> np.random.Generator:
    """The detector-noise generator of one frame: its own stream, apart from the render's."""
    return np.random.default_rng(np.random.SeedSequence([scenario_seed, frame_index, 1]))


def build_sensor(scenario: Scenario) -> SensorChain:
    """The scenario's camera optics and detector, ready to expose frames."""
    camera = scenario.camera
    return SensorChain(
        camera=camera.build(),
        optics=camera.build_optics(),
        detector=camera.build_detector(),
        band_nm=scenario.sun.band_nm,
        spectrum=scenario.sun.spectrum,
        exposure=camera.exposure,
        camera_seed=camera.seed,
    )


def add_frame_stars(
    scenario: Scenario,
    sensor: SensorChain,
    track: PoseTrack,
    index: int,
    irradiance_w_m2: np.ndarray,
    object_mask: np.ndarray,
    center_cam_m: np.ndarray,
    exposure_time_s: float,
) -> dict:
    """Add the catalogue stars in view of frame ``index`` to its focal-plane irradiance, in
    place, hidden behind the target (its mask), the Earth (with the atmosphere margin) and
    the Moon; return the frame's star labels (each star's catalogue id, pixel position, V
    magnitude and mean photons reaching the detector over the exposure)."""
    config = scenario.stars
    if not (config.enabled and track.has_sky):
        return {"star_count": 0}
    from satsight.sensor.star_catalog import load_star_catalog
    from satsight.sensor.star_field import (
        DEFAULT_STAMP_RADIUS_PX,
        star_photon_counts,
        star_photons_image,
        stars_in_view,
    )

    # Stamps wide enough for the defocus disc and the jitter; stars are kept (and labelled)
    # only when their stamp reaches the frame.
    stamp_radius_px = DEFAULT_STAMP_RADIUS_PX + blur_radius_px(
        sensor.optics, sensor.camera.pixel_pitch_m
    )

    def sphere(direction: np.ndarray, distance_m: float, radius_m: float):
        return center_cam_m + direction * distance_m, radius_m

    spheres = [
        sphere(
            track.earth_from_target_cam[index],
            track.earth_distance_m[index],
            EARTH_EQUATORIAL_RADIUS_M + config.earth_atmosphere_margin_km * 1e3,
        ),
        sphere(track.moon_from_target_cam[index], track.moon_distance_m[index], MOON_MEAN_RADIUS_M),
    ]
    stars = stars_in_view(
        load_star_catalog(config.v_mag_limit),
        track.R_cam_from_gcrs(index),
        sensor.camera,
        track.epoch_utc[index],
        track.camera_velocity_gcrs_m_s[index],
        occluding_spheres_cam=spheres,
        object_mask=object_mask,
        band_nm=sensor.band_nm,
        margin_px=stamp_radius_px + 0.5,
    )
    star_photons_image(
        stars,
        object_mask.shape,
        sensor.optics,
        sensor.camera.pixel_pitch_m,
        exposure_time_s,
        sensor.band_nm,
        stamp_radius_px,
        out=irradiance_w_m2,
        scale=sensor.photons_to_irradiance_factor(exposure_time_s),
    )
    labels = stars.labels()
    photons = star_photon_counts(stars.photon_flux_m2_s, sensor.optics, exposure_time_s)
    for record, count in zip(labels["stars"], photons, strict=True):
        record["photons"] = float(count)
    return labels


def expose_frame(
    scenario: Scenario,
    sensor: SensorChain,
    track: PoseTrack,
    index: int,
    image: RadianceImage,
    center_cam_m: np.ndarray,
) -> tuple[DnImage, dict]:
    """Frame ``index`` through the optics and the detector, with the stars behind the target.

    Returns the DN image and the frame's sensor labels (exposure, saturation, stars).
    """
    irradiance = sensor.focal_plane_irradiance_w_m2(image)
    mask = image.object_mask
    exposure_s = sensor.exposure_time_s(irradiance, mask)
    stars = add_frame_stars(
        scenario, sensor, track, index, irradiance, mask, center_cam_m, exposure_s
    )
    dn_image = sensor.read_out(
        irradiance, exposure_s, sensor_noise_rng(scenario.seed, index), stars["star_count"]
    )
    return dn_image, {"sensor": dn_image.labels(), **stars}


def _thumbnail_title(
    index: int, track: PoseTrack, plan_index: int, labels: dict, crop_width_px: int
) -> str:
    plan = track.record(plan_index)
    when = f"t = {plan['time_s']:.0f} s, " if plan["epoch_utc"] else ""
    flags = "" if plan["visible"] else "  [fails visibility]"
    return (
        f"#{index}  {when}{track.range_m[plan_index] / 1e3:.3g} km, "
        f"phase {labels['phase_angle_deg']:.0f}°{flags}\n"
        f"{labels['object_pixel_count']} px on target; crop {crop_width_px} px wide"
    )


def sensor_summary(sensor: SensorChain) -> dict:
    """The camera's optics, detector and exposure rule, JSON-ready, for labels.json."""
    return {
        "description": "images/ hold raw DN (uint16, bias included); per frame: sensor "
        "(exposure_time_s, saturated_pixel_count) and the stars drawn",
        "band_nm": list(sensor.band_nm),
        "effective_wavelength_m": sensor.effective_wavelength_m,
        "channel_weights_rgb": sensor.channel_weights.tolist(),
        "channel_photon_weights_rgb": sensor.channel_photon_weights.tolist(),
        "optics": dataclasses.asdict(sensor.optics),
        "f_number": sensor.optics.f_number,
        "detector": dataclasses.asdict(sensor.detector),
        "exposure": sensor.exposure.model_dump(),
        "camera_seed": sensor.camera_seed,
    }


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
    track, indices = planned_frames(scenario, mesh)
    renderer = Renderer(mesh, scenario.render.settings(), scenario.render.variant)
    sensor = build_sensor(scenario)
    if scenario.stars.enabled and track.has_sky:
        from satsight.sensor.star_catalog import load_star_catalog

        load_star_catalog(scenario.stars.v_mag_limit)  # fails here, before any rendering
    frames, thumbs, titles, render_seconds = [], [], [], []
    with (
        staged_folder(out_dir, overwrite) as root,
        ThreadPoolExecutor(max_workers=_WRITER_THREADS) as writers,
    ):
        # The model goes first: a mesh that cannot be written fails before any rendering.
        (root / "model").mkdir()
        write_obj(mesh, root / "model" / "target.obj")
        writes: list[Future] = []
        for index, plan_index in enumerate(indices):
            cam_from_body = track.cam_from_body(plan_index)
            light, sun = frame_light(scenario, track, plan_index)
            t0 = time.perf_counter()
            image = renderer.render(
                camera, cam_from_body, light, seed=frame_seed(scenario.seed, int(plan_index))
            )
            render_seconds.append(time.perf_counter() - t0)
            labels = frame_labels(mesh, camera, cam_from_body, sun, image)
            dn_image, sensor_labels = expose_frame(
                scenario, sensor, track, int(plan_index), image, cam_from_body.apply(mesh.center_m)
            )
            # Files are compressed and written in the background while the next frame
            # renders; waiting on older writes bounds the frames held in memory.
            writes.append(writers.submit(write_frame, root, index, image, dn_image))
            if index >= _WRITER_THREADS:
                writes[index - _WRITER_THREADS].result()
            record = {"frame_index": index, "plan_index": int(plan_index)}
            if scenario.frames:
                record["view"] = scenario.frames[plan_index].model_dump()
            record["plan"] = track.record(plan_index)
            record["sun_direction_body"] = sun.direction_body.tolist()
            record["environment_sh_radiance_w_m2_sr"] = light.sh_radiance_w_m2_sr.tolist()
            frames.append({**record, **labels, **sensor_labels})
            x0, y0, x1, y1 = crop_box_xyxy_px(labels["bbox_xyxy_px"], image.shape)
            thumbs.append(thumbnail(image.radiance_w_m2_sr[y0:y1, x0:x1]))
            titles.append(_thumbnail_title(index, track, plan_index, labels, x1 - x0))
            del image, dn_image
            if on_frame_done is not None:
                on_frame_done(index + 1, len(indices))
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
                    "description": "per frame: sun_direction_body, sun_direction_cam and "
                    "sun_irradiance_w_m2 (in band, at the target, after the Earth's shadow)",
                    "spectrum": scenario.sun.spectrum,
                    "band_nm": list(scenario.sun.band_nm),
                },
                "render_settings": dataclasses.asdict(renderer.settings),
                "sensor": sensor_summary(sensor),
                "preview": {"stretch": DN_PREVIEW_STRETCH},
                "environment_light": {
                    "description": "per frame: environment_sh_radiance_w_m2_sr, earthshine "
                    "and moonshine as real SH, index l(l+1)+m, body frame, direction towards "
                    "the source",
                    "sh_order": scenario.render.sh_order,
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
