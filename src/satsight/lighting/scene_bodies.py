"""The Earth and the Moon as bodies in the scene: shapes, orientation, surface albedo.

A body is an ellipsoid (semi-axes ``a, a, b`` along its body-fixed x, y, z; the Moon a
sphere) lit by the Sun, a collimated source of in-band irradiance ``E`` along the unit
vector ``s`` towards the Sun. Its surface is Lambertian: at a point with outward unit
normal ``n`` (the ellipsoid's normal, whose latitude is the geodetic latitude) and albedo
``rho`` (per colour channel, uniform or from a longitude-latitude map) the radiance is

    L = rho E max(n . s, 0) / pi        (W m^-2 sr^-1),

so the day side, the terminator and the black night side come out of the geometry. The
renderer traces rays to these surfaces (``satsight.render.body_light``): earthshine and
moonshine are then exact (shadowed by the target itself), and the bodies appear in the
image behind the target. ``radiance_along`` is the same model in float64 numpy, used by
tests, plots and the exposure labels.

Frames: everything is in the render frame (the target's body frame), lengths in m. A body's
fixed frame (the Earth's ITRS, or a stand-in when a scenario has no epoch) is given by
``R_body_from_fixed``.

Sources: WGS-84 semi-axes a = 6 378 137 m, 1/f = 298.257223563 (NIMA TR8350.2, 3rd ed.,
2000, Table 3.1); the spherical Earth's default radius, the mean radius R1 = 6 371 008.8 m
(Moritz 1980, Geodetic Reference System 1980); Moon mean radius 1 737.4 km (Archinal et
al. 2011, Celest. Mech. Dyn. Astron. 109, 101).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from satsight.constants import (
    EARTH_MEAN_RADIUS_M,
    WGS84_SEMI_MAJOR_AXIS_M,
    WGS84_SEMI_MINOR_AXIS_M,
)
from satsight.errors import SatsightError

#: Background label values: what a pixel-centre ray that misses the target meets.
BACKGROUND_SPACE, BACKGROUND_EARTH, BACKGROUND_MOON = 0, 1, 2
BODY_IDS = {"earth": BACKGROUND_EARTH, "moon": BACKGROUND_MOON}


@dataclass(frozen=True)
class AlbedoMap:
    """A body's surface albedo on a longitude-latitude grid (equirectangular).

    albedo_rgb: (rows, cols, 3) float32 in [0, 1], or (rows, cols, 1) for a grey map (the
    same albedo in every channel, a third of the memory: 26 MB instead of 78 for the
    Earth's 0.1 deg map, and as much again for the renderer's texture of it); row 0 is
    the band at latitude +90 deg (north edge), column 0 starts at longitude -180 deg;
    cell centres at lat = 90 - (i + 0.5) 180 / rows, lon = -180 + (j + 0.5) 360 / cols
    (degrees, geodetic latitude, east longitude). description: where the values come from.
    """

    albedo_rgb: np.ndarray
    description: str = ""

    def __post_init__(self) -> None:
        a = np.asarray(self.albedo_rgb, dtype=np.float32)
        if a.ndim != 3 or a.shape[2] not in (1, 3) or a.shape[0] < 2 or a.shape[1] < 2:
            raise SatsightError(
                f"albedo map must be (rows, cols, 3) or (rows, cols, 1), got {a.shape}"
            )
        if not (np.all(np.isfinite(a)) and a.min() >= 0.0 and a.max() <= 1.0):
            raise SatsightError("albedo map values must be finite and in [0, 1]")
        object.__setattr__(self, "albedo_rgb", np.ascontiguousarray(a))

    def lookup(self, lat_rad: np.ndarray, lon_rad: np.ndarray) -> np.ndarray:
        """(..., 3) albedo at geodetic latitude / east longitude (rad), bilinear between cell
        centres, wrapping in longitude and clamped at the poles (as the renderer's texture)."""
        rows, cols = self.albedo_rgb.shape[:2]
        y = (0.5 - np.asarray(lat_rad) / math.pi) * rows - 0.5
        x = (np.asarray(lon_rad) / (2.0 * math.pi) + 0.5) * cols - 0.5
        y = np.clip(y, 0.0, rows - 1.0)
        y0 = np.minimum(np.floor(y).astype(int), rows - 2)
        fy = (y - y0)[..., None]
        x0f = np.floor(x)
        fx = (x - x0f)[..., None]
        x0 = x0f.astype(int) % cols
        x1 = (x0 + 1) % cols
        # float32: the four corners are gathered (from the flat map: np.take is about 3x
        # faster than indexing with two arrays), then widened exactly.
        channels = self.albedo_rgb.shape[2]
        flat = self.albedo_rgb.reshape(-1, channels)

        def corner(rows_index, cols_index):
            return np.take(flat, rows_index * cols + cols_index, axis=0).astype(np.float64)

        top = corner(y0, x0) * (1 - fx) + corner(y0, x1) * fx
        bottom = corner(y0 + 1, x0) * (1 - fx) + corner(y0 + 1, x1) * fx
        value = top * (1 - fy) + bottom * fy
        return value if channels == 3 else np.repeat(value, 3, axis=-1)


@dataclass(frozen=True)
class SceneBody:
    """A sunlit Lambertian ellipsoid in the scene.

    name: "earth" or "moon". center_body_m: (3,) its centre from the target's body origin,
    body frame (m). semi_axes_m: (3,) along its fixed x, y, z (m). R_body_from_fixed: (3, 3)
    rotation from its fixed frame to the body frame. albedo_rgb: (3,) uniform albedo, used
    where ``albedo_map`` is None. sun_direction_body: (3,) unit vector towards the Sun.
    sun_irradiance_w_m2: in-band solar irradiance at the body (W m^-2; the body is never in
    the target's shadow).
    """

    name: str
    center_body_m: np.ndarray
    semi_axes_m: np.ndarray
    R_body_from_fixed: np.ndarray
    albedo_rgb: np.ndarray
    sun_direction_body: np.ndarray
    sun_irradiance_w_m2: float
    albedo_map: AlbedoMap | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.name not in BODY_IDS:
            raise SatsightError(f"unknown body '{self.name}'; expected one of {list(BODY_IDS)}")
        c = np.asarray(self.center_body_m, dtype=np.float64).reshape(3)
        axes = np.asarray(self.semi_axes_m, dtype=np.float64).reshape(3)
        R = np.asarray(self.R_body_from_fixed, dtype=np.float64).reshape(3, 3)
        s = np.asarray(self.sun_direction_body, dtype=np.float64).reshape(3)
        albedo = np.broadcast_to(np.asarray(self.albedo_rgb, dtype=np.float64), (3,)).copy()
        if not (np.all(np.isfinite(axes)) and np.all(axes > 0)):
            raise SatsightError(f"{self.name}: semi-axes must be > 0 m, got {axes}")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-9):
            raise SatsightError(f"{self.name}: R_body_from_fixed must be a rotation")
        if np.linalg.norm(c) <= axes.max():
            raise SatsightError(f"{self.name}: the target is inside the body")
        if not (np.all(albedo >= 0) and np.all(albedo <= 1)):
            raise SatsightError(f"{self.name}: albedo must be in [0, 1], got {albedo}")
        if not (self.sun_irradiance_w_m2 >= 0 and math.isfinite(self.sun_irradiance_w_m2)):
            raise SatsightError(f"{self.name}: sun irradiance must be finite and >= 0")
        object.__setattr__(self, "center_body_m", c)
        object.__setattr__(self, "semi_axes_m", axes)
        object.__setattr__(self, "R_body_from_fixed", R)
        object.__setattr__(self, "sun_direction_body", s / np.linalg.norm(s))
        object.__setattr__(self, "albedo_rgb", albedo)

    @property
    def body_id(self) -> int:
        """The background label value of this body."""
        return BODY_IDS[self.name]

    @property
    def bounding_radius_m(self) -> float:
        return float(self.semi_axes_m.max())

    def hit(self, origin_body_m: np.ndarray, directions: np.ndarray):
        """Where rays from ``origin_body_m`` (3,) along unit ``directions`` (N, 3) first meet
        the ellipsoid: (hit (N,) bool, t (N,) m, normal (N, 3) unit outward, body frame,
        lat (N,), lon (N,) geodetic, rad). float64; the quadratic is solved from the ray's
        closest approach to the centre in the unit-sphere space, which keeps grazing rays
        exact."""
        d = np.atleast_2d(np.asarray(directions, dtype=np.float64))
        R_fixed_from_body = self.R_body_from_fixed.T
        o = R_fixed_from_body @ (np.asarray(origin_body_m, dtype=np.float64) - self.center_body_m)
        o = o / self.semi_axes_m
        dd = (d @ R_fixed_from_body.T) / self.semi_axes_m
        a = np.sum(dd * dd, axis=-1)
        t_c = -(dd @ o) / a
        q = o + t_c[:, None] * dd
        h2 = np.sum(q * q, axis=-1)
        disc = np.maximum(1.0 - h2, 0.0) / a
        t = t_c - np.sqrt(disc)
        hit = (h2 < 1.0) & (t > 0.0)
        u = o + t[:, None] * dd  # on the unit sphere
        n_fixed = u / self.semi_axes_m
        n_fixed /= np.linalg.norm(n_fixed, axis=-1, keepdims=True)
        lat = np.arcsin(np.clip(n_fixed[:, 2], -1.0, 1.0))
        lon = np.arctan2(n_fixed[:, 1], n_fixed[:, 0])
        normal = n_fixed @ self.R_body_from_fixed.T
        return hit, np.where(hit, t, np.inf), normal, lat, lon

    def albedo_at(self, lat_rad: np.ndarray, lon_rad: np.ndarray) -> np.ndarray:
        """(N, 3) surface albedo at geodetic latitude / longitude (rad)."""
        if self.albedo_map is None:
            return np.broadcast_to(self.albedo_rgb, (*np.shape(lat_rad), 3))
        return self.albedo_map.lookup(lat_rad, lon_rad)

    def radiance_along(self, origin_body_m: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(N, 3) radiance (W m^-2 sr^-1) arriving at ``origin_body_m`` from each unit
        direction (N, 3): the body's surface radiance where the ray meets it, else 0."""
        hit, _, normal, lat, lon = self.hit(origin_body_m, directions)
        cos_sun = np.maximum(normal @ self.sun_direction_body, 0.0)
        value = self.albedo_at(lat, lon) * (self.sun_irradiance_w_m2 * cos_sun / math.pi)[:, None]
        return np.where(hit[:, None], value, 0.0)


def earth_body(
    center_body_m: np.ndarray,
    R_body_from_itrs: np.ndarray,
    albedo_rgb,
    sun_direction_body: np.ndarray,
    sun_irradiance_w_m2: float,
    albedo_map: AlbedoMap | None = None,
    shape: str = "wgs84",
    sphere_radius_m: float = EARTH_MEAN_RADIUS_M,
) -> SceneBody:
    """The Earth as the WGS-84 ellipsoid (``shape="wgs84"``) or as a sphere of radius
    ``sphere_radius_m`` (``"sphere"``; default the mean radius R1 = 6 371 008.8 m, the
    sphere above which a scenario's ``earth.altitude_km`` places the target). The sphere's
    radius is ignored for the ellipsoid."""
    if shape not in ("wgs84", "sphere"):
        raise SatsightError(f"earth shape must be 'wgs84' or 'sphere', got {shape!r}")
    if shape == "sphere":
        radius = float(sphere_radius_m)
        if not (math.isfinite(radius) and radius > 0.0):
            raise SatsightError(
                f"the spherical Earth's radius must be finite and > 0 m, got {sphere_radius_m}"
            )
        axes = np.full(3, radius)
    else:
        axes = np.array([WGS84_SEMI_MAJOR_AXIS_M, WGS84_SEMI_MAJOR_AXIS_M, WGS84_SEMI_MINOR_AXIS_M])
    return SceneBody(
        "earth",
        center_body_m,
        axes,
        R_body_from_itrs,
        albedo_rgb,
        sun_direction_body,
        sun_irradiance_w_m2,
        albedo_map,
    )


def moon_body(
    center_body_m: np.ndarray,
    radius_m: float,
    albedo_rgb,
    sun_direction_body: np.ndarray,
    sun_irradiance_w_m2: float,
) -> SceneBody:
    """The Moon as a uniform Lambertian sphere (its orientation does not matter)."""
    return SceneBody(
        "moon",
        center_body_m,
        np.full(3, float(radius_m)),
        np.eye(3),
        albedo_rgb,
        sun_direction_body,
        sun_irradiance_w_m2,
    )
