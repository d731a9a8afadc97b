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
light) are opaque (``satsight.render.frame_values``), so frames after the first reuse the
compiled kernels. Render space and ray start are as in ``satsight.render.direct`` (see
docs/design.md).

This module holds the API and the passes over the pixels; the camera rays and labels are
in ``satsight.render.camera_rays``, the light paths in ``satsight.render.path_tracing``
(their records in ``satsight.render.path_records``), the random numbers in
``satsight.render.path_streams`` and the SH environment in
``satsight.render.environment_light``.
"""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField
from satsight.render.backend import use_variant
from satsight.render.body_light import BodyLight
from satsight.render.buffers import RadianceImage, margin_pixels_xy
from satsight.render.camera_rays import LABEL_OPACITY_THRESHOLD, CameraRays
from satsight.render.environment_light import EnvironmentLight
from satsight.render.footprint import FootprintGrid, compose_pixels, plan_footprint
from satsight.render.frame_values import FrameValues
from satsight.render.kernel_arrays import kernel_array
from satsight.render.path_streams import PathStreams
from satsight.render.path_tracing import PathTracer
from satsight.render.settings import RenderSettings
from satsight.render.sunlit_surfaces import SunlitSurfaces
from satsight.render.surface import SurfaceModel, regularized
from satsight.render.target_geometry import TargetGeometry
from satsight.scene.mesh import TargetMesh

# Light paths traced per kernel launch when several passes share one launch.
_LANES_PER_LAUNCH = 1 << 20
# Pixels traced per launch when one pass fills more: a 4096 x 4112 frame in five blocks.
# The kernels' per-ray arrays then hold a block, not the frame (the block's results go
# straight into the frame's buffers), and a frame's memory peak is its buffers plus one
# block's.
_PIXELS_PER_BLOCK = 1 << 22


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
        surface = SurfaceModel(materials, self.settings, textures, shading_normals=shading_normals)
        # Surfaces reached by a bounce: roughness floored (path regularisation).
        surface_indirect = SurfaceModel(
            [regularized(m, self.settings.indirect_min_roughness) for m in materials],
            self.settings,
            textures,
            min_roughness=self.settings.indirect_min_roughness,
            shading_normals=shading_normals,
        )
        self._environment = EnvironmentLight(self.settings, self._geometry, surface)
        surface.evaluate_tables()
        surface_indirect.evaluate_tables()
        self._body_light = BodyLight(self._geometry.origin_body_m)
        streams = PathStreams(self.settings.bounces)
        self._sunlit = None
        if not self._transparent:
            self._sunlit = SunlitSurfaces(
                self._geometry.face_area_m2,
                self._geometry.face_normal,
                mesh.face_part_index,
                materials,
            )
        self._camera_rays = CameraRays(self.settings, self._geometry, self._body_light, streams)
        self._path_tracer = PathTracer(
            self.settings,
            self._geometry,
            surface,
            surface_indirect,
            self._body_light,
            self._environment,
            streams,
            self._sunlit,
        )

    @property
    def settings(self) -> RenderSettings:
        """The render choices (``DirectRenderer`` changes the supersampling between frames)."""
        return self._settings

    @settings.setter
    def settings(self, settings: RenderSettings) -> None:
        self._settings = settings
        # The parts that trace the kernels read the same settings.
        for name in ("_environment", "_camera_rays", "_path_tracer"):
            part = getattr(self, name, None)
            if part is not None:
                part.settings = settings

    # ------------------------------------------------------------------------------------
    def render(
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        light: LightField,
        seed: int = 0,
        margin_px: int = 0,
        normals: bool | str = True,
    ) -> RadianceImage:
        """Render one frame.

        camera: intrinsics and image size. cam_from_body: pose of the target in the camera
        frame. light: the light field at the target, body frame. seed: this frame's seed
        (e.g. from ``SeedSequence([scenario_seed, frame_index])``), so a frame's noise does
        not depend on which frames were rendered before it. margin_px: also render the
        radiance of a ring this wide around the frame (``RadianceImage.margin_radiance_w_m2_sr``),
        which the optics blur into the frame's edge pixels. normals: also the normals image,
        float32 (True) or float16 (``"half"``: what a half-float file holds, 6 bytes a pixel
        instead of 12); False: ``normals_cam`` is None, neither traced nor held.
        """
        mi, dr = self._mi, self._dr
        if mi.variant() != self.variant:  # another renderer switched Mitsuba's variant
            mi.set_variant(self.variant)
        width, height = camera.width_px, camera.height_px
        if cam_from_body.apply(self.mesh.center_m)[2] <= 0:
            raise SatsightError(
                "the target's bounding-box centre is behind the camera (z_cam <= 0); check the pose"
            )
        frame = self._frame_values(camera, cam_from_body, light, seed, margin_px)

        n_pix = width * height
        # Against empty space, or with one pixel-centre pass, only the target's box is
        # traced (the Earth and the Moon outside it drawn along the pixel-centre rays).
        box = None
        if not frame.bodies_in_view or self.settings.passes == 1:
            box = self._target_box_px(camera, cam_from_body)
        grid = None
        if self.settings.integrate_footprint:
            grid = plan_footprint(
                camera,
                cam_from_body,
                self.mesh.box_keypoints_body_m[:8],
                self.mesh.center_m,
                self.mesh.bounding_radius_m,
                self.settings.passes,
            )
        # With a footprint grid, the pixels that can see the target are the grid's, whose
        # radiance the grid replaces: the frame's passes then trace the labels and the
        # bodies behind the target, not the light the target's surfaces send.
        radiance, labels = self._radiance_passes(
            frame, n_pix, with_labels=True, box=box, normals=normals, shade=grid is None
        )
        depth, part_id, normals_image, background = labels
        part_pairs = self._pack_uint16_pairs(part_id)
        dr.eval(radiance, depth, part_pairs, *background)
        if normals_image is not None:
            dr.eval(normals_image)
        margin_radiance = None
        if margin_px > 0:
            if frame.bodies_in_view or self._margin_sees_target(camera, cam_from_body, margin_px):
                margin_radiance = self._render_margin(frame, width, height, margin_px)
            else:  # every ring ray sees empty space (0), as tracing them would give
                ring_count = len(margin_pixels_xy(width, height, margin_px)[0])
                margin_radiance = np.zeros((ring_count, 3), dtype=np.float32)
        radiance_w_m2_sr = radiance.numpy().reshape(height, width, 3)
        if grid is not None:
            if not radiance_w_m2_sr.flags.writeable:
                radiance_w_m2_sr = radiance_w_m2_sr.copy()
            flat = radiance_w_m2_sr.reshape(-1, 3)
            flat[grid.pixels] = self._footprint_radiance(frame, grid).astype(np.float32)

        return RadianceImage(
            radiance_w_m2_sr=radiance_w_m2_sr,
            depth_m=depth.numpy().reshape(height, width),
            part_id=part_pairs.numpy().view(np.uint16)[:n_pix].reshape(height, width),
            normals_cam=None
            if normals_image is None
            else normals_image.numpy().reshape(height, width, 3),
            margin_px=int(margin_px),
            margin_radiance_w_m2_sr=margin_radiance,
            background_id=background[0].numpy().reshape(height, width) if background else None,
            footprint=None if grid is None else grid.label(),
        )

    def _frame_values(
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        light: LightField,
        seed: int,
        margin_px: int,
    ) -> FrameValues:
        """The frame's values for the kernels, its Dr.Jit scalars opaque (so that every
        frame reuses the kernels compiled for the first)."""
        mi, dr = self._mi, self._dr
        s = self.settings
        width = camera.width_px
        body_from_cam = cam_from_body.inverse()
        camera_render_m = body_from_cam.t_a_from_b_m - self._geometry.origin_body_m
        env = self._environment.coefficients(light)
        opaque = {
            "R_body_from_cam": mi.Matrix3f(body_from_cam.R_a_from_b.astype(np.float32)),
            "R_cam_from_body": mi.Matrix3f(cam_from_body.R_a_from_b.astype(np.float32)),
            "camera_render_m": mi.Point3f(*(float(c) for c in camera_render_m)),
            "focal_length_px": mi.Float(float(camera.focal_length_px)),
            "cx_px": mi.Float(float(camera.cx_px)),
            "cy_px": mi.Float(float(camera.cy_px)),
            "sun_direction_body": mi.Vector3f(*(float(c) for c in light.sun_direction_body)),
            "sun_irradiance_w_m2": mi.Float(float(light.sun_irradiance_w_m2)),
            "ray_offset_m": mi.Float(float(self._geometry.ray_offset_m)),
            "ray_start_m": mi.Float(self._geometry.ray_start_m(camera_render_m)),
            # Two 32-bit keys of the frame seed, for the TEA hashes that seed the generators.
            "seed_key0": mi.UInt32(int(seed) & 0xFFFFFFFF),
            "seed_key1": mi.UInt32((int(seed) >> 32) & 0xFFFFFFFF),
        }
        env_sh = tuple(mi.Color3f(*(float(v) for v in row)) for row in env)
        dr.make_opaque(*opaque.values(), *env_sh)
        bodies = self._body_light.frame_values(light.bodies, s.environment == "sampled")
        return FrameValues(
            **opaque,
            env_sh_radiance_w_m2_sr=env_sh,
            bodies=bodies,
            env_is_zero=not np.any(env),
            # Bodies light the target in the sampled mode; every mode shows them behind it.
            bodies_light_target=s.environment == "sampled" and bodies.any_lit,
            bodies_in_view=bodies.any_lit
            and self._bodies_in_view(camera, cam_from_body, light, margin_px),
            pixel_position_px=lambda pixel: (mi.Float(pixel % width), mi.Float(pixel // width)),
            diffuse_env_table=self._environment.diffuse_table(env_sh)
            if s.environment == "unshadowed"
            else None,
            sunlit_tables=self._sunlit.frame_tables(light.sun_direction_body)
            if self._sunlit is not None
            and s.sunlit_sampling
            and s.sun == "delta"
            and s.bounces > 0
            and light.sun_irradiance_w_m2 > 0.0
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

    def _render_margin(
        self, frame: FrameValues, width: int, height: int, margin_px: int
    ) -> np.ndarray:
        """(n, 3) float32 radiance of the pixels of a ``margin_px`` wide ring around the
        frame (``margin_pixels_xy`` order): the light the optics spread into the frame from
        just outside it. Its random streams are apart from the frame's (another key)."""
        mi, dr = self._mi, self._dr
        ring_x, ring_y = margin_pixels_xy(width, height, margin_px)
        table_x = kernel_array(mi.Float, ring_x.astype(np.float32))
        table_y = kernel_array(mi.Float, ring_y.astype(np.float32))
        ring = dataclasses.replace(
            frame,
            seed_key0=frame.seed_key0 ^ 0x5BD1E995,
            pixel_position_px=lambda pixel: (
                dr.gather(mi.Float, table_x, pixel),
                dr.gather(mi.Float, table_y, pixel),
            ),
        )
        radiance, _ = self._radiance_passes(ring, len(ring_x), with_labels=False)
        dr.eval(radiance)
        return radiance.numpy().reshape(-1, 3)

    def _footprint_radiance(self, frame: FrameValues, grid: FootprintGrid) -> np.ndarray:
        """(len(grid.pixels), 3) radiance of the pixels under a small target's fine grid:
        one path per cell along its anchored ray (its own random streams, another key),
        summed over each pixel's area with the background at the pixel centre."""
        mi, dr = self._mi, self._dr
        origin = mi.Point3f(
            *(kernel_array(mi.Float, c) for c in grid.origin_render_m.T.astype(np.float32))
        )
        direction = mi.Vector3f(
            *(kernel_array(mi.Float, c) for c in grid.direction_body.T.astype(np.float32))
        )
        cells = dataclasses.replace(
            frame,
            seed_key0=frame.seed_key0 ^ 0x2545F491,
            anchored_rays=lambda index: (
                dr.gather(mi.Point3f, origin, index),
                dr.gather(mi.Vector3f, direction, index),
            ),
        )
        settings = self.settings
        self.settings = settings.with_(supersampling=1, samples_per_pixel=1)
        try:
            radiance, _ = self._radiance_passes(cells, grid.sample_count, with_labels=False)
            dr.eval(radiance)
        finally:
            self.settings = settings
        samples = radiance.numpy().reshape(-1, 3)
        background = None
        if frame.bodies_in_view:
            background = self._background_radiance(frame, grid)
        return compose_pixels(grid, samples, background)

    def _background_radiance(self, frame: FrameValues, grid: FootprintGrid) -> np.ndarray:
        """(len(grid.pixels), 3) radiance of the Earth or the Moon (0 for space) along the
        camera rays through the centres of the grid's pixels, the target left out."""
        mi, dr = self._mi, self._dr
        columns = grid.pixels % grid.frame_width_px
        rows = grid.pixels // grid.frame_width_px
        px = kernel_array(mi.Float, columns.astype(np.float32))
        py = kernel_array(mi.Float, rows.astype(np.float32))
        _, d_body = self._camera_rays.directions(frame, px, py)
        value, _ = self._body_light.radiance(
            frame.bodies, frame.camera_render_m, d_body, mi.Bool(True)
        )
        dr.eval(value)
        return np.stack([value[k].numpy() for k in range(3)], axis=-1)

    def _projected_box_px(self, camera: PinholeCamera, cam_from_body: RigidTransform):
        """(x0, y0, x1, y1), exclusive ends, unclipped: the pixels whose rays may meet the
        target, those of the projected corners of its box widened by a pixel for the
        passes' sub-pixel positions; None when the box reaches behind the camera."""
        corners = cam_from_body.apply(self.mesh.box_keypoints_body_m[:8])
        if np.any(corners[:, 2] <= 0):
            return None
        uv = camera.project(corners)
        return (
            int(np.floor(uv[:, 0].min())) - 1,
            int(np.floor(uv[:, 1].min())) - 1,
            int(np.ceil(uv[:, 0].max())) + 2,
            int(np.ceil(uv[:, 1].max())) + 2,
        )

    def _target_box_px(self, camera: PinholeCamera, cam_from_body: RigidTransform):
        """(x0, y0, x1, y1, width): the image's pixels whose rays may meet the target
        (``_projected_box_px`` within the image), or None when that is the whole image or
        the box reaches behind the camera. Every other pixel sees empty space: radiance and
        labels 0."""
        projected = self._projected_box_px(camera, cam_from_body)
        if projected is None:
            return None
        width, height = camera.width_px, camera.height_px
        x0, y0 = max(0, projected[0]), max(0, projected[1])
        x1, y1 = min(width, projected[2]), min(height, projected[3])
        if x1 <= x0 or y1 <= y0:
            return (0, 0, 0, 0, width)
        if (x1 - x0) * (y1 - y0) > 0.5 * width * height:
            return None  # most of the frame: tracing it whole is as cheap
        return (x0, y0, x1, y1, width)

    def _margin_sees_target(
        self, camera: PinholeCamera, cam_from_body: RigidTransform, margin_px: int
    ) -> bool:
        """Whether a ray of the ring ``margin_px`` wide around the image may meet the target
        (``_projected_box_px`` reaches into the ring, or behind the camera)."""
        box = self._projected_box_px(camera, cam_from_body)
        if box is None:
            return True
        m, width, height = margin_px, camera.width_px, camera.height_px
        x0, y0 = max(-m, box[0]), max(-m, box[1])
        x1, y1 = min(width + m, box[2]), min(height + m, box[3])
        if x1 <= x0 or y1 <= y0:
            return False  # the box misses the image and its ring
        return x0 < 0 or y0 < 0 or x1 > width or y1 > height

    def _radiance_passes(
        self,
        frame: FrameValues,
        n_pix: int,
        with_labels: bool,
        box: tuple | None = None,
        normals: bool | str = True,
        shade: bool = True,
    ) -> tuple:
        """Radiance (flat Float, three values per pixel) of pixels 0..n_pix-1 (positions
        from ``frame.pixel_position_px``), averaged over the settings' passes, and, with
        ``with_labels``, the label images (depth, part id, normals) of the pixel centres.
        box: (x0, y0, x1, y1, width), the only pixels of an image that passes of one path
        per pixel trace (``_target_box_px``); the others keep radiance and labels 0, but
        for the Earth and the Moon behind the target (``_bodies_outside_box``). normals:
        whether the labels hold the normals image, and its type (``render``'s). shade:
        False leaves out the light of the target's surfaces (the paths past the camera
        rays), for pixels whose radiance is replaced (``render``'s footprint grid); the
        bodies behind the target are still drawn."""
        mi, dr = self._mi, self._dr
        s = self.settings
        camera_rays = self._camera_rays
        idx = dr.arange(mi.UInt32, n_pix)

        # Passes are traced in launches of up to _LANES_PER_LAUNCH paths: one pass per launch
        # for large frames (memory stays that of a one-sample frame), many for small ones
        # (launch overhead). Every launch reuses the same compiled kernels.
        per_launch = max(1, min(s.passes, _LANES_PER_LAUNCH // n_pix))
        # With one pixel-centre pass and no transparency the pass's primary rays are the
        # label rays: labels and radiance then come from one trace.
        centre_labels = with_labels and s.passes == 1 and not self._transparent
        # Radiance and normals are flat (H, W, 3) arrays that the kernels write in place
        # (packet scatters of the three channels): no reordering pass after them.
        radiance = dr.zeros(mi.Float, 3 * n_pix)
        labels: tuple = ()
        if centre_labels:  # written block by block (``CameraRays.labels_into``)
            normals_image = dr.zeros(self._normals_type(normals), 3 * n_pix) if normals else None
            labels = (dr.zeros(mi.Float, n_pix), dr.zeros(mi.UInt32, n_pix), normals_image)
            if frame.bodies_in_view:
                labels += (dr.zeros(mi.UInt8, n_pix),)
        first = 0
        while first < s.passes:
            count = min(per_launch, s.passes - first)
            first_pass = mi.UInt32(first)
            dr.make_opaque(first_pass)
            # Each path adds its radiance to its own lane of ``lane_sum`` (no two paths of a
            # kernel share one, so no atomic operations); with several passes per launch the
            # lanes are pixel-major and each pixel's block is summed in a fixed order, so
            # the same seed gives the same bytes. A pass of one path per pixel is traced in
            # blocks of pixels (its lanes are the pixels: the same paths, the same bytes).
            if count == 1:
                traced = n_pix
                if box is not None:
                    x0, y0, x1, y1, width = box
                    traced = (x1 - x0) * (y1 - y0)
                    # The box's corner and width are opaque: as literals they would make
                    # new kernels (compiled, 0.1-0.5 s each) for every box, every frame.
                    box_x0, box_y0, box_width = (dr.opaque(mi.UInt32, v) for v in (x0, y0, x1 - x0))
                for start in range(0, traced, _PIXELS_PER_BLOCK):
                    block = dr.arange(mi.UInt32, start, min(traced, start + _PIXELS_PER_BLOCK))
                    if box is not None:  # the box's pixels, row by row
                        block = (box_y0 + block // box_width) * width + box_x0 + block % box_width
                    self._trace_lanes(frame, block, first_pass, block, radiance, labels, shade)
                    dr.eval(radiance, *labels)
                if box is not None and frame.bodies_in_view:
                    self._bodies_outside_box(frame, box, n_pix, radiance, labels)
            else:
                lanes = dr.arange(mi.UInt32, n_pix * count)
                pixel, pass_index = lanes // count, first_pass + lanes % count
                lane_sum = dr.zeros(mi.Color3f, n_pix * count)
                self._trace_lanes(frame, pixel, pass_index, lanes, lane_sum, (), shade)
                dr.scatter_add(radiance, dr.block_sum(lane_sum, count), idx)
                dr.eval(radiance)
            first += count
        if centre_labels:  # (depth, part id, normals, (background,) or ())
            labels = (*labels[:3], tuple(labels[3:]))
        if with_labels and not centre_labels:
            # Labels: the ray through each pixel centre; transparent parts count as solid
            # above the label opacity threshold.
            px, py = frame.pixel_position_px(idx)
            rays = camera_rays.primary(
                frame, px, py, lambda layer: mi.Float(LABEL_OPACITY_THRESHOLD)
            )
            labels = camera_rays.labels(frame, rays, idx)
            image = self._normals_type(normals)(labels[2]) if normals else None
            labels = (labels[0], labels[1], image, labels[3])  # (never evaluated if None)
        if s.passes > 1:
            radiance = radiance * (1.0 / s.passes)
        return radiance, labels

    def _normals_type(self, normals: bool | str):
        """The flat array type of the normals image: Float (True), or its float16 for
        ``"half"``."""
        if normals == "half":
            return self._dr.float16_array_t(self._mi.Float)
        if normals is not True:
            raise ValueError(f"normals must be True, False or 'half', got {normals!r}")
        return self._mi.Float

    def _bodies_outside_box(self, frame: FrameValues, box: tuple, n_pix: int, radiance, labels):
        """Add the Earth's and the Moon's radiance along the pixel-centre rays of the pixels
        outside ``box`` (x0, y0, x1, y1, width), which cannot meet the target, to
        ``radiance``, and write their background label (``labels``' fourth image, if any):
        what tracing them would give, without the ray casts. The frame has one pass whose
        rays go through the pixel centres (``passes == 1``)."""
        mi, dr = self._mi, self._dr
        x0, y0, x1, y1, width = box
        box_width = x1 - x0
        above = y0 * width  # the rows above the box, then beside it, then below it
        beside = (y1 - y0) * (width - box_width)
        outside = n_pix - (y1 - y0) * box_width
        row_part = max(1, width - box_width)  # pixels beside the box in a row (never 0)
        # Opaque, as in ``_radiance_passes``: one compiled kernel for every box.
        opaque = {name: dr.opaque(mi.UInt32, value) for name, value in (
            ("x0", x0), ("y0", y0), ("box_width", box_width), ("above", above),
            ("beside", beside), ("row_part", row_part), ("box_pixels", (y1 - y0) * box_width),
        )}  # fmt: skip
        for start in range(0, outside, _PIXELS_PER_BLOCK):
            index = dr.arange(mi.UInt32, start, min(outside, start + _PIXELS_PER_BLOCK))
            side = index - opaque["above"]
            column = side % opaque["row_part"]
            beside_pixel = (opaque["y0"] + side // opaque["row_part"]) * width + dr.select(
                column < opaque["x0"], column, column + opaque["box_width"]
            )
            pixel = dr.select(
                index < opaque["above"],
                index,
                dr.select(
                    index < opaque["above"] + opaque["beside"],
                    beside_pixel,
                    index + opaque["box_pixels"],
                ),
            )
            px, py = frame.pixel_position_px(pixel)
            _, d_body = self._camera_rays.directions(frame, px, py)
            sky, body = self._body_light.radiance(
                frame.bodies, frame.camera_render_m, d_body, mi.Bool(True)
            )
            dr.scatter_add(radiance, sky, pixel, mode=dr.ReduceMode.NoConflicts)
            if len(labels) > 3:
                dr.scatter(labels[3], mi.UInt8(body), pixel)
            dr.eval(radiance, *labels)

    def _trace_lanes(
        self, frame: FrameValues, pixel, pass_index, lane, lane_sum, labels, shade: bool = True
    ):
        """Trace the paths of pixels ``pixel`` in passes ``pass_index`` and add their radiance
        to entries ``lane`` of ``lane_sum``; with ``labels`` (the frame's label images),
        write the pixels' labels into them. shade: False adds only the bodies seen past the
        target, not the light of its surfaces (``_radiance_passes``)."""
        mi, dr = self._mi, self._dr
        s = self.settings
        camera_rays, tracer = self._camera_rays, self._path_tracer
        rays, path = camera_rays.pass_primary(frame, pixel, pass_index, lane)
        if frame.bodies_in_view:
            # Rays that miss the target see the Earth or the Moon behind it.
            sky, _ = self._body_light.radiance(
                frame.bodies, frame.camera_render_m, rays.direction_body, ~rays.hit
            )
            dr.scatter_add(lane_sum, sky, path.lane, ~rays.hit, mode=dr.ReduceMode.NoConflicts)
        if labels:
            camera_rays.labels_into(frame, rays, pixel, labels)
        if not shade:
            return
        # Paths that leave the pixel's primary ray are shaded only where it hits the
        # target: a first kernel finds the hits, dr.compress lists them, the shading kernel
        # runs on those lanes alone (a target covering 5 % of the frame costs 5 %).
        if not (s.environment != "off" or s.sun == "sh" or s.bounces > 0):
            tracer.trace(frame, rays, path, lane_sum)
            return
        hits = (rays.surface.face, rays.surface.u, rays.surface.v)
        dr.eval(rays.hit, *hits, *labels)
        selected = dr.compress(rays.hit)
        if dr.width(selected) == 0:
            return
        same = lane is pixel  # one pass: a path's lane is its pixel
        pixel = dr.gather(mi.UInt32, pixel, selected)
        if dr.width(pass_index) > 1:
            pass_index = dr.gather(mi.UInt32, pass_index, selected)
        lane = pixel if same else dr.gather(mi.UInt32, lane, selected)
        hits = tuple(dr.gather(type(v), v, selected) for v in hits)
        rays, path = camera_rays.pass_primary(frame, pixel, pass_index, lane, hits)
        tracer.trace(frame, rays, path, lane_sum)

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
