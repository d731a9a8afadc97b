"""Camera rays of the renderer: where each pixel's rays stop on the target, and the label
images (depth, part id, normals, background body) of the pixel centres.

A camera ray starts just outside the target's bounding sphere (render space and ray start
as in ``satsight.render.direct``, see docs/design.md). Its sub-pixel position is that of
its pass: s x s strata of supersampling, jittered by the path's low-discrepancy sample
where there are several samples per pixel.
"""

from __future__ import annotations

from satsight.render.body_light import BodyLight
from satsight.render.frame_values import FrameValues
from satsight.render.path_records import CameraRayHit, PathStart
from satsight.render.path_streams import PathStreams, texture_segment
from satsight.render.settings import RenderSettings
from satsight.render.target_geometry import TargetGeometry

# Opacity above which a surface counts as solid for the label images.
LABEL_OPACITY_THRESHOLD = 0.5


class CameraRays:
    """The camera rays of one renderer: its settings, target, bodies and random streams."""

    def __init__(
        self,
        settings: RenderSettings,
        geometry: TargetGeometry,
        body_light: BodyLight,
        streams: PathStreams,
    ) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.settings = settings
        self._geometry = geometry
        self._body_light = body_light
        self._streams = streams

    def primary(
        self,
        frame: FrameValues,
        px,
        py,
        opacity_sample,
        hits: tuple | None = None,
        footprint_sample=None,
    ) -> CameraRayHit:
        """Camera rays through image positions (px, py) (px) and the surfaces they stop at.

        hits: the rays' surfaces (face, u, v) found by an earlier trace of the same rays,
        which are then not traced again (and have no distance). footprint_sample: a
        function giving uniform random numbers (Float), for the point of the footprint
        whose textures the hit takes with ``texture_filter="stochastic"``; None: the
        footprint's mip level.
        """
        dr = self._dr
        d_cam, d_body = self.directions(frame, px, py)
        # Start the ray just outside the target's bounding sphere with one rounding (FMA),
        # so the start point and Embree's hit distances keep float32 precision.
        origin = dr.fma(d_body, frame.ray_start_m, frame.camera_render_m)
        return self._surfaces(
            frame, origin, d_body, d_cam, frame.ray_start_m, opacity_sample, hits, footprint_sample
        )

    def directions(self, frame: FrameValues, px, py) -> tuple:
        """Unit directions (camera frame, body frame) of the camera rays through image
        positions (px, py), px."""
        mi, dr = self._mi, self._dr
        d_cam = dr.normalize(
            mi.Vector3f(
                (px - frame.cx_px) / frame.focal_length_px,
                (py - frame.cy_px) / frame.focal_length_px,
                1.0,
            )
        )
        return d_cam, frame.R_body_from_cam @ d_cam

    def anchored(
        self,
        frame: FrameValues,
        idx,
        opacity_sample,
        hits: tuple | None = None,
        footprint_sample=None,
    ):
        """The rays of ``frame.anchored_rays`` (entry ``idx``: a start in front of the target,
        render space, and a unit direction, body frame; see ``render.footprint``) and the
        surfaces they stop at (``primary``; distances from the start)."""
        origin, d_body = frame.anchored_rays(idx)
        d_cam = frame.R_cam_from_body @ d_body
        return self._surfaces(
            frame, origin, d_body, d_cam, 0.0, opacity_sample, hits, footprint_sample
        )

    def _surfaces(
        self,
        frame: FrameValues,
        origin,
        d_body,
        d_cam,
        start_m,
        opacity_sample,
        hits,
        footprint_sample=None,
    ) -> CameraRayHit:
        mi, dr = self._mi, self._dr
        if hits is None:
            found = self._geometry.intersect(
                origin, d_body, mi.Bool(True), opacity_sample, coherent=True
            )
            hit, surface = found.hit, found.surface
            distance_m = found.distance_m + start_m
        else:
            hit = mi.Bool(True)
            surface = self._geometry.surface_at(*hits, hit)
            distance_m = None
        # Shading normal and geometric normal, both on the camera's side, and texture
        # coordinates (mip level from the sub-pixel footprint).
        footprint_m = point = None
        if self._geometry.textures is not None:
            ss = float(self.settings.supersampling)
            footprint_m = dr.norm(surface.point_m - frame.camera_render_m) / (
                frame.focal_length_px * ss
            )
            if footprint_sample is not None and self.settings.texture_filter == "stochastic":
                point = mi.Point2f(footprint_sample(), footprint_sample())
        shading = self._geometry.shading(surface, hit, -d_body, footprint_m, point)
        return CameraRayHit(hit, distance_m, surface, shading, d_cam, d_body)

    def pass_primary(
        self, frame: FrameValues, idx, pass_index, lane, hits: tuple | None = None
    ) -> tuple[CameraRayHit, PathStart]:
        """The camera ray of pixel ``idx`` in pass ``pass_index`` (UInt32) and the surface
        it stops at (see ``primary``, also for ``hits``), with the path it starts (its
        radiance goes to entry ``lane`` of the sum)."""
        mi = self._mi
        s = self.settings
        rng, ld = self._streams.streams(frame, idx, pass_index, 0)
        footprint_sample = None
        if s.texture_filter == "stochastic" and self._geometry.textures is not None:
            texture_rng = self._streams.streams(frame, idx, pass_index, texture_segment())[0]
            footprint_sample = texture_rng.next_float32
        if frame.anchored_rays is not None:  # one path per ray, no sub-pixel position
            hit = self.anchored(
                frame, idx, lambda layer: rng.next_float32(), hits, footprint_sample
            )
            return hit, PathStart(idx, pass_index, ld, lane)
        px, py = frame.pixel_position_px(idx)
        ss = float(s.supersampling)
        if s.samples_per_pixel == 1:
            jx, jy = mi.Float(0.5), mi.Float(0.5)
        else:
            jx, jy = ld(0), ld(1)
        stratum = pass_index // s.samples_per_pixel
        ox = (mi.Float(stratum % s.supersampling) + jx) / ss - 0.5
        oy = (mi.Float(stratum // s.supersampling) + jy) / ss - 0.5
        hit = self.primary(
            frame, px + ox, py + oy, lambda layer: rng.next_float32(), hits, footprint_sample
        )
        return hit, PathStart(idx, pass_index, ld, lane)

    def labels(self, frame: FrameValues, rays: CameraRayHit, pixel):
        """Depth along +z (m), part id (index + 1, 0 background), camera-frame normals
        (flat Float, three per pixel) and, with bodies in view, the background (a 1-tuple
        of the body id, 0 space, 1 Earth, 2 Moon; else empty) of the camera rays ``rays``
        of pixels ``pixel``."""
        mi, dr = self._mi, self._dr
        depth, part_id, n_cam, background = self._label_values(frame, rays)
        normals = dr.empty(mi.Float, 3 * dr.width(pixel))
        dr.scatter(normals, n_cam, pixel)  # one packet write of the three components
        return depth, part_id, normals, background

    def labels_into(self, frame: FrameValues, rays: CameraRayHit, pixel, images: tuple) -> None:
        """The labels of ``labels`` written into the whole frame's label images ``images``
        (depth, part id, flat normals or None[, background]) at entries ``pixel``: one block of
        pixels of a frame traced in blocks."""
        dr = self._dr
        depth, part_id, n_cam, background = self._label_values(frame, rays)
        if images[2] is not None and dr.type_v(images[2]) == dr.VarType.Float16:
            n_cam = dr.float16_array_t(type(n_cam))(n_cam)  # a half-float normals image
        for image, value in zip(images, (depth, part_id, n_cam, *background), strict=True):
            if image is not None:  # (the normals when none are asked for)
                dr.scatter(image, value, pixel)

    def _label_values(self, frame: FrameValues, rays: CameraRayHit) -> tuple:
        """(depth, part id, normal in camera axes (Vector3f), background tuple) per ray."""
        dr = self._dr
        hit = rays.hit
        background: tuple = ()
        if frame.bodies_in_view:
            _, body = self._body_light.radiance(
                frame.bodies, frame.camera_render_m, rays.direction_body, ~hit
            )
            background = (self._mi.UInt8(dr.select(hit, 0, body)),)  # one byte a pixel
        depth = dr.select(hit, rays.distance_m * rays.direction_cam.z, 0.0)
        part_id = dr.select(hit, rays.surface.part + 1, 0)
        n_cam = dr.select(hit, frame.R_cam_from_body @ rays.shading.normal, 0.0)
        return depth, part_id, n_cam, background
