"""The radiative renderer: sunlight, the SH light field and inter-reflections (paper Eq. 21).

For every pixel it estimates

    L_o(wo) = integral over the sphere of f_r(wi, wo) L_t(wi) cos(theta_i) dwi

at the first surface a camera ray meets, with the light field ``L_t`` = Sun + environment
(``satsight.lighting.light_field.LightField``) and light reflected by other parts of the
target, followed over ``bounces`` further surfaces:

* **Sun** (``sun="delta"``): the exact collimated source, one shadow ray per vertex.
  ``sun="sh"`` instead adds the Sun's delta, expanded in SH of order ``sh_order`` (paper
  Eq. 10), to the environment.
* **Environment** (``"sampled"``): one BRDF-sampled ray per vertex; where it leaves the
  target it picks up ``L_env(wi)`` from the SH expansion, so the target shadows its own
  environment. ``"unshadowed"``: the diffuse part from the SH irradiance-like convolution
  of ``L_env`` with the diffuse kernel (no ray), the specular part from the sampled ray.
* **Inter-reflection**: the same sampled ray, where it meets the target again, continues
  the path with throughput ``f cos / pdf``.

Random numbers: each pixel has a per-frame random shift (PCG32 seeded by a TEA hash of
the frame seed and the pixel index) of a Kronecker (R_d) low-discrepancy sequence over its
passes, so the passes of one pixel are stratified in every dimension. Parts with opacity
alpha < 1 are passed through stochastically (probability 1 - alpha) by rays; labels treat
a surface as solid where alpha > 0.5.

Everything is Dr.Jit code traced into a few kernels; per-frame values (pose, intrinsics,
light) are opaque, so frames after the first reuse the compiled kernels. Render space and
ray start are as in ``satsight.render.direct`` (see docs/design.md).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.lighting import sh
from satsight.lighting.light_field import LightField
from satsight.render.backend import use_variant
from satsight.render.buffers import RadianceImage
from satsight.render.settings import RenderSettings
from satsight.render.surface import SurfaceModel, regularized
from satsight.scene.mesh import TargetMesh

# Shadow- and bounce-ray origin offset along the normal, relative to the target's size.
_RAY_OFFSET_PER_M = 2e-5
_MIN_RAY_OFFSET_M = 1e-5
# Light paths traced per kernel launch when several passes share one launch.
_LANES_PER_LAUNCH = 1 << 20
# Opacity above which a surface counts as solid for the label images.
LABEL_OPACITY_THRESHOLD = 0.5


def _kronecker_generators(dimensions: int) -> np.ndarray:
    """Generators of the R_d low-discrepancy sequence: 1 / phi_d^(j+1), j < dimensions.

    phi_d is the positive root of x^(d+1) = x + 1 (M. Roberts, "The unreasonable
    effectiveness of quasirandom sequences", 2018).
    """
    phi = 2.0
    for _ in range(64):
        phi = (1.0 + phi) ** (1.0 / (dimensions + 1))
    return np.array([(1.0 / phi) ** (j + 1) % 1.0 for j in range(dimensions)])


class Renderer:
    """Renders one target under a light field; build once, call ``render`` per frame.

    mesh: the target in its body frame. settings: the render choices (fixed for the
    renderer's life, since they shape the compiled kernels). variant: ``"auto"``,
    ``"llvm_ad_rgb"`` or ``"cuda_ad_rgb"``.
    """

    def __init__(
        self, mesh: TargetMesh, settings: RenderSettings | None = None, variant: str = "auto"
    ) -> None:
        self.settings = settings or RenderSettings()
        self.variant = use_variant(variant)
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.mesh = mesh
        self._render_origin_body_m = mesh.center_m
        vertices = mesh.vertices_m - self._render_origin_body_m
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
        self._scene = mi.load_dict({"type": "scene", "target": mi_mesh})

        def vec3(a: np.ndarray):
            a = np.ascontiguousarray(a, dtype=np.float32)
            return mi.Vector3f(mi.Float(a[:, 0]), mi.Float(a[:, 1]), mi.Float(a[:, 2]))

        self._face_v0 = vec3(tri[:, 0])
        self._face_e1 = vec3(e1)
        self._face_e2 = vec3(e2)
        self._face_n = vec3(normal)
        self._face_part = mi.UInt32(mesh.face_part_index.astype(np.uint32))
        materials = [mesh.part_material(i) for i in range(len(mesh.part_names))]
        opacity = np.array([m.alpha for m in materials], dtype=np.float32)
        self._transparent = bool(np.any(opacity < 1.0))
        self._part_opacity = mi.Float(opacity)
        self._surface = SurfaceModel(materials, self.settings)
        # Surfaces reached by a bounce: roughness floored (path regularisation).
        self._surface_indirect = SurfaceModel(
            [regularized(m, self.settings.indirect_min_roughness) for m in materials],
            self.settings,
        )
        # Diffuse environment kernel per part and SH band (see SurfaceModel.diffuse_kernel).
        self._l_max = self.settings.sh_order
        kernel = self._surface.diffuse_band_factors(self._l_max)  # (parts, l_max + 1)
        self._band_factors = mi.Float(np.asarray(kernel, dtype=np.float32).ravel())
        dr.eval(
            self._face_v0,
            self._face_e1,
            self._face_e2,
            self._face_n,
            self._face_part,
            self._part_opacity,
            self._band_factors,
        )
        self._surface.evaluate_tables()
        self._surface_indirect.evaluate_tables()
        self._ray_offset_m = max(_MIN_RAY_OFFSET_M, _RAY_OFFSET_PER_M * mesh.bounding_radius_m)
        self._n_dims = 2 + 3 * (self.settings.bounces + 1)
        self._generators = _kronecker_generators(self._n_dims)

    # ------------------------------------------------------------------------------------
    def render(
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        light: LightField,
        seed: int = 0,
    ) -> RadianceImage:
        """Render one frame.

        camera: intrinsics and image size. cam_from_body: pose of the target in the camera
        frame. light: the light field at the target, body frame. seed: this frame's seed
        (e.g. from ``SeedSequence([scenario_seed, frame_index])``), so a frame's noise does
        not depend on which frames were rendered before it.
        """
        mi, dr = self._mi, self._dr
        if mi.variant() != self.variant:  # another renderer switched Mitsuba's variant
            mi.set_variant(self.variant)
        s = self.settings
        width, height = camera.width_px, camera.height_px
        body_from_cam = cam_from_body.inverse()
        camera_render_m = body_from_cam.t_a_from_b_m - self._render_origin_body_m
        if cam_from_body.apply(self.mesh.center_m)[2] <= 0:
            raise SatsightError(
                "the target's bounding-box centre is behind the camera (z_cam <= 0); check the pose"
            )
        env = self._environment_coefficients(light)
        frame = {
            "R_body_from_cam": mi.Matrix3f(body_from_cam.R_a_from_b.astype(np.float32)),
            "R_cam_from_body": mi.Matrix3f(cam_from_body.R_a_from_b.astype(np.float32)),
            "camera_body": mi.Point3f(*(float(c) for c in camera_render_m)),
            "fx": mi.Float(float(camera.focal_length_px)),
            "cx": mi.Float(float(camera.cx_px)),
            "cy": mi.Float(float(camera.cy_px)),
            "sun_dir": mi.Vector3f(*(float(c) for c in light.sun_direction_body)),
            "sun_e": mi.Float(float(light.sun_irradiance_w_m2)),
            "eps": mi.Float(float(self._ray_offset_m)),
            "t_start": mi.Float(self._ray_start_m(camera_render_m)),
            # Two 32-bit keys of the frame seed, for the TEA hashes that seed the generators.
            "key0": mi.UInt32(int(seed) & 0xFFFFFFFF),
            "key1": mi.UInt32((int(seed) >> 32) & 0xFFFFFFFF),
            "width": width,
            "env": [mi.Color3f(*(float(v) for v in row)) for row in env],
        }
        dr.make_opaque(*(v for k, v in frame.items() if k not in ("env", "width")), *frame["env"])

        n_pix = width * height
        idx = dr.arange(mi.UInt32, n_pix)
        px, py = self._pixel_xy(idx, width)

        # Passes are traced in launches of up to _LANES_PER_LAUNCH paths: one pass per launch
        # for large frames (memory stays that of a one-sample frame), many for small ones
        # (launch overhead). Every launch reuses the same compiled kernel.
        per_launch = max(1, min(s.passes, _LANES_PER_LAUNCH // n_pix))
        # With one pixel-centre pass and no transparency the pass's primary rays are the
        # label rays: labels and radiance then come from one trace.
        centre_labels = s.passes == 1 and not self._transparent
        # Paths that leave the pixel's primary ray are shaded only where it hits the
        # target: a first kernel finds the hits, dr.compress lists them, the shading kernel
        # runs on those lanes alone (a target covering 5 % of the frame costs 5 %).
        compact = s.environment != "off" or s.sun == "sh" or s.bounces > 0
        radiance = dr.zeros(mi.Color3f, n_pix)
        first = 0
        while first < s.passes:
            count = min(per_launch, s.passes - first)
            first_pass = mi.UInt32(first)
            dr.make_opaque(first_pass)
            if count == 1:
                pixel, pass_index = idx, first_pass
            else:
                lanes = dr.arange(mi.UInt32, n_pix * count)
                pixel, pass_index = lanes % n_pix, first_pass + lanes // n_pix
            if compact:
                geo, _, _ = self._pass_primary(frame, pixel, pass_index)
                if centre_labels:
                    labels = self._labels(frame, geo)
                    dr.eval(geo["hit"], *labels)
                selected = dr.compress(geo["hit"])
                if dr.width(selected) > 0:
                    if count > 1:
                        pixel = dr.gather(mi.UInt32, pixel, selected)
                        pass_index = dr.gather(mi.UInt32, pass_index, selected)
                    else:
                        pixel = selected
                        pass_index = dr.full(mi.UInt32, first, dr.width(selected))
                        dr.make_opaque(pass_index)
                    value = self._path(frame, pixel, pass_index)
                    dr.scatter_add(radiance, value, pixel)
            elif count == 1:
                value = self._path(frame, pixel, pass_index)
                if centre_labels:
                    labels = self._labels(frame, self._last_primary)
                    dr.eval(value, *labels)
                radiance += value
            else:
                dr.scatter_add(radiance, self._path(frame, pixel, pass_index), pixel)
            dr.eval(radiance)
            first += count
        if not centre_labels:
            # Labels: the ray through each pixel centre; transparent parts count as solid
            # above the label opacity threshold.
            geo = self._primary(frame, px, py, lambda layer: mi.Float(LABEL_OPACITY_THRESHOLD))
            labels = self._labels(frame, geo)
        depth, part_id, normals = labels
        radiance = radiance / float(s.passes)
        flat_rad = dr.ravel(radiance)
        flat_n = dr.ravel(normals)
        dr.eval(flat_rad, flat_n)
        return RadianceImage(
            radiance_w_m2_sr=flat_rad.numpy().reshape(height, width, 3),
            depth_m=depth.numpy().reshape(height, width),
            part_id=part_id.numpy().astype(np.uint16).reshape(height, width),
            normals_cam=flat_n.numpy().reshape(height, width, 3),
        )

    # ------------------------------------------------------------------------------------
    def _environment_coefficients(self, light: LightField) -> np.ndarray:
        """(n, 3) SH coefficients of the radiance the renderer treats as environment."""
        n = sh.sh_count(self._l_max)
        coeffs = np.zeros((n, 3))
        if self.settings.environment != "off" or self.settings.sun == "sh":
            m = min(n, light.sh_radiance_w_m2_sr.shape[0])
            if self.settings.environment != "off":
                coeffs[:m] = light.sh_radiance_w_m2_sr[:m]
            if self.settings.sun == "sh":
                sun = sh.delta_coeffs(light.sun_direction_body, self._l_max)
                coeffs += light.sun_irradiance_w_m2 * sun[:, None]
        return coeffs

    def _ray_start_m(self, camera_render_m: np.ndarray) -> float:
        """Distance along every primary ray that is surely in front of the target."""
        margin_m = 1e-3 * self.mesh.bounding_radius_m + 1e-3
        gap = np.linalg.norm(camera_render_m) - self.mesh.bounding_radius_m
        return float(max(0.0, gap - margin_m))

    def _surface_at(self, pi, active) -> dict:
        """Hit point (from barycentrics), unit geometric normal and part of a hit."""
        mi, dr = self._mi, self._dr
        face = pi.prim_index
        u, v = pi.prim_uv.x, pi.prim_uv.y
        p = (
            dr.gather(mi.Vector3f, self._face_v0, face, active)
            + u * dr.gather(mi.Vector3f, self._face_e1, face, active)
            + v * dr.gather(mi.Vector3f, self._face_e2, face, active)
        )
        return {
            "p": p,
            "n_geo": dr.gather(mi.Vector3f, self._face_n, face, active),
            "part": dr.gather(mi.UInt32, self._face_part, face, active),
        }

    def _intersect(self, origin, direction, active, opacity_sample, coherent=False) -> dict:
        """First surface along a ray that the ray does not pass through.

        opacity_sample(layer) -> Float in [0, 1): a surface of opacity alpha stops the ray
        where the sample is < alpha. Returns hit, t (from ``origin``), p, n_geo, part.
        """
        mi, dr = self._mi, self._dr
        pi = self._scene.ray_intersect_preliminary(
            mi.Ray3f(origin, direction), coherent=coherent, active=active
        )
        hit = active & pi.is_valid()
        surf = self._surface_at(pi, hit)
        t = dr.select(hit, pi.t, 0.0)
        if not self._transparent:
            return {"hit": hit, "t": t, **surf}
        stopped = hit & (opacity_sample(0) < dr.gather(mi.Float, self._part_opacity, surf["part"]))
        moving = hit & ~stopped
        for layer in range(1, self.settings.max_transparent_layers):
            # Continue just past the surface the ray went through.
            step_origin = surf["p"] + direction * self._ray_offset_m
            pi = self._scene.ray_intersect_preliminary(
                mi.Ray3f(step_origin, direction), coherent=coherent, active=moving
            )
            again = moving & pi.is_valid()
            nxt = self._surface_at(pi, again)
            t_next = dr.dot(step_origin - origin, direction) + pi.t
            for key in ("p", "n_geo", "part"):
                surf[key] = dr.select(again, nxt[key], surf[key])
            t = dr.select(again, t_next, t)
            opaque = opacity_sample(layer) < dr.gather(mi.Float, self._part_opacity, nxt["part"])
            stopped |= again & opaque
            moving = again & ~opaque
        return {"hit": stopped, "t": dr.select(stopped, t, 0.0), **surf}

    def _visible(self, origin, direction, active, rng):
        """Whether a ray from ``origin`` escapes the target (shadow test), Bool."""
        if not self._transparent:
            return ~self._scene.ray_test(self._mi.Ray3f(origin, direction), active)
        blocked = self._intersect(origin, direction, active, lambda layer: rng.next_float32())
        return ~blocked["hit"]

    def _primary(self, frame: dict, px, py, opacity_sample) -> dict:
        """Primary rays through pixel positions (px, py) and the surfaces they stop at."""
        mi, dr = self._mi, self._dr
        d_cam = dr.normalize(
            mi.Vector3f((px - frame["cx"]) / frame["fx"], (py - frame["cy"]) / frame["fx"], 1.0)
        )
        d_body = frame["R_body_from_cam"] @ d_cam
        # Start the ray just outside the target's bounding sphere with one rounding (FMA),
        # so the start point and Embree's hit distances keep float32 precision.
        origin = dr.fma(d_body, frame["t_start"], frame["camera_body"])
        geo = self._intersect(origin, d_body, mi.Bool(True), opacity_sample, coherent=True)
        n = geo["n_geo"]
        geo["n"] = dr.select(dr.dot(n, d_body) > 0.0, -n, n)
        geo["t"] = geo["t"] + frame["t_start"]
        geo["d_cam"] = d_cam
        geo["d_body"] = d_body
        return geo

    def _environment_radiance(self, frame: dict, direction):
        """L_env along ``direction`` (towards the source) from the SH coefficients, clamped
        at 0: a truncated expansion rings below zero away from bright sources."""
        basis = sh.sh_eval_dr(direction, self._l_max)
        total = self._mi.Color3f(0.0)
        for k, y in enumerate(basis):
            total += frame["env"][k] * y
        return self._dr.maximum(total, 0.0)

    def _diffuse_environment(self, frame: dict, n, wo_local, params, part, active):
        """Diffuse radiance from the unshadowed environment: kd_eq / pi * sum_l k_l E_l(n)."""
        mi, dr = self._mi, self._dr
        basis = sh.sh_eval_dr(n, self._l_max)
        total = mi.Color3f(0.0)
        bands = self._l_max + 1
        for l in range(bands):
            band = mi.Color3f(0.0)
            for m in range(-l, l + 1):
                k = l * (l + 1) + m
                band += frame["env"][k] * basis[k]
            factor = dr.gather(mi.Float, self._band_factors, part * bands + l, active)
            total += factor * band
        kd = self._surface.diffuse_coefficient(params, wo_local)
        # Clamped at 0 like the radiance: the truncated expansion can ring below zero.
        return kd * (1.0 / math.pi) * dr.maximum(total, 0.0)

    def _labels(self, frame: dict, geo: dict):
        """Depth along +z (m), part id (index + 1, 0 background), camera-frame normals."""
        dr = self._dr
        hit = geo["hit"]
        depth = dr.select(hit, geo["t"] * geo["d_cam"].z, 0.0)
        part_id = dr.select(hit, geo["part"] + 1, 0)
        normals = dr.select(hit, frame["R_cam_from_body"] @ geo["n"], 0.0)
        return depth, part_id, normals

    def _pixel_xy(self, pixel, width: int):
        mi = self._mi
        return mi.Float(pixel % width), mi.Float(pixel // width)

    def _pass_primary(self, frame: dict, idx, pass_index):
        """The primary ray of pixel ``idx`` in pass ``pass_index`` (UInt32) and the random
        streams of that path: (geo, rng, ld) with ld(dim) the low-discrepancy sample."""
        mi, dr = self._mi, self._dr
        s = self.settings
        px, py = self._pixel_xy(idx, frame["width"])
        # Per-pixel random shift of the Kronecker sequence, fixed over the frame's passes.
        # Generators are seeded through TEA hashes of (pixel, frame key[, pass]), so the
        # streams of neighbouring pixels and passes are decorrelated.
        shift_rng = mi.PCG32(1, mi.sample_tea_64(idx, frame["key0"]), mi.UInt64(frame["key1"]))
        pass_f = mi.Float(pass_index)
        gens = self._generators

        def ld(dim: int):
            x = dr.fma(pass_f, float(gens[dim]), shift_rng_values[dim])
            # Fractional part, kept below 1 in float32.
            return dr.minimum(x - dr.floor(x), 0.99999994)

        shift_rng_values = [shift_rng.next_float32() for _ in range(self._n_dims)]
        rng = mi.PCG32(
            1,
            mi.sample_tea_64(idx, frame["key0"] ^ (pass_index * 0x9E3779B9 + 0x7F4A7C15)),
            mi.UInt64(frame["key1"]) + 1,
        )

        ss = float(s.supersampling)
        if s.samples_per_pixel == 1:
            jx, jy = mi.Float(0.5), mi.Float(0.5)
        else:
            jx, jy = ld(0), ld(1)
        stratum = pass_index // s.samples_per_pixel
        ox = (mi.Float(stratum % s.supersampling) + jx) / ss - 0.5
        oy = (mi.Float(stratum // s.supersampling) + jy) / ss - 0.5
        geo = self._primary(frame, px + ox, py + oy, lambda layer: rng.next_float32())
        return geo, rng, ld

    def _path(self, frame: dict, idx, pass_index):
        """One light path per lane for pixel ``idx`` and pass ``pass_index`` (UInt32):
        its radiance estimate, Color3f (W m^-2 sr^-1)."""
        mi, dr = self._mi, self._dr
        s = self.settings
        geo, rng, ld = self._pass_primary(frame, idx, pass_index)
        self._last_primary = geo  # the label rays when the frame has one centred pass
        surface = self._surface
        radiance = mi.Color3f(0.0)
        throughput = mi.Color3f(1.0)
        active = geo["hit"]
        p, n, part, wo = geo["p"], geo["n"], geo["part"], -geo["d_body"]
        eps = frame["eps"]
        env_on = s.environment != "off" or s.sun == "sh"
        need_ray = env_on or s.bounces > 0
        for depth in range(s.bounces + 1):
            shading = mi.Frame3f(n)
            wo_local = shading.to_local(wo)
            origin = p + n * eps
            if depth == 1:
                surface = self._surface_indirect
            params = surface.at(part, active)  # gathered once per surface hit
            if s.sun == "delta":
                wi = frame["sun_dir"]
                wi_local = shading.to_local(wi)
                lit = active & (wi_local.z > 0.0) & (frame["sun_e"] > 0.0)
                lit &= self._visible(origin, wi, lit, rng)
                f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
                irradiance = frame["sun_e"] * wi_local.z
                radiance += dr.select(lit, throughput * (f_diffuse + f_specular) * irradiance, 0.0)
            if s.environment == "unshadowed":
                diffuse_env = self._diffuse_environment(frame, n, wo_local, params, part, active)
                radiance += dr.select(active, throughput * diffuse_env, 0.0)
            if not need_ray or (depth == s.bounces and not env_on):
                break
            base = 2 + 3 * depth
            u2 = mi.Point2f(ld(base + 1), ld(base + 2))
            wi_local, pdf = surface.sample(params, wo_local, ld(base), u2)
            valid = active & (pdf > 0.0) & (wi_local.z > 0.0)
            f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
            cos_over_pdf = wi_local.z / dr.maximum(pdf, 1e-30)
            weight = dr.select(valid, (f_diffuse + f_specular) * cos_over_pdf, 0.0)
            wi = shading.to_world(wi_local)
            if depth == s.bounces:
                # The path ends here: the ray only has to know whether it leaves the target.
                escaped = valid & self._visible(origin, wi, valid, rng)
            else:
                nxt = self._intersect(origin, wi, valid, lambda layer: rng.next_float32())
                escaped = valid & ~nxt["hit"]
            if env_on:
                env_weight = weight
                if s.environment == "unshadowed":
                    # The diffuse part came from the SH convolution above: only the
                    # specular part is taken from the sampled ray.
                    env_weight = f_specular * cos_over_pdf
                radiance += dr.select(
                    escaped, throughput * env_weight * self._environment_radiance(frame, wi), 0.0
                )
            if depth == s.bounces:
                break
            throughput = throughput * weight
            active = valid & nxt["hit"]
            wo = -wi
            ng = nxt["n_geo"]
            n = dr.select(dr.dot(ng, wo) < 0.0, -ng, ng)
            p, part = nxt["p"], nxt["part"]
        return radiance
