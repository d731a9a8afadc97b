"""Is a point in the Earth's shadow? Cylindrical and conical (umbra, penumbra) shadow models.

Frame and units: positions are geocentric **GCRS** vectors in metres, (3,) or (N, 3)
(:mod:`satsight.ephemeris.geometry` for the argument conventions), angles in rad. A scalar
comes back when every argument is a single vector, else an (N,) array.

The Earth's shape, chosen by ``R_itrs_from_gcrs`` (the Earth's orientation, (3, 3) or one
rotation per row (N, 3, 3), ``x_itrs = R_itrs_from_gcrs @ x_gcrs``):

* given: the **WGS-84 ellipsoid** (:mod:`satsight.ephemeris.wgs84`);
* None: a **sphere** of radius a (6378137 m) unless a radius argument says otherwise. It
  stands 21.4 km above the ellipsoid at the poles, so a shadow boundary crossed at high
  latitude comes early on entry and late on exit. Measured on circular polar orbits
  (400-800 km, 2025 equinox and solstice): 5-8 s at beta ~ 0, up to 13 s at beta 40-60 deg,
  20-48 s close to the beta beyond which there is no eclipse; the eclipse per orbit is
  10-45 s shorter on the ellipsoid (``docs/design.md``, Visibility).

The Sun is a sphere of radius ``SUN_RADIUS_M`` at the position given (e.g. from
:func:`satsight.ephemeris.sun_moon.sun_position_gcrs_m`), a uniformly bright disc (no limb
darkening). Eclipses by the Moon are ignored. The atmosphere is transparent for sunlight (no
refraction, no extinction) and the Earth's limb is sharp.

Shadow models (Montenbruck & Gill, "Satellite Orbits", Springer 2000, Sec. 3.4.2):

* *cylindrical*: the shadow is the part behind the Earth of the cylinder of the Earth's
  cross-section along the Earth-Sun line (an infinitely distant point Sun);
* *conical*: the fraction of the solar disc seen from the target that the Earth does not
  cover (:func:`sunlit_fraction`; Montenbruck & Gill's shadow function nu). It is 1 in full
  Sun, 0 in the umbra and in between in the penumbra; in the antumbra, far behind the Earth
  where its disc looks smaller than the Sun's, it is 1 - (b/a)^2 at most.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from satsight.constants import (
    EARTH_EQUATORIAL_RADIUS_M,
    WGS84_SEMI_MAJOR_AXIS_M,
    WGS84_SEMI_MINOR_AXIS_M,
)
from satsight.ephemeris.geometry import finish, positive_length, require_nonzero, rotate, stack
from satsight.ephemeris.orbits import MU_EARTH_M3_S2
from satsight.errors import SatsightError
from satsight.vectors import angle_between_rad, norm

# Nominal solar radius, m: IAU 2015 Resolution B3 (R_sun^N = 6.957e8 m).
SUN_RADIUS_M = 695_700_000.0

# In the ITRS, stretching z by a / b turns the WGS-84 ellipsoid into the sphere of radius a.
_SPHERE_FROM_ELLIPSOID = np.array([1.0, 1.0, WGS84_SEMI_MAJOR_AXIS_M / WGS84_SEMI_MINOR_AXIS_M])


def _check_earth_radius(radius: float, R: np.ndarray | None, name: str) -> None:
    if R is not None and radius != EARTH_EQUATORIAL_RADIUS_M:
        raise SatsightError(
            f"{name} sets the radius of the spherical Earth (R_itrs_from_gcrs=None); with "
            "R_itrs_from_gcrs the Earth is the WGS-84 ellipsoid, whose axes are fixed. Leave "
            f"{name} at its default, or drop R_itrs_from_gcrs for a sphere of radius {radius} m"
        )


def _to_sphere_space(R: np.ndarray | None, *vectors: np.ndarray) -> tuple[np.ndarray, ...]:
    """The vectors in the space where the Earth is a sphere of radius a: ITRS with z
    stretched by a / b when R is given, else unchanged (the spherical model)."""
    if R is None:
        return vectors
    return tuple(rotate(R, v) * _SPHERE_FROM_ELLIPSOID for v in vectors)


def in_cylindrical_shadow(
    position_m: ArrayLike,
    sun_position_m: ArrayLike,
    body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
    R_itrs_from_gcrs: ArrayLike | None = None,
) -> bool | np.ndarray:
    """Whether a point is in the Earth's cylindrical shadow (point Sun at infinity).

    position_m: the point, GCRS, m; sun_position_m: the Sun's geocentric position, GCRS, m
    (only its direction s is used); (3,) or (N, 3). Sphere (R_itrs_from_gcrs None): True
    where the point is behind the Earth (position . s < 0) and less than body_radius_m from
    the Earth-Sun line (Montenbruck & Gill, "Satellite Orbits", 2000, Sec. 3.4.2,
    cylindrical model). Ellipsoid (R_itrs_from_gcrs given, body_radius_m left at its
    default): the same test after the linear map that makes the WGS-84 ellipsoid the sphere
    of radius a (ITRS, z stretched by a / b), which maps the line through the point along s
    to a line and so keeps whether it meets the Earth on the Sun's side of the point: the
    shadow is then the elliptic cylinder of the ellipsoid's silhouette seen from the Sun.
    """
    radius = positive_length(body_radius_m, "body_radius_m")
    (r, sun), R, single = stack(
        R_itrs_from_gcrs, position_m=position_m, sun_position_m=sun_position_m
    )
    _check_earth_radius(radius, R, "body_radius_m")
    require_nonzero(sun, "sun_position_m")
    r, sun = _to_sphere_space(R, r, sun / norm(sun)[:, None])
    s = sun / norm(sun)[:, None]
    along = np.sum(r * s, axis=-1)
    across = norm(r - along[:, None] * s)
    return finish((along < 0.0) & (across < radius), single)


def _covered_fraction(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Fraction of a disc of radius a covered by a disc of radius b, centres c apart.

    a, b > 0, c >= 0: arrays of one shape (plane lengths). 0 when the discs are apart
    (c >= a + b); when one lies inside the other (c <= |a - b|), exactly 1 if b >= a, else
    (b / a)^2. Otherwise the lens area over pi a^2. The lens is split by the common chord
    into two circular segments. With the chord's half length k (the height of the triangle of sides
    a, b, c, by Heron's formula) and the signed distances of the chord from each centre,
    d_a = (c^2 + a^2 - b^2) / (2c) and d_b = (c^2 + b^2 - a^2) / (2c), the half-angle each
    segment subtends at its centre is phi = atan2(k, d) and a segment of radius rho has area
    rho^2 (2 phi - sin 2 phi) / 2. This is the lens of Montenbruck & Gill Sec. 3.4.2
    rearranged: written with atan2 and the factored differences (c - b)(c + b), it keeps
    full relative precision for a small Sun disc grazing the much larger Earth disc. The
    textbook's arccos form takes arccos of arguments within rounding of 1 there and errs by
    up to about 2e-5 of the disc near first and last contact (even going negative).
    """
    covered = np.zeros(np.shape(c))
    contained = c <= np.abs(a - b)
    covered[contained] = np.minimum(b[contained] / a[contained], 1.0) ** 2
    partial = ~contained & (c < a + b)
    if np.any(partial):
        ap, bp, cp = a[partial], b[partial], c[partial]
        heron = (ap + bp - cp) * (cp + ap - bp) * (cp - ap + bp) * (ap + bp + cp)
        k = 0.5 * np.sqrt(np.maximum(heron, 0.0)) / cp
        d_a = ((cp - bp) * (cp + bp) + ap * ap) / (2.0 * cp)
        d_b = ((cp - ap) * (cp + ap) + bp * bp) / (2.0 * cp)
        two_phi_a = 2.0 * np.arctan2(k, d_a)
        two_phi_b = 2.0 * np.arctan2(k, d_b)
        area = 0.5 * (
            ap * ap * (two_phi_a - np.sin(two_phi_a)) + bp * bp * (two_phi_b - np.sin(two_phi_b))
        )
        covered[partial] = area / (np.pi * ap * ap)
    return covered


def _unit(v: np.ndarray) -> np.ndarray:
    return v / norm(v)[:, None]


def _sun_width_in_sphere_space(
    s: np.ndarray, s_sphere: np.ndarray, towards_earth: np.ndarray
) -> np.ndarray:
    """Half-width across the limb of the solar disc's image on the stretched sky, per rad
    of the true disc's radius: |P_s S u| / |S s| (see :func:`sunlit_fraction`).

    s (N, 3): unit direction to the Sun's centre, ITRS; s_sphere: its image S s (unnormalised);
    towards_earth: unit directions towards the Earth's centre in the stretched space.
    """
    s_hat = _unit(s_sphere)
    u = towards_earth - np.sum(towards_earth * s_hat, axis=-1)[:, None] * s_hat
    u_norm = norm(u)
    on_axis = u_norm == 0.0
    if np.any(on_axis):
        # The Sun's centre exactly behind the Earth's: any direction across s will do.
        helper = np.where(np.abs(s_hat[on_axis, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        u[on_axis] = np.cross(s_hat[on_axis], helper)
        u_norm = norm(u)
    u = u / u_norm[:, None]
    stretched = u * _SPHERE_FROM_ELLIPSOID
    across = stretched - np.sum(stretched * s, axis=-1)[:, None] * s
    return norm(across) / norm(s_sphere)


def sunlit_fraction(
    position_m: ArrayLike,
    sun_position_m: ArrayLike,
    earth_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
    sun_radius_m: float = SUN_RADIUS_M,
    R_itrs_from_gcrs: ArrayLike | None = None,
) -> float | np.ndarray:
    """Fraction of the solar disc seen from a point that the Earth does not hide, in [0, 1].

    position_m: the point (the target), GCRS, m; sun_position_m: the Sun's geocentric
    position, GCRS, m; (3,) or (N, 3). Returns a scalar or (N,): 1 in full Sun, 0 in the
    umbra, in between in the penumbra, 1 - (b/a)^2 in the antumbra (the Earth's disc inside
    the Sun's). R_itrs_from_gcrs ((3, 3) or (N, 3, 3)): the Earth's orientation, for the
    WGS-84 ellipsoid; None: a sphere of radius earth_radius_m.

    Sphere: Montenbruck & Gill, "Satellite Orbits", 2000, Sec. 3.4.2 (conical shadow, their
    shadow function nu): seen from the point, the Sun's disc has the apparent radius
    a = arcsin(R_sun / |sun - r|), the Earth's b = arcsin(R_earth / |r|), and their centres
    are c apart (the angle between sun - r and -r). The covered fraction is the area of the
    lens common to two circles of radii a and b with centres c apart, over pi a^2
    (:func:`_covered_fraction`).

    Ellipsoid: the linear map S (ITRS, z stretched by k = a / b) makes the WGS-84 ellipsoid
    the sphere of radius a and maps every ray from the point r to a ray from S r, hitting
    the Earth or not as before. On the stretched sky the Earth's disc is therefore an exact
    circle, of radius b' = arcsin(a / |S r|), centred on -S r; the solar disc's centre moves
    to the direction of S s (s: unit vector to the Sun's centre), c' from the Earth's
    centre. The map's Jacobian on the sky, (I - s' s'^T) S / |S s|, turns the solar disc of
    radius a into a small ellipse; its half-width across the Earth's limb (along the unit
    vector u from s' towards the Earth's centre) is a' = a |P_s S u| / |S s|, P_s the
    projection across s. Fractions of area are invariant under a linear map, and a disc
    cut by a straight edge covers the same fraction as an ellipse of the same half-width
    across the edge, so the covered fraction is the lens of radii a', b' at distance c'.
    With k = 1 this is exactly the spherical formula.

    Approximations: (1) a uniform solar disc, no limb darkening (with the linear law
    I(mu) = 1 - 0.6 (1 - mu), the fraction of *flux* in the penumbra differs from this
    fraction of *area* by up to 0.02). (2) Flat discs on the sky: the lens is computed in a
    plane, with the apparent radii and separation as lengths. The Earth's limb is placed
    exactly on the line of centres (at c - b), but given the curvature 1/b of a plane circle
    instead of the cot b of a small circle of radius b on the sphere, which misplaces the
    covered area by at most (1/b - cot b) a / (3 pi) of the disc (when the limb crosses the
    Sun's centre): 2.1e-4 at 7000 km from the Earth's centre, 2.5e-5 at geostationary
    distance; small beside (1) and (3). (3) A transparent atmosphere and a sharp limb
    (module docstring); pass a larger ``earth_radius_m`` to treat a lower atmospheric layer
    as opaque (sphere only). (4) Ellipsoid only: the map is linearised over the solar disc
    (its Jacobian varies by ~f a = 1.6e-5 across it) and the slightly elliptical image of
    the disc (axis ratio within f = 0.34 % of 1) is replaced by the disc of its half-width
    across the limb, exact for a straight limb and changing the curvature term of (2) by
    under 1 % of itself: both far below (2). Against a brute-force count of solar-disc rays
    meeting the ellipsoid, eclipse boundaries agree to milliseconds (tests).

    Raises SatsightError for a point inside the Earth or the Sun, where there is no disc.
    """
    earth_radius = positive_length(earth_radius_m, "earth_radius_m")
    sun_radius = positive_length(sun_radius_m, "sun_radius_m")
    (r, sun), R, single = stack(
        R_itrs_from_gcrs, position_m=position_m, sun_position_m=sun_position_m
    )
    _check_earth_radius(earth_radius, R, "earth_radius_m")
    to_sun = sun - r
    sun_distance = norm(to_sun)
    if np.any(sun_distance <= sun_radius):
        raise SatsightError(
            f"sunlit_fraction needs points outside the Sun (distance > {sun_radius} m); got a "
            f"distance of {float(np.min(sun_distance))} m; check the Sun position's units (m)"
        )
    a = np.arcsin(sun_radius / sun_distance)
    if R is None:
        earth_distance = norm(r)
        _require_outside(
            earth_distance <= earth_radius, earth_distance, f"|position| > {earth_radius} m"
        )
        b = np.arcsin(earth_radius / earth_distance)
        c = angle_between_rad(to_sun, -r)
        return finish(np.clip(1.0 - _covered_fraction(a, b, c), 0.0, 1.0), single)
    s = rotate(R, to_sun / sun_distance[:, None])
    (r_sphere,) = _to_sphere_space(R, r)
    earth_distance = norm(r_sphere)
    _require_outside(earth_distance <= earth_radius, norm(r), "outside the WGS-84 ellipsoid")
    s_sphere = s * _SPHERE_FROM_ELLIPSOID
    towards_earth = -r_sphere / earth_distance[:, None]
    b = np.arcsin(earth_radius / earth_distance)
    c = angle_between_rad(s_sphere, towards_earth)
    a_across = a * _sun_width_in_sphere_space(s, s_sphere, towards_earth)
    return finish(np.clip(1.0 - _covered_fraction(a_across, b, c), 0.0, 1.0), single)


def _require_outside(inside: np.ndarray, distance: np.ndarray, needed: str) -> None:
    if np.any(inside):
        raise SatsightError(
            f"sunlit_fraction needs points outside the Earth ({needed}); got a point "
            f"{float(np.min(distance[inside]))} m from the Earth's centre; check the units "
            "(metres) and that the orbit does not reach the ground"
        )


def beta_angle_rad(r_m: ArrayLike, v_m_s: ArrayLike, sun_m: ArrayLike) -> float | np.ndarray:
    """Beta angle, rad in [-pi/2, pi/2]: the Sun's elevation above the orbit plane.

    r_m (m), v_m_s (m/s): the orbiting object's GCRS state; sun_m: the Sun's geocentric
    position, m; (3,) or (N, 3). beta = pi/2 - angle(h, s), with h = r x v the angular
    momentum and s the Earth -> Sun direction: positive when the Sun is on the side of h,
    +pi/2 when the Sun is along the orbit normal, 0 when it lies in the orbit plane (the
    usual definition; e.g. Gilmore (ed.), "Spacecraft Thermal Control Handbook", Vol. I,
    2nd ed., 2002, Ch. 2). Computed as atan2(h . s, |h x s|).
    """
    (r, v, s), _, single = stack(r_m=r_m, v_m_s=v_m_s, sun_m=sun_m)
    h = np.cross(r, v)
    if np.any(norm(h) == 0.0):
        raise SatsightError(
            "r_m and v_m_s are parallel (or zero) in some row: there is no orbit plane, so "
            "no beta angle; give a velocity with a component across r"
        )
    require_nonzero(s, "sun_m")
    beta = np.arctan2(np.sum(h * s, axis=-1), norm(np.cross(h, s)))
    return finish(beta, single)


def cylindrical_eclipse_duration_s(
    radius_m: ArrayLike,
    beta_rad: ArrayLike,
    mu_m3_s2: float = MU_EARTH_M3_S2,
    body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
) -> float | np.ndarray:
    """Time per orbit, s, that a circular orbit spends in the cylindrical shadow of a sphere.

    radius_m > body_radius_m: orbit radius r, m; beta_rad in [-pi/2, pi/2]: beta angle;
    scalars or broadcastable arrays (a scalar result for scalar input). The Sun's direction
    is held fixed over the orbit and the Earth is a sphere (a closed form exists only
    for it; the WGS-84 ellipsoid shortens polar eclipses by 10-45 s). With theta
    the angle along the orbit from the point nearest the Sun, the position's component
    along the Sun is r cos(beta) cos(theta) and its squared distance from the Earth-Sun line
    r^2 (1 - cos^2(beta) cos^2(theta)); it is in the shadow cylinder of radius R where
    cos(theta) < 0 and that distance is < R, i.e. for |theta - pi| < theta_0 with

        cos(theta_0) = sqrt(r^2 - R^2) / (r cos(beta)),

    so the duration is T theta_0 / pi with T = 2 pi sqrt(r^3 / mu). There is no eclipse
    when |beta| >= arcsin(R / r). (Cylindrical model: Montenbruck & Gill, "Satellite
    Orbits", 2000, Sec. 3.4.2; the same eclipse fraction theta_0 / pi is in Gilmore (ed.),
    "Spacecraft Thermal Control Handbook", Vol. I, 2nd ed., 2002, Ch. 2.)
    """
    mu = positive_length(mu_m3_s2, "mu_m3_s2")
    body_radius = positive_length(body_radius_m, "body_radius_m")
    radius = np.asarray(radius_m, dtype=np.float64)
    beta = np.asarray(beta_rad, dtype=np.float64)
    if not (np.all(np.isfinite(radius)) and np.all(radius > body_radius)):
        raise SatsightError(
            f"radius_m must be finite and above the body's radius {body_radius} m (an orbit "
            f"radius, from the centre, in metres); got {radius_m}"
        )
    if not (np.all(np.isfinite(beta)) and np.all(np.abs(beta) <= 0.5 * np.pi)):
        raise SatsightError(
            f"beta_rad must lie in [-pi/2, pi/2] rad (the Sun's elevation above the orbit "
            f"plane); got {beta_rad}"
        )
    radius, beta = np.broadcast_arrays(radius, beta)
    period = 2.0 * np.pi * np.sqrt(radius**3 / mu)
    across = np.sqrt((radius - body_radius) * (radius + body_radius))
    along = radius * np.cos(beta)
    eclipse = along > across
    cos_theta0 = np.where(eclipse, across / np.where(eclipse, along, 1.0), 1.0)
    duration = period / np.pi * np.arccos(np.clip(cos_theta0, -1.0, 1.0))
    if duration.ndim == 0:
        return float(duration)
    return duration
