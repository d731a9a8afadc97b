"""Direct sunlight renderer on Mitsuba 3 / Dr.Jit.

Per pixel: a primary ray from the pinhole camera, the first surface it hits, a shadow ray
towards the Sun, and the GGX metallic/roughness BRDF (``satsight.render.ggx``). All
shading is Dr.Jit code traced into the same kernels as the ray queries; per-frame values
(camera pose, intrinsics, sun direction and irradiance) enter as opaque Dr.Jit variables,
so frames after the first reuse the compiled kernels.

Render space is the target's body frame shifted to its bounding-box centre: the mesh never
moves (the camera does), the geometry stays where float32 is most precise, and shadow rays
start from hit points rebuilt from barycentric coordinates, so self-shadowing needs an
offset of only 2e-5 of the target's size even with the camera 200 km away. See docs/design.md.
"""

from __future__ import annotations

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.render.backend import use_variant
from satsight.render.buffers import RadianceImage, SunLight
from satsight.scene.mesh import TargetMesh

# Shadow-ray origin offset along the normal, relative to the target's size (m per m).
_SHADOW_OFFSET_PER_M = 2e-5
_MIN_SHADOW_OFFSET_M = 1e-5


class DirectRenderer:
    """Renders one target mesh under direct sunlight; reuse it for every frame.

    mesh: the target in its body frame. variant: ``"auto"``, ``"llvm_ad_rgb"`` or
    ``"cuda_ad_rgb"`` (see ``satsight.render.backend``).
    """

    def __init__(self, mesh: TargetMesh, variant: str = "auto") -> None:
        self.variant = use_variant(variant)
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.mesh = mesh
        # Render space: the body frame shifted (in float64) to the bounding-box centre, so
        # float32 geometry stays precise even for meshes modelled far from their origin.
        self._render_origin_body_m = mesh.center_m
        vertices = mesh.vertices_m - self._render_origin_body_m
        faces = mesh.faces
        tri = vertices[faces]  # (M, 3, 3) float64
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
        self._scene = mi.load_dict({"type": "scene", "target": mi_mesh})

        def vec3(a: np.ndarray):
            a = np.ascontiguousarray(a, dtype=np.float32)
            return mi.Vector3f(mi.Float(a[:, 0]), mi.Float(a[:, 1]), mi.Float(a[:, 2]))

        self._face_v0 = vec3(tri[:, 0])
        self._face_e1 = vec3(e1)
        self._face_e2 = vec3(e2)
        self._face_n = vec3(normal)
        self._face_part = mi.UInt32(mesh.face_part_index.astype(np.uint32))

        mats = [mesh.part_material(i) for i in range(len(mesh.part_names))]
        base = np.array([m.base_color_rgb for m in mats], dtype=np.float32)
        self._mat_base = mi.Color3f(
            mi.Float(base[:, 0]), mi.Float(base[:, 1]), mi.Float(base[:, 2])
        )
        self._mat_metallic = mi.Float(np.array([m.metallic for m in mats], dtype=np.float32))
        self._mat_roughness = mi.Float(np.array([m.roughness for m in mats], dtype=np.float32))
        self._mat_ior = mi.Float(np.array([m.ior for m in mats], dtype=np.float32))
        dr.eval(
            self._face_v0,
            self._face_e1,
            self._face_e2,
            self._face_n,
            self._face_part,
            self._mat_base,
            self._mat_metallic,
            self._mat_roughness,
            self._mat_ior,
        )
        self._shadow_offset_m = max(
            _MIN_SHADOW_OFFSET_M, _SHADOW_OFFSET_PER_M * mesh.bounding_radius_m
        )

    # ------------------------------------------------------------------------------------
    def render(
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        sun: SunLight,
        supersampling: int = 1,
    ) -> RadianceImage:
        """Render one frame.

        camera: intrinsics and image size. cam_from_body: pose of the target in the camera
        frame. sun: direction (body frame) and irradiance. supersampling: s gives s x s
        stratified rays per pixel for the radiance; labels (depth, masks, normals) always
        come from the ray through the pixel centre.
        """
        if supersampling < 1:
            raise SatsightError(f"supersampling must be >= 1, got {supersampling}")
        mi, dr = self._mi, self._dr
        if mi.variant() != self.variant:  # another renderer switched Mitsuba's variant
            mi.set_variant(self.variant)
        width, height = camera.width_px, camera.height_px
        body_from_cam = cam_from_body.inverse()
        camera_render_m = body_from_cam.t_a_from_b_m - self._render_origin_body_m
        if cam_from_body.apply(self.mesh.center_m)[2] <= 0:
            raise SatsightError(
                "the target's bounding-box centre is behind the camera (z_cam <= 0); check the pose"
            )

        frame = {
            "R_body_from_cam": mi.Matrix3f(body_from_cam.R_a_from_b.astype(np.float32)),
            "R_cam_from_body": mi.Matrix3f(cam_from_body.R_a_from_b.astype(np.float32)),
            "camera_body": mi.Point3f(*(float(c) for c in camera_render_m)),
            "fx": mi.Float(float(camera.focal_length_px)),
            "cx": mi.Float(float(camera.cx_px)),
            "cy": mi.Float(float(camera.cy_px)),
            "sun_dir": mi.Vector3f(*(float(c) for c in sun.direction_body)),
            "sun_e": mi.Float(float(sun.irradiance_w_m2)),
            "eps": mi.Float(float(self._shadow_offset_m)),
            "t_start": mi.Float(self._ray_start_m(camera_render_m)),
        }
        # Opaque: the values live in memory, not as literals in the kernel, so the next
        # frame with other values reuses the compiled kernel.
        dr.make_opaque(*frame.values())

        n_pix = width * height
        idx = dr.arange(mi.UInt32, n_pix)
        px = mi.Float(idx % width)
        py = mi.Float(idx // width)
        geo = self._trace(frame, px, py)
        hit, d_cam, t, part, n_f = geo["hit"], geo["d_cam"], geo["t"], geo["part"], geo["n_facing"]
        depth = dr.select(hit, t * d_cam.z, 0.0)
        part_id = dr.select(hit, part + 1, 0)
        normals = dr.select(hit, frame["R_cam_from_body"] @ n_f, 0.0)

        if supersampling == 1:
            radiance = self._shade(frame, geo)
        else:
            # s x s stratified sub-pixel rays, one pass per offset: memory stays that of a
            # single-sample frame and every pass reuses the same compiled kernel.
            dr.eval(depth, part_id, normals)
            s = int(supersampling)
            radiance = mi.Color3f(0.0)
            for j in range(s):
                for i in range(s):
                    ox = mi.Float((i + 0.5) / s - 0.5)
                    oy = mi.Float((j + 0.5) / s - 0.5)
                    dr.make_opaque(ox, oy)
                    radiance = radiance + self._shade(frame, self._trace(frame, px + ox, py + oy))
                    dr.eval(radiance)
            radiance = radiance / float(s * s)
        flat_rad = dr.ravel(radiance)
        flat_n = dr.ravel(normals)
        dr.eval(flat_rad, depth, part_id, flat_n)
        return RadianceImage(
            radiance_w_m2_sr=flat_rad.numpy().reshape(height, width, 3),
            depth_m=depth.numpy().reshape(height, width),
            part_id=part_id.numpy().astype(np.uint16).reshape(height, width),
            normals_cam=flat_n.numpy().reshape(height, width, 3),
        )

    def _ray_start_m(self, camera_render_m: np.ndarray) -> float:
        """Distance along every primary ray that is surely in front of the target."""
        margin_m = 1e-3 * self.mesh.bounding_radius_m + 1e-3
        gap = np.linalg.norm(camera_render_m) - self.mesh.bounding_radius_m
        return float(max(0.0, gap - margin_m))

    # ------------------------------------------------------------------------------------
    def _trace(self, frame: dict, px, py) -> dict:
        """Primary rays through pixel positions (px, py) and the surfaces they hit."""
        mi, dr = self._mi, self._dr
        d_cam = dr.normalize(
            mi.Vector3f((px - frame["cx"]) / frame["fx"], (py - frame["cy"]) / frame["fx"], 1.0)
        )
        d_body = frame["R_body_from_cam"] @ d_cam
        # Start the ray just outside the target's bounding sphere. The fused multiply-add
        # rounds once, so the start point keeps float32 precision near the target, and
        # Embree's hit distances are small numbers: faces 1 mm apart stay ordered even with
        # the camera 200 km away.
        origin = dr.fma(d_body, frame["t_start"], frame["camera_body"])
        pi = self._scene.ray_intersect_preliminary(mi.Ray3f(origin, d_body), coherent=True)
        hit = pi.is_valid()
        face = pi.prim_index
        n = dr.gather(mi.Vector3f, self._face_n, face, hit)
        n_facing = dr.select(dr.dot(n, d_body) > 0.0, -n, n)
        u, v = pi.prim_uv.x, pi.prim_uv.y
        p = (
            dr.gather(mi.Vector3f, self._face_v0, face, hit)
            + u * dr.gather(mi.Vector3f, self._face_e1, face, hit)
            + v * dr.gather(mi.Vector3f, self._face_e2, face, hit)
        )
        part = dr.gather(mi.UInt32, self._face_part, face, hit)
        return {
            "hit": hit,
            "d_cam": d_cam,
            "d_body": d_body,
            "t": pi.t + frame["t_start"],
            "p": p,
            "n_facing": n_facing,
            "part": part,
        }

    def _shade(self, frame: dict, geo: dict):
        """Sun radiance reflected to the camera, W m^-2 sr^-1 per channel (Color3f)."""
        from satsight.render.ggx import ggx_metallic_brdf

        mi, dr = self._mi, self._dr
        hit, n, part = geo["hit"], geo["n_facing"], geo["part"]
        wi = frame["sun_dir"]
        wo = -geo["d_body"]
        cos_i = dr.dot(n, wi)
        lit = hit & (cos_i > 0.0)
        shadow_ray = mi.Ray3f(geo["p"] + n * frame["eps"], wi)
        lit &= ~self._scene.ray_test(shadow_ray, lit)
        h = dr.normalize(wi + wo)
        f = ggx_metallic_brdf(
            cos_i,
            dr.dot(n, wo),
            dr.dot(n, h),
            dr.dot(wi, h),
            dr.gather(mi.Color3f, self._mat_base, part, lit),
            dr.gather(mi.Float, self._mat_metallic, part, lit),
            dr.gather(mi.Float, self._mat_roughness, part, lit),
            dr.gather(mi.Float, self._mat_ior, part, lit),
        )
        return dr.select(lit, f * (frame["sun_e"] * cos_i), 0.0)
