"""Does the Earth block a line of sight, and is a point inside the Earth?

Frame and units: positions are geocentric **GCRS** vectors in metres, (3,) or (N, 3)
(:mod:`satsight.ephemeris.geometry` for the argument conventions). A scalar comes back when
every argument is a single vector, else an (N,) array.

The Earth's shape, chosen by ``R_itrs_from_gcrs`` (the Earth's orientation, (3, 3) or one
rotation per row (N, 3, 3), ``x_itrs = R_itrs_from_gcrs @ x_gcrs``, e.g. skyfield's
``itrs.rotation_at(t)`` with its last axis moved first):

* given: the **WGS-84 ellipsoid** (:mod:`satsight.ephemeris.wgs84`), placed by the rotation;
* None: a **sphere** of radius ``body_radius_m`` (default WGS-84 a = 6378137 m). The sphere
  of radius a stands 21.4 km above the ellipsoid at the poles (0 at the equator): a
  line of sight passing over a polar region is judged up to 21.4 km lower than it is, and
  a point up to 21.4 km above the polar surface counts as inside the Earth.

The atmosphere is handled by a margin: a line of sight must pass at least
``DEFAULT_ATMOSPHERE_MARGIN_M`` (the Kármán line, 100 km) above the surface.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M, WGS84_SEMI_MINOR_AXIS_M
from satsight.ephemeris.geometry import finish, positive_length, rotate, stack
from satsight.ephemeris.wgs84 import UNIT_SPHERE_SCALE, ellipsoid_level, geodetic_height_m
from satsight.errors import SatsightError
from satsight.vectors import norm

# The Kármán line, 100 km: the conventional lower edge of space (FAI). A line of sight that
# passes lower than this through the atmosphere is counted as blocked by the Earth.
DEFAULT_ATMOSPHERE_MARGIN_M = 100e3

# Bisection steps for the lowest point of a segment above the ellipsoid: they pin the
# segment parameter to 2^-52 of its length, far finer than needed (the height is flat
# at its minimum: an error dt in the parameter costs (|d| dt)^2 / (2 * 6.4e6 m)).
_CLEARANCE_BISECTIONS = 52


def _sphere_clearance(a: np.ndarray, b: np.ndarray, radius: float) -> np.ndarray:
    """min over the segment a -> b of |p| - radius (N,): see :func:`los_clearance_m`."""
    d = b - a
    dd = np.sum(d * d, axis=-1)
    minus_ad = -np.sum(a * d, axis=-1)
    interior = (minus_ad > 0.0) & (minus_ad < dd)
    line_distance = norm(np.cross(a, b)) / np.sqrt(np.where(interior, dd, 1.0))
    end_distance = np.minimum(norm(a), norm(b))
    return np.where(interior, line_distance, end_distance) - radius


def _ellipsoid_clearance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Lowest geodetic height over the ITRS segment a -> b (N, 3), m; see los_clearance_m."""
    # Where the segment enters the ellipsoid: in unit-sphere coordinates its least distance
    # rho from the centre is below 1 (exact test), and b_axis (rho - 1) is reported.
    unit_a, unit_b = a * UNIT_SPHERE_SCALE, b * UNIT_SPHERE_SCALE
    clearance = WGS84_SEMI_MINOR_AXIS_M * (_sphere_clearance(unit_a, unit_b, 1.0))
    outside = clearance > 0.0
    if not np.any(outside):
        return clearance
    a_out, b_out = a[outside], b[outside]
    d = b_out - a_out
    # The height is convex along the segment (the signed distance to a convex body is
    # convex), with derivative normal . d: bisect on its sign.
    slope_start = np.sum(geodetic_height_m(a_out)[1] * d, axis=-1)
    slope_end = np.sum(geodetic_height_m(b_out)[1] * d, axis=-1)
    low = np.zeros(len(d))
    high = np.ones(len(d))
    at_start = slope_start >= 0.0
    at_end = slope_end <= 0.0
    for _ in range(_CLEARANCE_BISECTIONS):
        middle = 0.5 * (low + high)
        _, normal = geodetic_height_m(a_out + middle[:, None] * d)
        rising = np.sum(normal * d, axis=-1) >= 0.0
        high = np.where(rising, middle, high)
        low = np.where(rising, low, middle)
    t = np.where(at_start, 0.0, np.where(at_end, 1.0, 0.5 * (low + high)))
    clearance[outside] = geodetic_height_m(a_out + t[:, None] * d)[0]
    return clearance


def los_clearance_m(
    a_m: ArrayLike,
    b_m: ArrayLike,
    body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
    R_itrs_from_gcrs: ArrayLike | None = None,
) -> float | np.ndarray:
    """Lowest altitude, m, of the straight segment from a to b above the Earth's surface.

    a_m, b_m: the segment's end points, GCRS, m, (3,) or (N, 3). Returns a scalar for single
    input, else (N,). Negative means the segment passes through the Earth.

    With R_itrs_from_gcrs ((3, 3) or (N, 3, 3), the Earth's orientation): the WGS-84
    ellipsoid. Where the segment stays outside it, the result is the least *geodetic
    height* along the segment (the height above the ellipsoid along its normal, i.e. the
    distance to the nearest surface point), found to well below a millimetre: the height is
    a convex function along a line (the signed distance to a convex body is convex), so a
    bisection on the sign of its derivative, normal . (b - a), finds the minimum, each
    height by Heikkinen's closed form (:func:`satsight.ephemeris.wgs84.geodetic_height_m`).
    Whether the segment meets the ellipsoid is decided exactly, in coordinates where the
    ellipsoid is the unit sphere (a linear map keeps the segment straight); there the result
    is b (rho - 1) < 0 with rho < 1 the segment's least distance from the centre in those
    coordinates: -b through the centre, 0 at tangency, and within a factor a / b (0.34 %) of
    minus the depth of the deepest point. body_radius_m must then be left at its default.

    Without a rotation: a sphere of radius body_radius_m, m, and the result is
    min over the segment of |p| - body_radius_m (-R through the centre). The closest point
    of the infinite line to the origin has the parameter t* = -(a . d) / (d . d), d = b - a.
    If 0 < t* < 1 it lies inside the segment and its distance is |a x b| / |d| (the height
    of the triangle origin-a-b); otherwise the closest point is the nearer end point.
    """
    radius = positive_length(body_radius_m, "body_radius_m")
    (a, b), R, single = stack(R_itrs_from_gcrs, a_m=a_m, b_m=b_m)
    if R is None:
        return finish(_sphere_clearance(a, b, radius), single)
    _require_default_radius(radius, "body_radius_m")
    return finish(_ellipsoid_clearance(rotate(R, a), rotate(R, b)), single)


def earth_occults(
    observer_m: ArrayLike,
    target_m: ArrayLike,
    margin_m: float = DEFAULT_ATMOSPHERE_MARGIN_M,
    R_itrs_from_gcrs: ArrayLike | None = None,
) -> bool | np.ndarray:
    """Whether the Earth (with its atmosphere) blocks the line of sight observer -> target.

    observer_m, target_m: GCRS, m, (3,) or (N, 3). margin_m >= 0: how high above the
    surface the line must pass, m (default: the Kármán line, 100 km). R_itrs_from_gcrs: the
    Earth's orientation for the WGS-84 ellipsoid, or None for the sphere of radius a (module
    docstring). True where ``los_clearance_m(observer, target, ...) < margin_m``; bool or
    (N,) bool.
    """
    margin = float(margin_m)
    if not (math.isfinite(margin) and margin >= 0.0):
        raise SatsightError(f"margin_m must be a finite height >= 0 m; got {margin_m}")
    clearance = los_clearance_m(observer_m, target_m, R_itrs_from_gcrs=R_itrs_from_gcrs)
    return clearance < margin


def inside_earth(
    position_m: ArrayLike, R_itrs_from_gcrs: ArrayLike | None = None
) -> bool | np.ndarray:
    """Whether a point lies inside the Earth (strictly below its surface).

    position_m: GCRS, m, (3,) or (N, 3). With R_itrs_from_gcrs ((3, 3) or (N, 3, 3)): inside
    the WGS-84 ellipsoid, (x^2 + y^2) / a^2 + z^2 / b^2 < 1 in the ITRS (exact). With None:
    inside the sphere of radius a, |position| < a, which also takes in the 21.4 km above the
    polar surface that the sphere adds. bool or (N,) bool.
    """
    (position,), R, single = stack(R_itrs_from_gcrs, position_m=position_m)
    if R is None:
        return finish(norm(position) < EARTH_EQUATORIAL_RADIUS_M, single)
    return finish(ellipsoid_level(rotate(R, position)) < 1.0, single)


def _require_default_radius(radius: float, name: str) -> None:
    if radius != EARTH_EQUATORIAL_RADIUS_M:
        raise SatsightError(
            f"{name} sets the radius of the spherical Earth (R_itrs_from_gcrs=None); with "
            "R_itrs_from_gcrs the Earth is the WGS-84 ellipsoid, whose axes are fixed. Leave "
            f"{name} at its default, or drop R_itrs_from_gcrs for a sphere of radius {radius} m"
        )
