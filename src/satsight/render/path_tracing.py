"""Light paths of the renderer: from a camera ray's surface over ``bounces`` further
surfaces, with the light each vertex picks up (paper Eq. 21).

At each vertex: the Sun by one shadow ray (``sun="delta"``), the unshadowed environment's
diffuse part from its SH convolution (``environment="unshadowed"``), the Earth and the
Moon by one body-light sample (``environment="sampled"``), and one BRDF-sampled ray that
picks up the environment where it leaves the target and continues the path where it meets
the target again (throughput f cos / pdf). Body-light and BRDF samples of the bodies are
weighted by multiple importance sampling (power heuristic). A vertex whose path goes on
also samples a point of the sunlit target and adds the Sun's light it reflects, weighted
against the bounce ray's way to that light (``satsight.render.sunlit_surfaces``).
"""

from __future__ import annotations

from satsight.render.body_light import BodyLight
from satsight.render.environment_light import EnvironmentLight
from satsight.render.frame_values import FrameValues
from satsight.render.path_records import BounceRay, CameraRayHit, PathStart, PathVertex
from satsight.render.path_streams import (
    PathStreams,
    bounce_segment,
    light_segment,
    shading_segment,
    sunlit_segment,
)
from satsight.render.settings import RenderSettings
from satsight.render.sunlit_surfaces import SunlitSurfaces
from satsight.render.surface import SurfaceModel
from satsight.render.target_geometry import TargetGeometry

# A sampled point q seen this close to edge-on gives no sample (and the bounce ray's
# weight there is then 1).
_MIN_COS_Q = 1e-6


class PathTracer:
    """The light paths of one renderer.

    surface: the parts' reflection models at the first vertex; surface_indirect: those at
    vertices reached by a bounce (roughness floored, path regularisation). sunlit: the
    target's faces as sources of reflected sunlight, or None to leave that light to the
    bounce rays alone.
    """

    def __init__(
        self,
        settings: RenderSettings,
        geometry: TargetGeometry,
        surface: SurfaceModel,
        surface_indirect: SurfaceModel,
        body_light: BodyLight,
        environment: EnvironmentLight,
        streams: PathStreams,
        sunlit: SunlitSurfaces | None = None,
    ) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.settings = settings
        self._geometry = geometry
        self._surface = surface
        self._surface_indirect = surface_indirect
        self._body_light = body_light
        self._environment = environment
        self._streams = streams
        self._sunlit = sunlit

    def trace(self, frame: FrameValues, start: CameraRayHit, path: PathStart, lane_sum) -> None:
        """Follow the light paths ``path`` that start at the camera rays' surfaces
        ``start`` and add their radiance to ``lane_sum`` (entry ``path.lane``; Color3f per
        lane, or a flat Float of three values per lane).

        One kernel per path vertex (a wavefront). A vertex's bounce ray is first only
        tested for occlusion (cheaper than finding the hit); the paths whose ray meets the
        target again are listed (dr.compress) and the next kernel, on those lanes alone,
        traces the ray to its hit and shades it. So a vertex costs only the paths that
        reach it. The last kernel is left unevaluated for the caller to launch.
        """
        mi, dr = self._mi, self._dr
        pixel, pass_index, ld = path.pixel, path.pass_index, path.low_discrepancy
        lane = path.lane
        vertex = PathVertex(
            point_m=start.surface.point_m,
            normal=start.shading.normal,
            normal_geo=start.shading.normal_facing,
            uv=start.shading.uv,
            mip_level=start.shading.mip_level,
            part=start.surface.part,
            wo=-start.direction_body,
            face_side=self._geometry.face_side(
                start.surface.face, start.surface.normal_geo, -start.direction_body
            ),
            throughput=mi.Color3f(1.0),
            normal_smooth=start.shading.normal_smooth,
            lift_m=start.shading.lift_m,
        )
        active = start.hit
        for depth in range(self.settings.bounces + 1):

            def rng(segment: int, pixel=pixel, pass_index=pass_index):
                return self._streams.streams(frame, pixel, pass_index, segment)[0]

            value, ray = self._shade_vertex(frame, vertex, active, depth, rng, ld)
            dr.scatter_add(lane_sum, value, lane, active, mode=dr.ReduceMode.NoConflicts)
            if ray is None:
                return
            hit = ray.meets_target
            dr.eval(lane_sum, hit, ray.origin_m, ray.direction, ray.throughput, ray.pdf)
            selected = dr.compress(hit)
            if dr.width(selected) == 0:
                return
            same = lane is pixel
            pixel = dr.gather(mi.UInt32, pixel, selected)
            lane = pixel if same else dr.gather(mi.UInt32, lane, selected)
            if dr.width(pass_index) > 1:
                pass_index = dr.gather(mi.UInt32, pass_index, selected)
            origin, direction, throughput, pdf = (
                dr.gather(type(v), v, selected)
                for v in (ray.origin_m, ray.direction, ray.throughput, ray.pdf)
            )
            # The same stream as the occlusion test, so a partly transparent surface lets
            # the ray through (or not) exactly as it did there.
            opacity, ld = self._streams.streams(frame, pixel, pass_index, bounce_segment(depth))
            found = self._geometry.intersect(
                origin,
                direction,
                mi.Bool(True),
                lambda layer, opacity=opacity: opacity.next_float32(),
            )
            sun_weight = None
            if self._samples_sunlit(frame, depth):
                # The bounce ray's share of the Sun's light at the surface it meets.
                pdf_light = self._sunlit_pdf(
                    frame, found.surface, found.distance_m, direction, found.hit
                )
                count = self._light_count(depth)
                sun_weight = _power_heuristic(pdf, count * pdf_light)
            vertex = self._vertex(found.surface, found.hit, -direction, throughput, sun_weight)
            # Occlusion test and hit search agree but for rounding at edges; a path whose
            # ray finds no surface after all ends there.
            active = found.hit

    def _samples_sunlit(self, frame: FrameValues, depth: int) -> bool:
        """Whether vertex ``depth`` samples the sunlit surfaces (its path goes on)."""
        return (
            self._sunlit is not None
            and frame.sunlit_tables is not None
            and depth < self.settings.bounces
        )

    def _light_count(self, depth: int) -> int:
        """Light samples (of the sunlit surfaces, of the Earth and the Moon) at vertex
        ``depth``: ``light_samples`` at the camera ray's surface, where the light a pixel
        shows is decided, one further on."""
        return self.settings.light_samples if depth == 0 else 1

    def _sunlit_pdf(self, frame: FrameValues, surface, distance_m, direction, hit):
        """Solid-angle density, seen from a ray's origin, with which the sunlit-surface
        sample picks the point ``surface`` at ``distance_m`` along unit ``direction``
        (lanes ``hit``; 0 elsewhere, and where the sample would give up: grazing q)."""
        dr = self._dr
        cos_q = dr.abs(dr.dot(surface.normal_geo, direction))
        ok = hit & (cos_q > _MIN_COS_Q)
        pdf_area = self._sunlit.pdf_area(frame.sunlit_tables, surface.face, ok)
        return dr.select(ok, pdf_area * dr.square(distance_m) / cos_q, 0.0)

    def _vertex(self, surface, hit, wo, throughput, sun_weight=None) -> PathVertex:
        """The path vertex at the surface point ``surface`` (lanes ``hit``) seen from unit
        direction ``wo``."""
        shade = self._geometry.shading(surface, hit, wo)
        return PathVertex(
            point_m=surface.point_m,
            normal=shade.normal,
            normal_geo=shade.normal_facing,
            uv=shade.uv,
            mip_level=shade.mip_level,
            part=surface.part,
            wo=wo,
            face_side=self._geometry.face_side(surface.face, surface.normal_geo, wo),
            throughput=throughput,
            normal_smooth=shade.normal_smooth,
            lift_m=shade.lift_m,
            sun_weight=sun_weight,
        )

    def _sun_light(self, frame, surface, vertex, params, shading, wo_local, active, shadow_rng):
        """The Sun's light a vertex reflects towards ``wo`` (Color3f, W m^-2 sr^-1): one
        shadow ray from the smooth surface, no light from below that surface's horizon
        (Hanika 2021, see target_geometry)."""
        mi, dr = self._mi, self._dr
        origin = vertex.point_m + vertex.normal_geo * frame.ray_offset_m
        light_origin = origin if vertex.lift_m is None else origin + vertex.lift_m
        horizon = vertex.normal_geo if vertex.normal_smooth is None else vertex.normal_smooth
        wi = frame.sun_direction_body
        wi_local = shading.to_local(wi)
        lit = active & (wi_local.z > 0.0) & (frame.sun_irradiance_w_m2 > 0.0)
        if self._geometry.shading_normals:  # no light from below the surface
            lit &= dr.dot(wi, horizon) > 0.0
        lit &= self._geometry.visible(light_origin, wi, lit, shadow_rng)
        f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local, smooth_horizon=True)
        irradiance = frame.sun_irradiance_w_m2 * wi_local.z
        return dr.select(lit, (f_diffuse + f_specular) * irradiance, mi.Color3f(0.0))

    def _sunlit_sample(
        self, frame, surface, params, shading, origin, wo_local, active, depth: int, rng
    ):
        """The Sun's light that ``light_samples`` sampled points q of the target reflect
        to a vertex, and the vertex reflects towards ``wo`` (Color3f, their mean, before
        the path's throughput), weighted against the bounce ray's way to it (power
        heuristic, the light samples counted). q's reflection is that of a vertex reached
        by a bounce (``surface_indirect``), as on the bounce ray's path."""
        mi = self._mi
        count = self._light_count(depth)
        numbers = rng(sunlit_segment(depth))
        total = mi.Color3f(0.0)
        for _ in range(count):
            total += self._sunlit_point(
                frame, surface, params, shading, origin, wo_local, active, numbers, count
            )
        return total * (1.0 / count)

    def _sunlit_point(
        self, frame, surface, params, shading, origin, wo_local, active, numbers, count: int
    ):
        """One light sample of ``_sunlit_sample`` (``count`` of them per vertex)."""
        mi, dr = self._mi, self._dr
        tables = frame.sunlit_tables
        face, u, v, pdf_area = self._sunlit.sample(
            tables, numbers.next_float32(), numbers.next_float32(), numbers.next_float32()
        )
        q = self._geometry.surface_at(face, u, v, active)
        to_q = q.point_m - origin
        distance_m = dr.norm(to_q)
        wi = to_q / dr.maximum(distance_m, 1e-30)
        wi_local = shading.to_local(wi)
        cos_q = dr.abs(dr.dot(q.normal_geo, wi))
        ok = active & (wi_local.z > 0.0) & (pdf_area > 0.0) & (cos_q > _MIN_COS_Q)
        f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local)
        f = f_diffuse + f_specular
        ok &= dr.max(f) > 0.0
        # q is seen from the vertex: nothing on the segment short of q (a relative and an
        # absolute margin, so that q's own triangle never blocks it).
        short_m = dr.minimum(distance_m * 0.9999, distance_m - 2.0 * frame.ray_offset_m)
        ok &= self._geometry.visible(origin, wi, ok, numbers, max_distance_m=short_m)
        at_q = self._vertex(q, ok, -wi, mi.Color3f(1.0))
        shading_q = mi.Frame3f(at_q.normal)
        params_q = self._surface_indirect.at(q.part, ok, at_q, shading_q)
        light = self._sun_light(
            frame,
            self._surface_indirect,
            at_q,
            params_q,
            shading_q,
            shading_q.to_local(at_q.wo),
            ok,
            numbers,
        )
        pdf_light = pdf_area * dr.square(distance_m) / cos_q
        weight = _power_heuristic(count * pdf_light, surface.pdf(params, wi_local, wo_local))
        value = f * light * (wi_local.z * weight / dr.maximum(pdf_light, 1e-30))
        return dr.select(ok, value, mi.Color3f(0.0))

    def _body_light_sample(
        self, frame, surface, params, shading, origin, wo_local, active, depth: int, rng, ld
    ):
        """Light from the Earth and the Moon by ``light_samples`` directions (one beyond
        the camera ray's surface) sampled in a body's cone, shadowed by the target,
        weighted against BRDF sampling (power heuristic, the light samples counted): their
        mean. The first direction takes the path's low-discrepancy numbers, the others
        the light segment's generator."""
        mi = self._mi
        count = self._light_count(depth)
        numbers = rng(light_segment(depth))
        base = self._streams.light_dims + 3 * depth
        total = mi.Color3f(0.0)
        for k in range(count):
            u = (
                (ld(base), ld(base + 1), ld(base + 2))
                if k == 0
                else (numbers.next_float32(), numbers.next_float32(), numbers.next_float32())
            )
            total += self._body_light_direction(
                frame, surface, params, shading, origin, wo_local, active, numbers, u, count
            )
        return total if count == 1 else total * (1.0 / count)

    def _body_light_direction(
        self, frame, surface, params, shading, origin, wo_local, active, numbers, u, count
    ):
        """One direction of ``_body_light_sample`` from the uniform numbers ``u``."""
        mi, dr = self._mi, self._dr
        bodies = frame.bodies
        wi, pdf_light = self._body_light.sample(bodies, origin, *u)
        wi_local = shading.to_local(wi)
        ok = active & (wi_local.z > 0.0) & (pdf_light > 0.0)
        sky, _ = self._body_light.radiance(bodies, origin, wi, ok)
        ok &= dr.max(sky) > 0.0
        ok &= self._geometry.visible(origin, wi, ok, numbers)
        f_diffuse, f_specular = surface.eval_parts(params, wi_local, wo_local, smooth_horizon=True)
        pdf_brdf = surface.pdf(params, wi_local, wo_local)
        mis = _power_heuristic(count * pdf_light, pdf_brdf)
        weight = wi_local.z * mis / dr.maximum(pdf_light, 1e-30)
        return dr.select(ok, (f_diffuse + f_specular) * sky * weight, mi.Color3f(0.0))

    def _shade_vertex(
        self, frame: FrameValues, vertex: PathVertex, active, depth: int, rng, ld
    ) -> tuple[object, BounceRay | None]:
        """Radiance a path picks up at one surface vertex, and the ray it continues on.

        rng(segment): the path's PCG32 of a stream segment; ld(dim): its low-discrepancy
        sample. Returns (radiance Color3f, ray) with ray None at the path's last vertex.
        """
        mi, dr = self._mi, self._dr
        s = self.settings
        env_on = s.environment != "off" or s.sun == "sh"
        surface = self._surface if depth == 0 else self._surface_indirect
        p, n, part, wo = vertex.point_m, vertex.normal, vertex.part, vertex.wo
        throughput = vertex.throughput
        shading = mi.Frame3f(n)
        wo_local = shading.to_local(wo)
        origin = p + vertex.normal_geo * frame.ray_offset_m  # off the geometric surface
        # Shadow rays towards light sources start on the smooth surface (Hanika 2021, see
        # target_geometry).
        light_origin = origin if vertex.lift_m is None else origin + vertex.lift_m
        params = surface.at(part, active, vertex, shading)  # gathered once per surface hit
        radiance = mi.Color3f(0.0)
        if s.sun == "delta":
            sun = self._sun_light(
                frame,
                surface,
                vertex,
                params,
                shading,
                wo_local,
                active,
                rng(shading_segment(depth)),
            )
            if vertex.sun_weight is not None:
                sun = sun * vertex.sun_weight
            radiance += sun
        if self._samples_sunlit(frame, depth):
            radiance += self._sunlit_sample(
                frame, surface, params, shading, origin, wo_local, active, depth, rng
            )
        if s.environment == "unshadowed":
            table = frame.diffuse_env_table
            if table is None:  # shading normals: the SH sum at each hit's normal
                diffuse_env = self._environment.diffuse(frame.env_sh_radiance_w_m2_sr, n, part)
            else:
                diffuse_env = dr.gather(type(table), table, vertex.face_side, active)
            kd = surface.diffuse_coefficient(params, wo_local)
            radiance += dr.select(active, kd * diffuse_env, 0.0)
        if frame.bodies_light_target:
            radiance += self._body_light_sample(
                frame, surface, params, shading, light_origin, wo_local, active, depth, rng, ld
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
            bounce_rng = rng(bounce_segment(depth))
            escaped = valid & self._geometry.visible(origin, wi, valid, bounce_rng)
        if env_on:
            env_weight = weight
            if s.environment == "unshadowed":
                # The diffuse part came from the SH convolution above: only the specular
                # part is taken from the sampled ray.
                env_weight = f_specular * cos_over_pdf
            if not frame.env_is_zero:
                sky = self._environment.radiance(frame.env_sh_radiance_w_m2_sr, wi)
                radiance += dr.select(escaped, env_weight * sky, 0.0)
            if frame.bodies_light_target:
                # The BRDF sample's share of the bodies' light (multiple importance
                # sampling with the body-light sample, power heuristic).
                bodies = frame.bodies
                sky, _ = self._body_light.radiance(bodies, origin, wi, escaped)
                pdf_light = self._body_light.light_pdf(bodies, origin, wi)
                mis = _power_heuristic(pdf, self._light_count(depth) * pdf_light)
                radiance += dr.select(escaped, env_weight * sky * mis, 0.0)
        radiance = throughput * radiance
        if last:
            return radiance, None
        return radiance, BounceRay(
            meets_target=valid & ~escaped,
            origin_m=origin,
            direction=wi,
            throughput=throughput * weight,
            pdf=pdf,
        )


def _power_heuristic(pdf_this, pdf_other):
    """Multiple-importance weight of a sample drawn with density ``pdf_this`` against one
    other strategy of density ``pdf_other`` (Veach's power heuristic, exponent 2)."""
    import drjit as dr

    this = dr.square(pdf_this)
    return this / dr.maximum(this + dr.square(pdf_other), 1e-30)
