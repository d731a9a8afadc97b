"""The scenario's ``objects``: other things beside the target (a second spacecraft, a mesh,
a cloud of debris), placed fixed in the target's body frame (``satsight.scene.objects``).

Placement, one of two:

- fixed in the target's body frame: ``offset_m`` (the object's origin, metres) and
  ``q_target_from_object`` (scalar-first), so the object moves with the target on every
  frame plan. A debris cloud is placed by its shell about the target's box centre (its
  offset and rotation then move the whole cloud).
- ``flight:``, its own flight (frames planned from orbits only): its own ``orbit``
  (osculating elements at the epoch) or a start relative to the target in RTN
  (``position_rtn_m``, ``velocity_rtn_m_s``), and an ``attitude`` law of its own (the
  target's form); ``satsight.poses.object_flight``. A flying debris cloud's shell is about
  its own origin.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from satsight.config.orbital import AttitudeConfig, OrbitConfig
from satsight.config.target import MeshTargetConfig, ProceduralTargetConfig, TargetConfig
from satsight.frames.rigid import RigidTransform
from satsight.poses.object_flight import ObjectFlight
from satsight.scene.band_reflectance import library_materials
from satsight.scene.mesh import TargetMesh
from satsight.scene.objects import DEBRIS_MATERIALS, debris_cloud


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DebrisConfig(_Strict):
    """``count`` fragments with characteristic lengths in ``size_m`` [min, max] (NASA
    breakup model power law, ``satsight.scene.objects``), centres uniform in volume in the
    shell ``shell_m`` [r_min, r_max] about the target's box centre; ``seed`` draws them."""

    count: int = Field(ge=1, le=2000)
    size_m: tuple[float, float] = (0.05, 0.5)
    shell_m: tuple[float, float] = (5.0, 20.0)
    seed: int = Field(default=0, ge=0)

    @model_validator(mode="after")
    def _ordered(self) -> DebrisConfig:
        if not (0 < self.size_m[0] <= self.size_m[1]):
            raise ValueError(f"size_m must satisfy 0 < min <= max, got {list(self.size_m)}")
        if not (0 <= self.shell_m[0] <= self.shell_m[1]):
            raise ValueError(f"shell_m must satisfy 0 <= r_min <= r_max, got {list(self.shell_m)}")
        return self


class FlightConfig(_Strict):
    """An object's own flight: exactly one of ``orbit`` (its osculating elements at the
    epoch) or ``position_rtn_m`` (with ``velocity_rtn_m_s``: its state relative to the
    target's body origin in the target's RTN frame at the epoch), and its ``attitude``
    (default LVLH-fixed about its own orbit)."""

    orbit: OrbitConfig | None = None
    position_rtn_m: tuple[float, float, float] | None = None
    velocity_rtn_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    attitude: AttitudeConfig = AttitudeConfig()

    @model_validator(mode="after")
    def _one_start(self) -> FlightConfig:
        if (self.orbit is None) == (self.position_rtn_m is None):
            raise ValueError("a flight starts from exactly one of 'orbit' or 'position_rtn_m'")
        if self.orbit is not None and any(self.velocity_rtn_m_s):
            raise ValueError("velocity_rtn_m_s goes with position_rtn_m, not with 'orbit'")
        values = [*(self.position_rtn_m or ()), *self.velocity_rtn_m_s]
        if not all(np.isfinite(values)):
            raise ValueError("position_rtn_m and velocity_rtn_m_s must be finite")
        return self

    def build(self) -> ObjectFlight:
        if self.orbit is not None:
            return ObjectFlight(self.orbit.build(), None, None, self.attitude.build())
        return ObjectFlight(
            None,
            np.asarray(self.position_rtn_m, dtype=np.float64),
            np.asarray(self.velocity_rtn_m_s, dtype=np.float64),
            self.attitude.build(),
        )


class ObjectConfig(_Strict):
    """One object: a ``name``, exactly one of ``procedural``, ``mesh`` or ``debris``, and its
    placement: fixed in the target's body frame or its own ``flight`` (module docstring)."""

    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    procedural: ProceduralTargetConfig | None = None
    mesh: MeshTargetConfig | None = None
    debris: DebrisConfig | None = None
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    q_target_from_object: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    flight: FlightConfig | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> ObjectConfig:
        given = [k for k in ("procedural", "mesh", "debris") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                f"object '{self.name}': give exactly one of 'procedural', 'mesh' or 'debris'"
            )
        fixed = any(self.offset_m) or tuple(self.q_target_from_object) != (1.0, 0.0, 0.0, 0.0)
        if self.flight is not None and fixed:
            raise ValueError(
                f"object '{self.name}': a 'flight' places the object; leave out offset_m and "
                "q_target_from_object"
            )
        return self

    @field_validator("q_target_from_object")
    @classmethod
    def _unit(cls, value: tuple[float, float, float, float]) -> tuple:
        norm = float(np.linalg.norm(value))
        if not np.isfinite(norm) or abs(norm - 1.0) > 1e-6:
            raise ValueError(f"q_target_from_object must be a unit quaternion, |q| = {norm}")
        return value

    def target_from_object(self) -> RigidTransform:
        """The object's pose in the target's body frame (fixed placement; the identity for
        a flying object, whose frame is then its own)."""
        return RigidTransform.from_quaternion(
            np.array(self.q_target_from_object), np.array(self.offset_m)
        )

    def shape(self) -> TargetConfig | None:
        """The object's shape as a target section (procedural or mesh); None for debris."""
        if self.debris is not None:
            return None
        return TargetConfig(procedural=self.procedural, mesh=self.mesh)

    def with_paths_from(self, folder: Path) -> ObjectConfig:
        """This object with a relative mesh path taken from ``folder``."""
        if self.mesh is None or self.mesh.path.is_absolute():
            return self
        mesh = self.mesh.model_copy(update={"path": (folder / self.mesh.path).resolve()})
        return self.model_copy(update={"mesh": mesh})


def unique_object_names(objects: list[ObjectConfig]) -> list[ObjectConfig]:
    """The objects, checked for unique names other than ``target`` (object id 1)."""
    names = [o.name for o in objects]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated or "target" in names:
        raise ValueError(
            f"object names must be unique and not 'target'; repeated: {repeated or ['target']}"
        )
    return objects


def placed_objects(
    objects: list[ObjectConfig],
    target: TargetMesh,
    band_nm: tuple[float, float],
    build_shape: Callable[[TargetConfig], TargetMesh],
) -> list[tuple[str, TargetMesh, RigidTransform]]:
    """Each object as (name, mesh in its own frame, target_from_object) for
    ``satsight.scene.objects.merge_scene``; a flying object's pose is the identity here
    (``satsight.frame_scene`` places it at each frame).

    build_shape: makes a procedural or mesh object as the target is made
    (``TargetConfig.build``); debris takes the library materials of
    ``band_nm``.
    """
    placed = []
    for item in objects:
        shape = item.shape()
        if shape is not None:
            mesh = build_shape(shape)
        else:
            d = item.debris
            pool = library_materials(DEBRIS_MATERIALS, band_nm)
            center = target.center_m if item.flight is None else np.zeros(3)
            mesh = debris_cloud(item.name, d.count, d.size_m, d.shell_m, center, pool, d.seed).mesh
        placed.append((item.name, mesh, item.target_from_object()))
    return placed
