"""The target as the renderer's rays see it: the merged Mitsuba mesh, per-triangle tables
and the ray queries (first surface, shadow test) on them.

The mesh lives in its body frame shifted to its bounding-box centre (render space, see
docs/design.md "Render space"). A hit is rebuilt from its triangle and barycentrics
(``v0 + u e1 + v e2``), so shadow and bounce rays start from a point as exact as the mesh.
Parts with opacity alpha < 1 are passed through stochastically (probability 1 - alpha).

Shading normals (``shading``). Where the mesh has per-corner normals they are
interpolated with the hit's barycentrics; where a part has a normal map the normal is
tilted in the tangent frame of the triangle (tangent and bitangent: the directions of
increasing u and v on the triangle, from its texture coordinates, made orthonormal to
the interpolated normal). The geometric normal keeps its roles: it decides which side a
ray sees, it offsets the origins of shadow and bounce rays, and bounce directions below it
(``SurfaceModel``) never count, so a shading normal cannot let light through a surface;
light sources are seen from the smooth surface instead (below).
Where the viewer is closer to the shading horizon than to the triangle's (cosine below
that with the geometric normal) and within ``VIEW_COSINE_MIN`` of it, or below it (a
normal bent away from the viewer at a silhouette), the shading normal is tilted towards
the viewer until their cosine is the smaller of ``VIEW_COSINE_MIN`` and the geometric
one (a simple form of the shading-normal adaptation of Keller et al. 2017, "The Iray
light transport simulation and rendering system", arXiv:1705.01263, section "Bump and
normal mapping"): without it such pixels would turn black. A smooth surface seen at
grazing angles, as a finely tessellated sphere near its limb, keeps its normals (tilting
them there towards the viewer turned them from the Sun and cost a sphere 4 % of its light
at 170 degrees phase).

The smooth surface and the shadow terminator. Corner normals describe a smooth surface
that the flat triangles only approximate: on a convex part it bulges out of each
triangle, and near the terminator the triangle's own plane, or its neighbours, hide
light that the smooth surface receives (the "shadow terminator"). Light sources tested
by a shadow ray (the Sun, the Earth and the Moon) are therefore seen from the smooth
surface, as in Hanika 2021 ("Hacking the shadow terminator", Ray Tracing Gems II, ch. 4,
doi:10.1007/978-1-4842-7185-8_4): their shadow ray starts at the hit moved onto the
tangent planes of the triangle's corners,

    p' = p - sum_i b_i min(0, (p - p_i).n_i) n_i

(b_i the barycentrics, p_i the corners, n_i their normals on the viewer's side), and
their horizon is that of the interpolated normal (``ShadingGeometry.normal_smooth``,
before normal mapping and view adaptation) instead of the triangle's. Only convex
corners move the point (the min), so where the surface is flat or concave the shadow ray
starts on the triangle, and the triangle itself still blocks light from below it.
Chosen over the shadowing terms of Chiang et al. 2019 ("Taming the shadow terminator",
SIGGRAPH 2019 talks) and of Estevez et al. 2019 (Ray Tracing Gems, ch. 12), which
smooth the terminator by removing light, so a smooth sphere would stay too dark: the
moved origin gives back the light the smooth surface receives and no more, since a
convex closed mesh lies inside its smooth surface and the moved shadow ray escapes where
that surface is lit. A normal map describes no displaced surface: it moves neither the
point nor the horizon.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from satsight.render.textures import TextureTables, guarded
from satsight.scene.mesh import TargetMesh

# Shadow- and bounce-ray origin offset along the normal, relative to the target's size.
_RAY_OFFSET_PER_M = 2e-5
_MIN_RAY_OFFSET_M = 1e-5
# Smallest cosine between the viewer and the shading normal where that between the viewer
# and the geometric normal is larger (see the module docstring).
VIEW_COSINE_MIN = 0.05
# Grazing views stretch a pixel's footprint by 1 / cos; capped at 1 / 0.01 (mip-mapping).
_MIN_FOOTPRINT_COSINE = 0.01


@dataclass(frozen=True, eq=False)
class SurfacePoint:
    """A point on the target's triangles, per lane (Dr.Jit arrays).

    point_m: the point in render space (body frame, origin at the mesh centre), m.
    normal_geo: the triangle's stored unit normal (either side of the surface), body frame.
    part: part index. face: triangle index. u, v: barycentrics of the point on the
    triangle (point = v0 + u e1 + v e2).
    """

    point_m: object
    normal_geo: object
    part: object
    face: object
    u: object
    v: object

    def where(self, condition, other: SurfacePoint) -> SurfacePoint:
        """This point where ``condition`` holds, ``other`` elsewhere (field by field)."""
        import drjit as dr

        return SurfacePoint(
            *(
                dr.select(condition, getattr(self, f.name), getattr(other, f.name))
                for f in dataclasses.fields(self)
            )
        )


@dataclass(frozen=True, eq=False)
class RayHit:
    """The first surface a ray stops at. hit: Bool, the ray stops at the target.
    distance_m: distance from the ray's origin to the surface along its unit direction, m
    (0 for a miss). surface: the point hit."""

    hit: object
    distance_m: object
    surface: SurfacePoint


@dataclass(frozen=True, eq=False)
class ShadingGeometry:
    """The normals and texture coordinates of a hit seen from one side.

    normal: unit shading normal on the viewer's side (interpolated, normal mapped and
    adapted to the view, see the module docstring), body frame. normal_facing: unit
    geometric normal on the viewer's side. uv: texture coordinates (Point2f) or None
    without textures. mip_level: log2 of the ray's footprint on the surface in texture
    units (mip-mapping), or None. normal_smooth: unit interpolated corner normal on the
    viewer's side (the smooth surface's normal, before normal mapping and view
    adaptation), or None where it is the geometric normal (flat meshes). lift_m: vector
    from the hit to the smooth surface above it (Hanika 2021, see the module docstring),
    m, or None where there is none; shadow rays towards light sources start there.
    """

    normal: object
    normal_facing: object
    uv: object = None
    mip_level: object = None
    normal_smooth: object = None
    lift_m: object = None


class TargetGeometry:
    """Per-triangle tables of a target and the ray queries against it.

    mesh: the target in its body frame. opacity: per-part opacity alpha in [0, 1].
    max_transparent_layers: surfaces of alpha < 1 a ray may pass through before it stops.
    """

    def __init__(self, mesh: TargetMesh, opacity: np.ndarray, max_transparent_layers: int) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.mesh = mesh
        self.origin_body_m = mesh.center_m
        self.max_transparent_layers = max_transparent_layers
        vertices = mesh.vertices_m - self.origin_body_m
        faces = mesh.faces
        tri = vertices[faces]
        e1 = tri[:, 1] - tri[:, 0]
        e2 = tri[:, 2] - tri[:, 0]
        normal = np.cross(e1, e2)
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
        # Host copies for the sunlit-surface sampling tables.
        self.face_area_m2 = 0.5 * length[:, 0]
        self.face_normal = normal

        mi_mesh = mi.Mesh(mesh.name, len(vertices), len(faces), has_vertex_normals=False)
        params = mi.traverse(mi_mesh)
        params["vertex_positions"] = mi.Float(vertices.astype(np.float32).ravel())
        params["faces"] = mi.UInt32(faces.astype(np.uint32).ravel())
        params.update()
        self.scene = mi.load_dict({"type": "scene", "target": mi_mesh})

        def vec3(a: np.ndarray):
            a = np.ascontiguousarray(a, dtype=np.float32)
            return mi.Vector3f(mi.Float(a[:, 0]), mi.Float(a[:, 1]), mi.Float(a[:, 2]))

        self.face_v0 = vec3(tri[:, 0])
        self.face_e1 = vec3(e1)
        self.face_e2 = vec3(e2)
        self.face_n = vec3(normal)
        self.face_part = mi.UInt32(mesh.face_part_index.astype(np.uint32))
        opacity = np.asarray(opacity, dtype=np.float32)
        self.transparent = bool(np.any(opacity < 1.0))
        self.part_opacity = mi.Float(opacity)
        dr.eval(
            self.face_v0, self.face_e1, self.face_e2, self.face_n, self.face_part, self.part_opacity
        )
        self.ray_offset_m = max(_MIN_RAY_OFFSET_M, _RAY_OFFSET_PER_M * mesh.bounding_radius_m)
        self._surface_tables(mesh, e1, e2, vec3)

    def _surface_tables(self, mesh: TargetMesh, e1: np.ndarray, e2: np.ndarray, vec3) -> None:
        """Per-triangle corner normals, texture coordinates, tangents and texel scale, and
        the textures, where the mesh has them."""
        mi, dr = self._mi, self._dr
        self.smooth = mesh.corner_normals is not None
        self.textures = TextureTables(mesh) if mesh.textured else None
        self.normal_mapped = self.textures is not None and self.textures.has_slot["normal"]
        # Whether shading normals can differ from the geometric normal.
        self.shading_normals = self.smooth or self.normal_mapped
        tables = []
        if self.smooth:
            corners = mesh.corner_normals
            self.face_n_corner = [vec3(corners[:, k]) for k in range(3)]
            tables += self.face_n_corner
        if self.textures is not None:
            uv = mesh.corner_uv
            self.face_uv = [
                mi.Point2f(*(mi.Float(uv[:, k, j].astype(np.float32)) for j in range(2)))
                for k in range(3)
            ]
            du1, dv1 = (uv[:, 1] - uv[:, 0]).T
            du2, dv2 = (uv[:, 2] - uv[:, 0]).T
            det = du1 * dv2 - du2 * dv1
            ok = np.abs(det) > 1e-20
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
            dp_du = (e1 * dv2[:, None] - e2 * dv1[:, None]) * inv  # metres per unit u
            dp_dv = (e2 * du1[:, None] - e1 * du2[:, None]) * inv
            area_m2 = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
            area_uv = 0.5 * np.abs(det)
            # uv units per metre (isotropic): scales a footprint in metres to one in uv.
            uv_per_m = np.sqrt(
                np.divide(area_uv, area_m2, out=np.zeros_like(area_uv), where=area_m2 > 0)
            )
            self.face_uv_per_m = mi.Float(uv_per_m.astype(np.float32))
            self.face_dp_du, self.face_dp_dv = vec3(dp_du), vec3(dp_dv)
            tables += [*self.face_uv, self.face_uv_per_m, self.face_dp_du, self.face_dp_dv]
        if tables:
            dr.eval(*tables)

    @property
    def face_count(self) -> int:
        return self._dr.width(self.face_part)

    def ray_start_m(self, camera_render_m: np.ndarray) -> float:
        """Distance along every primary ray that is surely in front of the target."""
        margin_m = 1e-3 * self.mesh.bounding_radius_m + 1e-3
        gap = np.linalg.norm(camera_render_m) - self.mesh.bounding_radius_m
        return float(max(0.0, gap - margin_m))

    def surface_at(self, face, u, v, active) -> SurfacePoint:
        """The point at barycentrics (u, v) on triangle ``face``, with its unit geometric
        normal and part."""
        mi, dr = self._mi, self._dr
        p = (
            dr.gather(mi.Vector3f, self.face_v0, face, active)
            + u * dr.gather(mi.Vector3f, self.face_e1, face, active)
            + v * dr.gather(mi.Vector3f, self.face_e2, face, active)
        )
        return SurfacePoint(
            point_m=p,
            normal_geo=dr.gather(mi.Vector3f, self.face_n, face, active),
            part=dr.gather(mi.UInt32, self.face_part, face, active),
            face=face,
            u=u,
            v=v,
        )

    def shading(
        self, surf: SurfacePoint, active, wo, footprint_m=None, footprint_point=None
    ) -> ShadingGeometry:
        """The normals and texture coordinates of the hits ``surf`` (on lanes ``active``)
        seen from direction ``wo`` (unit, towards the viewer).

        footprint_m: the width of the ray's footprint across its direction at the hit, m;
        given, with textures, the result has a mip level. footprint_point: with
        ``footprint_m``, a point of the unit square (Point2f, uniform random): the textures
        are then looked up in full size at that point of a square of the footprint's width
        around the hit (axis-aligned in texture space; stochastic texture filtering, Pharr
        et al. 2024, "Filtering after shading with stochastic texture filtering", Proc. ACM
        Comput. Graph. Interact. Tech. 7(1)): the expected radiance is the radiance averaged
        over that square, where a mip level averages the texture's values before shading.
        For a flat untextured mesh the shading normal is the facing geometric normal.
        """
        mi, dr = self._mi, self._dr
        n_geo = surf.normal_geo
        n_facing = dr.select(dr.dot(n_geo, wo) < 0.0, -n_geo, n_geo)
        face, u, v = surf.face, surf.u, surf.v
        uv = lod = None
        if self.textures is not None:
            w = 1.0 - u - v
            corner_uv = [dr.gather(mi.Point2f, t, face, active) for t in self.face_uv]
            uv = w * corner_uv[0] + u * corner_uv[1] + v * corner_uv[2]
            if footprint_m is not None:
                # The footprint ellipse's axes are f and f / cos(view): their geometric
                # mean, in texture units (uv per metre of the triangle).
                scale = dr.gather(mi.Float, self.face_uv_per_m, face, active)
                cos_view = dr.maximum(dr.abs(dr.dot(n_geo, wo)), _MIN_FOOTPRINT_COSINE)
                width = footprint_m * scale * dr.rsqrt(cos_view)
                if footprint_point is None:
                    lod = dr.log2(width)
                else:
                    uv = uv + (footprint_point - 0.5) * width
        if not self.shading_normals:
            return ShadingGeometry(n_facing, n_facing, uv, lod)
        corners = None
        if self.smooth:
            w = 1.0 - u - v
            corners = [dr.gather(mi.Vector3f, t, face, active) for t in self.face_n_corner]
            n = w * corners[0] + u * corners[1] + v * corners[2]
            length = dr.norm(n)
            n = dr.select(length > 1e-6, n / length, n_geo)
        else:
            n = n_geo
        # The surface's own side: that of the interpolated normal (files may wind
        # triangles against their normals); the view decides which side is seen.
        flip = dr.dot(n, n_facing) < 0.0
        smooth = lift = None
        if corners is not None:
            smooth = dr.select(flip, -n, n)
            lift = self._lift(surf, corners, flip, active)
        if self.normal_mapped:
            n = self._normal_mapped(surf, n, uv, lod, active)
        n = dr.select(flip, -n, n)
        # Keep the viewer above the shading horizon (adaptation), as far as it is above
        # the triangle's, up to VIEW_COSINE_MIN.
        cos_view = dr.dot(n, wo)
        cos_min = dr.minimum(VIEW_COSINE_MIN, dr.dot(n_facing, wo))
        bent = dr.normalize(n + (cos_min - cos_view) * wo)
        n = dr.select(cos_view < cos_min, bent, n)
        return ShadingGeometry(n, n_facing, uv, lod, smooth, lift)

    def _lift(self, surf: SurfacePoint, corners, flip, active):
        """Vector from the hit to the smooth surface the corner normals describe, m:
        -sum_i b_i min(0, (p - p_i).n_i) n_i (Hanika 2021, see the module docstring), the
        corner normals n_i taken on the side of the interpolated normal ``flip`` gives."""
        mi, dr = self._mi, self._dr
        e1 = dr.gather(mi.Vector3f, self.face_e1, surf.face, active)
        e2 = dr.gather(mi.Vector3f, self.face_e2, surf.face, active)
        u, v = surf.u, surf.v
        to_p = u * e1 + v * e2  # p - p0
        lift = mi.Vector3f(0.0)
        for b, offset, corner in (
            (1.0 - u - v, to_p, corners[0]),
            (u, to_p - e1, corners[1]),
            (v, to_p - e2, corners[2]),
        ):
            n_i = dr.select(flip, -corner, corner)
            lift -= b * dr.minimum(dr.dot(offset, n_i), 0.0) * n_i
        return lift

    def _normal_mapped(self, surf: SurfacePoint, n, uv, lod, active):
        """n tilted by the part's normal map (tangent space: +x along u, +y along v), at
        texture coordinates ``uv`` and mip level ``lod``."""
        mi, dr = self._mi, self._dr
        tex = self.textures
        texture = tex.slot("normal", surf.part, active)
        mapped = active & (texture >= 0)
        face = surf.face

        def tilt():
            value = tex.sample(texture, uv, mapped, lod)
            scale = tex.normal_scale(surf.part, mapped)
            dp_du = dr.gather(mi.Vector3f, self.face_dp_du, face, mapped)
            dp_dv = dr.gather(mi.Vector3f, self.face_dp_dv, face, mapped)
            t = dr.normalize(dp_du - n * dr.dot(n, dp_du))
            b = dp_dv - n * dr.dot(n, dp_dv)
            b = dr.normalize(b - t * dr.dot(t, b))
            x = (2.0 * value.x - 1.0) * scale
            y = (2.0 * value.y - 1.0) * scale
            z = 2.0 * value.z - 1.0
            tilted = dr.normalize(x * t + y * b + z * n)
            # Degenerate texture coordinates or a broken map leave the normal as it was.
            ok = mapped & dr.isfinite(tilted.x) & (dr.dot(tilted, n) > 0.0)
            return dr.select(ok, tilted, n)

        return guarded(mapped, tilt, lambda: mi.Vector3f(n))

    def facing_normal(self, surf: SurfacePoint, towards):
        """The surface's unit normal flipped to the side of ``towards`` (surfaces are
        two-sided: a ray sees the side it arrives on)."""
        n = surf.normal_geo
        return self._dr.select(self._dr.dot(n, towards) < 0.0, -n, n)

    def face_side(self, face, n_geo, towards):
        """Index into per-face-side tables: ``face`` where the stored normal n_geo faces
        ``towards``, ``face + faces`` where the surface is seen from its back."""
        return self._dr.select(self._dr.dot(n_geo, towards) < 0.0, face + self.face_count, face)

    def intersect(self, origin, direction, active, opacity_sample, coherent=False) -> RayHit:
        """First surface along a ray that the ray does not pass through.

        opacity_sample(layer) -> Float in [0, 1): a surface of opacity alpha stops the ray
        where the sample is < alpha.
        """
        mi, dr = self._mi, self._dr
        pi = self.scene.ray_intersect_preliminary(
            mi.Ray3f(origin, direction), coherent=coherent, active=active
        )
        hit = active & pi.is_valid()
        surf = self.surface_at(pi.prim_index, pi.prim_uv.x, pi.prim_uv.y, hit)
        t = dr.select(hit, pi.t, 0.0)
        if not self.transparent:
            return RayHit(hit, t, surf)
        stopped = hit & (opacity_sample(0) < dr.gather(mi.Float, self.part_opacity, surf.part))
        moving = hit & ~stopped
        for layer in range(1, self.max_transparent_layers):
            # Continue just past the surface the ray went through.
            step_origin = surf.point_m + direction * self.ray_offset_m
            pi = self.scene.ray_intersect_preliminary(
                mi.Ray3f(step_origin, direction), coherent=coherent, active=moving
            )
            again = moving & pi.is_valid()
            nxt = self.surface_at(pi.prim_index, pi.prim_uv.x, pi.prim_uv.y, again)
            t_next = dr.dot(step_origin - origin, direction) + pi.t
            surf = nxt.where(again, surf)
            t = dr.select(again, t_next, t)
            opaque = opacity_sample(layer) < dr.gather(mi.Float, self.part_opacity, nxt.part)
            stopped |= again & opaque
            moving = again & ~opaque
        return RayHit(stopped, dr.select(stopped, t, 0.0), surf)

    def visible(self, origin, direction, active, rng, max_distance_m=None):
        """Whether a ray from ``origin`` escapes the target (shadow test), Bool; with
        ``max_distance_m`` (Float), whether nothing stops it within that distance."""
        mi = self._mi
        ray = mi.Ray3f(origin, direction)
        if max_distance_m is not None:
            ray.maxt = max_distance_m
        if not self.transparent:
            return ~self.scene.ray_test(ray, active)
        blocked = self.intersect(origin, direction, active, lambda layer: rng.next_float32())
        if max_distance_m is not None:
            return ~(blocked.hit & (blocked.distance_m < max_distance_m))
        return ~blocked.hit
