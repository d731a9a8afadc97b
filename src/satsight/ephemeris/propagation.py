"""Orbit propagation: two-body + zonal gravity (J2, optionally J3, J4) about the Earth's pole.

Frame: positions and velocities are in GCRS (the Earth-centred inertial frame of
:mod:`satsight.ephemeris.orbits`), in m and m/s; times in s after the initial epoch;
float64 throughout.

Gravity model: the point mass ``-mu r / |r|^3`` plus the zonal harmonics of the Earth's
field, the gradient of ``-mu / r sum_n J_n (R / r)^n P_n(u)`` with ``u = (r . p) / |r|`` and
``p`` the unit vector of the Earth's pole (Vallado, "Fundamentals of Astrodynamics and
Applications", 4th ed., Ch. 8; Montenbruck & Gill, "Satellite Orbits", Sec. 3.2):

    a_n = mu J_n R^n / r^(n+2) * [((n+1) P_n(u) + u P_n'(u)) r/|r| - P_n'(u) p]

For n = 2 this is the familiar
``-3/2 J2 mu R^2 / r^5 [(1 - 5 u^2) r + 2 (r . p) p]``, i.e. with p = z:
``[x (1 - 5 z^2/r^2), y (1 - 5 z^2/r^2), z (3 - 5 z^2/r^2)]`` times the prefactor.

Which pole (``j2_axis`` of :func:`propagate`):

* ``"true_pole"``: the ITRS z axis in GCRS at each integrator stage time, from skyfield's
  precession-nutation model (:mod:`satsight.ephemeris.earth_orientation`, interpolated
  linearly between hourly nodes: < 1e-5 m per orbit; polar motion, 0.1-0.5 m per orbit,
  is not modelled). This needs the epoch of t = 0.
* ``"gcrs_z"``: the GCRS z axis, fixed. An **approximation**: the Earth's pole is off the
  GCRS z axis by precession since J2000 (about 20 arcsec per year) plus nutation (up to
  ~17 arcsec), 2.4e-3 rad at 2025 and 4.9e-3 rad at 2050. Measured against
  ``"true_pole"`` (J2 only, RK4 1 s) for a 7000 km orbit (e = 0.001) inclined 97.9 deg with
  RAAN 0, argument of perigee 40 deg, from 2025-06-21T06:00Z: 430 m after one orbit and
  6.4 km after a day; from 2050-06-21T06:00Z: 862 m and 12.9 km. The size depends on the
  orbit's orientation and phase against the pole's offset: over a grid of RAAN and
  argument of latitude (51.6 and 97.9 deg, circular 7000 km) it spans 2-650 m after one
  orbit at 2025 (median 220 m) and 2-1280 m at 2050.

Neglected: tesseral and sectorial harmonics (C22, S22 are about as large as J3), zonal
terms past J4, atmospheric drag, solar radiation pressure and third-body (Sun, Moon)
attraction. Over the hours simulated for an image sequence these move a LEO object by
metres to kilometres along track, which changes lighting geometry negligibly but matters for
precise tracking: this is a scene-geometry model, not an orbit-determination one.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from skyfield.timelib import Time

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.earth_orientation import pole_track
from satsight.ephemeris.elements import MU_EARTH_M3_S2, _check_mu, _check_vector
from satsight.errors import SatsightError

# Unnormalised zonal harmonics of the Earth's gravity field, EGM96 (Lemoine et al., "The
# Development of the Joint NASA GSFC and NIMA Geopotential Model EGM96", NASA/TP-1998-
# 206861), from its fully normalised coefficients by J_n = -sqrt(2n + 1) Cbar_n0:
# Cbar_20 = -0.484165371736e-3, Cbar_30 = 0.957254173792e-6, Cbar_40 = 0.539873863789e-6.
# J2 = 0.0010826267 as in Vallado, 4th ed., Appendix D (Table D-1).
J2 = 1.08262668e-3
J3 = -math.sqrt(7.0) * 0.957254173792e-6  # -2.5326565e-6
J4 = -3.0 * 0.539873863789e-6  # -1.6196216e-6
_ZONAL = {2: J2, 3: J3, 4: J4}

J2_AXES = ("true_pole", "gcrs_z")

# Integrator tolerances of method="dop853" (see `propagate`).
DOP853_RTOL = 1e-12
DOP853_ATOL_POSITION_M = 1e-6
DOP853_ATOL_VELOCITY_M_S = 1e-9

_Z_AXIS = (0.0, 0.0, 1.0)


def _check_degree(max_zonal_degree: int) -> int:
    if max_zonal_degree not in _ZONAL:
        raise SatsightError(
            f"max_zonal_degree must be 2 (J2), 3 (J2, J3) or 4 (J2-J4); got {max_zonal_degree!r}"
        )
    return int(max_zonal_degree)


def _zonal_factors(u, n: int):
    """(A_n(u), P_n'(u)) with A_n = (n + 1) P_n + u P_n' (Legendre polynomials P_n)."""
    if n == 2:
        return 7.5 * u * u - 1.5, 3.0 * u
    if n == 3:
        return (17.5 * u * u - 7.5) * u, 7.5 * u * u - 1.5
    return (39.375 * u * u - 26.25) * u * u + 1.875, (17.5 * u * u - 7.5) * u


def gravity_acceleration_m_s2(
    r_m: np.ndarray,
    *,
    j2: bool = True,
    mu_m3_s2: float = MU_EARTH_M3_S2,
    pole_gcrs: np.ndarray | None = None,
    max_zonal_degree: int = 2,
) -> np.ndarray:
    """Gravitational acceleration (..., 3), m s^-2, at GCRS positions r_m (..., 3), m.

    Point mass plus (if j2) the zonal terms J2 .. J_max_zonal_degree of the module
    docstring, with R = EARTH_EQUATORIAL_RADIUS_M and the EGM96 constants J2, J3, J4.
    pole_gcrs: unit vector (3,) or (..., 3) of the Earth's pole in GCRS (e.g. from
    :func:`satsight.ephemeris.earth_orientation.pole_gcrs`); None means the GCRS z axis.
    """
    mu = _check_mu(mu_m3_s2)
    degree = _check_degree(max_zonal_degree)
    r = np.asarray(r_m, dtype=np.float64)
    if r.shape[-1:] != (3,):
        raise SatsightError(f"r_m must have shape (..., 3); got {r.shape}")
    r_sq = np.sum(r * r, axis=-1, keepdims=True)
    r_norm = np.sqrt(r_sq)
    acceleration = -mu * r / (r_sq * r_norm)
    if not j2:
        return acceleration
    if pole_gcrs is None:
        p = np.array(_Z_AXIS)
    else:
        p = np.asarray(pole_gcrs, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise SatsightError(f"pole_gcrs must have shape (3,) or (..., 3); got {p.shape}")
    u = np.sum(r * p, axis=-1, keepdims=True) / r_norm
    for n in range(2, degree + 1):
        c = mu * _ZONAL[n] * EARTH_EQUATORIAL_RADIUS_M**n / r_norm ** (n + 2)
        a_n, dp_n = _zonal_factors(u, n)
        acceleration = acceleration + c * (a_n * r / r_norm - dp_n * p)
    return acceleration


_Accel = Callable[[float, float, float, float], tuple[float, float, float]]


def _scalar_acceleration(
    mu: float,
    j2: bool,
    pole: Callable[[float], tuple[float, float, float]] | None = None,
    max_zonal_degree: int = 2,
) -> _Accel:
    """``accel(t_s, x, y, z)`` of `gravity_acceleration_m_s2` on Python floats, for the loops.

    pole: ``pole(t_s) -> (px, py, pz)`` unit pole in GCRS, or None for the fixed GCRS z
    axis. Plain float arithmetic is several times faster than numpy on 3-vectors, which is
    what makes a day of 1 s RK4 steps take about a second.
    """
    if not j2:

        def two_body(_t: float, x: float, y: float, z: float) -> tuple[float, float, float]:
            r_sq = x * x + y * y + z * z
            k = -mu / (r_sq * math.sqrt(r_sq))
            return k * x, k * y, k * z

        return two_body

    R = EARTH_EQUATORIAL_RADIUS_M
    if pole is None and max_zonal_degree == 2:
        k_j2 = -1.5 * J2 * mu * R**2

        def j2_about_z(_t: float, x: float, y: float, z: float) -> tuple[float, float, float]:
            r_sq = x * x + y * y + z * z
            r_norm = math.sqrt(r_sq)
            k = -mu / (r_sq * r_norm)
            f = k_j2 / (r_sq * r_sq * r_norm)
            s = 5.0 * z * z / r_sq
            return (
                k * x + f * x * (1.0 - s),
                k * y + f * y * (1.0 - s),
                k * z + f * z * (3.0 - s),
            )

        return j2_about_z

    if pole is not None and max_zonal_degree == 2:
        k_j2 = -1.5 * J2 * mu * R**2

        def j2_about_pole(t: float, x: float, y: float, z: float) -> tuple[float, float, float]:
            px, py, pz = pole(t)
            r_sq = x * x + y * y + z * z
            r_norm = math.sqrt(r_sq)
            k = -mu / (r_sq * r_norm)
            f = k_j2 / (r_sq * r_sq * r_norm)
            zp = px * x + py * y + pz * z  # the coordinate along the pole
            g = k + f * (1.0 - 5.0 * zp * zp / r_sq)
            fz = 2.0 * f * zp
            return g * x + fz * px, g * y + fz * py, g * z + fz * pz

        return j2_about_pole

    fixed = pole is None
    c2 = mu * J2 * R**2
    c3 = mu * J3 * R**3 if max_zonal_degree >= 3 else 0.0
    c4 = mu * J4 * R**4 if max_zonal_degree >= 4 else 0.0

    def zonal(t: float, x: float, y: float, z: float) -> tuple[float, float, float]:
        px, py, pz = _Z_AXIS if fixed else pole(t)
        r_sq = x * x + y * y + z * z
        r_norm = math.sqrt(r_sq)
        inv_r = 1.0 / r_norm
        k = -mu * inv_r / r_sq
        u = (px * x + py * y + pz * z) * inv_r
        uu = u * u
        q = c2 * inv_r**4  # mu J_n R^n / r^(n+2), n = 2
        # Along r/|r| (s_r) and along p (s_p): sum over n of q_n A_n(u) and -q_n P_n'(u).
        s_r = q * (7.5 * uu - 1.5)
        s_p = -q * 3.0 * u
        if c3:
            q = c3 * inv_r**5
            s_r += q * (17.5 * uu - 7.5) * u
            s_p -= q * (7.5 * uu - 1.5)
        if c4:
            q = c4 * inv_r**6
            s_r += q * ((39.375 * uu - 26.25) * uu + 1.875)
            s_p -= q * (17.5 * uu - 7.5) * u
        kr = k + s_r * inv_r
        return kr * x + s_p * px, kr * y + s_p * py, kr * z + s_p * pz

    return zonal


def _propagate_rk4(
    state: np.ndarray, times_s: np.ndarray, step_s: float, accel: _Accel
) -> np.ndarray:
    x, y, z, vx, vy, vz = (float(c) for c in state)
    out = np.empty((times_s.size, 6))
    t_now = 0.0
    for index, t_target in enumerate(times_s.tolist()):
        span = t_target - t_now
        # Whole steps, then one shortened step landing exactly on t_target. Step starts are
        # t_now + k step_s (not accumulated sums), so rounding does not drift the clock.
        n_steps = math.ceil(span / step_s - 1e-9) if span > 0.0 else 0
        for k in range(n_steps):
            h = step_s if k < n_steps - 1 else span - (n_steps - 1) * step_s
            half = 0.5 * h
            t0 = t_now + k * step_s
            a1x, a1y, a1z = accel(t0, x, y, z)
            a2x, a2y, a2z = accel(t0 + half, x + half * vx, y + half * vy, z + half * vz)
            v2x, v2y, v2z = vx + half * a1x, vy + half * a1y, vz + half * a1z
            a3x, a3y, a3z = accel(t0 + half, x + half * v2x, y + half * v2y, z + half * v2z)
            v3x, v3y, v3z = vx + half * a2x, vy + half * a2y, vz + half * a2z
            a4x, a4y, a4z = accel(t0 + h, x + h * v3x, y + h * v3y, z + h * v3z)
            v4x, v4y, v4z = vx + h * a3x, vy + h * a3y, vz + h * a3z
            sixth = h / 6.0
            x += sixth * (vx + 2.0 * v2x + 2.0 * v3x + v4x)
            y += sixth * (vy + 2.0 * v2y + 2.0 * v3y + v4y)
            z += sixth * (vz + 2.0 * v2z + 2.0 * v3z + v4z)
            vx += sixth * (a1x + 2.0 * a2x + 2.0 * a3x + a4x)
            vy += sixth * (a1y + 2.0 * a2y + 2.0 * a3y + a4y)
            vz += sixth * (a1z + 2.0 * a2z + 2.0 * a3z + a4z)
        t_now = t_target
        out[index] = (x, y, z, vx, vy, vz)
    return out


def _propagate_dop853(state: np.ndarray, times_s: np.ndarray, accel: _Accel) -> np.ndarray:
    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        ax, ay, az = accel(t, y[0], y[1], y[2])
        return np.array([y[3], y[4], y[5], ax, ay, az])

    t_end = float(times_s[-1])
    if t_end == 0.0:
        return np.repeat(state[None, :], times_s.size, axis=0)
    atol = np.array([DOP853_ATOL_POSITION_M] * 3 + [DOP853_ATOL_VELOCITY_M_S] * 3)
    from scipy.integrate import solve_ivp  # here: scipy.integrate takes 0.15 s to import

    # solve_ivp wants strictly increasing sample times: integrate through the distinct ones.
    distinct_times, index = np.unique(times_s, return_inverse=True)
    solution = solve_ivp(
        rhs,
        (0.0, t_end),
        state,
        method="DOP853",
        t_eval=distinct_times,
        rtol=DOP853_RTOL,
        atol=atol,
    )
    if not solution.success:
        raise SatsightError(f"the DOP853 orbit integration failed: {solution.message}")
    return solution.y.T[index]


def _resolve_axis(j2_axis: str | None, epoch: Time | str | None) -> str:
    if j2_axis is None:
        return "true_pole" if epoch is not None else "gcrs_z"
    if j2_axis not in J2_AXES:
        raise SatsightError(f"j2_axis must be one of {J2_AXES} or None; got {j2_axis!r}")
    if j2_axis == "true_pole" and epoch is None:
        raise SatsightError(
            "j2_axis='true_pole' needs the epoch of t = 0 (the Earth's pole moves in GCRS): "
            "pass epoch= as a skyfield Time or a UTC string such as '2025-03-20T12:00:00Z', "
            "or use j2_axis='gcrs_z'"
        )
    return j2_axis


def propagate(
    r0_m: np.ndarray,
    v0_m_s: np.ndarray,
    times_s: np.ndarray,
    *,
    j2: bool = True,
    method: str = "rk4",
    step_s: float = 1.0,
    mu_m3_s2: float = MU_EARTH_M3_S2,
    epoch: Time | str | None = None,
    j2_axis: str | None = None,
    max_zonal_degree: int = 2,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3), m, and velocities (N, 3), m/s, in GCRS at times_s after the epoch.

    r0_m (3,), v0_m_s (3,): GCRS state at t = 0. times_s (N,): ascending (repeats
    allowed), >= 0, in s (elapsed, TT) from the epoch; 0 returns the initial state. j2:
    include the zonal terms (J2, and J3, J4 if max_zonal_degree is 3 or 4), else pure
    two-body.

    epoch: the instant of t = 0, a scalar skyfield ``Time`` or a UTC ISO-8601 string (see
    :func:`satsight.ephemeris.time.parse_epoch_utc`). j2_axis: the symmetry axis of the
    zonal terms (module docstring): "true_pole" (the Earth's pole at each stage time; needs
    epoch) or "gcrs_z" (fixed GCRS z axis, an approximation: 0.4 km after one LEO orbit at
    2025). None picks "true_pole" when an epoch is given, else "gcrs_z": without an epoch
    the pole's position is unknown, and the old behaviour is kept for callers that give
    none. max_zonal_degree: 2 (J2 only, the default), 3 or 4 (EGM96 J3, J4).

    method="rk4": classical fixed-step fourth-order Runge-Kutta at step_s (1 s in the paper);
    before each requested time the last step is shortened so the integration lands on it
    exactly. For a 7000 km LEO at 1 s the truncation error is far below a millimetre per
    orbit. method="dop853": scipy's adaptive 8th-order Dormand-Prince (solve_ivp) with
    rtol = 1e-12 and atol = 1e-6 m on position, 1e-9 m/s on velocity, sampled at times_s;
    step_s is ignored. Raises SatsightError for non-finite input, unsorted or negative
    times, a non-positive step, an unknown method or axis, or "true_pole" without an epoch.
    """
    mu = _check_mu(mu_m3_s2)
    r0 = _check_vector(r0_m, "r0_m")
    v0 = _check_vector(v0_m_s, "v0_m_s")
    if float(np.linalg.norm(r0)) == 0.0:
        raise SatsightError("r0_m is the zero vector: the object would be at the Earth's centre")
    times = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    if times.ndim != 1 or times.size == 0:
        raise SatsightError(f"times_s must be a non-empty 1-D array; got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise SatsightError("times_s must be finite")
    if times[0] < 0.0:
        raise SatsightError(
            f"times_s must be >= 0 (s after the initial epoch); got {float(times[0])}"
        )
    if np.any(np.diff(times) < 0.0):
        raise SatsightError("times_s must be sorted in ascending order")
    step = float(step_s)
    if not (math.isfinite(step) and step > 0.0):
        raise SatsightError(f"step_s must be a finite number > 0 s; got {step_s}")
    if method not in ("rk4", "dop853"):
        raise SatsightError(f"method must be 'rk4' or 'dop853'; got {method!r}")
    degree = _check_degree(max_zonal_degree)
    axis = _resolve_axis(j2_axis, epoch)
    pole = None
    if j2 and axis == "true_pole":
        pole = pole_track(epoch, float(times[-1])).scalar_function()
    accel = _scalar_acceleration(mu, j2, pole, degree)
    state = np.concatenate([r0, v0])
    if method == "rk4":
        out = _propagate_rk4(state, times, step, accel)
    else:
        out = _propagate_dop853(state, times, accel)
    return out[:, :3].copy(), out[:, 3:].copy()
