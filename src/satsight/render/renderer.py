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
import sys

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.lighting import sh
from satsight.lighting.light_field import LightField
from satsight.render.backend import use_variant
from satsight.render.body_light import BodyLight
from satsight.render.buffers import RadianceImage, margin_pixels_xy
from satsight.render.settings import RenderSettings
from satsight.render.surface import SurfaceModel, regularized
from satsight.render.target_geometry import TargetGeometry
from satsight.scene.mesh import TargetMesh

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
        materials = [mesh.part_material(i) for i in range(len(mesh.part_names))]
        self._geometry = TargetGeometry(
            mesh, np.array([m.alpha for m in materials]), self.settings.max_transparent_layers
        )
        self._transparent = self._geometry.transparent
        textures, shading_normals = self._geometry.textures, self._geometry.shading_normals
        self._surface = SurfaceModel(
            materials, self.settings, textures, shading_normals=shading_normals
        )
        # Surfaces reached by a bounce: roughness floored (path regularisation).
        self._surface_indirect = SurfaceModel(
            [regularized(m, self.settings.indirect_min_roughness) for m in materials],
            self.settings,
            textures,
            min_roughness=self.settings.indirect_min_roughness,
            shading_normals=shading_normals,
        )
        # Diffuse environment kernel per part and SH band (see SurfaceModel.diffuse_kernel).
        self._l_max = self.settings.sh_order
        kernel = self._surface.diffuse_band_factors(self._l_max)  # (parts, l_max + 1)
        self._band_factors = mi.Float(np.asarray(kernel, dtype=np.float32).ravel())
        dr.eval(self._band_factors)
        self._surface.evaluate_tables()
        self._surface_indirect.evaluate_tables()
        self._body_light = BodyLight(self._geometry.origin_body_m)
        # Low-discrepancy dimensions: 2 for the pixel position, 3 per path vertex for the
        # BRDF sample, then 3 per path vertex for the body-light sample.
        self._light_dims = 2 + 3 * (self.settings.bounces + 1)
        self._n_dims = self._light_dims + 3 * (self.settings.bounces + 1)
        self._generators = _kronecker_generators(self._n_dims)

    # ------------------------------------------------------------------------------------
    def render(
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        light: LightField,
        seed: int = 0,
        margin_px: int = 0,
    ) -> RadianceImage:
        """Render one frame.

        camera: intrinsics and image size. cam_from_body: pose of the target in the camera
        frame. light: the light field at the target, body frame. seed: this frame's seed
        (e.g. from ``SeedSequence([scenario_seed, frame_index])``), so a frame's noise does
        not depend on which frames were rendered before it. margin_px: also render the
        radiance of a ring this wide around the frame (``RadianceImage.margin_radiance_w_m2_sr``),
        which the optics blur into the frame's edge pixels.
        """
        mi, dr = self._mi, self._dr
        if mi.variant() != self.variant:  # another renderer switched Mitsuba's variant
            mi.set_variant(self.variant)
        s = self.settings
        width, height = camera.width_px, camera.height_px
        body_from_cam = cam_from_body.inverse()
        camera_render_m = body_from_cam.t_a_from_b_m - self._geometry.origin_body_m
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
            "eps": mi.Float(float(self._geometry.ray_offset_m)),
            "t_start": mi.Float(self._geometry.ray_start_m(camera_render_m)),
            # Two 32-bit keys of the frame seed, for the TEA hashes that seed the generators.
            "key0": mi.UInt32(int(seed) & 0xFFFFFFFF),
            "key1": mi.UInt32((int(seed) >> 32) & 0xFFFFFFFF),
            "env": [mi.Color3f(*(float(v) for v in row)) for row in env],
        }
        dr.make_opaque(*(v for k, v in frame.items() if k != "env"), *frame["env"])
        bodies = self._body_light.frame_values(light.bodies)
        frame["bodies"] = bodies
        frame["env_zero"] = not np.any(env)
        # Bodies light the target in the sampled mode; every mode shows them behind it.
        frame["body_light"] = s.environment == "sampled" and bodies["any"]
        frame["background"] = bodies["any"] and self._bodies_in_view(
            camera, cam_from_body, light, margin_px
        )
        if s.environment == "unshadowed":
            frame["diffuse_env"] = self._diffuse_environment_table(frame)

        n_pix = width * height
        frame["pixel_xy"] = lambda pixel: (mi.Float(pixel % width), mi.Float(pixel // width))
        radiance, labels = self._radiance_passes(frame, n_pix, with_labels=True)
        depth, part_id, normals, background = labels
        part_pairs = self._pack_uint16_pairs(part_id)
        dr.eval(radiance, depth, part_pairs, normals, *background)
        margin_radiance = None
        if margin_px > 0:
            margin_radiance = self._render_margin(frame, width, height, margin_px)

        return RadianceImage(
            radiance_w_m2_sr=radiance.numpy().reshape(height, width, 3),
            depth_m=depth.numpy().reshape(height, width),
            part_id=part_pairs.numpy().view(np.uint16)[:n_pix].reshape(height, width),
            normals_cam=normals.numpy().reshape(height, width, 3),
            margin_px=int(margin_px),
            margin_radiance_w_m2_sr=margin_radiance,
            background_id=background[0].numpy().astype(np.uint8).reshape(height, width)
            if background
            else None,
        )

    def _bodies_in_view(
        self, camera: PinholeCamera, cam_from_body: RigidTransform, light: LightField, margin: int
    ) -> bool:
        """Whether the bounding sphere of a body reaches the frame (with its margin)."""
        half_w = max(camera.cx_px, camera.width_px - 1 - camera.cx_px) + margin + 1
        half_h = max(camera.cy_px, camera.height_px - 1 - camera.cy_px) + margin + 1
        half_diagonal = math.atan(math.hypot(half_w, half_h) / camera.focal_length_px)
        for body in light.bodies:
            c_cam = cam_from_body.apply(body.center_body_m)
            distance = float(np.linalg.norm(c_cam))
            off_axis = math.acos(max(-1.0, min(1.0, c_cam[2] / distance)))
            if off_axis - math.asin(min(1.0, body.bounding_radius_m / distance)) < half_diagonal:
                return True
        return False

    def _render_margin(self, frame: dict, width: int, height: int, margin_px: int) -> np.ndarray:
        """(n, 3) float32 radiance of the pixels of a ``margin_px`` wide ring around the
        frame (``margin_pixels_xy`` order): the light the optics spread into the frame from
        just outside it. Its random streams are apart from the frame's (another key)."""
        mi, dr = self._mi, self._dr
        ring_x, ring_y = margin_pixels_xy(width, height, margin_px)
        table_x = mi.Float(ring_x.astype(np.float32))
        table_y = mi.Float(ring_y.astype(np.float32))
        ring = dict(frame)
        ring["key0"] = frame["key0"] ^ 0x5BD1E995
        ring["pixel_xy"] = lambda pixel: (
            dr.gather(mi.Float, table_x, pixel),
            dr.gather(mi.Float, table_y, pixel),
        )
        radiance, _ = self._radiance_passes(ring, len(ring_x), with_labels=False)
        dr.eval(radiance)
        return radiance.numpy().reshape(-1, 3)

    def _radiance_passes(self, frame: dict, n_pix: int, with_labels: bool) -> tuple:
        """Radiance (flat Float, three values per pixel) of pixels 0..n_pix-1 (positions
        from ``frame["pixel_xy"]``), averaged over the settings' passes, and, with
        ``with_labels``, the label images (depth, part id, normals) of the pixel centres."""
        mi, dr = self._mi, self._dr
        s = self.settings
        idx = dr.arange(mi.UInt32, n_pix)

        # Passes are traced in launches of up to _LANES_PER_LAUNCH paths: one pass per launch
        # for large frames (memory stays that of a one-sample frame), many for small ones
        # (launch overhead). Every launch reuses the same compiled kernels.
        per_launch = max(1, min(s.passes, _LANES_PER_LAUNCH // n_pix))
        # With one pixel-centre pass and no transparency the pass's primary rays are the
        # label rays: labels and radiance then come from one trace.
        centre_labels = with_labels and s.passes == 1 and not self._transparent
        # Paths that leave the pixel's primary ray are shaded only where it hits the
        # target: a first kernel finds the hits, dr.compress lists them, the shading kernel
        # runs on those lanes alone (a target covering 5 % of the frame costs 5 %).
        compact = s.environment != "off" or s.sun == "sh" or s.bounces > 0
        # Radiance and normals are flat (H, W, 3) arrays that the kernels write in place
        # (packet scatters of the three channels): no reordering pass after them.
        radiance = dr.zeros(mi.Float, 3 * n_pix)
        labels: tuple = ()
        first = 0
        while first < s.passes:
            count = min(per_launch, s.passes - first)
            first_pass = mi.UInt32(first)
            dr.make_opaque(first_pass)
            # Each path adds its radiance to its own lane of ``lane_sum`` (no two paths of a
            # kernel share one, so no atomic operations); with several passes per launch the
            # lanes are pixel-major and each pixel's block is summed in a fixed order, so
            # the same seed gives the same bytes.
            if count == 1:
                pixel, pass_index = idx, first_pass
                lane_sum = radiance
            else:
                lanes = dr.arange(mi.UInt32, n_pix * count)
                pixel, pass_index = lanes // count, first_pass + lanes % count
                lane_sum = dr.zeros(mi.Color3f, n_pix * count)
            geo = self._pass_primary(frame, pixel, pass_index)
            geo["lane"] = pixel if count == 1 else lanes
            if frame["background"]:
                # Rays that miss the target see the Earth or the Moon behind it.
                sky, _ = self._body_light.radiance(
                    frame["bodies"], frame["camera_body"], geo["d_body"], ~geo["hit"]
                )
                dr.scatter_add(
                    lane_sum, sky, geo["lane"], ~geo["hit"], mode=dr.ReduceMode.NoConflicts
                )
            if centre_labels:
                labels = self._labels(frame, geo, idx)
            if compact:
                hits = {k: geo[k] for k in ("face", "u", "v")}
                dr.eval(geo["hit"], *hits.values(), *labels)
                selected = dr.compress(geo["hit"])
                if dr.width(selected) > 0:
                    pixel = dr.gather(mi.UInt32, pixel, selected)
                    lane = pixel
                    if count > 1:
                        pass_index = dr.gather(mi.UInt32, pass_index, selected)
                        lane = dr.gather(mi.UInt32, lanes, selected)
                    hits = {k: dr.gather(type(v), v, selected) for k, v in hits.items()}
                    geo = self._pass_primary(frame, pixel, pass_index, hits)
                    geo["lane"] = lane
                    self._trace(frame, geo, lane_sum)
            else:
                self._trace(frame, geo, lane_sum)
            if count > 1:
                dr.scatter_add(radiance, dr.block_sum(lane_sum, count), idx)
            dr.eval(radiance, *labels)
            first += count
        if with_labels and not centre_labels:
            # Labels: the ray through each pixel centre; transparent parts count as solid
            # above the label opacity threshold.
            px, py = frame["pixel_xy"](idx)
            geo = self._primary(frame, px, py, lambda layer: mi.Float(LABEL_OPACITY_THRESHOLD))
            labels = self._labels(frame, geo, idx)
        if s.passes > 1:
            radiance = radiance * (1.0 / s.passes)
        return radiance, labels

    def _pack_uint16_pairs(self, values):
        """UInt32 values < 2^16, two per UInt32 in memory order, so that numpy reads the
        result as uint16 without a conversion pass."""
        mi, dr = self._mi, self._dr
        n = dr.width(values)
        pair = dr.arange(mi.UInt32, (n + 1) // 2)
        first = dr.gather(mi.UInt32, values, 2 * pair)
        second = dr.gather(mi.UInt32, values, 2 * pair + 1, 2 * pair + 1 < n)
        if sys.byteorder == "big":
            first, second = second, first
        return first | (second << 16)

    # ------------------------------------------------------------------------------------
    def _environment_coefficients(self, light: LightField) -> np.ndarray:
        """(n, 3) SH coefficients of the radiance the renderer treats as environment."""
        n = sh.sh_count(self._l_max)
        coeffs = np.zeros((n, 3))
        if self.settings.environment != "off" or self.settings.sun == "sh":
            m = min(n, light.sh_radiance_w_m2_sr.shape[0])
            bodies_traced = self.settings.environment == "sampled" and light.bodies
            if self.settings.environment != "off" and not bodies_traced:
                coeffs[:m] = light.sh_radiance_w_m2_sr[:m]
            if self.settings.sun == "sh":
                sun = sh.delta_coeffs(light.sun_direction_body, self._l_max)
                coeffs += light.sun_irradiance_w_m2 * sun[:, None]
        return coeffs

    def _primary(self, frame: dict, px, py, opacity_sample, hits: dict | None = None) -> dict:
        """Primary rays through pixel positions (px, py) and the surfaces they stop at.

        hits: the rays' surfaces (face, u, v) found by an earlier trace of the same rays,
        which are then not traced again (and have no ``t``).
        """
        mi, dr = self._mi, self._dr
        d_cam = dr.normalize(
            mi.Vector3f((px - frame["cx"]) / frame["fx"], (py - frame["cy"]) / frame["fx"], 1.0)
        )
        d_body = frame["R_body_from_cam"] @ d_cam
        if hits is None:
            # Start the ray just outside the target's bounding sphere with one rounding
            # (FMA), so the start point and Embree's hit distances keep float32 precision.
            origin = dr.fma(d_body, frame["t_start"], frame["camera_body"])
            geo = self._geometry.intersect(
                origin, d_body, mi.Bool(True), opacity_sample, coherent=True
            )
            geo["t"] = geo["t"] + frame["t_start"]
        else:
            hit = mi.Bool(True)
            geo = {"hit": hit, **self._geometry.surface_at(hits["face"], hits["u"], hits["v"], hit)}
        # Shading normal geo["n"] and geometric normal geo["n_facing"], both on the camera's
        # side, and texture coordinates (mip level from the sub-pixel footprint).
        footprint_m = None
        if self._geometry.textures is not None:
            ss = float(self.settings.supersampling)
            footprint_m = dr.norm(geo["p"] - frame["camera_body"]) / (frame["fx"] * ss)
        geo.update(self._geometry.shading(geo, -d_body, footprint_m))
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

    def _diffuse_environment_table(self, frame: dict):
        """Per face side, the unshadowed environment's diffuse radiance over kd_eq,
        1 / pi * sum_l k_l E_l(n) (Color3f, W m^-2 sr^-1): entry ``face`` for the side of
        the stored normal, ``face + faces`` for the other (see ``TargetGeometry.face_side``).

        Normals are flat per face, so this one small kernel per frame replaces the SH
        evaluation at every shaded lane by a gather. None where the mesh has shading
        normals: the sum is then evaluated at each hit's shading normal.
        """
        mi, dr = self._mi, self._dr
        if self._geometry.shading_normals:
            return None
        faces = dr.width(self._geometry.face_part)
        side = dr.arange(mi.UInt32, 2 * faces)
        face = side % faces
        n = dr.gather(mi.Vector3f, self._geometry.face_n, face)
        n = dr.select(side < faces, n, -n)
        table = self._diffuse_environment(
            frame, n, dr.gather(mi.UInt32, self._geometry.face_part, face)
        )
        dr.eval(table)
        return table

    def _diffuse_environment(self, frame: dict, n, part):
        """Diffuse radiance over kd_eq from the unshadowed environment at unit normal n:
        1 / pi * sum_l k_l E_l(n), with the part's band factors k_l, clamped at 0."""
        mi, dr = self._mi, self._dr
        basis = sh.sh_eval_dr(n, self._l_max)
        total = mi.Color3f(0.0)
        bands = self._l_max + 1
        for l in range(bands):
            band = mi.Color3f(0.0)
            for m in range(-l, l + 1):
                k = l * (l + 1) + m
                band += frame["env"][k] * basis[k]
            factor = dr.gather(mi.Float, self._band_factors, part * bands + l)
            total += factor * band
        # Clamped at 0 like the radiance: the truncated expansion can ring below zero.
        return (1.0 / math.pi) * dr.maximum(total, 0.0)

    def _labels(self, frame: dict, geo: dict, pixel):
        """Depth along +z (m), part id (index + 1, 0 background), camera-frame normals
        (flat Float, three per pixel) and, with bodies in view, the background (a 1-tuple
        of the body id, 0 space, 1 Earth, 2 Moon; else empty) of the rays ``geo`` of
        pixels ``pixel``."""
        mi, dr = self._mi, self._dr
        hit = geo["hit"]
        background: tuple = ()
        if frame["background"]:
            _, body = self._body_light.radiance(
                frame["bodies"], frame["camera_body"], geo["d_body"], ~hit
            )
            background = (dr.select(hit, 0, body),)
        depth = dr.select(hit, geo["t"] * geo["d_cam"].z, 0.0)
        part_id = dr.select(hit, geo["part"] + 1, 0)
        n_cam = dr.select(hit, frame["R_cam_from_body"] @ geo["n"], 0.0)
        normals = dr.empty(mi.Float, 3 * dr.width(pixel))
        dr.scatter(normals, n_cam, pixel)  # one packet write of the three components
        return depth, part_id, normals, background

    def _streams(self, frame: dict, idx, pass_index, segment: int):
        """Random numbers of the paths of pixel ``idx`` in pass ``pass_index`` (UInt32):
        (rng, ld) with rng a PCG32 for this path segment and ld(dim) the path's
        low-discrepancy sample in dimension ``dim``.

        The Kronecker sequence's per-pixel random shift is fixed over the frame's passes, so
        the passes of one pixel are stratified; the generators are seeded through TEA
        hashes of (pixel, frame key[, pass, segment]), which decorrelates neighbouring
        pixels and passes. Both depend on the pixel and pass only, so a path continued in a
        later kernel (``segment``) draws the same sequence whatever lane it is on.
        """
        mi, dr = self._mi, self._dr
        shift_rng = mi.PCG32(1, mi.sample_tea_64(idx, frame["key0"]), mi.UInt64(frame["key1"]))
        shift = [shift_rng.next_float32() for _ in range(self._n_dims)]
        pass_f = mi.Float(pass_index)
        gens = self._generators

        def ld(dim: int):
            x = dr.fma(pass_f, float(gens[dim]), shift[dim])
            # Fractional part, kept below 1 in float32.
            return dr.minimum(x - dr.floor(x), 0.99999994)

        salt = (0x7F4A7C15 + segment * 0x85EBCA6B) & 0xFFFFFFFF
        key = frame["key0"] ^ (pass_index * 0x9E3779B9 + salt)
        rng = mi.PCG32(1, mi.sample_tea_64(idx, key), mi.UInt64(frame["key1"]) + 1)
        return rng, ld

    def _pass_primary(self, frame: dict, idx, pass_index, hits: dict | None = None) -> dict:
        """The primary ray of pixel ``idx`` in pass ``pass_index`` (UInt32) and the surface
        it stops at (see ``_primary``, also for ``hits``), with the path's pixel, pass and
        low-discrepancy sample ``ld``."""
        mi = self._mi
        s = self.settings
        px, py = frame["pixel_xy"](idx)
        rng, ld = self._streams(frame, idx, pass_index, 0)
        ss = float(s.supersampling)
        if s.samples_per_pixel == 1:
            jx, jy = mi.Float(0.5), mi.Float(0.5)
        else:
            jx, jy = ld(0), ld(1)
        stratum = pass_index // s.samples_per_pixel
        ox = (mi.Float(stratum % s.supersampling) + jx) / ss - 0.5
        oy = (mi.Float(stratum // s.supersampling) + jy) / ss - 0.5
        geo = self._primary(frame, px + ox, py + oy, lambda layer: rng.next_float32(), hits)
        geo.update(pixel=idx, pass_index=pass_index, ld=ld)
        return geo

    def _trace(self, frame: dict, geo: dict, lane_sum) -> None:
        """Follow the light paths that start at the primary hits ``geo`` (from
        ``_pass_primary``, with ``lane``: each path's own entry of ``lane_sum``) and add
        their radiance to ``lane_sum`` (Color3f per lane, or a flat Float of three values per
        lane).

        One kernel per path vertex (a wavefront). A vertex's bounce ray is first only
        tested for occlusion (cheaper than finding the hit); the paths whose ray meets the
        target again are listed (dr.compress) and the next kernel, on those lanes alone,
        traces the ray to its hit and shades it. So a vertex costs only the paths that
        reach it. The last kernel is left unevaluated for the caller to launch.
        """
        mi, dr = self._mi, self._dr
        pixel, pass_index, ld = geo["pixel"], geo["pass_index"], geo["ld"]
        lane = geo["lane"]
        vertex = {
            "p": geo["p"],
            "n": geo["n"],
            "n_geo": geo["n_facing"],
            **{k: geo[k] for k in ("uv", "lod") if k in geo},
            "part": geo["part"],
            "wo": -geo["d_body"],
            "side": self._geometry.face_side(geo["face"], geo["n_geo"], -geo["d_body"]),
            "throughput": mi.Color3f(1.0),
        }
        active = geo["hit"]
        for depth in range(self.settings.bounces + 1):

            def rng(segment: int, pixel=pixel, pass_index=pass_index):
                return self._streams(frame, pixel, pass_index, segment)[0]

            value, ray = self._shade_vertex(frame, vertex, active, depth, rng, ld)
            dr.scatter_add(lane_sum, value, lane, active, mode=dr.ReduceMode.NoConflicts)
            if ray is None:
                return
            hit = ray.pop("hit")
            dr.eval(lane_sum, hit, *ray.values())
            selected = dr.compress(hit)
            if dr.width(selected) == 0:
                return
            same = lane is pixel
            pixel = dr.gather(mi.UInt32, pixel, selected)
            lane = pixel if same else dr.gather(mi.UInt32, lane, selected)
            if dr.width(pass_index) > 1:
                pass_index = dr.gather(mi.UInt32, pass_index, selected)
            ray = {k: dr.gather(type(v), v, selected) for k, v in ray.items()}
            # The same stream as the occlusion test, so a partly transparent surface lets
            # the ray through (or not) exactly as it did there.
            opacity, ld = self._streams(frame, pixel, pass_index, self._bounce_segment(depth))
            found = self._geometry.intersect(
                ray["origin"],
                ray["direction"],
                mi.Bool(True),
                lambda layer, opacity=opacity: opacity.next_float32(),
            )
            wo = -ray["direction"]
            ng = found["n_geo"]
            shade = self._geometry.shading(found, wo)
            vertex = {
                "p": found["p"],
                "n": shade["n"],
                "n_geo": shade["n_facing"],
                **{k: shade[k] for k in ("uv",) if k in shade},
                "part": found["part"],
                "wo": wo,
                "side": self._geometry.face_side(found["face"], ng, wo),
                "throughput": ray["throughput"],
            }
            # Occlusion test and hit search agree but for rounding at edges; a path whose
            # ray finds no surface after all ends there.
            active = found["hit"]

    def _body_light_sample(
        self, frame, surface, params, shading, origin, wo_local, active, depth: int, rng, ld
    ):
        """Light from the Earth and the Moon by one direction sampled in a body's cone,
        shadowed by the target, weighted against BRDF sampling (power heuristic)."""
        mi, dr = self._mi, self._dr
        bodies = frame["bodies"]
        base = self._light_dims + 3 * depth
        wi, pdf_light = self._body_light.sample(
            bodies, origin, ld(base), ld(base + 1), ld(base + 2)
        )
        wi_local = shading.to_local(wi)
        ok = active & (wi_local.z > 0.0) & (pdf_light > 0.0)
        sky, _ = self._body_light.radiance(bodies, origin, wi, ok)
        ok &= dr.max(sky) > 0.0
        ok &= self._geometry.visible(origin, wi, ok, rng(self._light_segment(depth)))
        f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
        pdf_brdf = surface.pdf(params, wi_local, wo_local)
        mis = dr.square(pdf_light) / dr.maximum(dr.square(pdf_light) + dr.square(pdf_brdf), 1e-30)
        weight = wi_local.z * mis / dr.maximum(pdf_light, 1e-30)
        return dr.select(ok, (f_diffuse + f_specular) * sky * weight, mi.Color3f(0.0))

    @staticmethod
    def _light_segment(depth: int) -> int:
        """Random-stream segment of the body-light shadow ray at path vertex ``depth``."""
        return 1000 + depth

    @staticmethod
    def _shading_segment(depth: int) -> int:
        """Random-stream segment of the shadow rays at path vertex ``depth``."""
        return 1 + 2 * depth

    @staticmethod
    def _bounce_segment(depth: int) -> int:
        """Random-stream segment of the bounce ray that leaves path vertex ``depth``."""
        return 2 + 2 * depth

    def _shade_vertex(self, frame: dict, vertex: dict, active, depth: int, rng, ld):
        """Radiance a path picks up at one surface vertex, and the ray it continues on.

        vertex: p, n (unit normal on the side of wo), part, wo (towards the previous
        vertex), side (see ``TargetGeometry.face_side``), throughput (path weight so far).
        rng(segment): the path's PCG32 of a stream segment. Returns (radiance Color3f, ray)
        with ray None at the path's last vertex, else ``hit`` (the ray meets the target),
        origin, direction and the path's throughput after this vertex.
        """
        mi, dr = self._mi, self._dr
        s = self.settings
        env_on = s.environment != "off" or s.sun == "sh"
        surface = self._surface if depth == 0 else self._surface_indirect
        p, n, part, wo = vertex["p"], vertex["n"], vertex["part"], vertex["wo"]
        throughput = vertex["throughput"]
        shading = mi.Frame3f(n)
        wo_local = shading.to_local(wo)
        origin = p + vertex["n_geo"] * frame["eps"]  # off the geometric surface
        params = surface.at(part, active, vertex, shading)  # gathered once per surface hit
        radiance = mi.Color3f(0.0)
        if s.sun == "delta":
            wi = frame["sun_dir"]
            wi_local = shading.to_local(wi)
            lit = active & (wi_local.z > 0.0) & (frame["sun_e"] > 0.0)
            if self._geometry.shading_normals:  # no light from below the geometric surface
                lit &= dr.dot(wi, vertex["n_geo"]) > 0.0
            lit &= self._geometry.visible(origin, wi, lit, rng(self._shading_segment(depth)))
            f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
            irradiance = frame["sun_e"] * wi_local.z
            radiance += dr.select(lit, (f_diffuse + f_specular) * irradiance, 0.0)
        if s.environment == "unshadowed":
            table = frame["diffuse_env"]
            if table is None:  # shading normals: the SH sum at each hit's normal
                diffuse_env = self._diffuse_environment(frame, n, part)
            else:
                diffuse_env = dr.gather(type(table), table, vertex["side"], active)
            kd = surface.diffuse_coefficient(params, wo_local)
            radiance += dr.select(active, kd * diffuse_env, 0.0)
        if frame["body_light"]:
            radiance += self._body_light_sample(
                frame, surface, params, shading, origin, wo_local, active, depth, rng, ld
            )
        last = depth == s.bounces
        if last and not env_on:
            return throughput * radiance, None
        base = 2 + 3 * depth
        u2 = mi.Point2f(ld(base + 1), ld(base + 2))
        wi_local, pdf = surface.sample(params, wo_local, ld(base), u2)
        valid = active & (pdf > 0.0) & (wi_local.z > 0.0)
        f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
        cos_over_pdf = wi_local.z / dr.maximum(pdf, 1e-30)
        weight = dr.select(valid, (f_diffuse + f_specular) * cos_over_pdf, 0.0)
        wi = shading.to_world(wi_local)
        if last and s.environment == "unshadowed":
            # No visibility ray for the environment: the path's last vertex sees it
            # unshadowed, as the diffuse part does.
            escaped = valid
        else:
            bounce_rng = rng(self._bounce_segment(depth))
            escaped = valid & self._geometry.visible(origin, wi, valid, bounce_rng)
        if env_on:
            env_weight = weight
            if s.environment == "unshadowed":
                # The diffuse part came from the SH convolution above: only the specular
                # part is taken from the sampled ray.
                env_weight = f_specular * cos_over_pdf
            if not frame["env_zero"]:
                sky = self._environment_radiance(frame, wi)
                radiance += dr.select(escaped, env_weight * sky, 0.0)
            if frame["body_light"]:
                # The BRDF sample's share of the bodies' light (multiple importance
                # sampling with the body-light sample, power heuristic).
                bodies = frame["bodies"]
                sky, _ = self._body_light.radiance(bodies, origin, wi, escaped)
                pdf_light = self._body_light.light_pdf(bodies, origin, wi)
                mis = dr.square(pdf) / dr.maximum(dr.square(pdf) + dr.square(pdf_light), 1e-30)
                radiance += dr.select(escaped, env_weight * sky * mis, 0.0)
        radiance = throughput * radiance
        if last:
            return radiance, None
        return radiance, {
            "hit": valid & ~escaped,
            "origin": origin,
            "direction": wi,
            "throughput": throughput * weight,
        }
