"""The Earth and the Moon in the renderer: rays traced to sunlit Lambertian ellipsoids.

Two body slots (0: the Earth, 1: the Moon) are per-frame opaque values, so frames with or
without a body reuse one compiled kernel (an absent body has zero irradiance and is never
sampled). For each body:

* ``hit``: the ray's first point on the ellipsoid, solved in the space where it is the
  unit sphere from the ray's closest approach to the centre (no cancellation for grazing
  rays; float32 places the limb to ~1 m at the Earth);
* radiance there: rho E max(n . s, 0) / pi with the ellipsoid's normal n (its latitude is
  the geodetic one) and rho the uniform albedo or the albedo map (bilinear texture);
* light sampling: the Moon by directions uniform in the cone of its bounding sphere seen
  from the shading point, pdf 1 / (2 pi (1 - cos alpha)), with 1 - cos alpha = sin^2 alpha
  / (1 + cos alpha) so that its 0.26 deg cone keeps its precision; the Earth by the
  frame's table of its radiance over its cone (``satsight.render.earth_table``).

See ``satsight.lighting.scene_bodies`` for the model and its numpy twin.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from satsight.lighting.scene_bodies import BODY_IDS, SceneBody
from satsight.render import earth_table
from satsight.render.earth_table import EarthTable

SLOTS = ("earth", "moon")
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class BodySlot:
    """One body slot's per-frame opaque values (Dr.Jit scalars).

    center_render_m: the body's centre in render space (body frame, origin at the mesh
    centre), m. R_fixed_from_body, R_body_from_fixed: rotations between the target's body
    frame and the body's fixed frame. inv_semi_axes_per_m: 1 / the ellipsoid's semi-axes,
    m^-1. radius_m: its bounding-sphere radius, m. sun_irradiance_over_pi_w_m2: the Sun's
    irradiance at the body over pi, W m^-2. albedo_rgb: uniform albedo (the Moon's; the
    Earth's albedo is the frame's texture). sun_direction_body: unit vector towards the Sun.
    An absent body sits far away with zero irradiance.
    """

    center_render_m: object
    R_fixed_from_body: object
    R_body_from_fixed: object
    inv_semi_axes_per_m: object
    radius_m: object
    sun_irradiance_over_pi_w_m2: object
    albedo_rgb: object
    sun_direction_body: object


@dataclass(frozen=True, eq=False)
class BodyFrameValues:
    """The bodies of one frame for the kernels.

    slots: the Earth's and the Moon's ``BodySlot``. earth_albedo: the Earth slot's albedo
    texture (mi.Texture2f). earth_v_range: the texture's v coordinates of its first and last
    row centres. p_earth: the probability that a light sample picks the Earth (opaque
    Float). any_lit: whether a body lights the target at all (host bool). earth_table:
    the table the Earth's light samples are drawn from.
    """

    slots: tuple[BodySlot, ...]
    earth_albedo: object
    earth_v_range: tuple[float, float]
    p_earth: object
    any_lit: bool
    earth_table: EarthTable


class BodyLight:
    """Per-frame body values for the kernels and the Dr.Jit functions that use them.

    origin_body_m: the render space's origin in the target's body frame (the renderer's
    mesh centre), subtracted from the bodies' centres.
    """

    def __init__(self, origin_body_m: np.ndarray) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self._origin_body_m = np.asarray(origin_body_m, dtype=np.float64)
        self._textures: dict[int, object] = {}

    # --- host side -----------------------------------------------------------------------
    def _texture(self, body: SceneBody | None):
        """The Earth slot's albedo texture: the map, or a 2 x 2 texture of the uniform
        albedo (cached per map / albedo, so that frames reuse one texture object)."""
        mi, dr = self._mi, self._dr
        if body is not None and body.albedo_map is not None:
            key, data = id(body.albedo_map), body.albedo_map.albedo_rgb
        else:
            albedo = np.zeros(3) if body is None else body.albedo_rgb
            key = hash(tuple(np.round(albedo, 9)))
            data = np.broadcast_to(albedo.astype(np.float32), (2, 2, 3))
        if key not in self._textures:
            if len(self._textures) > 8:
                self._textures.clear()
            texture = mi.Texture2f(
                mi.TensorXf(np.ascontiguousarray(data, dtype=np.float32)),
                use_accel=False,
                filter_mode=dr.FilterMode.Linear,
                wrap_mode=dr.WrapMode.Repeat,
            )
            # The map is kept with its texture, so that its id is not reused while cached.
            self._textures[key] = (texture, None if body is None else body.albedo_map)
        return self._textures[key][0], np.asarray(data.shape[:2])

    def frame_values(
        self, bodies: tuple[SceneBody, ...], sample_earth: bool = True
    ) -> BodyFrameValues:
        """Opaque per-frame values of the two slots from the light field's bodies;
        sample_earth: build the Earth's radiance table for light samples (else a
        placeholder: the light paths then draw none)."""
        mi, dr = self._mi, self._dr
        by_name = {b.name: b for b in bodies}
        slots = []
        for name in SLOTS:
            body = by_name.get(name)
            if body is None:
                center, axes, R, e = np.array([0.0, 0.0, 1e12]), np.ones(3), np.eye(3), 0.0
                albedo, sun = np.zeros(3), np.array([0.0, 0.0, 1.0])
            else:
                center = body.center_body_m - self._origin_body_m
                axes, R = body.semi_axes_m, body.R_body_from_fixed.T
                e, albedo, sun = body.sun_irradiance_w_m2, body.albedo_rgb, body.sun_direction_body
            slot = BodySlot(
                center_render_m=mi.Point3f(*(float(c) for c in center)),
                R_fixed_from_body=mi.Matrix3f(R.astype(np.float32)),
                R_body_from_fixed=mi.Matrix3f(R.T.astype(np.float32)),
                inv_semi_axes_per_m=mi.Vector3f(*(float(1.0 / a) for a in axes)),
                radius_m=mi.Float(float(axes.max())),
                sun_irradiance_over_pi_w_m2=mi.Float(float(e / math.pi)),
                albedo_rgb=mi.Color3f(*(float(a) for a in albedo)),
                sun_direction_body=mi.Vector3f(*(float(c) for c in sun)),
            )
            dr.make_opaque(*(getattr(slot, f.name) for f in dataclasses.fields(slot)))
            slots.append(slot)
        earth = by_name.get("earth")
        texture, shape = self._texture(earth)
        rows = float(shape[0])
        v_range = (0.5 / rows, 1.0 - 0.5 / rows)
        # Light-sampling choice: the Earth's share of the bodies' power, roughly
        # E * albedo * solid angle (only a choice of samples; any value gives the right mean).
        weights = []
        for name in SLOTS:
            body = by_name.get(name)
            if body is None:
                weights.append(0.0)
                continue
            distance = np.linalg.norm(body.center_body_m - self._origin_body_m)
            sin2 = min(1.0, (body.bounding_radius_m / distance) ** 2)
            weights.append(body.sun_irradiance_w_m2 * (0.05 + body.albedo_rgb.mean()) * sin2)
        total = sum(weights)
        p_earth = 0.5 if total == 0.0 else weights[0] / total
        p_earth_value = mi.Float(float(p_earth))
        dr.make_opaque(p_earth_value)
        table = earth_table.earth_table(earth if sample_earth else None, self._origin_body_m)
        return BodyFrameValues(tuple(slots), texture, v_range, p_earth_value, total > 0.0, table)

    # --- kernels ---------------------------------------------------------------------------
    def _slot_hit(self, slot: BodySlot, origin, direction, active):
        """(hit, t, unit normal in the fixed frame) of a ray on one slot's ellipsoid."""
        mi, dr = self._mi, self._dr
        R, inv = slot.R_fixed_from_body, slot.inv_semi_axes_per_m
        o = (R @ (origin - slot.center_render_m)) * inv
        d = (R @ direction) * inv
        a = dr.squared_norm(d)
        t_c = -dr.dot(d, o) / a
        q = dr.fma(d, t_c, o)
        h2 = dr.squared_norm(q)
        t = t_c - dr.safe_sqrt((1.0 - h2) / a)
        hit = active & (h2 < 1.0) & (t > 0.0)
        n_fixed = dr.normalize(dr.fma(d, t, o) * inv)
        return hit, t, mi.Vector3f(n_fixed)

    def _slot_radiance(self, values: BodyFrameValues, k: int, n_fixed, hit):
        """Radiance of slot ``k``'s surface with fixed-frame normal n_fixed."""
        mi, dr = self._mi, self._dr
        slot = values.slots[k]
        n_body = slot.R_body_from_fixed @ n_fixed
        cos_sun = dr.maximum(dr.dot(n_body, slot.sun_direction_body), 0.0)
        if k == 0:
            lat = dr.asin(dr.clip(n_fixed.z, -1.0, 1.0))
            lon = dr.atan2(n_fixed.y, n_fixed.x)
            lo, hi = values.earth_v_range
            u = lon * (1.0 / _TWO_PI) + 0.5
            v = dr.clip(0.5 - lat * (1.0 / math.pi), lo, hi)
            albedo = mi.Color3f(*values.earth_albedo.eval(mi.Point2f(u, v), active=hit))
        else:
            albedo = slot.albedo_rgb
        return dr.select(hit, albedo * (slot.sun_irradiance_over_pi_w_m2 * cos_sun), 0.0)

    def radiance(self, values: BodyFrameValues, origin, direction, active):
        """(radiance Color3f, body id UInt32: 0 none, 1 Earth, 2 Moon) along rays from
        ``origin`` (render space) in unit ``direction``: the nearest body's surface."""
        mi, dr = self._mi, self._dr
        hit0, t0, n0 = self._slot_hit(values.slots[0], origin, direction, active)
        hit1, t1, n1 = self._slot_hit(values.slots[1], origin, direction, active)
        hit1 &= ~hit0 | (t1 < t0)
        hit0 &= ~hit1
        value = self._slot_radiance(values, 0, n0, hit0) + self._slot_radiance(values, 1, n1, hit1)
        body = dr.select(
            hit0, mi.UInt32(BODY_IDS["earth"]), dr.select(hit1, mi.UInt32(BODY_IDS["moon"]), 0)
        )
        return value, body

    def _cone(self, slot: BodySlot, p):
        """Axis (unit), cos alpha and 1 - cos alpha of a slot's bounding cone from p."""
        dr = self._dr
        to_center = slot.center_render_m - p
        distance2 = dr.squared_norm(to_center)
        sin2 = dr.minimum(dr.square(slot.radius_m) / distance2, 1.0)
        cos_max = dr.safe_sqrt(1.0 - sin2)
        return to_center * dr.rsqrt(distance2), cos_max, sin2 / (1.0 + cos_max)

    def sample(self, values: BodyFrameValues, p, u_choice, u1, u2):
        """A direction towards one body (chosen with probability ``p_earth`` for the
        Earth): from the Earth's radiance table, or uniform in the Moon's bounding cone
        seen from p; and its density ``light_pdf``."""
        mi, dr = self._mi, self._dr
        earth = u_choice < values.p_earth
        to_earth, _ = earth_table.sample(values.earth_table, u1, u2)
        axis, _, one_minus = self._cone(values.slots[1], p)
        one_minus_cos = u1 * one_minus
        cos_t = 1.0 - one_minus_cos
        sin_t = dr.safe_sqrt(one_minus_cos * (2.0 - one_minus_cos))
        sin_p, cos_p = dr.sincos(_TWO_PI * u2)
        to_moon = mi.Frame3f(axis).to_world(mi.Vector3f(sin_t * cos_p, sin_t * sin_p, cos_t))
        direction = dr.select(earth, to_earth, to_moon)
        return direction, self.light_pdf(values, p, direction)

    def light_pdf(self, values: BodyFrameValues, p, direction):
        """Solid-angle density of ``sample`` choosing ``direction`` from p."""
        dr = self._dr
        axis, cos_max, one_minus = self._cone(values.slots[1], p)
        inside = dr.dot(direction, axis) >= cos_max
        moon = dr.select(inside & (one_minus > 0.0), 1.0 / (_TWO_PI * one_minus), 0.0)
        earth = earth_table.pdf(values.earth_table, direction)
        return values.p_earth * earth + (1.0 - values.p_earth) * moon
