"""The values one frame passes to the renderer's kernels.

Dr.Jit scalars in ``FrameValues`` are made opaque once per frame (``Renderer.render``), so
that the kernels of later frames, which differ only in these values, are reused instead of
traced and compiled again. Host values (bools, tables, the pixel-position function) shape
the traced code.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from satsight.render.body_light import BodyFrameValues


# Compared by identity (eq=False): the fields are Dr.Jit arrays.
@dataclass(frozen=True, eq=False)
class FrameValues:
    """One frame's camera, light and random-number keys, as the kernels read them.

    R_body_from_cam, R_cam_from_body: rotations between the camera frame and the target's
    body frame (Matrix3f). camera_render_m: the camera's position in render space (body
    frame, origin at the mesh centre), m. focal_length_px, cx_px, cy_px: the pinhole
    intrinsics, px. sun_direction_body: unit vector towards the Sun, body frame.
    sun_irradiance_w_m2: the Sun's irradiance at the target, W m^-2. ray_offset_m: offset
    of shadow- and bounce-ray origins along the geometric normal, m. ray_start_m: distance
    along every camera ray that is surely in front of the target, m. seed_key0, seed_key1:
    the low and high 32 bits of the frame seed (UInt32), keys of the TEA hashes that seed
    the random generators. env_sh_radiance_w_m2_sr: the environment's SH coefficients of
    radiance (one Color3f per coefficient, W m^-2 sr^-1), the Sun's delta included with
    ``sun="sh"``.
    bodies: the Earth and the Moon of this frame. env_is_zero: whether every environment
    coefficient is 0 (host bool; the environment is then not evaluated). bodies_light_target:
    the bodies light the target by traced rays (``environment="sampled"`` with a body).
    bodies_in_view: a body's bounding sphere reaches the frame, so camera rays that miss
    the target look for it. pixel_position_px: pixel index (UInt32) -> (x, y) Float
    image coordinates of the pixel's centre, px. diffuse_env_table: per face side, the unshadowed
    environment's diffuse radiance over kd_eq (Color3f, W m^-2 sr^-1), with
    ``environment="unshadowed"`` on a flat-shaded mesh; else None. anchored_rays: for the
    footprint pass (``render.footprint``), entry index (UInt32) -> (start Point3f in render
    space, unit direction Vector3f in the body frame) of rays anchored at the target, which
    then replace the pixels' camera rays (one path each); else None. sunlit_tables: the
    frame's tables for sampling the sunlit target (``satsight.render.sunlit_surfaces``),
    or None where no vertex samples it.
    """

    R_body_from_cam: object
    R_cam_from_body: object
    camera_render_m: object
    focal_length_px: object
    cx_px: object
    cy_px: object
    sun_direction_body: object
    sun_irradiance_w_m2: object
    ray_offset_m: object
    ray_start_m: object
    seed_key0: object
    seed_key1: object
    env_sh_radiance_w_m2_sr: tuple
    bodies: BodyFrameValues
    env_is_zero: bool
    bodies_light_target: bool
    bodies_in_view: bool
    pixel_position_px: Callable
    diffuse_env_table: object = None
    anchored_rays: Callable | None = None
    sunlit_tables: object = None
