"""Can the camera see the target, and is the target in sunlight? Geometry per frame.

Frame and units: every position is a geocentric **GCRS** vector in metres (the frame of
:mod:`satsight.ephemeris.sun_moon` and :mod:`satsight.ephemeris.orbits`), velocities in m/s,
angles in rad. Vector arguments have shape (3,) or (N, 3) (components on the last axis,
float64); a (3,) argument is broadcast against (N, 3) ones. Functions return a Python
scalar when every vector argument is (3,), else an (N,) array; :func:`assess_visibility`
always returns (N,) arrays.

Model:

* The Earth is a sphere of radius ``EARTH_EQUATORIAL_RADIUS_M`` (WGS-84 a, 6378137 m)
  centred at the origin, unless a radius argument says otherwise. The polar flattening
  (21 km) is neglected.
* The Sun is a sphere of radius ``SUN_RADIUS_M`` at the position given (e.g. from
  :func:`satsight.ephemeris.sun_moon.sun_position_gcrs_m`), a uniformly bright disc (no limb
  darkening). Eclipses by the Moon are ignored.
* The atmosphere is transparent for sunlight (no refraction, no extinction) and the
  Earth's disc has a sharp edge. For the line of sight between camera and target, the
  atmosphere is accounted for by a margin: the line must pass at least
  ``DEFAULT_ATMOSPHERE_MARGIN_M`` (the Kármán line) above the sphere.

Shadow models (Montenbruck & Gill, "Satellite Orbits", Springer 2000, Sec. 3.4.2):

* *cylindrical*: the shadow is the half-cylinder of radius R behind the Earth, its axis
  along the Earth-Sun line (an infinitely distant point Sun);
* *conical*: the fraction of the solar disc seen from the target that the Earth's disc does
  not cover (:func:`sunlit_fraction`; Montenbruck & Gill's shadow function nu). It is 1 in
  full Sun, 0 in the umbra and in between in the penumbra; in the antumbra, far behind the
  Earth where its disc looks smaller than the Sun's, it is 1 - (b/a)^2 at most.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from satsight.ephemeris.orbits import EARTH_EQUATORIAL_RADIUS_M, MU_EARTH_M3_S2
from satsight.errors import SatsightError

# Nominal solar radius, m: IAU 2015 Resolution B3 (R_sun^N = 6.957e8 m).
SUN_RADIUS_M = 695_700_000.0

# The Kármán line, 100 km: the conventional lower edge of space (FAI). A line of sight that
# passes lower than this through the atmosphere is counted as blocked by the Earth.
DEFAULT_ATMOSPHERE_MARGIN_M = 100e3

# A frame counts as eclipsed when sunlit_fraction < min_sunlit_fraction - this tolerance,
# so that exactly 1.0 (full Sun) passes min_sunlit_fraction = 1 and a rounding-level dip in
# the first or last instant of a penumbra does not flip a flag. Dimensionless (a fraction
# of the solar flux).
SUNLIT_FRACTION_TOLERANCE = 1e-9


# --- input handling ------------------------------------------------------------------------


def _stack(**vectors: ArrayLike) -> tuple[list[np.ndarray], bool]:
    """The named vectors as (N, 3) float64 arrays with a common N, and whether all were (3,).

    Each must be (3,) or (N, 3) and finite; (3,) ones are broadcast to the common N.
    """
    arrays: list[np.ndarray] = []
    n: int | None = None
    n_from = ""
    for name, value in vectors.items():
        array = np.asarray(value, dtype=np.float64)
        if array.ndim not in (1, 2) or array.shape[-1] != 3:
            raise SatsightError(
                f"{name} must be a GCRS vector in metres of shape (3,) or a stack (N, 3); "
                f"got shape {array.shape}"
            )
        if not np.all(np.isfinite(array)):
            raise SatsightError(f"{name} must be finite; got non-finite values in {name}")
        if array.ndim == 2:
            if n is None:
                n, n_from = array.shape[0], name
            elif array.shape[0] != n:
                raise SatsightError(
                    f"{n_from} has {n} rows but {name} has {array.shape[0]}: give stacks of "
                    "the same length N, or a single (3,) vector to use at every row"
                )
        arrays.append(array)
    single = n is None
    rows = 1 if n is None else n
    return [np.broadcast_to(np.atleast_2d(a), (rows, 3)) for a in arrays], single


def _finish(values: np.ndarray, single: bool) -> float | bool | np.ndarray:
    if single:
        return values[0].item()
    return values


def _positive_length(value: float, name: str) -> float:
    length = float(value)
    if not (math.isfinite(length) and length > 0.0):
        raise SatsightError(f"{name} must be a finite length > 0 m; got {value}")
    return length


def _norm(v: np.ndarray) -> np.ndarray:
    return np.linalg.norm(v, axis=-1)


def _angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle in [0, pi] between the rows of u and v (N, 3), by atan2 (accurate everywhere)."""
    return np.arctan2(_norm(np.cross(u, v)), np.sum(u * v, axis=-1))


def _require_nonzero(v: np.ndarray, what: str) -> None:
    if np.any(_norm(v) == 0.0):
        raise SatsightError(
            f"{what} is the zero vector in some row, so the angle is undefined; give distinct "
            "positions"
        )


# --- line of sight -------------------------------------------------------------------------


def los_clearance_m(
    a_m: ArrayLike, b_m: ArrayLike, body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M
) -> float | np.ndarray:
    """Lowest altitude, m, of the straight segment from a to b above a sphere at the origin.

    a_m, b_m: the segment's end points, GCRS, m, (3,) or (N, 3). body_radius_m: the sphere's
    radius, m. Returns min over the segment of |p| - body_radius_m: a scalar for (3,) input,
    else (N,). Negative means the segment passes through the sphere (-R if through its
    centre).

    The closest point of the infinite line to the origin has the parameter
    t* = -(a . d) / (d . d), d = b - a. If 0 < t* < 1 it lies inside the segment and its
    distance is |a x b| / |d| (the height of the triangle origin-a-b); otherwise the closest
    point is the nearer end point.
    """
    radius = _positive_length(body_radius_m, "body_radius_m")
    (a, b), single = _stack(a_m=a_m, b_m=b_m)
    d = b - a
    dd = np.sum(d * d, axis=-1)
    minus_ad = -np.sum(a * d, axis=-1)
    interior = (minus_ad > 0.0) & (minus_ad < dd)
    line_distance = _norm(np.cross(a, b)) / np.sqrt(np.where(interior, dd, 1.0))
    end_distance = np.minimum(_norm(a), _norm(b))
    distance = np.where(interior, line_distance, end_distance)
    return _finish(distance - radius, single)


def earth_occults(
    observer_m: ArrayLike, target_m: ArrayLike, margin_m: float = DEFAULT_ATMOSPHERE_MARGIN_M
) -> bool | np.ndarray:
    """Whether the Earth (with its atmosphere) blocks the line of sight observer -> target.

    observer_m, target_m: GCRS, m, (3,) or (N, 3). margin_m >= 0: how high above the sphere
    the line must pass, m (default: the Kármán line, 100 km). True where
    ``los_clearance_m(observer, target) < margin_m``; bool or (N,) bool.
    """
    margin = float(margin_m)
    if not (math.isfinite(margin) and margin >= 0.0):
        raise SatsightError(f"margin_m must be a finite height >= 0 m; got {margin_m}")
    return los_clearance_m(observer_m, target_m) < margin


# --- shadows -------------------------------------------------------------------------------


def in_cylindrical_shadow(
    position_m: ArrayLike,
    sun_position_m: ArrayLike,
    body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
) -> bool | np.ndarray:
    """Whether a point is in the Earth's cylindrical shadow (point Sun at infinity).

    position_m: the point, GCRS, m; sun_position_m: the Sun's geocentric position, GCRS, m
    (only its direction s is used); (3,) or (N, 3). True where the point is behind the
    Earth (position . s < 0) and less than body_radius_m from the Earth-Sun line
    (Montenbruck & Gill, "Satellite Orbits", 2000, Sec. 3.4.2, cylindrical model).
    """
    radius = _positive_length(body_radius_m, "body_radius_m")
    (r, sun), single = _stack(position_m=position_m, sun_position_m=sun_position_m)
    _require_nonzero(sun, "sun_position_m")
    s = sun / _norm(sun)[:, None]
    along = np.sum(r * s, axis=-1)
    across = _norm(r - along[:, None] * s)
    return _finish((along < 0.0) & (across < radius), single)


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


def sunlit_fraction(
    position_m: ArrayLike,
    sun_position_m: ArrayLike,
    earth_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
    sun_radius_m: float = SUN_RADIUS_M,
) -> float | np.ndarray:
    """Fraction of the solar disc seen from a point that the Earth does not hide, in [0, 1].

    position_m: the point (the target), GCRS, m; sun_position_m: the Sun's geocentric
    position, GCRS, m; (3,) or (N, 3). Returns a scalar or (N,): 1 in full Sun, 0 in the
    umbra, in between in the penumbra, 1 - (b/a)^2 in the antumbra (the Earth's disc inside
    the Sun's).

    Montenbruck & Gill, "Satellite Orbits", 2000, Sec. 3.4.2 (conical shadow, their shadow
    function nu): seen from the point, the Sun's disc has the apparent radius
    a = arcsin(R_sun / |sun - r|), the Earth's b = arcsin(R_earth / |r|), and their centres
    are c apart (the angle between sun - r and -r). The covered fraction is the area of the
    lens common to two circles of radii a and b with centres c apart, over pi a^2
    (:func:`_covered_fraction`).

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
    as opaque.

    Raises SatsightError for a point inside the Earth or the Sun, where there is no disc.
    """
    earth_radius = _positive_length(earth_radius_m, "earth_radius_m")
    sun_radius = _positive_length(sun_radius_m, "sun_radius_m")
    (r, sun), single = _stack(position_m=position_m, sun_position_m=sun_position_m)
    to_sun = sun - r
    sun_distance = _norm(to_sun)
    earth_distance = _norm(r)
    if np.any(earth_distance <= earth_radius):
        raise SatsightError(
            f"sunlit_fraction needs points outside the Earth (|position| > {earth_radius} m); "
            f"got |position| = {float(np.min(earth_distance))} m; check the units (metres) "
            "and that the orbit does not reach the ground"
        )
    if np.any(sun_distance <= sun_radius):
        raise SatsightError(
            f"sunlit_fraction needs points outside the Sun (distance > {sun_radius} m); got a "
            f"distance of {float(np.min(sun_distance))} m; check the Sun position's units (m)"
        )
    a = np.arcsin(sun_radius / sun_distance)
    b = np.arcsin(earth_radius / earth_distance)
    c = _angle_between(to_sun, -r)
    return _finish(np.clip(1.0 - _covered_fraction(a, b, c), 0.0, 1.0), single)


# --- angles --------------------------------------------------------------------------------


def phase_angle_rad(
    target_m: ArrayLike, observer_m: ArrayLike, sun_m: ArrayLike
) -> float | np.ndarray:
    """Sun-target-observer angle, rad in [0, pi], at the target.

    target_m, observer_m, sun_m: GCRS positions, m, (3,) or (N, 3). The angle between the
    directions target -> Sun and target -> observer: 0 when the observer has the Sun behind
    it (it sees the fully lit face), pi when it looks at the target against the Sun.
    """
    (t, o, s), single = _stack(target_m=target_m, observer_m=observer_m, sun_m=sun_m)
    to_sun, to_observer = s - t, o - t
    _require_nonzero(to_sun, "sun_m - target_m")
    _require_nonzero(to_observer, "observer_m - target_m")
    return _finish(_angle_between(to_sun, to_observer), single)


def sun_boresight_angle_rad(
    observer_m: ArrayLike, target_m: ArrayLike, sun_m: ArrayLike
) -> float | np.ndarray:
    """Angle at the observer between the boresight and the Sun, rad in [0, pi].

    observer_m, target_m, sun_m: GCRS positions, m, (3,) or (N, 3). The angle between the
    directions observer -> target (the camera's boresight) and observer -> Sun's centre:
    0 when the camera looks straight at the Sun.
    """
    (o, t, s), single = _stack(observer_m=observer_m, target_m=target_m, sun_m=sun_m)
    boresight, to_sun = t - o, s - o
    _require_nonzero(boresight, "target_m - observer_m")
    _require_nonzero(to_sun, "sun_m - observer_m")
    return _finish(_angle_between(boresight, to_sun), single)


def beta_angle_rad(r_m: ArrayLike, v_m_s: ArrayLike, sun_m: ArrayLike) -> float | np.ndarray:
    """Beta angle, rad in [-pi/2, pi/2]: the Sun's elevation above the orbit plane.

    r_m (m), v_m_s (m/s): the orbiting object's GCRS state; sun_m: the Sun's geocentric
    position, m; (3,) or (N, 3). beta = pi/2 - angle(h, s), with h = r x v the angular
    momentum and s the Earth -> Sun direction: positive when the Sun is on the side of h,
    +pi/2 when the Sun is along the orbit normal, 0 when it lies in the orbit plane (the
    usual definition; e.g. Gilmore (ed.), "Spacecraft Thermal Control Handbook", Vol. I,
    2nd ed., 2002, Ch. 2). Computed as atan2(h . s, |h x s|).
    """
    (r, v, s), single = _stack(r_m=r_m, v_m_s=v_m_s, sun_m=sun_m)
    h = np.cross(r, v)
    if np.any(_norm(h) == 0.0):
        raise SatsightError(
            "r_m and v_m_s are parallel (or zero) in some row: there is no orbit plane, so "
            "no beta angle; give a velocity with a component across r"
        )
    _require_nonzero(s, "sun_m")
    beta = np.arctan2(np.sum(h * s, axis=-1), _norm(np.cross(h, s)))
    return _finish(beta, single)


def cylindrical_eclipse_duration_s(
    radius_m: ArrayLike,
    beta_rad: ArrayLike,
    mu_m3_s2: float = MU_EARTH_M3_S2,
    body_radius_m: float = EARTH_EQUATORIAL_RADIUS_M,
) -> float | np.ndarray:
    """Time per orbit, s, that a circular orbit spends in the cylindrical shadow.

    radius_m > body_radius_m: orbit radius r, m; beta_rad in [-pi/2, pi/2]: beta angle;
    scalars or broadcastable arrays (a scalar result for scalar input). The Sun's direction
    is held fixed over the orbit. With theta the angle along the orbit from the point
    nearest the Sun, the position's component along the Sun is r cos(beta) cos(theta) and
    its squared distance from the Earth-Sun line r^2 (1 - cos^2(beta) cos^2(theta)); it is
    in the shadow cylinder of radius R where cos(theta) < 0 and that distance is < R, i.e.
    for |theta - pi| < theta_0 with

        cos(theta_0) = sqrt(r^2 - R^2) / (r cos(beta)),

    so the duration is T theta_0 / pi with T = 2 pi sqrt(r^3 / mu). There is no eclipse
    when |beta| >= arcsin(R / r). (Cylindrical model: Montenbruck & Gill, "Satellite
    Orbits", 2000, Sec. 3.4.2; the same eclipse fraction theta_0 / pi is in Gilmore (ed.),
    "Spacecraft Thermal Control Handbook", Vol. I, 2nd ed., 2002, Ch. 2.)
    """
    mu = _positive_length(mu_m3_s2, "mu_m3_s2")
    body_radius = _positive_length(body_radius_m, "body_radius_m")
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


# --- per-frame summary ---------------------------------------------------------------------


@dataclass(frozen=True)
class VisibilityLimits:
    """Thresholds that decide whether a frame is usable.

    atmosphere_margin_m >= 0: the camera-target line of sight must pass at least this high
    above the Earth's sphere, m (default 100 km, the Kármán line: below it the line crosses
    the atmosphere, which scatters and absorbs; flag ``earth_occulted``).

    min_sunlit_fraction in [0, 1]: a frame is ``eclipsed`` when the target's
    :func:`sunlit_fraction` is below this (less SUNLIT_FRACTION_TOLERANCE). Default 1: any
    frame in the penumbra is rejected, since the irradiance there falls from full to zero
    within seconds and the flux then also depends on limb darkening and the atmosphere,
    which the model leaves out. 0 disables the test.

    sun_exclusion_rad in [0, pi]: a frame is ``sun_excluded`` when the Sun's centre is
    closer than this to the boresight. Default 30 deg, a typical Sun exclusion half-angle of
    a baffled visible camera or star tracker: nearer to the Sun, stray light floods the
    detector.

    min_phase_angle_rad <= max_phase_angle_rad, both in [0, pi]: a frame is
    ``phase_rejected`` outside this range of the Sun-target-camera angle. Defaults 0 and
    150 deg: beyond 150 deg a sphere shows the camera less than (1 + cos 150 deg) / 2 = 7 %
    of its lit face, a thin crescent. For a Sun much farther than the camera-target range,
    phase angle = pi - sun_boresight_angle (up to the range / Sun-distance parallax), so
    with the defaults the two tests reject the same frames; each is kept so that either can
    be loosened alone.
    """

    atmosphere_margin_m: float = DEFAULT_ATMOSPHERE_MARGIN_M
    min_sunlit_fraction: float = 1.0
    sun_exclusion_rad: float = math.radians(30.0)
    min_phase_angle_rad: float = 0.0
    max_phase_angle_rad: float = math.radians(150.0)

    def __post_init__(self) -> None:
        for name in (
            "atmosphere_margin_m",
            "min_sunlit_fraction",
            "sun_exclusion_rad",
            "min_phase_angle_rad",
            "max_phase_angle_rad",
        ):
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not math.isfinite(number):
                raise SatsightError(f"VisibilityLimits.{name} must be a finite number; got {value}")
            object.__setattr__(self, name, number)
        if self.atmosphere_margin_m < 0.0:
            raise SatsightError(
                "VisibilityLimits.atmosphere_margin_m must be >= 0 m (how high above the "
                f"surface the line of sight must pass); got {self.atmosphere_margin_m} m"
            )
        if not 0.0 <= self.min_sunlit_fraction <= 1.0:
            raise SatsightError(
                "VisibilityLimits.min_sunlit_fraction must lie in [0, 1] (1: full Sun only, "
                f"0: never reject for shadow); got {self.min_sunlit_fraction}"
            )
        for name in ("sun_exclusion_rad", "min_phase_angle_rad", "max_phase_angle_rad"):
            value = getattr(self, name)
            if not 0.0 <= value <= math.pi:
                raise SatsightError(
                    f"VisibilityLimits.{name} must lie in [0, pi] rad; got {value} rad "
                    f"({math.degrees(value)} deg); give angles in radians"
                )
        if self.min_phase_angle_rad > self.max_phase_angle_rad:
            raise SatsightError(
                "VisibilityLimits.min_phase_angle_rad must not exceed max_phase_angle_rad; got "
                f"{self.min_phase_angle_rad} > {self.max_phase_angle_rad} rad"
            )


@dataclass(frozen=True)
class FrameVisibility:
    """Per-frame visibility geometry and flags; every field is a read-only (N,) array.

    los_clearance_m: lowest altitude of the camera-target segment above the Earth's
    sphere, m. sunlit_fraction: :func:`sunlit_fraction` at the target. sun_boresight_angle_rad:
    boresight-Sun angle at the camera. phase_angle_rad: Sun-target-camera angle.
    earth_occulted, eclipsed, sun_excluded, phase_rejected: bool flags from
    :class:`VisibilityLimits`.
    """

    los_clearance_m: np.ndarray
    sunlit_fraction: np.ndarray
    sun_boresight_angle_rad: np.ndarray
    phase_angle_rad: np.ndarray
    earth_occulted: np.ndarray
    eclipsed: np.ndarray
    sun_excluded: np.ndarray
    phase_rejected: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in (
            ("los_clearance_m", np.float64),
            ("sunlit_fraction", np.float64),
            ("sun_boresight_angle_rad", np.float64),
            ("phase_angle_rad", np.float64),
            ("earth_occulted", bool),
            ("eclipsed", bool),
            ("sun_excluded", bool),
            ("phase_rejected", bool),
        ):
            value = np.array(getattr(self, name), dtype=dtype).reshape(-1)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        n = self.los_clearance_m.shape[0]
        if any(getattr(self, f).shape[0] != n for f in self.__dataclass_fields__):
            raise SatsightError("FrameVisibility fields must all have the same length N")

    @property
    def visible(self) -> np.ndarray:
        """(N,) bool: frames with none of the four flags set."""
        return ~(self.earth_occulted | self.eclipsed | self.sun_excluded | self.phase_rejected)


def assess_visibility(
    target_m: ArrayLike,
    observer_m: ArrayLike,
    sun_m: ArrayLike,
    limits: VisibilityLimits | None = None,
) -> FrameVisibility:
    """Visibility geometry and flags of N frames.

    target_m, observer_m (the camera), sun_m (the Sun's geocentric position): GCRS, m, (3,)
    or (N, 3); all (3,) gives N = 1. limits: thresholds (default ``VisibilityLimits()``).
    Flags: earth_occulted where los_clearance_m < atmosphere_margin_m; eclipsed where
    sunlit_fraction < min_sunlit_fraction - SUNLIT_FRACTION_TOLERANCE; sun_excluded where
    sun_boresight_angle_rad < sun_exclusion_rad; phase_rejected where the phase angle is
    outside [min_phase_angle_rad, max_phase_angle_rad]. The Sun exclusion does not ask
    whether the Earth hides the Sun from the camera (it errs on the side of rejecting).
    """
    limits = VisibilityLimits() if limits is None else limits
    if not isinstance(limits, VisibilityLimits):
        raise SatsightError(
            f"limits must be a VisibilityLimits (or None for the defaults); got {type(limits)}"
        )
    (target, observer, sun), _ = _stack(target_m=target_m, observer_m=observer_m, sun_m=sun_m)
    clearance = np.asarray(los_clearance_m(observer, target))
    fraction = np.asarray(sunlit_fraction(target, sun))
    boresight = np.asarray(sun_boresight_angle_rad(observer, target, sun))
    phase = np.asarray(phase_angle_rad(target, observer, sun))
    return FrameVisibility(
        los_clearance_m=clearance,
        sunlit_fraction=fraction,
        sun_boresight_angle_rad=boresight,
        phase_angle_rad=phase,
        earth_occulted=clearance < limits.atmosphere_margin_m,
        eclipsed=fraction < limits.min_sunlit_fraction - SUNLIT_FRACTION_TOLERANCE,
        sun_excluded=boresight < limits.sun_exclusion_rad,
        phase_rejected=(phase < limits.min_phase_angle_rad) | (phase > limits.max_phase_angle_rad),
    )
