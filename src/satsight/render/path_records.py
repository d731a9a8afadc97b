"""Records the renderer's kernels pass along a light path: the surface a camera ray stops
at, where a path starts, a path vertex and the ray a path continues on.

Fields are Dr.Jit arrays, one entry per lane (path). Positions are in render space (the
target's body frame with its origin at the mesh centre, m) and directions are unit vectors
in the body frame unless named otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from satsight.render.target_geometry import ShadingGeometry, SurfacePoint


# Compared by identity (eq=False): the fields are Dr.Jit arrays.
@dataclass(frozen=True, eq=False)
class CameraRayHit:
    """Where camera rays stop.

    hit: Bool, the ray stops at the target. distance_m: distance from the camera along the
    ray, m (None where the surface was found by an earlier trace of the same rays). surface:
    the point hit. shading: its normals and texture coordinates seen from the camera.
    direction_cam, direction_body: the ray's unit direction in the camera and body frames.
    """

    hit: object
    distance_m: object
    surface: SurfacePoint
    shading: ShadingGeometry
    direction_cam: object
    direction_body: object


@dataclass(frozen=True, eq=False)
class PathStart:
    """Which path a lane follows.

    pixel: the pixel index (UInt32). pass_index: the pass (UInt32). low_discrepancy:
    dimension -> the path's low-discrepancy sample in [0, 1) (Float). lane: the path's own
    entry of the radiance sum (UInt32).
    """

    pixel: object
    pass_index: object
    low_discrepancy: Callable
    lane: object


@dataclass(frozen=True, eq=False)
class PathVertex:
    """A surface vertex of a light path.

    point_m: the point. normal: unit shading normal on the side of wo. normal_geo: unit
    geometric normal on the side of wo. uv: texture coordinates or None. mip_level: log2
    of the ray's footprint in texture units, or None. part: part index. wo: unit direction
    towards the previous vertex. face_side: index into per-face-side tables (see
    ``TargetGeometry.face_side``). throughput: the path's weight so far (Color3f).
    normal_smooth: unit interpolated corner normal on the side of wo, the horizon of light
    sources, or None where it is normal_geo. lift_m: vector from the point to the smooth
    surface, where shadow rays towards light sources start, or None (see
    ``satsight.render.target_geometry``). sun_weight: the multiple-importance weight of the
    Sun's light at this vertex (Float), where the path's previous vertex also sampled the
    sunlit surfaces (``satsight.render.sunlit_surfaces``); None for 1.
    """

    point_m: object
    normal: object
    normal_geo: object
    uv: object
    mip_level: object
    part: object
    wo: object
    face_side: object
    throughput: object
    normal_smooth: object = None
    lift_m: object = None
    sun_weight: object = None


@dataclass(frozen=True, eq=False)
class BounceRay:
    """The ray a path continues on from a vertex.

    meets_target: Bool, the ray meets the target again. origin_m: its origin, off the
    surface. direction: its unit direction. throughput: the path's weight after the vertex
    (Color3f). pdf: the density the direction was sampled with, sr^-1.
    """

    meets_target: object
    origin_m: object
    direction: object
    throughput: object
    pdf: object = None
