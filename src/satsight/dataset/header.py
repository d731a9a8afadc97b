"""The header of labels.json (and the manifest): everything it holds besides the frames.

The conventions every label follows, the camera and sensor that took the frames, the
render settings, the preview stretch, the light and the target, as JSON-ready values
(see docs/dataset_format.md). Built from plain typed values, so that the format does not
depend on how a scenario is written.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.dataset.journal import file_checksum
from satsight.dataset.labels import KEYPOINT_DEPTH_TOLERANCE
from satsight.dataset.preview import PreviewStretch
from satsight.render.settings import RenderSettings
from satsight.scene.keypoints import KEYPOINT_DESCRIPTIONS
from satsight.scene.mesh import TargetMesh
from satsight.sensor.chain import SensorChain
from satsight.version import __version__

CONVENTIONS = {
    "units": "SI; names carry non-SI units",
    "quaternion": "scalar-first [qw, qx, qy, qz], Hamilton, qw >= 0",
    "pose": "x_cam = R(q_cam_from_body) @ x_body + t_cam_from_body_m",
    "camera_frame": "OpenCV: +x right, +y down, +z boresight",
    "pixel_origin": "(0, 0) is the centre of the top-left pixel",
    "depth": "metres along +z_cam; 0 where no surface",
    "part_mask": "0 background; part id = part index + 1",
    "keypoints": "target.keypoints_body_m projected (target.keypoints says how they were "
    "chosen); keypoints_visible: inside the image and not hidden by the target (depth "
    "buffer, 3 x 3 pixels, tolerance " + KEYPOINT_DEPTH_TOLERANCE + ")",
    "box_keypoints": "8 bounding-box corners (bit 0: x, bit 1: y, bit 2: z; 0 min, 1 max), "
    "then the box centre",
}


def camera_summary(camera: PinholeCamera) -> dict:
    """A pinhole camera's numbers, JSON-ready, for labels.json."""
    return {
        "focal_length_m": camera.focal_length_m,
        "pixel_pitch_m": camera.pixel_pitch_m,
        "image_size_px": [camera.width_px, camera.height_px],
        "K": camera.K.tolist(),
        "fov_x_deg": float(np.degrees(camera.fov_x_rad)),
        "fov_y_deg": float(np.degrees(camera.fov_y_rad)),
    }


def sensor_summary(sensor: SensorChain) -> dict:
    """The camera's optics, detector and exposure rule, JSON-ready, for labels.json."""
    return {
        "description": "images/ hold raw DN (uint16, bias included); per frame: sensor "
        "(exposure_time_s, saturated_pixel_count, and per region - target, earth, moon - its "
        "pixel_count, fill_fraction_p99 and saturated_pixel_count) and the stars drawn",
        "band_nm": list(sensor.band_nm),
        "effective_wavelength_m": sensor.effective_wavelength_m,
        "channel_weights_rgb": sensor.channel_weights.tolist(),
        "channel_photon_weights_rgb": sensor.channel_photon_weights.tolist(),
        "quantum_efficiency": sensor.quantum_efficiency,
        "quantum_efficiency_source": sensor.quantum_efficiency_source,
        "channel_quantum_efficiency_rgb": sensor.channel_quantum_efficiency.tolist(),
        "optics": dataclasses.asdict(sensor.optics),
        "f_number": sensor.optics.f_number,
        "detector": dataclasses.asdict(sensor.detector),
        "exposure": dataclasses.asdict(sensor.exposure),
        "frame_kernel": {
            "description": "kernel applied to rendered frames so that their MTF is the "
            "system MTF up to Nyquist, designed for the render's sub-pixel sampling; the "
            "renderer adds a ring margin_px wide around the frame",
            "size_px": int(sensor.psf.shape[0]),
            "margin_px": sensor.margin_px,
            "supersampling": sensor.supersampling,
            "samples_per_pixel": sensor.samples_per_pixel,
        },
        "camera_seed": sensor.camera_seed,
    }


@dataclass(frozen=True)
class FarCamera:
    """The second camera of a dual-mode dataset, for frames beyond a range.

    preset: the far camera's preset name. switch_range_m: range to the target's box centre
    (metres) beyond which frames are taken with it. camera, sensor: its pinhole model and
    its optics and detector.
    """

    preset: str
    switch_range_m: float
    camera: PinholeCamera
    sensor: SensorChain


@dataclass(frozen=True)
class TargetDescription:
    """The target as labels.json describes it.

    mesh: the target mesh. keypoints_body_m: (N, 3) the keypoints labelled in each frame,
    body frame, metres. keypoints_method: how they were chosen (a key of
    ``KEYPOINT_DESCRIPTIONS``). mesh_file: the mesh file it was loaded from (its SHA-256
    goes into the header), or None for a procedural target.
    """

    mesh: TargetMesh
    keypoints_body_m: np.ndarray
    keypoints_method: str
    mesh_file: Path | None


def labels_header(
    *,
    scenario_name: str,
    plan_indices: Sequence[int],
    render_variant: str,
    outputs: dict,
    file_keys: Sequence[str],
    camera: PinholeCamera,
    sensor: SensorChain,
    sun_spectrum: str,
    band_nm: Sequence[float],
    render_settings: RenderSettings,
    preview: PreviewStretch,
    target: TargetDescription,
    far: FarCamera | None = None,
) -> dict:
    """The dataset's description: everything labels.json holds besides its frames.

    scenario_name: the scenario's name. plan_indices: the plan index of each frame of the
    dataset. render_variant: the Mitsuba variant that rendered it. outputs: the scenario's
    ``outputs`` block as JSON values; file_keys: the file keys it writes per frame.
    camera, sensor: the (primary) camera and its optics and detector. sun_spectrum,
    band_nm: the Sun's spectrum name and the band (nm). render_settings: the renderer's
    settings. preview: the 8-bit previews' stretch. target: the target mesh and keypoints.
    far: the far camera of a dual-mode dataset, or None.
    """
    mesh = target.mesh
    header = {
        "satsight_version": __version__,
        "scenario": scenario_name,
        "frame_count": len(plan_indices),
        "plan_indices": [int(i) for i in plan_indices],
        "render_variant": render_variant,
        "conventions": CONVENTIONS,
        "outputs": {**outputs, "file_keys": list(file_keys)},
        "camera": camera_summary(camera),
        "sun": {
            "description": "per frame: sun_direction_body, sun_direction_cam and "
            "sun_irradiance_w_m2 (in band, at the target, after the Earth's shadow)",
            "spectrum": sun_spectrum,
            "band_nm": list(band_nm),
        },
        "render_settings": dataclasses.asdict(render_settings),
        "sensor": sensor_summary(sensor),
        "preview": preview.header(),
        "environment_light": {
            "description": "per frame: environment_sh_radiance_w_m2_sr, earthshine "
            "and moonshine as real SH, index l(l+1)+m, body frame, direction towards "
            "the source",
            "sh_order": render_settings.sh_order,
        },
        "target": {
            **mesh.summary(),
            "model_obj": "model/target.obj",
            "keypoints_body_m": target.keypoints_body_m.tolist(),
            "keypoints": {
                "method": target.keypoints_method,
                "count": len(target.keypoints_body_m),
                "description": KEYPOINT_DESCRIPTIONS[target.keypoints_method],
            },
            "box_keypoints_body_m": mesh.box_keypoints_body_m.tolist(),
            # A mesh file edited between an interruption and --resume is refused.
            "mesh_file_sha256": None
            if target.mesh_file is None
            else file_checksum(target.mesh_file)["sha256"],
        },
    }
    if far is not None:
        header["far_camera"] = {
            "description": "frames with camera_mode 'far' (range to the target's box "
            "centre beyond switch_range_m) are taken with this camera and sensor; "
            "'camera' and 'sensor' above describe the 'primary' frames",
            "preset": far.preset,
            "switch_range_m": far.switch_range_m,
            "camera": camera_summary(far.camera),
            "sensor": sensor_summary(far.sensor),
        }
    return header
