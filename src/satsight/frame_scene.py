"""The scene of each frame: the target and the scenario's ``objects``, the flying ones placed
where they are at the frame's instant, and the object masks and records of a frame.

Objects fixed in the target's body frame make one scene for every frame (built once, one
renderer). An object on its own ``flight`` (``satsight.poses.object_flight``) moves in the
target's body frame: the scene of a frame is merged anew with it at the frame's time, or at
an instant within the exposure (a time sample of the motion blur), and the frame gets a
renderer of its own (~35 ms for 6 000 triangles; the compiled kernels are shared).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.config.objects import placed_objects
from satsight.config.scenario import Scenario
from satsight.config.target import TargetConfig
from satsight.dataset.object_labels import object_records, target_occlusion
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField
from satsight.poses.object_flight import ObjectFlight, ObjectPoses, object_poses
from satsight.poses.plan_request import PlanRequest
from satsight.poses.track import PoseTrack
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.mesh import TargetMesh
from satsight.scene.objects import SceneMesh, merge_scene, objects_only

#: An object whose light on the target is below this fraction of the Sun's is left out of
#: a frame it is not seen in (``FrameView``'s docstring).
NEGLIGIBLE_REFLECTED_FRACTION = 1e-4
#: The Sun's angular radius (rad; 959.6" at 1 au): how fast a shadow's penumbra widens.
SUN_ANGULAR_RADIUS_RAD = 4.652e-3


@dataclass(frozen=True)
class FrameView:
    """A frame's camera and Sun, to tell which flying objects can show in it.

    An object (bounding sphere of radius r at distance d from the target's bounding-sphere
    centre, target radius R) is kept when any of these holds, and left out of the frame's
    geometry otherwise (its parts keep their ids; its record shows 0 pixels):

    - its sphere meets the camera's field of view (the image widened by ``margin_px``);
    - it is near: a Lambertian surface of albedo <= 1 filling the sphere's disc sends the
      target at most E (r / (d - r - R))^2, below ``NEGLIGIBLE_REFLECTED_FRACTION`` of the
      Sun's irradiance E beyond d = r / sqrt(f) + r + R (100 r + r + R); it also hides at
      most that share of the Earth's light;
    - it is sunward of the target within R + r + d_sun alpha_sun of the Sun line (it may
      shadow the target, penumbra included).

    A specular part of a far object can still glint sunlight onto the target; that light
    is left out with it.
    """

    camera: PinholeCamera
    cam_from_body: RigidTransform
    sun_direction_body: np.ndarray
    margin_px: int = 0

    def shows(self, target: TargetMesh, placed: tuple[str, TargetMesh, RigidTransform]) -> bool:
        """Whether the object ``placed`` (name, mesh, target_from_object) beside ``target``
        can show in the frame (the class docstring's rules)."""
        _, mesh, pose = placed
        radius = mesh.bounding_radius_m
        center = pose.apply(mesh.center_m[None, :])[0]
        offset = center - target.center_m
        distance = float(np.linalg.norm(offset))
        near = radius / np.sqrt(NEGLIGIBLE_REFLECTED_FRACTION) + radius + target.bounding_radius_m
        if distance < near:
            return True
        sun = np.asarray(self.sun_direction_body, dtype=np.float64)
        along = float(offset @ sun)
        across = float(np.linalg.norm(offset - along * sun))
        reach = target.bounding_radius_m + radius + max(along, 0.0) * SUN_ANGULAR_RADIUS_RAD
        if along > -radius and across < reach:
            return True
        return self._in_view(self.cam_from_body.apply(center[None, :])[0], radius)

    def sees(self, center_body_m: np.ndarray, radius_m: float) -> bool:
        """Whether a sphere (centre in the target's body frame) meets the field of view."""
        return self._in_view(self.cam_from_body.apply(center_body_m[None, :])[0], radius_m)

    def _in_view(self, center_cam: np.ndarray, radius: float) -> bool:
        """Whether a sphere meets the pyramid of the image widened by ``margin_px``."""
        if center_cam[2] < -radius:
            return False
        camera, m = self.camera, self.margin_px
        u = np.array([-0.5 - m, camera.width_px - 0.5 + m])
        v = np.array([-0.5 - m, camera.height_px - 0.5 + m])
        x = (u - camera.cx_px) / camera.focal_length_px
        y = (v - camera.cy_px) / camera.focal_length_px
        corners = [np.array([x[i], y[j], 1.0]) for i, j in ((0, 0), (1, 0), (1, 1), (0, 1))]
        inside = np.array([x.mean(), y.mean(), 1.0])  # the ray through the image centre
        for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
            normal = np.cross(a, b)
            normal /= np.linalg.norm(normal)
            if normal @ inside < 0:
                normal = -normal  # inward
            if center_cam @ normal < -radius:
                return False
        return True


class FrameScene:
    """The target and its objects; ``at`` gives the scene of a frame.

    placed: (name, mesh in its own frame, target_from_object) of every object, in order;
    flights: per object its ``ObjectFlight`` or None (fixed placement). request, track: the
    frame plan whose times place the flying objects (request None: none flies).
    label_settings, variant: how the labels-only renders of ``masks`` are made.
    """

    def __init__(
        self,
        target: TargetMesh,
        placed: Sequence[tuple[str, TargetMesh, RigidTransform]],
        flights: Sequence[ObjectFlight | None],
        request: PlanRequest | None,
        track: PoseTrack,
        label_settings: RenderSettings,
        variant: str,
    ) -> None:
        self._target = target
        self._placed = list(placed)
        self._flying = [k for k, f in enumerate(flights) if f is not None]
        self._track = track
        self._poses: list[ObjectPoses] = []
        if self._flying:
            flying = [flights[k] for k in self._flying]
            self._poses = object_poses(request, flying, track.time_s)
        self.fixed = merge_scene(target, self._placed)  # the flying objects at the identity
        self._label_renderers: tuple[Renderer, Renderer] | None = None
        self._label_settings = (label_settings, variant)

    @property
    def moving(self) -> bool:
        """Whether any object flies (a scene per frame)."""
        return bool(self._flying)

    def at(
        self,
        plan_index: int,
        offset_s: float = 0.0,
        target: TargetMesh | None = None,
        view: FrameView | None = None,
    ) -> SceneMesh:
        """The scene of plan frame ``plan_index``, ``offset_s`` from its time; target: the
        target's mesh of this frame (its randomised materials), default the scenario's;
        view: the frame's camera and Sun, which leave out the flying objects that cannot
        show in it (``FrameView``). Without flying objects the one fixed scene."""
        if not self._flying:
            return self.fixed
        placed = list(self._placed)
        for k in self._flying:
            name, mesh, _ = placed[k]
            placed[k] = (name, mesh, self._pose(k, plan_index, offset_s))
        absent = frozenset()
        if view is not None:
            absent = frozenset(k for k in self._flying if not view.shows(self._target, placed[k]))
        return merge_scene(self._target if target is None else target, placed, absent)

    def moving_corners(
        self, plan_index: int, view: FrameView
    ) -> Callable[[float], np.ndarray] | None:
        """The box corners (8 per object, target body frame) of the flying objects in the
        frame's field of view at its time, as a function of the offset from it (their motion
        over an exposure); None when no flying object is in view."""
        if not self._flying:
            return None
        scene_poses = {k: self._pose(k, plan_index, 0.0) for k in self._flying}
        seen = []
        for k in self._flying:
            _, mesh, _ = self._placed[k]
            center = scene_poses[k].apply(mesh.center_m[None, :])[0]
            if view.sees(center, mesh.bounding_radius_m):
                seen.append(k)
        if not seen:
            return None

        def corners(offset_s: float) -> np.ndarray:
            return np.concatenate(
                [
                    self._pose(k, plan_index, offset_s).apply(
                        self._placed[k][1].box_keypoints_body_m[:8]
                    )
                    for k in seen
                ]
            )

        return corners

    def _pose(self, k: int, plan_index: int, offset_s: float) -> RigidTransform:
        """Flying object ``k``'s target_from_object at plan frame ``plan_index`` + offset."""
        omega = np.zeros(3)
        if self._track.omega_body_rad_s is not None:
            omega = self._track.omega_body_rad_s[plan_index]
        poses = self._poses[self._flying.index(k)]
        return poses.target_from_object(plan_index, offset_s, omega)

    def masks(
        self,
        scene: SceneMesh,
        part_id: np.ndarray,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        light: LightField,
        record: dict,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The object ids and the target's amodal mask of a frame of ``scene`` (its
        ``part_id`` image; ``satsight.dataset.object_labels``), from labels-only renders of
        the target alone and of the objects alone (direct light, one sample, no
        footprint); the target's ``occlusion`` and the ``objects`` records are added to
        ``record``."""
        settings, variant = self._label_settings
        if self._label_renderers is None:
            self._label_renderers = (
                Renderer(self._target, settings, variant),
                Renderer(objects_only(self.fixed), settings, variant),
            )
        alone_renderer, objects_renderer = self._label_renderers
        alone = alone_renderer.render(camera, cam_from_body, light, normals=False).part_id
        if not self.moving:
            objects = objects_renderer.render(camera, cam_from_body, light, normals=False).part_id
        elif np.any(scene.mesh.face_part_index >= scene.target_part_count):
            # The objects where they are in this frame.
            objects_renderer = Renderer(objects_only(scene), settings, variant)
            objects = objects_renderer.render(camera, cam_from_body, light, normals=False).part_id
        else:  # every object left out of this frame
            objects = np.zeros_like(alone)
        object_id = scene.object_id(part_id)
        amodal = alone > 0
        record["occlusion"] = target_occlusion(object_id, amodal)
        poses = [cam_from_body @ pose for pose in scene.target_from_object]
        record["objects"] = object_records(
            scene.object_names, poses, object_id, scene.object_id(objects)
        )
        return object_id, amodal


def frame_scene(
    scenario: Scenario,
    target: TargetMesh,
    track: PoseTrack,
    build_shape: Callable[[TargetConfig], TargetMesh],
) -> FrameScene | None:
    """The scene of the scenario's ``objects`` beside ``target`` (None without objects);
    build_shape: makes a procedural or mesh object as the target is made."""
    if not scenario.objects:
        return None
    placed = placed_objects(scenario.objects, target, scenario.sun.band_nm, build_shape)
    flights = [None if o.flight is None else o.flight.build() for o in scenario.objects]
    request = scenario.plan_request() if any(flights) else None
    label_settings = replace(
        scenario.render.settings(),
        bounces=0, samples_per_pixel=1, supersampling=1, integrate_footprint=False,
        environment="off",
    )  # fmt: skip
    return FrameScene(
        target, placed, flights, request, track, label_settings, scenario.render.variant
    )
