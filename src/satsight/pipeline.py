"""One frame end to end: target -> pose -> light -> render -> labels -> sensor -> DN.

``FrameEngine`` holds what every frame of a scenario shares (mesh, plan, renderer and its
compiled kernels, sensor) and makes one frame's record and arrays; ``satsight.run``
runs it over a dataset and writes the files.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.config.camera import CameraConfig
from satsight.config.scenario import Scenario
from satsight.dataset.frame_files import OBJECT_FILE_KEYS, FrameArrays
from satsight.dataset.header import FarCamera, TargetDescription, labels_header
from satsight.dataset.labels import crop_labels, crop_window_xyxy_px, frame_labels
from satsight.errors import SatsightError
from satsight.frame_light import (
    LightInputs,
    frame_light_inputs,
    light_from_inputs,
    sun_irradiance_w_m2,
)
from satsight.frame_memory import check_frame_memory
from satsight.frame_scene import FrameView, frame_scene
from satsight.frame_variation import FramePoses, FrameVariation
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField
from satsight.poses.plan import frames_to_render, plan_track
from satsight.poses.track import PoseTrack
from satsight.randomization.draws import FrameDraws
from satsight.render.buffers import RadianceImage, within_box
from satsight.render.motion import (
    MOTION_THRESHOLD_PX,
    ExposureMotion,
    exposure_motion,
    render_over_exposure,
)
from satsight.render.renderer import Renderer
from satsight.scene.keypoints import target_keypoints_body_m
from satsight.scene.mesh import TargetMesh
from satsight.scene.objects import SceneMesh
from satsight.sensor.chain import DnImage, SensorChain, exposure_regions
from satsight.sensor.frame_stars import add_frame_stars
from satsight.sensor.photometry import frame_photometry

# Distinct light fields a FrameEngine keeps (its frames' light at up to this many target
# states: an exposure's sub-instants, or the epochs an RSSF plan may hold).
LIGHT_CACHE_SIZE = 8


def planned_frames(scenario: Scenario, mesh: TargetMesh) -> tuple[PoseTrack, np.ndarray]:
    """The scenario's frame plan and the indices of the frames to render."""
    request = scenario.plan_request()
    track = plan_track(request, mesh.center_m, mesh.bounding_radius_m)
    indices = frames_to_render(request, track)
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


def build_sensor(scenario: Scenario, camera: CameraConfig | None = None) -> SensorChain:
    """The scenario's camera optics and detector, ready to expose frames (the blur kernel
    designed for the render settings' sub-pixel sampling). camera: another mode of it (the
    far camera, ``CameraConfig.far_mode``); default the scenario's camera."""
    camera = scenario.camera if camera is None else camera
    return SensorChain(
        camera=camera.build(),
        optics=camera.build_optics(),
        detector=camera.build_detector(),
        band_nm=scenario.sun.band_nm,
        spectrum=scenario.sun.spectrum,
        exposure=camera.exposure.build(),
        camera_seed=camera.seed,
        supersampling=scenario.render.supersampling,
        samples_per_pixel=scenario.render.samples_per_pixel,
    )


def expose_frame(
    scenario: Scenario,
    sensor: SensorChain,
    track: PoseTrack,
    index: int,
    image: RadianceImage,
    center_cam_m: np.ndarray,
    exposure_s: float | None = None,
    R_cam_from_planned: np.ndarray | None = None,
    irradiance_w_m2: np.ndarray | None = None,
) -> tuple[DnImage, dict]:
    """Frame ``index`` through the optics and the detector, with the stars behind the target.

    Returns the DN image and the frame's sensor labels (exposure, saturation, stars), with
    the exposure of the target and of the Earth and the Moon behind it told apart
    (``sensor.regions``): the exposure rule serves the target, and a bright Earth behind it
    may saturate; the labels say by how much. exposure_s: the exposure decided before
    (from the still of a frame blurred over it); default the rule's on ``image``.
    R_cam_from_planned: a randomised camera roll, which turns the stars (default none).
    irradiance_w_m2: ``image``'s focal-plane irradiance when already computed (copied).
    """
    if irradiance_w_m2 is None:
        irradiance = sensor.focal_plane_irradiance_w_m2(image)
    else:
        irradiance = irradiance_w_m2.copy()
    mask = image.object_mask
    if exposure_s is None:
        exposure_s = sensor.exposure_time_s(irradiance, mask)
    # Each region as (its box, its mask in the box), or None: the same pixels in the same
    # order as the whole frame's, without a pass over the frame for each label (4096 x 4112:
    # 60 ms a frame).
    regions = {
        name: None if where is None else within_box(where)
        for name, where in exposure_regions(mask, image.background_id).items()
    }
    # The regions' levels before the stars are added to the focal plane.
    fills = {
        name: None if box is None else sensor.region_fill(irradiance[box[0]], exposure_s, box[1])
        for name, box in regions.items()
    }
    config, stars = scenario.stars, {"star_count": 0}
    if config.enabled and track.has_sky:
        stars = add_frame_stars(
            sensor, track, index, irradiance, mask, center_cam_m, exposure_s,
            config.v_mag_limit, config.earth_atmosphere_margin_km * 1e3, R_cam_from_planned,
        )  # fmt: skip
    dn_image = sensor.read_out(
        irradiance, exposure_s, sensor_noise_rng(scenario.seed, index), stars["star_count"]
    )
    labels = dn_image.labels()
    labels["regions"] = {
        name: {
            "pixel_count": 0 if box is None else int(np.count_nonzero(box[1])),
            "fill_fraction_p99": fills[name],
            "saturated_pixel_count": 0
            if box is None
            else int(np.count_nonzero(sensor.saturated(dn_image.dn[box[0]]) & box[1])),
        }
        for name, box in regions.items()
    }
    return dn_image, {"sensor": labels, **stars}


@dataclass(frozen=True)
class RenderedFrame:
    """One frame after the renderer: its numbers, pose, light and images."""

    frame_index: int
    plan_index: int
    cam_from_body: RigidTransform
    light: LightField
    image: RadianceImage
    camera_mode: str = "primary"
    motion: ExposureMotion | None = None  # None: a still, its exposure decided in finish
    still_irradiance_w_m2: np.ndarray | None = None  # the still's, when its image is the still
    draws: FrameDraws | None = None  # a randomised frame's draws
    poses: FramePoses | None = None  # and its poses
    scene: SceneMesh | None = None  # the target and objects at mid-exposure (None: none)


class FrameEngine:
    """What every frame of one scenario shares, built once per process and kept.

    The mesh, the frame plan, the sensor (optics kernel, detector, fixed pattern) and the
    renderer with its compiled kernels: a process that renders many frames of a scenario
    (one ``generate`` run, or one distributed worker) builds them once.
    """

    def __init__(
        self,
        scenario: Scenario,
        normals: bool | str | None = None,
        keeps_buffers: bool = True,
    ):
        """normals: render the normals image (``RadianceImage.normals_cam``): float32
        (True), float16 (``"half"``) or not at all (False); None: in float16 when the
        outputs write it (its file holds half floats), else not at all (a 4096 x 4112
        frame's normals are 0.1 GB in float16, 0.2 GB in float32). keeps_buffers: the
        frame-size check counts the memory of a process that keeps Dr.Jit's buffers between
        frames (the Python interface, a Dask worker, a render process); False for a local
        run, which hands them back when it must (``satsight.frame_memory``)."""
        camera = scenario.camera.build()
        # Before the mesh and the renderer.
        check_frame_memory(camera.width_px, camera.height_px, kept=keeps_buffers)
        self.scenario = scenario
        self.mesh = scenario.target.build(scenario.sun.band_nm)
        self.keypoints_body_m = target_keypoints_body_m(
            self.mesh, scenario.target.keypoints.build()
        )
        self.camera = camera
        self.track, self.plan_indices = planned_frames(scenario, self.mesh)
        band = scenario.sun.band_nm  # other objects, merged after the target's parts:
        self.objects = frame_scene(scenario, self.mesh, self.track, lambda c: c.build(band))
        self.scene = None if self.objects is None else self.objects.fixed
        self._moving = self.objects is not None and self.objects.moving
        self.sensor = build_sensor(scenario)
        # Camera modes: "primary", and "far" beyond camera.far.switch_range_km.
        self.modes: dict[str, tuple[PinholeCamera, SensorChain]] = {
            "primary": (self.camera, self.sensor)
        }
        far = scenario.camera.far_mode()
        if far is not None:
            self.modes["far"] = (far.build(), build_sensor(scenario, far))
        self._renderer: Renderer | None = None
        self.variation = FrameVariation.of(scenario, self.mesh)
        if normals is None:
            normals = "half" if "normals_exr" in scenario.outputs.file_keys() else False
        self.normals = normals
        # The light of the last few distinct inputs: the frames of an RSSF plan share the
        # target's state, so one light field (13 ms at 1024^2 with the Earth and the Moon)
        # serves them all (``satsight.frame_light``). A plain dict: the engine pickles.
        self._lights: dict[LightInputs, LightField] = {}

    def light(self, inputs: LightInputs) -> LightField:
        """The light of a frame's inputs, kept for the frames that share them (up to
        ``LIGHT_CACHE_SIZE`` inputs, the oldest dropped first)."""
        light = self._lights.get(inputs)
        if light is None:
            light = light_from_inputs(self.scenario, inputs)
            while len(self._lights) >= LIGHT_CACHE_SIZE:
                self._lights.pop(next(iter(self._lights)))
            self._lights[inputs] = light
        return light

    def camera_mode(self, plan_index: int) -> str:
        """The camera mode of plan frame ``plan_index``: ``far`` when its range to the
        target's box centre is beyond ``camera.far.switch_range_km``, else ``primary``."""
        far = self.scenario.camera.far
        if far is not None and self.track.range_m[plan_index] > far.switch_range_km * 1e3:
            return "far"
        return "primary"

    @property
    def frame_count(self) -> int:
        """Frames of the dataset (the plan's frames that pass the visibility rule)."""
        return len(self.plan_indices)

    @property
    def renderer(self) -> Renderer:
        if self._renderer is None:
            mesh = self.mesh if self.scene is None else self.scene.mesh
            self._renderer = Renderer(
                mesh, self.scenario.render.settings(), self.scenario.render.variant
            )
        return self._renderer

    def load_star_catalogue(self) -> None:
        """Load the catalogue now if frames need it, so that a missing one fails early."""
        if self.scenario.stars.enabled and self.track.has_sky:
            from satsight.sensor.star_catalog import load_star_catalog

            load_star_catalog(self.scenario.stars.v_mag_limit)

    def render(self, frame_index: int) -> RenderedFrame:
        """Render frame ``frame_index`` of the dataset (its seed from its plan index)."""
        plan_index = int(self.plan_indices[frame_index])
        mode = self.camera_mode(plan_index)
        camera, sensor = self.modes[mode]
        seed = frame_seed(self.scenario.seed, plan_index)
        variation, draws, scene = self.variation, None, self.scene
        # With flying objects each render builds its own renderer (below), else the kept one.
        renderer = None if self._moving else self.renderer
        if variation is not None:
            draws = variation.draw(plan_index)
            sensor = variation.sensor(sensor, draws)
            if renderer is not None:
                renderer = variation.renderer(renderer, draws)
        target = self.mesh
        if self._moving and variation is not None:  # objects on their own flight
            target = variation.varied_mesh(self.mesh, draws)
        scenes: dict[float, SceneMesh] = {}

        def light_at(track: PoseTrack, i: int) -> LightField:
            if variation is None:
                return self.light(frame_light_inputs(self.scenario, track, i))
            scenario = variation.light_scenario(draws)
            inputs = frame_light_inputs(
                scenario,
                track,
                i,
                variation.poses(track.cam_from_body(i), draws).light_cam_from_body,
                variation.sun_direction_cam(track.sun_from_target_cam[i], draws),
                variation.irradiance_scale(draws),
                variation.earth_direction_cam(draws),
            )
            return light_from_inputs(scenario, inputs)

        def render(
            pose: RigidTransform, light: LightField, seed: int, offset_s: float = 0.0
        ) -> RadianceImage:
            if variation is not None:  # the planned pose, rolled and jittered
                pose = variation.poses(pose, draws).cam_from_body
            used = renderer
            if self._moving:  # the objects at this instant, those that can show
                view = FrameView(camera, pose, light.sun_direction_body, sensor.margin_px)
                moved = self.objects.at(plan_index, offset_s, target, view)
                if offset_s == 0.0:
                    scenes[offset_s] = moved  # the frame's own, for its labels
                render_config = self.scenario.render
                used = Renderer(moved.mesh, render_config.settings(), render_config.variant)
            image = used.render(camera, pose, light, seed, sensor.margin_px, self.normals)
            if scene is None:
                return image
            return replace(image, target_part_count=scene.target_part_count)

        planned = self.track.cam_from_body(plan_index)
        light = light_at(self.track, plan_index)
        image = render(planned, light, seed)
        motion, irradiance = self.exposure_motion(plan_index, camera, sensor, image)
        if motion is not None and motion.sample_count > 1:
            irradiance = None
            image = render_over_exposure(
                render, light_at, self.track, plan_index, image, seed, motion
            )
        poses = None if variation is None else variation.poses(planned, draws)
        cam_from_body = planned if poses is None else poses.cam_from_body
        return RenderedFrame(
            frame_index, plan_index, cam_from_body, light, image, mode, motion, irradiance,
            draws, poses, scenes.get(0.0, scene),
        )  # fmt: skip

    def exposure_motion(
        self, plan_index: int, camera: PinholeCamera, sensor: SensorChain, still: RadianceImage
    ) -> tuple[ExposureMotion | None, np.ndarray | None]:
        """The motion of a frame over its exposure, decided on its still (``motion_blur``;
        ``satsight.render.motion``), or None when it cannot reach the threshold; and the
        still's focal-plane irradiance when the auto exposure needed it (None otherwise)."""
        mode = self.scenario.render.motion_blur
        corners = self.mesh.box_keypoints_body_m[:8]
        if self._moving:  # flying objects in view move over the exposure too
            view = FrameView(camera, self.track.cam_from_body(plan_index), np.zeros(3))
            objects = self.objects.moving_corners(plan_index, view)
            if objects is not None:
                target = corners
                corners = lambda tau: np.concatenate([target, objects(tau)])  # noqa: E731
        longest = sensor.longest_exposure_s
        probe = None
        if mode is not False:
            probe = exposure_motion(camera, self.track, plan_index, corners, longest, mode)
        if probe is None or (probe.sample_count == 1 and probe.path_px <= MOTION_THRESHOLD_PX):
            return None, None  # (the path grows with the exposure)
        exposure_s, irradiance = sensor.still_exposure(still)
        motion = exposure_motion(camera, self.track, plan_index, corners, exposure_s, mode)
        return motion, irradiance

    def finish(self, frame: RenderedFrame) -> tuple[dict, FrameArrays, tuple | None]:
        """Labels, optics and detector of a rendered frame.

        Returns the frame's label record (without its files), the arrays its files are
        made of, and the crop window (x0, y0, x1, y1), or None without a crop.
        """
        scenario, plan_index = self.scenario, frame.plan_index
        camera, sensor = self.modes[frame.camera_mode]
        variation, roll = self.variation, None
        if variation is not None:
            sensor = variation.sensor(sensor, frame.draws)
            roll = frame.poses.rolled_from_planned.R_a_from_b
        labels = frame_labels(
            self.mesh,
            camera,
            frame.cam_from_body,
            frame.light.sun,
            frame.image,
            self.keypoints_body_m,
        )
        sun_irradiance, sun_distance_m = self.sun_irradiance_at_camera(plan_index)
        if variation is not None:
            sun_irradiance *= variation.irradiance_scale(frame.draws)
        photometry = frame_photometry(
            frame.image,
            camera,
            sensor.channel_weights,
            labels["box_keypoints_px"][:8],
            sun_irradiance,
            sun_distance_m,
        )
        dn_image, sensor_labels = expose_frame(
            scenario,
            sensor,
            self.track,
            plan_index,
            frame.image,
            frame.cam_from_body.apply(self.mesh.center_m),
            None if frame.motion is None else frame.motion.exposure_s,
            roll,
            frame.still_irradiance_w_m2,
        )
        motion = frame.motion or exposure_motion(
            camera, self.track, plan_index, self.mesh.box_keypoints_body_m[:8],
            dn_image.exposure_time_s, False,
        )  # fmt: skip
        record: dict = {"frame_index": frame.frame_index, "plan_index": plan_index}
        if len(self.modes) > 1:
            record["camera_mode"] = frame.camera_mode
        if scenario.frames:
            record["view"] = scenario.frames[plan_index].model_dump(exclude_none=True)
        record["plan"] = self.track.record(plan_index)
        record["sun_direction_body"] = frame.light.sun_direction_body.tolist()
        record["environment_sh_radiance_w_m2_sr"] = frame.light.sh_radiance_w_m2_sr.tolist()
        record.update(labels)
        record.update(photometry)
        record.update(sensor_labels)
        record["exposure_motion"] = motion.labels()
        if variation is not None:
            record["randomized"] = variation.record(frame.draws, sensor, frame.poses)
        crop = scenario.outputs.crop
        box = None
        if crop is not None:
            center_px = labels["box_keypoints_px"][-1]
            box = crop_window_xyxy_px(center_px, crop.size_px, frame.image.shape)
            record["crop"] = crop_labels(labels, frame.image.object_mask, box)
        if self.scene is None:
            return record, FrameArrays(frame.image, dn_image), box
        object_id, amodal = self.objects.masks(
            frame.scene, frame.image.part_id, camera, frame.cam_from_body, frame.light, record
        )
        return record, FrameArrays(frame.image, dn_image, object_id, amodal), box

    def sun_irradiance_at_camera(self, plan_index: int) -> tuple[float, float]:
        """The Sun's in-band irradiance (W m^-2) at plan frame ``plan_index`` before the
        Earth's shadow, as ``frame_light`` lights it (the photometric labels' reference),
        and the Sun's distance (m)."""
        sun_distance_m = float(self.track.sun_distance_m[plan_index])
        return float(sun_irradiance_w_m2(self.scenario, self.track, plan_index)), sun_distance_m

    def file_keys(self) -> tuple[str, ...]:
        """The file keys of every frame: the outputs', and with objects in the scene the
        object-id and amodal masks beside the object mask."""
        keys = self.scenario.outputs.file_keys()
        if self.scene is not None and "object_mask_png" in keys:
            keys += OBJECT_FILE_KEYS
        return keys

    def header(self) -> dict:
        """The dataset's description: everything labels.json holds besides its frames."""
        from satsight.render.backend import use_variant

        scenario = self.scenario
        far = None
        if "far" in self.modes:
            far_camera, far_sensor = self.modes["far"]
            far = FarCamera(
                scenario.camera.far.preset,
                scenario.camera.far.switch_range_km * 1e3,
                far_camera,
                far_sensor,
            )
        render_variant = use_variant(scenario.render.variant)
        return labels_header(
            scenario_name=scenario.name,
            plan_indices=self.plan_indices,
            render_variant=render_variant,
            outputs=scenario.outputs.model_dump(mode="json"),
            file_keys=self.file_keys(),
            camera=self.camera,
            sensor=self.sensor,
            sun_spectrum=scenario.sun.spectrum,
            band_nm=scenario.sun.band_nm,
            render_settings=scenario.render.settings(),
            preview=scenario.outputs.build_preview(),
            target=TargetDescription(
                self.mesh,
                self.keypoints_body_m,
                scenario.target.keypoints.method,
                None if scenario.target.mesh is None else scenario.target.mesh.path,
            ),
            far=far,
        )
