"""One frame's domain randomisation in the pipeline: the scenario's ``randomize`` ranges,
each frame's draws (``satsight.randomization``) and what they change.

``FrameVariation`` is built once per scenario (None when nothing varies) and gives, for a
frame: the varied scenario sections (Sun, Earth), the poses (the light follows the
target's jitter; the render also takes the camera's roll), the renderer of the varied
materials (a new ``Renderer`` shares the compiled kernels: ~0.1 s), the varied sensor
chain, and the record written under the frame's ``randomized`` label.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from satsight.config.scenario import Scenario
from satsight.frames.rigid import RigidTransform
from satsight.randomization.apply import (
    attitude_jitter_transform,
    earth_behind_direction,
    jittered_direction,
    material_record,
    pose_record,
    roll_transform,
    sensor_record,
    swapped_name,
    varied_material,
    varied_sensor,
)
from satsight.randomization.draws import (
    EarthDraw,
    FrameDraws,
    MaterialDraw,
    draw_frame,
    draw_record,
)
from satsight.randomization.ranges import RandomizationRanges
from satsight.render.renderer import Renderer
from satsight.scene.band_reflectance import BandMaterials, builtins_from_library
from satsight.scene.material_families import swap_candidates
from satsight.scene.material_library import LIBRARY_PREFIX
from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh
from satsight.scene.procedural_textures import reseedable_parts, reseeded
from satsight.sensor.chain import SensorChain


@dataclass(frozen=True)
class FramePoses:
    """light_cam_from_body: the target's pose in the planned camera frame, turned by its
    attitude jitter (what the light in the body frame is made from). cam_from_body: that
    pose seen by the rolled camera (what is rendered and labelled). rolled_from_planned:
    the camera's roll (planned camera frame -> rolled camera frame)."""

    light_cam_from_body: RigidTransform
    cam_from_body: RigidTransform
    rolled_from_planned: RigidTransform


class FrameVariation:
    """The randomisation of one scenario's frames (module docstring)."""

    def __init__(self, scenario: Scenario, mesh: TargetMesh, ranges: RandomizationRanges):
        self.scenario = scenario
        self.mesh = mesh
        self.ranges = ranges
        self._hand_placed = scenario.sampler is None
        self._materials = sorted(set(mesh.part_materials))
        self._band_materials: BandMaterials | None = None

    @classmethod
    def of(cls, scenario: Scenario, mesh: TargetMesh) -> FrameVariation | None:
        ranges = scenario.randomize.build()
        return None if ranges is None else cls(scenario, mesh, ranges)

    def draw(self, plan_index: int) -> FrameDraws:
        return draw_frame(
            self.ranges, self.scenario.seed, plan_index, self._materials, self._hand_placed
        )

    # --- lighting -------------------------------------------------------------------------
    def light_scenario(self, draws: FrameDraws) -> Scenario:
        """The scenario with the frame's Earth (its surface, cloud pattern and cover, and a
        uniform Earth's albedo) in place of the scenario's."""
        earth = self.scenario.earth
        if draws.earth is None or earth is None:
            return self.scenario
        d = draws.earth
        albedo = earth.albedo
        scaled = (
            min(1.0, albedo * d.albedo_scale)
            if isinstance(albedo, float | int)
            else tuple(min(1.0, a * d.albedo_scale) for a in albedo)
        )
        update = {
            "albedo": scaled,
            "surface": d.surface,
            "cloud_seed": earth.cloud_seed + d.cloud_pattern,
        }
        if d.cloud_fraction is not None:
            update["cloud_fraction"] = d.cloud_fraction
        varied = earth.model_copy(update=update)
        return self.scenario.model_copy(update={"earth": varied})

    def earth_direction_cam(self, draws: FrameDraws | None) -> np.ndarray | None:
        """The Earth's direction from the target in the plan's camera frame where the
        frame moves it behind the target (hand-placed views), else None (the plan's)."""
        if draws is None or draws.earth is None or not self._earth_behind(draws.earth):
            return None
        return self._behind(draws.earth)[0]

    def _earth_behind(self, draw: EarthDraw) -> bool:
        """Whether the frame's Earth is moved behind the target (hand-placed views)."""
        return draw.behind and self._hand_placed and self.scenario.earth is not None

    def _behind(self, draw: EarthDraw) -> tuple[np.ndarray, float]:
        """(unit Earth direction in the camera frame, its angle off the line of sight +z)."""
        altitude_m = self.scenario.earth.altitude_km * 1e3
        return earth_behind_direction(np.array([0.0, 0.0, 1.0]), altitude_m, draw)

    @staticmethod
    def irradiance_scale(draws: FrameDraws | None) -> float:
        return 1.0 if draws is None or draws.sun is None else draws.sun.irradiance_scale

    @staticmethod
    def sun_direction_cam(direction_cam: np.ndarray, draws: FrameDraws | None) -> np.ndarray:
        """The Sun's direction (planned camera frame) turned by the frame's jitter."""
        if draws is None or draws.sun is None:
            return np.asarray(direction_cam, dtype=np.float64)
        return jittered_direction(direction_cam, draws.sun)

    # --- pose -----------------------------------------------------------------------------
    def poses(self, planned: RigidTransform, draws: FrameDraws | None) -> FramePoses:
        """The frame's poses from the planned cam_from_body (``FramePoses``)."""
        identity = RigidTransform.identity()
        if draws is None or draws.pose is None:
            return FramePoses(planned, planned, identity)
        jittered = planned @ attitude_jitter_transform(draws.pose, self.mesh.center_m)
        roll = roll_transform(draws.pose)
        return FramePoses(jittered, roll @ jittered, roll)

    # --- materials and sensor ---------------------------------------------------------------
    def renderer(self, base: Renderer, draws: FrameDraws | None) -> Renderer:
        """A renderer of the frame's materials, or ``base`` when materials do not vary.
        The renderer's own mesh is varied (with ``objects``, the target merged with them:
        the target's materials vary, the objects' keep theirs unless they share one)."""
        if draws is None or draws.materials is None:
            return base
        return Renderer(self.varied_mesh(base.mesh, draws), base.settings, base.variant)

    def varied_mesh(self, base: TargetMesh, draws: FrameDraws | None) -> TargetMesh:
        """``base`` (the target, or the target merged with objects after it) with the
        frame's materials and reseeded textures."""
        if draws is None or draws.materials is None:
            return base
        materials = dict(base.materials)
        for name, draw in draws.materials.items():
            materials[name] = varied_material(self.material(name, draw), draw)
        mesh = dataclasses.replace(base, materials=materials)
        if draws.texture_seed is not None:  # the target's parts come first in a scene
            mesh = reseeded(mesh, draws.texture_seed, reseedable_parts(self.mesh))
        return mesh

    def material(self, name: str, draw: MaterialDraw) -> Material:
        """The target's material ``name``, or the library material of its family that the
        draw swaps it for (made for the scenario's band, named as the part knows it)."""
        swapped = swapped_name(swap_candidates(name), draw)
        if swapped is None:
            return self.mesh.materials[name]
        if self._band_materials is None:
            self._band_materials = builtins_from_library(self.scenario.sun.band_nm)
        chosen = self._band_materials[LIBRARY_PREFIX + swapped]
        return dataclasses.replace(chosen, name=name)

    @staticmethod
    def sensor(base: SensorChain, draws: FrameDraws | None) -> SensorChain:
        if draws is None or draws.sensor is None:
            return base
        return varied_sensor(base, draws.sensor)

    # --- labels -----------------------------------------------------------------------------
    def record(self, draws: FrameDraws, sensor: SensorChain, poses: FramePoses) -> dict:
        """The frame's ``randomized`` label: one entry per varying group, SI values."""
        out: dict = {}
        if draws.materials is not None:
            out["materials"] = {
                name: material_record(
                    varied_material(self.material(name, d), d),
                    d,
                    swapped_name(swap_candidates(name), d),
                )
                for name, d in draws.materials.items()
            }
        if draws.texture_seed is not None:
            names = self.mesh.part_names
            out["textures"] = {"reseeded_parts": [names[k] for k in reseedable_parts(self.mesh)]}
        if draws.sun is not None:
            out["sun"] = draw_record(draws.sun)
        if draws.earth is not None:
            d = draws.earth
            behind = self._earth_behind(d)
            out["earth"] = {
                "albedo_scale": d.albedo_scale,
                "surface": d.surface,
                "cloud_pattern": d.cloud_pattern,
                "behind": behind,
                "behind_offset_rad": self._behind(d)[1] if behind else 0.0,
                "applies": self.scenario.earth is not None,
            }
            if d.cloud_fraction is not None:  # drawn (else the scenario's cover)
                out["earth"]["cloud_fraction"] = d.cloud_fraction
        if draws.sensor is not None:
            out["sensor"] = sensor_record(sensor, draws.sensor)
        if draws.pose is not None:
            out["pose"] = {
                **pose_record(draws.pose),
                "q_rolled_cam_from_planned_cam": poses.rolled_from_planned.q_a_from_b.tolist(),
            }
        return out
