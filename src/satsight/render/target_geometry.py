"""The target as the renderer's rays see it: the merged Mitsuba mesh, per-triangle tables
and the ray queries (first surface, shadow test) on them.

The mesh lives in its body frame shifted to its bounding-box centre (render space, see
docs/design.md "Render space"). A hit is rebuilt from its triangle and barycentrics
(``v0 + u e1 + v e2``), so shadow and bounce rays start from a point as exact as the mesh.
Parts with opacity alpha < 1 are passed through stochastically (probability 1 - alpha).
"""

from __future__ import annotations

import numpy as np

from satsight.scene.mesh import TargetMesh

# Shadow- and bounce-ray origin offset along the normal, relative to the target's size.
_RAY_OFFSET_PER_M = 2e-5
_MIN_RAY_OFFSET_M = 1e-5


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

    @property
    def face_count(self) -> int:
        return self._dr.width(self.face_part)

    def ray_start_m(self, camera_render_m: np.ndarray) -> float:
        """Distance along every primary ray that is surely in front of the target."""
        margin_m = 1e-3 * self.mesh.bounding_radius_m + 1e-3
        gap = np.linalg.norm(camera_render_m) - self.mesh.bounding_radius_m
        return float(max(0.0, gap - margin_m))

    def surface_at(self, face, u, v, active) -> dict:
        """Hit point (from the barycentrics u, v on triangle ``face``), unit geometric
        normal and part of a hit, with the hit's face, u and v."""
        mi, dr = self._mi, self._dr
        p = (
            dr.gather(mi.Vector3f, self.face_v0, face, active)
            + u * dr.gather(mi.Vector3f, self.face_e1, face, active)
            + v * dr.gather(mi.Vector3f, self.face_e2, face, active)
        )
        return {
            "p": p,
            "n_geo": dr.gather(mi.Vector3f, self.face_n, face, active),
            "part": dr.gather(mi.UInt32, self.face_part, face, active),
            "face": face,
            "u": u,
            "v": v,
        }

    def facing_normal(self, surf: dict, towards):
        """The surface's unit normal flipped to the side of ``towards`` (surfaces are
        two-sided: a ray sees the side it arrives on)."""
        n = surf["n_geo"]
        return self._dr.select(self._dr.dot(n, towards) < 0.0, -n, n)

    def face_side(self, face, n_geo, towards):
        """Index into per-face-side tables: ``face`` where the stored normal n_geo faces
        ``towards``, ``face + faces`` where the surface is seen from its back."""
        return self._dr.select(self._dr.dot(n_geo, towards) < 0.0, face + self.face_count, face)

    def intersect(self, origin, direction, active, opacity_sample, coherent=False) -> dict:
        """First surface along a ray that the ray does not pass through.

        opacity_sample(layer) -> Float in [0, 1): a surface of opacity alpha stops the ray
        where the sample is < alpha. Returns hit, t (from ``origin``) and the surface
        (see ``surface_at``).
        """
        mi, dr = self._mi, self._dr
        pi = self.scene.ray_intersect_preliminary(
            mi.Ray3f(origin, direction), coherent=coherent, active=active
        )
        hit = active & pi.is_valid()
        surf = self.surface_at(pi.prim_index, pi.prim_uv.x, pi.prim_uv.y, hit)
        t = dr.select(hit, pi.t, 0.0)
        if not self.transparent:
            return {"hit": hit, "t": t, **surf}
        stopped = hit & (opacity_sample(0) < dr.gather(mi.Float, self.part_opacity, surf["part"]))
        moving = hit & ~stopped
        for layer in range(1, self.max_transparent_layers):
            # Continue just past the surface the ray went through.
            step_origin = surf["p"] + direction * self.ray_offset_m
            pi = self.scene.ray_intersect_preliminary(
                mi.Ray3f(step_origin, direction), coherent=coherent, active=moving
            )
            again = moving & pi.is_valid()
            nxt = self.surface_at(pi.prim_index, pi.prim_uv.x, pi.prim_uv.y, again)
            t_next = dr.dot(step_origin - origin, direction) + pi.t
            for key in nxt:
                surf[key] = dr.select(again, nxt[key], surf[key])
            t = dr.select(again, t_next, t)
            opaque = opacity_sample(layer) < dr.gather(mi.Float, self.part_opacity, nxt["part"])
            stopped |= again & opaque
            moving = again & ~opaque
        return {"hit": stopped, "t": dr.select(stopped, t, 0.0), **surf}

    def visible(self, origin, direction, active, rng):
        """Whether a ray from ``origin`` escapes the target (shadow test), Bool."""
        if not self.transparent:
            return ~self.scene.ray_test(self._mi.Ray3f(origin, direction), active)
        blocked = self.intersect(origin, direction, active, lambda layer: rng.next_float32())
        return ~blocked["hit"]
