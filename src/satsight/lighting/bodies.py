"""Light from sunlit Lambertian spheres (the Earth, the Moon) arriving at the target.

Model (paper Eq. 13, with the body resolved as a disc rather than a point): a body of
radius ``R`` is a Lambertian sphere of albedo ``rho`` (per colour channel) lit by the Sun,
a collimated source of in-band irradiance ``E_sun`` along the unit vector ``s`` from the
body towards the Sun. A surface point with outward unit normal ``n`` has the radiance

    L = rho E_sun max(n . s, 0) / pi        (W m^-2 sr^-1; 0 on the night side).

Seen from the target, whose vector to the body's centre is ``c`` (``D = |c|``), the body
fills the cone of half-angle ``alpha = asin(R / D)`` around ``c / D``. Each direction ``w``
in that cone sees the first point where the ray ``t w`` meets the sphere, and the radiance
from ``w`` is that point's ``L``; outside the cone the body contributes nothing.

The paper's Eq. 13 scales a body's contribution by ``1 / d_ast^2``: that is the shrinking
solid angle of a distant body. Integrating the radiance over the body's disc (cone)
contains this factor exactly, so it is not applied a second time here.

Frame: everything is in the render frame (the target's body frame); directions point away
from the target, towards the light. The Sun is at infinity, so the Earth and the Moon see
the same ``s`` as the target (``sun_direction``). Lengths are in m.

Neglected: the Earth's atmosphere and its non-Lambertian, non-uniform reflectance (clouds,
oceans' glint), the Moon's opposition surge, light reflected between the Earth and the
Moon, and eclipses of the Moon by the Earth's shadow (the Moon stays sunlit).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.constants import EARTH_ALBEDO, EARTH_MEAN_RADIUS_M, MOON_ALBEDO, MOON_MEAN_RADIUS_M
from satsight.errors import SatsightError
from satsight.lighting import sh
from satsight.lighting.light_field import LightField
from satsight.lighting.scene_bodies import SceneBody
from satsight.quadrature import gauss_legendre

# Default polar nodes of the cone quadrature (twice as many azimuth nodes). Where the
# terminator crosses the disc its kink limits the accuracy to order n_nodes^-2: with 64
# nodes the SH coefficients (l_max = 8) are within 2e-4 (relative) of a 512-node
# projection; a fully lit or fully dark disc converges exponentially.
DEFAULT_SH_NODES = 64
# Default polar nodes for the reference irradiance (terminator error about 2e-5).
DEFAULT_IRRADIANCE_NODES = 192
# Polar nodes for the projection of a scene body (ellipsoid limb and albedo map inside the
# cone): see scene_body_sh.
SCENE_BODY_SH_NODES = 128
_IRRADIANCE_BLOCK = 1 << 22  # normals x nodes per block in body_irradiance_w_m2


def _vector3(v: object, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SatsightError(f"{name} must be a finite 3-vector, got {v!r}")
    return a


def _unit3(v: object, name: str) -> np.ndarray:
    a = _vector3(v, name)
    n = float(np.linalg.norm(a))
    if n == 0.0:
        raise SatsightError(f"{name} must be a non-zero vector, got {v!r}")
    return a / n


def _albedo_rgb(albedo: float | tuple[float, float, float] | np.ndarray) -> np.ndarray:
    a = np.asarray(albedo, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,) or not np.all((a >= 0.0) & (a <= 1.0)):
        raise SatsightError(f"albedo must be a number or 3 numbers in [0, 1], got {albedo!r}")
    return a


def _check_irradiance(e: float) -> float:
    value = float(e)
    if not (math.isfinite(value) and value >= 0.0):
        raise SatsightError(f"sun irradiance must be finite and >= 0 W m^-2, got {e}")
    return value


def _geometry(
    body_center_from_target_m: object, radius_m: float
) -> tuple[np.ndarray, float, float]:
    """Centre vector, centre distance D and altitude h = D - R, checked."""
    c = _vector3(body_center_from_target_m, "body_center_from_target_m")
    r = float(radius_m)
    if not (math.isfinite(r) and r > 0.0):
        raise SatsightError(f"radius_m must be finite and > 0 m, got {radius_m}")
    d = float(np.linalg.norm(c))
    if not d > r:
        raise SatsightError(
            f"the target is inside the body: distance to its centre {d:.6g} m <= radius "
            f"{r:.6g} m; body_center_from_target_m is the vector from the target to the centre"
        )
    return c, d, d - r


def _perpendicular_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit ``axis`` to a right-handed orthonormal frame."""
    reference = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, reference)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _cone_quadrature(
    body_center_from_target_m: object, radius_m: float, n_nodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature over the cone a sphere fills as seen from the target.

    Returns ``(directions, weights, normals)``: (M, 3) unit directions from the target
    inside the cone, (M,) solid-angle weights in sr (summing to the cone's solid angle
    ``2 pi (1 - cos alpha)``), and (M, 3) outward unit normals of the sphere at the first
    point each direction meets; ``M = 2 n_nodes^2``.

    With ``mu`` the cosine of the angle from the cone's axis and ``phi`` the azimuth
    around it, ``d omega = d mu d phi``. ``mu`` runs over ``[cos alpha, 1]``; the
    substitution ``mu = cos alpha + (1 - cos alpha) v^2`` (v in [0, 1], Gauss-Legendre with
    ``n_nodes`` points) absorbs the square-root behaviour of the ray-sphere distance at the
    limb, so the integrand is smooth in ``v``. ``phi`` takes ``2 n_nodes`` uniform nodes
    (exact for trigonometric polynomials of degree < 2 n_nodes). Integrating over the
    cone only keeps the limb's discontinuity out of the quadrature.
    """
    n = int(n_nodes)
    if n < 2:
        raise SatsightError(f"n_nodes must be >= 2, got {n_nodes}")
    c, d, h = _geometry(body_center_from_target_m, radius_m)
    r = float(radius_m)
    axis = c / d
    e1, e2 = _perpendicular_frame(axis)
    sin_a = r / d
    cos_a = math.sqrt(h * (d + r)) / d
    one_minus_cos_a = sin_a**2 / (1.0 + cos_a)

    x, wx = gauss_legendre(n)
    v = 0.5 * (x + 1.0)
    wv = 0.5 * wx
    mu = cos_a + one_minus_cos_a * v**2
    one_minus_mu = one_minus_cos_a * (1.0 - v**2)
    w_mu = 2.0 * one_minus_cos_a * v * wv
    sin_t = np.sqrt(one_minus_mu * (1.0 + mu))
    # sqrt(mu^2 - cos^2 alpha): the half-chord of the ray inside the sphere, over D.
    half_chord = np.sqrt(one_minus_cos_a * v**2 * (mu + cos_a))
    # First hit distance t = D (mu - half_chord) in the stable form (D^2 - R^2) / (...).
    t = h * (d + r) / (d * (mu + half_chord))

    n_az = 2 * n
    phi = 2.0 * math.pi * (np.arange(n_az) + 0.5) / n_az
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2  # (n_az, 3)
    dirs = mu[:, None, None] * axis + sin_t[:, None, None] * radial[None, :, :]
    weights = np.repeat(w_mu * (2.0 * math.pi / n_az), n_az)
    points = t[:, None, None] * dirs
    normals = (points - c) / r
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return dirs.reshape(-1, 3), weights, normals.reshape(-1, 3)


def _lambert_radiance(
    normals: np.ndarray, sun_direction: np.ndarray, albedo: np.ndarray, e_sun: float
) -> np.ndarray:
    """``rho E max(n . s, 0) / pi`` per channel: (M, 3) W m^-2 sr^-1."""
    cos_sun = np.maximum(normals @ sun_direction, 0.0)
    return cos_sun[:, None] * (albedo * (e_sun / math.pi))[None, :]


def body_radiance_w_m2_sr(
    directions: np.ndarray,
    body_center_from_target_m: np.ndarray,
    radius_m: float,
    sun_direction: np.ndarray,
    albedo_rgb: float | tuple[float, float, float] | np.ndarray,
    sun_irradiance_w_m2: float,
) -> np.ndarray:
    """Radiance arriving at the target from a sunlit Lambertian sphere, per direction.

    directions: (N, 3) directions from the target (normalised here), render frame.
    body_center_from_target_m: (3,) vector from the target to the body's centre, m.
    radius_m: the body's radius, m. sun_direction: (3,) from the body towards the Sun.
    albedo_rgb: the body's Lambertian albedo, a number or one per channel.
    sun_irradiance_w_m2: in-band solar irradiance at the body, W m^-2.

    Returns (N, 3) radiance in W m^-2 sr^-1: ``rho E max(n . s, 0) / pi`` at the first
    point where the ray meets the sphere, 0 where it misses the sphere.
    """
    w = np.asarray(directions, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != 3:
        raise SatsightError(f"directions must have shape (N, 3), got {w.shape}")
    norms = np.linalg.norm(w, axis=1)
    if not np.all(np.isfinite(norms) & (norms > 0.0)):
        raise SatsightError("directions must be finite non-zero vectors")
    w = w / norms[:, None]
    c, d, h = _geometry(body_center_from_target_m, radius_m)
    r = float(radius_m)
    s = _unit3(sun_direction, "sun_direction")
    albedo = _albedo_rgb(albedo_rgb)
    e_sun = _check_irradiance(sun_irradiance_w_m2)

    b = w @ c  # D cos(angle from the centre)
    # Discriminant b^2 - (D^2 - R^2), with D^2 - R^2 = h (D + R) to keep low altitudes exact.
    disc = b * b - h * (d + r)
    hit = (disc >= 0.0) & (b > 0.0)
    root = np.sqrt(np.where(hit, disc, 0.0))
    t = np.where(hit, h * (d + r) / np.where(hit, b + root, 1.0), 0.0)
    normals = (t[:, None] * w - c) / r
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    radiance = _lambert_radiance(normals, s, albedo, e_sun)
    radiance[~hit] = 0.0
    return radiance


def body_sh(
    body_center_from_target_m: np.ndarray,
    radius_m: float,
    sun_direction: np.ndarray,
    albedo_rgb: float | tuple[float, float, float] | np.ndarray,
    sun_irradiance_w_m2: float,
    l_max: int = 4,
    n_nodes: int = DEFAULT_SH_NODES,
) -> np.ndarray:
    """Real SH coefficients of a sunlit Lambertian sphere's radiance seen from the target.

    ``c_lm = integral over the body's cone of L(w) Y_lm(w) d omega``, by the cone
    quadrature (Gauss-Legendre in the cosine ``mu`` from the cone's axis over
    ``[cos alpha, 1]``, written as ``mu = cos alpha + (1 - cos alpha) v^2`` to absorb the
    limb's square root; uniform in azimuth; solid-angle weights; ``n_nodes`` polar and
    ``2 n_nodes`` azimuth nodes). See :func:`body_radiance_w_m2_sr` for the arguments. Integrating
    over the cone only keeps the limb's discontinuity out of the quadrature; the remaining
    quadrature error comes from the terminator's kink (order ``n_nodes^-2``).

    Returns ((l_max + 1)^2, 3) coefficients of the radiance in W m^-2 sr^-1, render frame,
    index ``l (l + 1) + m`` (:mod:`satsight.lighting.sh`).
    """
    dirs, weights, normals = _cone_quadrature(body_center_from_target_m, radius_m, n_nodes)
    s = _unit3(sun_direction, "sun_direction")
    radiance = _lambert_radiance(
        normals, s, _albedo_rgb(albedo_rgb), _check_irradiance(sun_irradiance_w_m2)
    )
    return np.asarray(sh.project_samples(dirs, radiance, weights, int(l_max)), dtype=np.float64)


def scene_body_sh(
    body: SceneBody, l_max: int = 4, n_nodes: int = SCENE_BODY_SH_NODES
) -> np.ndarray:
    """Real SH coefficients of a scene body's radiance seen from the target (the origin):
    ((l_max + 1)^2, 3), W m^-2 sr^-1, render frame.

    The same projection as :func:`body_sh`, of the body the renderer traces
    (:class:`satsight.lighting.scene_bodies.SceneBody`: the WGS-84 ellipsoid, its albedo
    map, its orientation) instead of a uniform sphere: the radiance along each node of the
    cone quadrature over the body's bounding sphere is ``SceneBody.radiance_along``. The
    ellipsoid's limb then lies inside the cone near the poles (a band of width a - b = 21 km
    at most), where the quadrature sees a discontinuity; the map's coastlines are sampled by
    the 2 n_nodes^2 nodes. With 128 nodes both stay below 4e-4 of c_00 (64 nodes: 2.5e-3),
    far below the SH truncation's percent-level errors; it costs 20-80 ms per frame.
    """
    dirs, weights, _ = _cone_quadrature(body.center_body_m, body.bounding_radius_m, n_nodes)
    radiance = body.radiance_along(np.zeros(3), dirs)
    return np.asarray(sh.project_samples(dirs, radiance, weights, int(l_max)), dtype=np.float64)


def body_irradiance_w_m2(
    normal: np.ndarray,
    body_center_from_target_m: np.ndarray,
    radius_m: float,
    sun_direction: np.ndarray,
    albedo_rgb: float | tuple[float, float, float] | np.ndarray,
    sun_irradiance_w_m2: float,
    n_nodes: int = DEFAULT_IRRADIANCE_NODES,
) -> np.ndarray:
    """Irradiance from a sunlit Lambertian sphere on a small plate at the target.

    ``E = integral over the body's cone of L(w) max(normal . w, 0) d omega``, by the same
    cone quadrature as :func:`body_sh` (no SH truncation): the reference that the SH
    irradiance converges to. The plate is not shadowed by anything else.

    normal: (3,) or (K, 3) unit normals of the plate (normalised here), render frame.
    Returns (3,) or (K, 3) irradiance per channel in W m^-2.
    """
    nrm = np.asarray(normal, dtype=np.float64)
    single = nrm.ndim == 1
    nrm = np.atleast_2d(nrm)
    if nrm.shape[-1] != 3 or nrm.ndim != 2:
        raise SatsightError(f"normal must have shape (3,) or (K, 3), got {np.shape(normal)}")
    lengths = np.linalg.norm(nrm, axis=1, keepdims=True)
    if not np.all(np.isfinite(lengths) & (lengths > 0.0)):
        raise SatsightError("normal must be finite non-zero vectors")
    nrm = nrm / lengths
    dirs, weights, normals = _cone_quadrature(body_center_from_target_m, radius_m, n_nodes)
    s = _unit3(sun_direction, "sun_direction")
    radiance = _lambert_radiance(
        normals, s, _albedo_rgb(albedo_rgb), _check_irradiance(sun_irradiance_w_m2)
    )
    weighted = weights[:, None] * radiance  # (M, 3)
    e = np.empty((nrm.shape[0], 3))
    block = max(1, _IRRADIANCE_BLOCK // dirs.shape[0])  # normals per block, bounded memory
    for start in range(0, nrm.shape[0], block):
        cos_plate = np.maximum(nrm[start : start + block] @ dirs.T, 0.0)  # (k, M)
        e[start : start + block] = cos_plate @ weighted
    return e[0] if single else e


def occulted_by(
    point_from_target_m: np.ndarray,
    occluder_center_from_target_m: np.ndarray,
    occluder_radius_m: float,
) -> bool:
    """Whether a sphere hides a point from the target (the paper's visibility V_ast = 0).

    True when the segment from the target to ``point_from_target_m`` passes through the
    sphere of radius ``occluder_radius_m`` centred at ``occluder_center_from_target_m``
    (all in m, render frame). Used on the Moon's centre with the Earth as the occluder:
    the Moon counts as wholly hidden or wholly visible (a partly hidden disc is not cut).
    """
    p = _vector3(point_from_target_m, "point_from_target_m")
    c, _, _ = _geometry(occluder_center_from_target_m, occluder_radius_m)
    pp = float(p @ p)
    if pp == 0.0:
        return False
    t = min(max(float(p @ c) / pp, 0.0), 1.0)
    return bool(np.linalg.norm(c - t * p) < float(occluder_radius_m))


def earthshine_sh(
    earth_center_from_target_m: np.ndarray,
    sun_direction: np.ndarray,
    sun_irradiance_w_m2: float,
    albedo: float | tuple[float, float, float] | np.ndarray = EARTH_ALBEDO,
    l_max: int = 4,
    n_nodes: int = DEFAULT_SH_NODES,
) -> np.ndarray:
    """SH coefficients of the sunlit Earth's radiance at the target: (n, 3) W m^-2 sr^-1.

    The Earth as a Lambertian sphere of radius ``EARTH_MEAN_RADIUS_M`` and albedo
    ``albedo`` (default 0.30); see :func:`body_sh`.
    """
    return body_sh(
        earth_center_from_target_m,
        EARTH_MEAN_RADIUS_M,
        sun_direction,
        albedo,
        sun_irradiance_w_m2,
        l_max=l_max,
        n_nodes=n_nodes,
    )


def moonshine_sh(
    moon_center_from_target_m: np.ndarray,
    sun_direction: np.ndarray,
    sun_irradiance_w_m2: float,
    albedo: float | tuple[float, float, float] | np.ndarray = MOON_ALBEDO,
    l_max: int = 4,
    n_nodes: int = DEFAULT_SH_NODES,
    earth_center_from_target_m: np.ndarray | None = None,
) -> np.ndarray:
    """SH coefficients of the sunlit Moon's radiance at the target: (n, 3) W m^-2 sr^-1.

    The Moon as a Lambertian sphere of radius ``MOON_MEAN_RADIUS_M`` and albedo ``albedo``
    (default 0.12); see :func:`body_sh`. With ``earth_center_from_target_m`` given, the
    coefficients are zero when the Earth hides the Moon's centre (:func:`occulted_by`).
    The Moon is always taken as sunlit: lunar eclipses are ignored.
    """
    n = sh.sh_count(int(l_max))
    if earth_center_from_target_m is not None and occulted_by(
        moon_center_from_target_m, earth_center_from_target_m, EARTH_MEAN_RADIUS_M
    ):
        return np.zeros((n, 3))
    return body_sh(
        moon_center_from_target_m,
        MOON_MEAN_RADIUS_M,
        sun_direction,
        albedo,
        sun_irradiance_w_m2,
        l_max=l_max,
        n_nodes=n_nodes,
    )


def environment_light_field(
    sun_direction: np.ndarray,
    sun_irradiance_w_m2: float,
    earth_center_from_target_m: np.ndarray | None = None,
    earth_albedo: float | tuple[float, float, float] | np.ndarray = EARTH_ALBEDO,
    moon_center_from_target_m: np.ndarray | None = None,
    moon_albedo: float | tuple[float, float, float] | np.ndarray = MOON_ALBEDO,
    extra_sh: np.ndarray | None = None,
    l_max: int = 4,
    *,
    sun_irradiance_at_target_w_m2: float | None = None,
    n_nodes: int = DEFAULT_SH_NODES,
    earth: SceneBody | None = None,
) -> LightField:
    """The light field at the target: the Sun plus earthshine, moonshine and extra terms.

    sun_direction: (3,) unit vector from the target towards the Sun, render frame; the Sun
    is at infinity, so the Earth and the Moon are lit from the same direction.
    sun_irradiance_w_m2: in-band solar irradiance that lights the Earth and the Moon,
    W m^-2. sun_irradiance_at_target_w_m2: what reaches the target itself (lower in the
    Earth's shadow); defaults to ``sun_irradiance_w_m2``.
    earth_center_from_target_m, moon_center_from_target_m: (3,) vectors from the target to
    the bodies' centres in m, render frame, or None to leave a body out. The Moon is left
    out when the Earth hides its centre (paper Eq. 13's V_ast).
    extra_sh: ((l_max + 1)^2, 3) or ((l_max + 1)^2,) SH radiance coefficients of any other
    environment light, W m^-2 sr^-1, added as they are.
    earth: the Earth as the renderer traces it (ellipsoid, albedo map); when given, its
    earthshine is projected from it (:func:`scene_body_sh`) instead of from a uniform
    sphere of ``earth_albedo`` (``earth_center_from_target_m`` still places it for the
    Moon's occultation).

    The environment radiance is the sum of the terms (radiance is additive), each projected
    over its body's disc (see :func:`body_sh`).
    """
    l_max = int(l_max)
    if l_max < 0:
        raise SatsightError(f"l_max must be >= 0, got {l_max}")
    n = sh.sh_count(l_max)
    coeffs = np.zeros((n, 3))
    if earth is not None:
        coeffs += scene_body_sh(earth, l_max=l_max)
    elif earth_center_from_target_m is not None:
        coeffs += earthshine_sh(
            earth_center_from_target_m,
            sun_direction,
            sun_irradiance_w_m2,
            earth_albedo,
            l_max=l_max,
            n_nodes=n_nodes,
        )
    if moon_center_from_target_m is not None:
        coeffs += moonshine_sh(
            moon_center_from_target_m,
            sun_direction,
            sun_irradiance_w_m2,
            moon_albedo,
            l_max=l_max,
            n_nodes=n_nodes,
            earth_center_from_target_m=earth_center_from_target_m,
        )
    if extra_sh is not None:
        extra = np.asarray(extra_sh, dtype=np.float64)
        if extra.ndim == 1:
            extra = extra[:, None].repeat(3, axis=1)
        if extra.shape != (n, 3):
            raise SatsightError(
                f"extra_sh must have shape ({n}, 3) or ({n},) for l_max = {l_max}, "
                f"got {np.shape(extra_sh)}"
            )
        coeffs += extra
    e_target = (
        _check_irradiance(sun_irradiance_w_m2)
        if sun_irradiance_at_target_w_m2 is None
        else _check_irradiance(sun_irradiance_at_target_w_m2)
    )
    return LightField(_unit3(sun_direction, "sun_direction"), e_target, coeffs)
