"""The scenario file: what the user asks satsight to render.

A scenario is YAML validated by the pydantic models below. Non-SI units appear only here,
and always in the key's name (``distance_km``, ``azimuth_deg``, ``pixel_pitch_um``).
Unknown keys are errors, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from satsight.camera.pinhole import CAMERA_PRESETS, PinholeCamera
from satsight.errors import SatsightError
from satsight.poses.views import View, direction_from_angles
from satsight.render.buffers import SunLight
from satsight.scene.procedural import SATELLITE_CLASSES

# In-band (450-900 nm) solar irradiance at 1 AU from the ASTM E-490 air-mass-zero spectrum,
# W m^-2, taken as a constant (no spectrum is integrated).
DEFAULT_SUN_IRRADIANCE_W_M2 = 671.5


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CameraConfig(_Strict):
    """Camera: a preset, optionally with any of its values overridden."""

    preset: Literal["high_resolution", "wide_field"] = "high_resolution"
    focal_length_m: float | None = Field(default=None, gt=0)
    pixel_pitch_um: float | None = Field(default=None, gt=0)
    width_px: int | None = Field(default=None, ge=1, le=32768)
    height_px: int | None = Field(default=None, ge=1, le=32768)

    def build(self) -> PinholeCamera:
        base = CAMERA_PRESETS[self.preset]()
        return PinholeCamera(
            focal_length_m=self.focal_length_m or base.focal_length_m,
            pixel_pitch_m=(self.pixel_pitch_um * 1e-6)
            if self.pixel_pitch_um
            else base.pixel_pitch_m,
            width_px=self.width_px or base.width_px,
            height_px=self.height_px or base.height_px,
        )


class ProceduralTargetConfig(_Strict):
    satellite_class: str = "two_wings"
    seed: int = Field(default=0, ge=0)

    @model_validator(mode="after")
    def _known_class(self) -> ProceduralTargetConfig:
        if self.satellite_class not in SATELLITE_CLASSES:
            raise ValueError(
                f"unknown satellite_class '{self.satellite_class}'; "
                f"choose one of {', '.join(SATELLITE_CLASSES)}"
            )
        return self


class MeshTargetConfig(_Strict):
    path: Path
    scale_m: float = Field(default=1.0, gt=0, description="metres per file unit")


class TargetConfig(_Strict):
    """Exactly one of ``procedural`` or ``mesh``."""

    procedural: ProceduralTargetConfig | None = None
    mesh: MeshTargetConfig | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> TargetConfig:
        if (self.procedural is None) == (self.mesh is None):
            raise ValueError("give exactly one of 'procedural' or 'mesh'")
        return self


class SunConfig(_Strict):
    """Sun direction (from the target) in the body frame, and in-band irradiance."""

    azimuth_deg: float = 45.0
    elevation_deg: float = Field(default=30.0, ge=-90, le=90)
    irradiance_w_m2: float = Field(default=DEFAULT_SUN_IRRADIANCE_W_M2, gt=0)

    def build(self) -> SunLight:
        direction = direction_from_angles(
            math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        )
        return SunLight(direction, self.irradiance_w_m2)


class FrameConfig(_Strict):
    """One viewpoint: camera direction and distance from the target, in the body frame."""

    distance_km: float = Field(gt=0, le=1000)
    azimuth_deg: float = 0.0
    elevation_deg: float = Field(default=0.0, ge=-90, le=90)
    roll_deg: float = 0.0

    def build(self) -> View:
        return View(
            distance_m=self.distance_km * 1e3,
            azimuth_rad=math.radians(self.azimuth_deg),
            elevation_rad=math.radians(self.elevation_deg),
            roll_rad=math.radians(self.roll_deg),
        )


class RenderConfig(_Strict):
    supersampling: int = Field(default=1, ge=1, le=8)
    variant: Literal["auto", "llvm_ad_rgb", "cuda_ad_rgb"] = "auto"


class Scenario(_Strict):
    """A complete scenario: camera, target, sun, frames and render settings."""

    name: str = "scenario"
    seed: int = Field(default=0, ge=0)
    camera: CameraConfig = CameraConfig()
    target: TargetConfig
    sun: SunConfig = SunConfig()
    frames: list[FrameConfig] = Field(min_length=1)
    render: RenderConfig = RenderConfig()


def _format_validation_error(error: ValidationError, source: str) -> str:
    lines = [f"{source}: the scenario is not valid:"]
    for item in error.errors():
        where = ".".join(str(p) for p in item["loc"]) or "(top level)"
        message = item["msg"].removeprefix("Value error, ")
        if item["type"] == "extra_forbidden":
            message = "unknown key (check the spelling; see examples for valid keys)"
        elif item["type"] == "missing":
            message = "required key is missing"
        got = item.get("input")
        suffix = (
            ""
            if item["type"] in ("missing", "extra_forbidden") or isinstance(got, dict)
            else f" (got {got!r})"
        )
        lines.append(f"  - {where}: {message}{suffix}")
    return "\n".join(lines)


def parse_scenario(data: object, source: str = "scenario") -> Scenario:
    """Validate a parsed YAML/JSON object as a Scenario, with messages naming bad keys."""
    if not isinstance(data, dict):
        raise SatsightError(f"{source}: expected a mapping of keys at the top level")
    try:
        return Scenario.model_validate(data)
    except ValidationError as error:
        raise SatsightError(_format_validation_error(error, source)) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file. Mesh paths are resolved against its folder."""
    path = Path(path)
    if not path.is_file():
        raise SatsightError(f"scenario file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as error:
        raise SatsightError(f"{path}: not valid YAML: {error}") from None
    except UnicodeDecodeError:
        raise SatsightError(f"{path}: not a UTF-8 text file; save it as UTF-8 YAML") from None
    scenario = parse_scenario(data, str(path))
    mesh = scenario.target.mesh
    if mesh is not None and not mesh.path.is_absolute():
        resolved = (path.parent / mesh.path).resolve()
        scenario = scenario.model_copy(
            update={"target": TargetConfig(mesh=mesh.model_copy(update={"path": resolved}))}
        )
    return scenario
