"""Relative motion of an observer about a target on a (near-)circular orbit.

States are expressed in the target's RTN frame (`satsight.frames.orbital`): position
``rho = [x, y, z]`` in m with x radial (R, up), y along-track (T) and z orbit normal (N), and
its rate ``rho_dot`` in m/s seen in that rotating frame (the convention of
`satsight.frames.orbital.relative_rtn`). Stacks are (N, 3), float64.

Linearised about a circular reference orbit of mean motion ``n = sqrt(mu / a^3)`` (rad/s),
the relative motion obeys the Clohessy-Wiltshire (Hill) equations (W. H. Clohessy and
R. S. Wiltshire, "Terminal Guidance System for Satellite Rendezvous", J. Aerospace Sciences
27(9), 653-658, 1960; Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed.,
Sec. 6.8, Hill's equations):

    x'' = 3 n^2 x + 2 n y'
    y'' = -2 n x'
    z'' = -n^2 z

whose closed-form solution `cw_propagate` evaluates. Neglected:

* terms of second order in |rho| / a. The CW no-drift condition matches the energies of
  the two orbits to first order only: a trajectory starting on the V-bar at range rho has a
  semi-major axis 2 rho^2 / a too large and falls behind by 6 pi rho^2 / a per orbit
  (2.7 m for 1 km at a = 7000 km);
* the eccentricity of the reference orbit;
* differential perturbations. For J2 the largest effect on a relative state set up from
  osculating states is the short-period term of the semi-major axis,
  (3/2) J2 R^2 / a sin^2(i) cos(2 u) (u: argument of latitude): two objects at the same
  osculating state a distance rho apart along track differ in mean semi-major axis by up
  to 3 J2 (R / a)^2 sin^2(i) rho and drift apart by 3 pi times that per orbit (up to 16 m
  for 1 km at 7000 km, 51.6 deg); drag and other forces are not modelled here.

Natural (force-free) trajectories built here, all periodic or uniform in CW:

* `fly_around_initial_state`: a closed relative orbit at constant range (a circle);
* `in_plane_ellipse_initial_state`: the 2:1 ellipse in the R-T plane;
* `fly_by_initial_state`: a co-elliptic pass at constant radial offset;
* `hover_initial_state`: station keeping on the V-bar (along-track axis).

`spiral_approach` is a prescribed, guided trajectory (it needs thrust), not a natural one.
"""

from __future__ import annotations

import math

import numpy as np

from satsight.errors import SatsightError

_SQRT3 = math.sqrt(3.0)


def _check_positive(value: float, name: str) -> float:
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        raise SatsightError(f"{name} must be a finite number > 0; got {value}")
    return number


def _check_sign(value: int, name: str) -> float:
    if value not in (1, -1):
        raise SatsightError(f"{name} must be +1 or -1; got {value!r}")
    return float(value)


def _check_times(times_s: np.ndarray) -> np.ndarray:
    times = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    if times.ndim != 1 or times.size == 0:
        raise SatsightError(f"times_s must be a non-empty 1-D array of s; got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise SatsightError("times_s must be finite")
    return times


def _check_rtn_vector(value: np.ndarray, name: str) -> np.ndarray:
    vector = np.asarray(value, dtype=np.float64)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise SatsightError(
            f"{name} must be 3 finite numbers [R, T, N]; got shape {vector.shape}: {vector}"
        )
    return vector


def cw_propagate(
    rho0_rtn_m: np.ndarray,
    rho_dot0_rtn_m_s: np.ndarray,
    mean_motion_rad_s: float,
    times_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form Clohessy-Wiltshire solution: relative state (N, 3), (N, 3) at times_s.

    rho0_rtn_m (3,), m, and rho_dot0_rtn_m_s (3,), m/s: the observer's relative state at
    t = 0 in the target's RTN frame [x (R), y (T), z (N)]. mean_motion_rad_s: n of the
    target's circular orbit. times_s (N,): s from that state (any order, negative allowed:
    the solution is exact in both directions). With c = cos(n t), s = sin(n t)
    (Clohessy and Wiltshire 1960; Vallado, 4th ed., Sec. 6.8):

        x  = (4 - 3c) x0 + (s/n) vx0 + (2/n)(1 - c) vy0
        y  = 6 (s - n t) x0 + y0 - (2/n)(1 - c) vx0 + (4 s/n - 3 t) vy0
        z  = c z0 + (s/n) vz0
        vx = 3 n s x0 + c vx0 + 2 s vy0
        vy = -6 n (1 - c) x0 - 2 s vx0 + (4 c - 3) vy0
        vz = -n s z0 + c vz0

    The secular term (-6 n x0 - 3 vy0) t in y vanishes when vy0 = -2 n x0: the no-drift
    condition of every closed relative orbit. Returns (rho_rtn_m, rho_dot_rtn_m_s).
    """
    x0, y0, z0 = _check_rtn_vector(rho0_rtn_m, "rho0_rtn_m")
    vx0, vy0, vz0 = _check_rtn_vector(rho_dot0_rtn_m_s, "rho_dot0_rtn_m_s")
    n = _check_positive(mean_motion_rad_s, "mean_motion_rad_s")
    t = _check_times(times_s)
    nt = n * t
    c, s = np.cos(nt), np.sin(nt)
    one_minus_c = 1.0 - c
    x = (4.0 - 3.0 * c) * x0 + (s / n) * vx0 + (2.0 / n) * one_minus_c * vy0
    y = 6.0 * (s - nt) * x0 + y0 - (2.0 / n) * one_minus_c * vx0 + (4.0 * s / n - 3.0 * t) * vy0
    z = c * z0 + (s / n) * vz0
    vx = 3.0 * n * s * x0 + c * vx0 + 2.0 * s * vy0
    vy = -6.0 * n * one_minus_c * x0 - 2.0 * s * vx0 + (4.0 * c - 3.0) * vy0
    vz = -n * s * z0 + c * vz0
    return np.stack([x, y, z], axis=-1), np.stack([vx, vy, vz], axis=-1)


def _fly_around_axes(cross_track_sign: float) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal axes (e1, e2) in RTN of the fly-around circle: u = sin(th) e1 + cos(th) e2."""
    e1 = np.array([0.5, 0.0, 0.5 * _SQRT3 * cross_track_sign])
    e2 = np.array([0.0, 1.0, 0.0])
    return e1, e2


def fly_around_initial_state(
    radius_m: float,
    mean_motion_rad_s: float,
    phase_rad: float = 0.0,
    cross_track_sign: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Initial RTN state (3,), m and m/s, of the natural closed fly-around at constant range.

    The CW trajectory, with A = radius_m / 2 and theta = n t + phase_rad,

        x = A sin(theta),  y = 2 A cos(theta),  z = cross_track_sign sqrt(3) A sin(theta)

    keeps the range x^2 + y^2 + z^2 = A^2 (sin^2 + 4 cos^2 + 3 sin^2) = 4 A^2 constant, so
    the observer circles the target at exactly radius_m. Written as
    ``rho = radius_m (sin(theta) e1 + cos(theta) e2)`` with e1 = (1, 0, +-sqrt(3)) / 2 and
    e2 = (0, 1, 0), the circle lies in the plane through the along-track axis whose normal
    e1 x e2 = (-+sqrt(3), 0, 1) / 2 makes 60 deg with the orbit normal: the plane is tilted
    60 deg from the orbit plane about T. It closes after one revolution of the target,
    period 2 pi / n (the target's orbital period), moving from +T (theta = 0) towards e1
    (up and, for cross_track_sign = +1, towards +N). The in-plane part is the 2:1 ellipse
    of `in_plane_ellipse_initial_state` (x = A sin, y = 2 A cos satisfies the no-drift
    condition vy = -2 n x) and the cross-track part is the free harmonic oscillation of z
    in phase with x. Only in the linear (CW) model is the range exactly constant; the
    nonlinear and J2 departures are of the size given in the module docstring.

    radius_m: constant observer-target distance, m. mean_motion_rad_s: n, rad/s.
    phase_rad: theta at t = 0. cross_track_sign: +1 or -1, the side of the orbit plane the
    observer is on while above the target. Returns (rho0_rtn_m, rho_dot0_rtn_m_s).
    """
    radius = _check_positive(radius_m, "radius_m")
    n = _check_positive(mean_motion_rad_s, "mean_motion_rad_s")
    sign = _check_sign(cross_track_sign, "cross_track_sign")
    if not math.isfinite(phase_rad):
        raise SatsightError(f"phase_rad must be finite; got {phase_rad}")
    e1, e2 = _fly_around_axes(sign)
    s, c = math.sin(phase_rad), math.cos(phase_rad)
    return radius * (s * e1 + c * e2), radius * n * (c * e1 - s * e2)


def in_plane_ellipse_initial_state(
    semi_minor_radial_m: float,
    mean_motion_rad_s: float,
    phase_rad: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Initial RTN state (3,) of the natural 2:1 relative ellipse in the orbit (R-T) plane.

    x = b sin(n t + phase), y = 2 b cos(n t + phase), z = 0, with b = semi_minor_radial_m
    (radial semi-axis, m; the along-track semi-axis is 2 b). Centred on the target (no drift:
    vy0 = -2 n x0), period 2 pi / n, travelled clockwise seen from +N (from +T the observer
    moves up, x increasing, then back along -T above the target). Returns
    (rho0_rtn_m, rho_dot0_rtn_m_s).
    """
    b = _check_positive(semi_minor_radial_m, "semi_minor_radial_m")
    n = _check_positive(mean_motion_rad_s, "mean_motion_rad_s")
    if not math.isfinite(phase_rad):
        raise SatsightError(f"phase_rad must be finite; got {phase_rad}")
    s, c = math.sin(phase_rad), math.cos(phase_rad)
    return np.array([b * s, 2.0 * b * c, 0.0]), np.array([b * n * c, -2.0 * b * n * s, 0.0])


def _check_fly_by(
    miss_distance_m: float, start_along_track_m: float, mean_motion_rad_s: float
) -> tuple[float, float, float]:
    miss = float(miss_distance_m)
    start = float(start_along_track_m)
    n = _check_positive(mean_motion_rad_s, "mean_motion_rad_s")
    if not (math.isfinite(miss) and miss != 0.0):
        raise SatsightError(
            f"miss_distance_m must be a finite non-zero radial offset in m (positive: above the "
            f"target); got {miss_distance_m}. With no radial offset there is no drift: use "
            "hover_initial_state for a fixed along-track position"
        )
    if not (math.isfinite(start) and start != 0.0):
        raise SatsightError(
            f"start_along_track_m must be a finite non-zero along-track offset in m; got "
            f"{start_along_track_m}"
        )
    if math.copysign(1.0, miss) != math.copysign(1.0, start):
        direction = "-T" if miss > 0.0 else "+T"
        raise SatsightError(
            f"the fly-by would never pass the target: at radial offset {miss} m the observer "
            f"drifts towards {direction} (along-track rate -3/2 n x0), so it must start on the "
            f"other side; got start_along_track_m = {start}. Give start_along_track_m the sign "
            "of miss_distance_m (above the target: start ahead, +T; below: start behind, -T)"
        )
    return miss, start, n


def fly_by_initial_state(
    miss_distance_m: float, start_along_track_m: float, mean_motion_rad_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Initial RTN state (3,) of a co-elliptic pass under or over the target.

    The observer starts at x0 = miss_distance_m (radial; positive above the target),
    y0 = start_along_track_m, z0 = 0, with vx0 = 0 and vy0 = -(3/2) n x0. Then in the CW
    solution (`cw_propagate`) x stays at x0 and y = y0 - (3/2) n x0 t: a higher orbit is
    slower, so an observer above the target drifts backwards (towards -T). Closest approach,
    at distance |miss_distance_m|, is at y = 0, t = y0 / ((3/2) n x0); the symmetric pass ends
    at y = -y0 after `fly_by_duration_s` (twice that time). Raises SatsightError when
    start_along_track_m does not have the sign of miss_distance_m (the observer would drift
    away and never pass the target). Returns (rho0_rtn_m, rho_dot0_rtn_m_s).
    """
    miss, start, n = _check_fly_by(miss_distance_m, start_along_track_m, mean_motion_rad_s)
    return np.array([miss, start, 0.0]), np.array([0.0, -1.5 * n * miss, 0.0])


def fly_by_duration_s(
    miss_distance_m: float, start_along_track_m: float, mean_motion_rad_s: float
) -> float:
    """Time, s, for the fly-by of `fly_by_initial_state` to go from y0 to -y0: 4 y0 / (3 n x0).

    Closest approach is at half this time. Same arguments and errors as the state function.
    """
    miss, start, n = _check_fly_by(miss_distance_m, start_along_track_m, mean_motion_rad_s)
    return 4.0 * start / (3.0 * n * miss)


def hover_initial_state(
    range_m: float,
    along_track_sign: int = -1,
    orbit_radius_m: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Initial RTN state (3,) of V-bar station keeping: the observer at rest on the T axis.

    Without orbit_radius_m: rho = (0, along_track_sign range_m, 0), rho_dot = 0, an
    equilibrium of the CW equations (every point of the T axis is). In the full two-body
    dynamics that point is range_m^2 / (2 a) above the target's circular orbit and moves
    with the frame at |omega| |r|, faster than a circular orbit there: its semi-major axis
    exceeds a by 2 range_m^2 / a, and it drifts along track by -3 pi times that,
    -6 pi range_m^2 / a per orbit (-2.7 m for 1 km at 7000 km).

    With orbit_radius_m = a, the target's circular orbit radius: the point of that same
    orbit at chord distance range_m, shifted in phase by delta = 2 arcsin(range_m / (2 a)):
    rho = (a (cos delta - 1), along_track_sign a sin delta, 0), rho_dot = 0. Both objects then
    fly the same circle and keep this relative state exactly under two-body gravity; CW,
    which sees the curvature offset x = a (cos delta - 1) as a radial offset, does not.

    along_track_sign: -1 behind the target (default), +1 ahead of it. Returns
    (rho0_rtn_m, rho_dot0_rtn_m_s).
    """
    distance = _check_positive(range_m, "range_m")
    sign = _check_sign(along_track_sign, "along_track_sign")
    if orbit_radius_m is None:
        return np.array([0.0, sign * distance, 0.0]), np.zeros(3)
    a = _check_positive(orbit_radius_m, "orbit_radius_m")
    if distance > 2.0 * a:
        raise SatsightError(
            f"range_m = {distance} m exceeds the diameter 2 a = {2.0 * a} m of the orbit: no "
            "point of the same orbit is that far; give a smaller range or leave orbit_radius_m "
            "out"
        )
    delta = 2.0 * math.asin(distance / (2.0 * a))
    # a (cos delta - 1) = -2 a sin^2(delta / 2), written so as not to lose digits.
    radial = -2.0 * a * math.sin(0.5 * delta) ** 2
    return np.array([radial, sign * a * math.sin(delta), 0.0]), np.zeros(3)


def spiral_approach(
    times_s: np.ndarray,
    start_range_m: float,
    end_range_m: float,
    mean_motion_rad_s: float,
    revolutions: float | None = None,
    phase_rad: float = 0.0,
    cross_track_sign: int = 1,
    via_ranges_m: tuple[float, ...] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """A prescribed spiral approach: relative state (N, 3) m and (N, 3) m/s in target RTN.

    Not a natural trajectory: following it needs continuous thrust. The direction follows
    the fly-around circle of `fly_around_initial_state`,

        u(theta) = sin(theta) e1 + cos(theta) e2,  e1 = (1, 0, +-sqrt(3)) / 2, e2 = (0, 1, 0)

    at theta(t) = phase_rad + omega_s (t - t0), and the range decays geometrically,

        r(t) = r0 (r1 / r0)^((t - t0) / T),  T = times_s[-1] - times_s[0] = t1 - t0,

    so equal time spans cover equal distance ratios: each interval between ranges r_a > r_b
    takes a time proportional to ln(r_a / r_b) (for 50 -> 40 -> 30 -> 20 -> 10 -> 5 ->
    0.5 km, the last, tenfold step takes the longest). omega_s = n (one turn per target
    orbit, the fly-around rate) unless revolutions is given, then 2 pi revolutions / T.
    With r1 = r0 and omega_s = n this is exactly the natural CW fly-around.

    via_ranges_m: ranges strictly between r0 and r1, in order, that the approach passes at
    equal time steps: with K segments between r0, the via ranges and r1, segment k takes
    T / K and the range decays geometrically within it. Giving the edges of the distance
    intervals (40, 30, 20, 10, 5 km) spends equal time, hence equally many uniform frames,
    in each interval.

    rho = r u, rho_dot = r (ln(r1 / r0) / T) u + r omega_s u'(theta) (per segment
    ln(r_b / r_a) K / T in place of ln(r1 / r0) / T), with
    u' = cos(theta) e1 - sin(theta) e2: analytic. r passes r0 at t0 and r1 at t1 exactly
    (the range is ``r`` itself since |u| = 1) and is monotonic in between.

    times_s (N,): ascending, s, spanning T > 0. start_range_m, end_range_m: r0, r1 > 0, m
    (end > start spirals outwards). mean_motion_rad_s: n, rad/s. revolutions: turns over
    the span, or None. phase_rad, cross_track_sign: as for `fly_around_initial_state`.
    """
    times = _check_times(times_s)
    if times.size < 2 or np.any(np.diff(times) < 0.0) or not times[-1] > times[0]:
        raise SatsightError(
            "times_s must be ascending with at least two samples spanning a positive time; got "
            f"{times.size} samples from {times[0]} s to {times[-1]} s"
        )
    r0 = _check_positive(start_range_m, "start_range_m")
    r1 = _check_positive(end_range_m, "end_range_m")
    n = _check_positive(mean_motion_rad_s, "mean_motion_rad_s")
    sign = _check_sign(cross_track_sign, "cross_track_sign")
    if not math.isfinite(phase_rad):
        raise SatsightError(f"phase_rad must be finite; got {phase_rad}")
    span_s = float(times[-1] - times[0])
    if revolutions is None:
        omega_rad_s = n
    else:
        turns = float(revolutions)
        if not math.isfinite(turns):
            raise SatsightError(f"revolutions must be finite or None; got {revolutions}")
        omega_rad_s = 2.0 * math.pi * turns / span_s
    elapsed_s = times - times[0]
    fraction = elapsed_s / span_s
    fraction[-1] = 1.0  # the end range exactly, whatever the rounding of the division
    edges = np.array([r0, *(float(v) for v in via_ranges_m), r1])
    steps = np.diff(np.log(edges)) if np.all(edges > 0) else np.array([np.nan])
    monotonic = np.all(steps < 0) or np.all(steps > 0) or not via_ranges_m
    if not (np.all(np.isfinite(steps)) and monotonic):
        raise SatsightError(
            "via_ranges_m must be positive ranges strictly between start_range_m and "
            f"end_range_m, in order; got {list(via_ranges_m)} between {r0} and {r1} m"
        )
    segments = edges.size - 1
    position = fraction * segments
    segment = np.minimum(np.floor(position).astype(int), segments - 1)
    log_ratio = steps[segment]
    rng = edges[segment] * np.exp(log_ratio * (position - segment))
    rng[0], rng[-1] = r0, r1
    range_rate_m_s = rng * log_ratio * (segments / span_s)
    theta = phase_rad + omega_rad_s * elapsed_s
    e1, e2 = _fly_around_axes(sign)
    s, c = np.sin(theta)[:, None], np.cos(theta)[:, None]
    u = s * e1 + c * e2
    du = c * e1 - s * e2
    rho = rng[:, None] * u
    rho_dot = range_rate_m_s[:, None] * u + (rng * omega_rad_s)[:, None] * du
    return rho, rho_dot
