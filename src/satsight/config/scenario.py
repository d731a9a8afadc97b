"""The scenario file: what the user asks satsight to render.

A scenario is YAML validated by the pydantic models below and by those of its sections
(``config.camera``, ``config.lighting``, ``config.orbital``, ``config.sensor``,
``config.target``, ``config.outputs``). Non-SI units appear only in config, and always in
the key's name (``distance_km``, ``azimuth_deg``, ``pixel_pitch_um``). Unknown keys are
errors, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    field_validator,
    model_serializer,
    model_validator,
)

from satsight.config.camera import CameraConfig
from satsight.config.lighting import EarthConfig, MoonConfig, SunConfig
from satsight.config.objects import ObjectConfig, unique_object_names
from satsight.config.orbital import (
    ABSOLUTE_TRAJECTORY_MODES,
    TRAJECTORY_KEYS,
    AttitudeConfig,
    ObserverConfig,
    OemConfig,
    OmmConfig,
    OrbitConfig,
    PropagationConfig,
    SamplerConfig,
    TleConfig,
    TrajectoryConfig,
    VisibilityConfig,
)
from satsight.config.outputs import OutputsConfig
from satsight.config.plan_request import check_sspt_size, orbital_plan_request
from satsight.config.randomize import RandomizeConfig
from satsight.config.sensor import StarsConfig
from satsight.config.target import (  # noqa: F401 (re-exported: the scenario's sections)
    KeypointsConfig,
    MeshTargetConfig,
    ProceduralTargetConfig,
    TargetConfig,
)
from satsight.config.validation_errors import format_validation_error
from satsight.config.yaml_safety import load_yaml_file
from satsight.constants import AU_M
from satsight.ephemeris.time import parse_epoch_utc
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.poses.plan_request import PlanRequest, ViewsPlanRequest
from satsight.poses.views import View
from satsight.render.settings import (
    BRDF_MODELS,
    ENVIRONMENT_MODES,
    GGX_MASKINGS,
    SH_ORDER_RANGE,
    SUN_REPRESENTATIONS,
    TEXTURE_FILTERS,
    RenderSettings,
)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


#: How far from 1 a given q_cam_from_body's norm may be (it is then normalised).
QUATERNION_NORM_TOLERANCE = 1e-6


class FrameConfig(_Strict):
    """One viewpoint, in either of two forms.

    A view: camera direction (azimuth, elevation) and distance from the target's
    bounding-box centre in the body frame, and a roll about the boresight; the camera
    looks at the box centre. Or a pose: ``q_cam_from_body`` (scalar-first, unit to 1e-6)
    and ``t_cam_from_body_m`` with x_cam = R(q) x_body + t (OpenCV camera axes), for poses
    from another tool.
    """

    distance_km: float | None = Field(default=None, gt=0, le=1000)
    azimuth_deg: float = 0.0
    elevation_deg: float = Field(default=0.0, ge=-90, le=90)
    roll_deg: float = 0.0
    q_cam_from_body: tuple[float, float, float, float] | None = None
    t_cam_from_body_m: tuple[float, float, float] | None = None

    @model_validator(mode="after")
    def _one_form(self) -> FrameConfig:
        pose = (self.q_cam_from_body is not None, self.t_cam_from_body_m is not None)
        if pose[0] != pose[1]:
            raise ValueError("a pose needs both q_cam_from_body and t_cam_from_body_m")
        if pose[0]:
            if (
                self.distance_km is not None
                or self.azimuth_deg
                or self.elevation_deg
                or (self.roll_deg)
            ):
                raise ValueError(
                    "give a view (distance_km, azimuth_deg, elevation_deg, roll_deg) or a "
                    "pose (q_cam_from_body, t_cam_from_body_m), not both"
                )
            norm = math.sqrt(sum(v * v for v in self.q_cam_from_body))
            if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
                raise ValueError(
                    f"q_cam_from_body must be a unit quaternion [qw, qx, qy, qz], its norm is "
                    f"{norm:.9g}"
                )
            if not all(math.isfinite(v) for v in self.t_cam_from_body_m):
                raise ValueError("t_cam_from_body_m must be finite")
            if self.t_cam_from_body_m[2] <= 0:
                raise ValueError(
                    "t_cam_from_body_m puts the body origin at or behind the camera (z <= 0); "
                    "the camera frame is OpenCV's, +z along the boresight"
                )
        elif self.distance_km is None:
            raise ValueError(
                "a frame needs distance_km (a view) or q_cam_from_body and t_cam_from_body_m "
                "(a pose)"
            )
        return self

    def build(self) -> View:
        """The view (a frame given as a view only)."""
        return View(
            distance_m=self.distance_km * 1e3,
            azimuth_rad=math.radians(self.azimuth_deg),
            elevation_rad=math.radians(self.elevation_deg),
            roll_rad=math.radians(self.roll_deg),
        )

    def placement(self) -> View | RigidTransform:
        """The frame for the plan: its view, or its pose x_cam = R x_body + t."""
        if self.q_cam_from_body is not None:
            return RigidTransform.from_quaternion(
                np.array(self.q_cam_from_body), np.array(self.t_cam_from_body_m)
            )
        return self.build()

    def cam_from_body(self, target_center_body_m: np.ndarray) -> RigidTransform:
        """The camera pose of this frame (a view looks at ``target_center_body_m``)."""
        placement = self.placement()
        if isinstance(placement, RigidTransform):
            return placement
        return placement.cam_from_body(target_center_body_m)


class RenderConfig(_Strict):
    """How frames are rendered; see ``satsight.render.settings.RenderSettings``."""

    brdf: Literal[BRDF_MODELS] = "ggx"
    ggx_masking: Literal[GGX_MASKINGS] = "schlick"
    sh_order: int = Field(default=4, ge=SH_ORDER_RANGE[0], le=SH_ORDER_RANGE[1])
    sun_model: Literal[SUN_REPRESENTATIONS] = "delta"
    environment: Literal[ENVIRONMENT_MODES] = "sampled"
    bounces: int = Field(default=2, ge=0, le=16)
    samples_per_pixel: int = Field(default=1, ge=1, le=4096)
    supersampling: int = Field(default=1, ge=1, le=8)
    indirect_min_roughness: float = Field(default=0.2, ge=0.0, le=1.0)
    integrate_footprint: bool = True
    texture_filter: Literal[TEXTURE_FILTERS] = "mip"
    sunlit_sampling: bool = True
    light_samples: int = Field(default=2, ge=1, le=64)
    variant: Literal["auto", "llvm_ad_rgb", "cuda_ad_rgb"] = "auto"
    # Motion during the exposure (``satsight.frame_motion``): "auto" renders time samples
    # over the exposure when the target's box corners move more than 0.1 px across it.
    motion_blur: Literal["auto"] | bool = "auto"

    def settings(self) -> RenderSettings:
        return RenderSettings(
            brdf=self.brdf,
            ggx_masking=self.ggx_masking,
            sh_order=self.sh_order,
            sun=self.sun_model,
            environment=self.environment,
            bounces=self.bounces,
            samples_per_pixel=self.samples_per_pixel,
            supersampling=self.supersampling,
            indirect_min_roughness=self.indirect_min_roughness,
            integrate_footprint=self.integrate_footprint,
            texture_filter=self.texture_filter,
            sunlit_sampling=self.sunlit_sampling,
            light_samples=self.light_samples,
        )


# Keys that place a body by hand; with frames planned from orbits they come from the
# ephemeris and the orbit instead.
_HAND_PLACED = {
    "sun": ("azimuth_deg", "elevation_deg", "distance_au"),
    "earth": ("azimuth_deg", "elevation_deg", "altitude_km"),
    "moon": ("azimuth_deg", "elevation_deg", "distance_km"),
}
_ORBITAL_KEYS = (
    "epoch_utc",
    "orbit",
    "tle",
    "omm",
    "oem",
    "attitude",
    "observer",
    "visibility",
    "propagation",
    "stars",
)


def _differs_from_default(model: BaseModel, key: str) -> bool:
    """Whether a key holds something other than its default (by value, so that a complete
    copy of a scenario, defaults written out, reads back the same)."""
    field = type(model).model_fields[key]
    default = field.get_default(call_default_factory=True)
    return getattr(model, key) != default


class Scenario(_Strict):
    """A complete scenario: camera, target, light, frames and render settings.

    Frames come either from ``frames`` (viewpoints given in the target's body frame, with the
    Sun, the Earth and the Moon placed by hand) or from ``sampler`` (frames planned from
    orbits: ``epoch_utc``, the target's ``orbit`` and ``attitude``, the ``observer``'s mode
    for SSPT, ``visibility`` limits; the Sun and the Moon come from the ephemeris).

    The target's trajectory is exactly one of ``orbit`` (osculating elements, propagated),
    ``tle`` or ``omm`` (SGP4 mean elements) or ``oem`` (an ephemeris file). With ``tle`` or
    ``omm``, ``epoch_utc`` may be left out: it is then the element epoch; with ``oem``, the
    file's first useable time.
    """

    name: str = "scenario"
    seed: int = Field(default=0, ge=0)
    camera: CameraConfig = CameraConfig()
    target: TargetConfig
    sun: SunConfig = SunConfig()
    earth: EarthConfig | None = None
    moon: MoonConfig | None = None
    frames: list[FrameConfig] = Field(default_factory=list)
    epoch_utc: str | None = None
    orbit: OrbitConfig | None = None
    tle: TleConfig | None = None
    omm: OmmConfig | None = None
    oem: OemConfig | None = None
    attitude: AttitudeConfig = AttitudeConfig()
    observer: ObserverConfig | None = None
    sampler: SamplerConfig | None = None
    visibility: VisibilityConfig = VisibilityConfig()
    propagation: PropagationConfig = PropagationConfig()
    render: RenderConfig = RenderConfig()
    stars: StarsConfig = StarsConfig()
    outputs: OutputsConfig = OutputsConfig()
    randomize: RandomizeConfig = RandomizeConfig()
    objects: list[ObjectConfig] = Field(default_factory=list)

    @field_validator("objects")
    @classmethod
    def _object_names(cls, value: list[ObjectConfig]) -> list[ObjectConfig]:
        return unique_object_names(value)

    @model_validator(mode="after")
    def _flights_need_orbits(self) -> Scenario:
        flying = [o.name for o in self.objects if o.flight is not None]
        if flying and self.sampler is None:
            raise ValueError(
                f"objects {flying} fly on their own, which needs frames planned from orbits "
                "(epoch_utc, the target's orbit and a sampler); with frames placed by hand, "
                "place objects by offset_m and q_target_from_object"
            )
        return self

    @model_serializer(mode="wrap")
    def _without_empty_objects(self, handler: SerializerFunctionWrapHandler) -> dict:
        # A scenario without objects dumps (and hashes) as it did before they existed.
        data = handler(self)
        if not self.objects and isinstance(data, dict):
            data.pop("objects", None)
        return data

    @model_validator(mode="after")
    def _crop_fits(self) -> Scenario:
        crop = self.outputs.crop
        if crop is not None:
            camera = self.camera.build()
            if crop.size_px > min(camera.width_px, camera.height_px):
                raise ValueError(
                    f"outputs.crop.size_px ({crop.size_px}) exceeds the image "
                    f"({camera.width_px} x {camera.height_px} px); choose a smaller crop"
                )
        return self

    @model_validator(mode="before")
    @classmethod
    def _epoch_from_trajectory(cls, data: object) -> object:
        """Without epoch_utc, a TLE/OMM target starts at its element epoch and an OEM target
        at its first useable time."""
        if not isinstance(data, dict) or data.get("epoch_utc") is not None:
            return data
        given = [k for k in ("tle", "omm", "oem") if data.get(k) is not None]
        if len(given) != 1 or data.get("orbit") is not None:
            return data  # the errors are reported by the validators below
        config_class = {"tle": TleConfig, "omm": OmmConfig, "oem": OemConfig}[given[0]]
        try:
            config = config_class.model_validate(data[given[0]])
            epoch = config.default_epoch_utc()
        except (ValidationError, SatsightError):
            return data  # reported, with the key's location, by the field validation
        return {**data, "epoch_utc": epoch}

    def plan_request(self) -> PlanRequest:
        """What the frame plan (``satsight.poses.plan.plan_track``) is asked for: typed, SI."""
        if self.sampler is None:
            return ViewsPlanRequest(
                frames=tuple(frame.placement() for frame in self.frames),
                sun_direction_body=self.sun.build().direction_body,
                sun_distance_m=self.sun.distance_au * AU_M,
                earth_center_from_target_m=None
                if self.earth is None
                else self.earth.center_from_target_m(),
                moon_center_from_target_m=None
                if self.moon is None
                else self.moon.center_from_target_m(),
            )
        return orbital_plan_request(
            self.epoch_utc,
            self.trajectory,
            self.attitude,
            self.sampler,
            self.observer,
            self.visibility,
            self.propagation,
        )

    @property
    def trajectory(self) -> TrajectoryConfig | None:
        """The target's trajectory: whichever of orbit, tle, omm or oem is given."""
        for key in TRAJECTORY_KEYS:
            value = getattr(self, key)
            if value is not None:
                return value
        return None

    @field_validator("epoch_utc")
    @classmethod
    def _valid_epoch(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                parse_epoch_utc(value)
            except SatsightError as error:
                raise ValueError(str(error)) from None
        return value

    @model_validator(mode="after")
    def _one_source_of_frames(self) -> Scenario:
        if self.frames and self.sampler is not None:
            raise ValueError(
                "give either 'frames' (views in the body frame) or 'sampler' (frames planned "
                "from orbits), not both"
            )
        if not self.frames and self.sampler is None:
            raise ValueError(
                "no frames: give a list of 'frames', or a 'sampler' (sspt or rssf) with "
                "'epoch_utc' and 'orbit'"
            )
        if self.sampler is None:
            unused = [key for key in _ORBITAL_KEYS if _differs_from_default(self, key)]
            if unused:
                raise ValueError(
                    f"{', '.join(unused)} only apply to frames planned from orbits; add a "
                    "'sampler' or remove them"
                )
            return self
        given = [key for key in TRAJECTORY_KEYS if getattr(self, key) is not None]
        if len(given) > 1:
            raise ValueError(
                f"give the target's trajectory once: {', '.join(given)} are all given; keep one "
                "of orbit (elements), tle, omm or oem"
            )
        _load_trajectories(self)  # a bad file is reported before what it would have given
        missing = [key for key in ("epoch_utc",) if getattr(self, key) is None]
        if not given:
            missing.append("orbit (or tle, omm, oem)")
        if missing:
            raise ValueError(
                f"a sampler plans frames from orbits and needs {' and '.join(missing)}"
            )
        if self.sampler.kind == "sspt" and self.observer is None:
            raise ValueError(
                "sampler sspt follows the observer's trajectory: add an 'observer' with a mode "
                "(fly_around, fly_by, approach, hover, elements or relative_rtn)"
            )
        if self.sampler.kind == "rssf" and self.observer is not None:
            raise ValueError("sampler rssf places the camera itself; remove 'observer'")
        if self.sampler.kind == "sspt" and self.sampler.step_deg is not None:
            if self.observer.mode != "fly_around":
                raise ValueError("sampler step_deg applies only to observer mode fly_around")
        if self.sampler.kind == "sspt":
            check_sspt_size(self.trajectory, self.observer, self.sampler)
        for section, keys in _HAND_PLACED.items():
            config = getattr(self, section)
            placed = [] if config is None else [k for k in keys if _differs_from_default(config, k)]
            if placed:
                raise ValueError(
                    f"{section}.{', '.join(placed)}: with frames planned from orbits the "
                    f"{section}'s place comes from the ephemeris and the orbit; remove them"
                )
        return self


def _load_trajectories(scenario: Scenario) -> None:
    """Read the target's and the observer's element sets or ephemeris files now, so that a
    bad file is reported when the scenario is read."""
    sources = [] if scenario.trajectory is None else [scenario.trajectory]
    if scenario.observer is not None and scenario.observer.mode in ABSOLUTE_TRAJECTORY_MODES:
        sources.append(scenario.observer)
    for source in sources:
        if isinstance(source, OrbitConfig):
            continue
        try:
            source.load()
        except SatsightError as error:
            raise ValueError(str(error)) from None


def _resolve_trajectory_files(data: object, folder: Path) -> object:
    """The scenario mapping with relative ``file`` paths of tle, omm, oem and of an observer
    in mode tle, omm or oem made relative to the scenario's folder."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for key in ("tle", "omm", "oem", "observer"):
        section = out.get(key)
        if not isinstance(section, dict) or not isinstance(section.get("file"), str):
            continue
        if key == "observer" and section.get("mode") not in ABSOLUTE_TRAJECTORY_MODES:
            continue
        file = Path(section["file"]).expanduser()
        if not file.is_absolute():
            out[key] = {**section, "file": str((folder / file).resolve())}
    return out


def parse_scenario(data: object, source: str = "scenario") -> Scenario:
    """Validate a parsed YAML/JSON object as a Scenario, with messages naming bad keys."""
    if not isinstance(data, dict):
        raise SatsightError(f"{source}: expected a mapping of keys at the top level")
    try:
        return Scenario.model_validate(data)
    except ValidationError as error:
        raise SatsightError(format_validation_error(error, source)) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file. Mesh and keypoint file paths, and the files
    of ``tle``, ``omm``
    and ``oem`` (target or observer), are resolved against its folder.

    The file is read within the limits of ``satsight.config.yaml_safety`` (size, nesting,
    aliases; no repeated keys).
    """
    path = Path(path)
    data = _resolve_trajectory_files(load_yaml_file(path), path.parent)
    scenario = parse_scenario(data, str(path))
    target = scenario.target.with_paths_from(path.parent)
    if target is not scenario.target:
        scenario = scenario.model_copy(update={"target": target})
    objects = [o.with_paths_from(path.parent) for o in scenario.objects]
    if any(a is not b for a, b in zip(objects, scenario.objects, strict=True)):
        scenario = scenario.model_copy(update={"objects": objects})
    return scenario
