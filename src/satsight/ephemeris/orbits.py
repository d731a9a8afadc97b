"""Earth orbits: classical elements, state vectors, and propagation with two-body + J2 gravity.

Frame: every position and velocity is in an Earth-centred inertial frame with the z axis
along the Earth's rotation axis and x towards the equinox (GCRS-like; the precession and
nutation of the axis are neglected over the spans simulated here). Positions are in m,
velocities in m/s, times in s, angles in rad; float64 throughout.

Gravity model: the point-mass term ``-mu r / |r|^3`` plus, optionally, the Earth's
oblateness through the zonal harmonic J2, minus the gradient of the potential
``J2 mu R^2 / (2 r^3) (3 z^2 / r^2 - 1)`` (Vallado, "Fundamentals of Astrodynamics and
Applications", 4th ed., Ch. 8; Curtis, "Orbital Mechanics for Engineering Students",
3rd ed., Ch. 10):

    a_J2 = -3/2 J2 mu R^2 / r^5 * [x (1 - 5 z^2/r^2), y (1 - 5 z^2/r^2), z (3 - 5 z^2/r^2)]

Neglected: higher harmonics (J3, J4, ...), atmospheric drag, solar radiation pressure and
third-body (Sun, Moon) attraction. Over the hours simulated for an image sequence these
move a LEO object by metres to kilometres along track, which changes lighting geometry
negligibly but matters for precise tracking: this is a scene-geometry model, not an
orbit-determination one.

Only closed (elliptical, ``0 <= e < 1``) orbits are supported by the element conversions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from satsight.errors import SatsightError

# Earth's gravitational parameter GM, m^3 s^-2, including the mass of the atmosphere:
# IERS Conventions (2010), Technical Note 36, Table 1.1; the EGM96 / WGS-84 (G1150) value,
# as tabulated in Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed.,
# Appendix D (Table D-1).
MU_EARTH_M3_S2 = 3.986004418e14

# Equatorial radius of the Earth, m: WGS-84 defining parameter (NIMA TR8350.2, 3rd ed.,
# Table 3.1); also Vallado, 4th ed., Appendix D.
EARTH_EQUATORIAL_RADIUS_M = 6378137.0

# Unnormalised second zonal harmonic of the Earth's gravity field (EGM96): Vallado, 4th ed.,
# Appendix D (Table D-1), J2 = 0.0010826267.
J2 = 1.08262668e-3

# Below these, an orbit is treated as circular (|e|) or equatorial (|h_xy| / |h|), and the
# angles that are undefined there follow the conventions of `elements_from_state`.
_CIRCULAR_TOLERANCE = 1e-11
_EQUATORIAL_TOLERANCE = 1e-11

_TWO_PI = 2.0 * math.pi

# Integrator tolerances of method="dop853" (see `propagate`).
DOP853_RTOL = 1e-12
DOP853_ATOL_POSITION_M = 1e-6
DOP853_ATOL_VELOCITY_M_S = 1e-9


@dataclass(frozen=True)
class OrbitalElements:
    """Classical (Keplerian) osculating elements of an elliptical orbit.

    semi_major_axis_m: a > 0, m. eccentricity: 0 <= e < 1. inclination_rad: i in [0, pi],
    the angle between the orbit normal and the inertial z axis. raan_rad: right ascension of
    the ascending node, measured from x about z. arg_perigee_rad: from the ascending node to
    perigee, in the direction of motion. true_anomaly_rad: from perigee to the object, in the
    direction of motion. Angles are in rad and need not be reduced to [0, 2 pi).
    """

    semi_major_axis_m: float
    eccentricity: float
    inclination_rad: float
    raan_rad: float
    arg_perigee_rad: float
    true_anomaly_rad: float

    def __post_init__(self) -> None:
        values = {
            "semi_major_axis_m": self.semi_major_axis_m,
            "eccentricity": self.eccentricity,
            "inclination_rad": self.inclination_rad,
            "raan_rad": self.raan_rad,
            "arg_perigee_rad": self.arg_perigee_rad,
            "true_anomaly_rad": self.true_anomaly_rad,
        }
        for name, value in values.items():
            if not math.isfinite(value):
                raise SatsightError(f"orbital element {name} must be a finite number; got {value}")
            object.__setattr__(self, name, float(value))
        if not self.semi_major_axis_m > 0.0:
            raise SatsightError(
                "semi_major_axis_m must be > 0 (only elliptical orbits are supported); "
                f"got {self.semi_major_axis_m} m"
            )
        if not 0.0 <= self.eccentricity < 1.0:
            raise SatsightError(
                "eccentricity must satisfy 0 <= e < 1 (only elliptical orbits are supported); "
                f"got {self.eccentricity}"
            )
        if not 0.0 <= self.inclination_rad <= math.pi:
            raise SatsightError(
                f"inclination_rad must lie in [0, pi]; got {self.inclination_rad} rad "
                f"({math.degrees(self.inclination_rad)} deg)"
            )

    @classmethod
    def from_km_deg(
        cls,
        a_km: float,
        e: float,
        i_deg: float,
        raan_deg: float,
        argp_deg: float,
        nu_deg: float,
    ) -> OrbitalElements:
        """Elements from the units a configuration file uses: a in km, angles in degrees."""
        return cls(
            semi_major_axis_m=a_km * 1e3,
            eccentricity=e,
            inclination_rad=math.radians(i_deg),
            raan_rad=math.radians(raan_deg),
            arg_perigee_rad=math.radians(argp_deg),
            true_anomaly_rad=math.radians(nu_deg),
        )

    @property
    def semi_latus_rectum_m(self) -> float:
        """p = a (1 - e^2), m."""
        return self.semi_major_axis_m * (1.0 - self.eccentricity**2)


def orbital_period_s(semi_major_axis_m: float, mu_m3_s2: float = MU_EARTH_M3_S2) -> float:
    """Two-body period T = 2 pi sqrt(a^3 / mu), s (Kepler's third law)."""
    if not semi_major_axis_m > 0.0:
        raise SatsightError(f"semi_major_axis_m must be > 0; got {semi_major_axis_m} m")
    return _TWO_PI * math.sqrt(semi_major_axis_m**3 / mu_m3_s2)


def _check_mu(mu_m3_s2: float) -> float:
    mu = float(mu_m3_s2)
    if not (math.isfinite(mu) and mu > 0.0):
        raise SatsightError(f"mu_m3_s2 must be a finite positive number; got {mu_m3_s2}")
    return mu


def _check_vector(value: np.ndarray, name: str) -> np.ndarray:
    vector = np.asarray(value, dtype=np.float64)
    if vector.shape != (3,):
        raise SatsightError(f"{name} must have shape (3,); got {vector.shape}")
    if not np.all(np.isfinite(vector)):
        raise SatsightError(f"{name} must be finite; got {vector}")
    return vector


def state_from_elements(
    elements: OrbitalElements, mu_m3_s2: float = MU_EARTH_M3_S2
) -> tuple[np.ndarray, np.ndarray]:
    """Inertial position r_m (3,) and velocity v_m_s (3,) of the object described by elements.

    The state is built in the perifocal frame (P towards perigee, W along the orbit normal)
    and rotated by R3(-raan) R1(-i) R3(-argp) into the inertial frame (Vallado, 4th ed.,
    Algorithm 10 "COE2RV"; Curtis, 3rd ed., Algorithm 4.5).
    """
    mu = _check_mu(mu_m3_s2)
    e = elements.eccentricity
    p = elements.semi_latus_rectum_m
    nu = elements.true_anomaly_rad
    cos_nu, sin_nu = math.cos(nu), math.sin(nu)
    r_pqw = p / (1.0 + e * cos_nu) * np.array([cos_nu, sin_nu, 0.0])
    v_pqw = math.sqrt(mu / p) * np.array([-sin_nu, e + cos_nu, 0.0])
    R = _inertial_from_perifocal(
        elements.raan_rad, elements.inclination_rad, elements.arg_perigee_rad
    )
    return R @ r_pqw, R @ v_pqw


def _inertial_from_perifocal(
    raan_rad: float, inclination_rad: float, argp_rad: float
) -> np.ndarray:
    """R3(-raan) R1(-i) R3(-argp): columns are P (perigee), Q, W (orbit normal) in inertial."""
    cO, sO = math.cos(raan_rad), math.sin(raan_rad)
    ci, si = math.cos(inclination_rad), math.sin(inclination_rad)
    cw, sw = math.cos(argp_rad), math.sin(argp_rad)
    return np.array(
        [
            [cO * cw - sO * sw * ci, -cO * sw - sO * cw * ci, sO * si],
            [sO * cw + cO * sw * ci, -sO * sw + cO * cw * ci, -cO * si],
            [sw * si, cw * si, ci],
        ]
    )


def _angle_about(axis: np.ndarray, from_vec: np.ndarray, to_vec: np.ndarray) -> float:
    """Angle in [0, 2 pi) rotating from_vec onto to_vec, right-handed about the unit axis."""
    angle = math.atan2(float(axis @ np.cross(from_vec, to_vec)), float(from_vec @ to_vec))
    return angle % _TWO_PI


def elements_from_state(
    r_m: np.ndarray, v_m_s: np.ndarray, mu_m3_s2: float = MU_EARTH_M3_S2
) -> OrbitalElements:
    """Osculating classical elements of the inertial state r_m (3,), v_m_s (3,).

    Follows Vallado, 4th ed., Algorithm 9 "RV2COE", with angles computed by atan2 (about the
    angular-momentum direction) rather than acos, so they keep full precision everywhere.

    Conventions where an angle is undefined:

    * circular (e < 1e-11): perigee is put at the ascending node, so ``arg_perigee_rad = 0``
      and ``true_anomaly_rad`` is the argument of latitude u (node to object);
    * equatorial (sin i < 1e-11, prograde or retrograde): the node is put on the x axis, so
      ``raan_rad = 0`` and ``arg_perigee_rad`` is the true longitude of perigee (x axis to
      perigee, measured in the direction of motion);
    * circular and equatorial: ``raan_rad = arg_perigee_rad = 0`` and ``true_anomaly_rad``
      is the true longitude (x axis to object, in the direction of motion).

    With these conventions `state_from_elements` reproduces the input state. Angles are
    returned in [0, 2 pi). Raises SatsightError for open (e >= 1) or degenerate
    (rectilinear, zero-radius) states.
    """
    mu = _check_mu(mu_m3_s2)
    r = _check_vector(r_m, "r_m")
    v = _check_vector(v_m_s, "v_m_s")
    r_norm = float(np.linalg.norm(r))
    if r_norm == 0.0:
        raise SatsightError("r_m is the zero vector: the object would be at the Earth's centre")
    h = np.cross(r, v)
    h_norm = float(np.linalg.norm(h))
    if h_norm <= 1e-12 * r_norm * float(np.linalg.norm(v)) or h_norm == 0.0:
        raise SatsightError(
            "r_m and v_m_s are parallel (zero angular momentum): a rectilinear trajectory has "
            "no orbital plane; give a velocity with a component across r"
        )
    h_hat = h / h_norm
    v_sq = float(v @ v)
    energy = 0.5 * v_sq - mu / r_norm
    e_vec = ((v_sq - mu / r_norm) * r - float(r @ v) * v) / mu
    e = float(np.linalg.norm(e_vec))
    if energy >= 0.0 or e >= 1.0:
        raise SatsightError(
            "only elliptical orbits (specific energy < 0, e < 1) are supported; got specific "
            f"energy {energy:.6g} J/kg and e = {e:.6g} (the object escapes the Earth)"
        )
    a = -mu / (2.0 * energy)
    inclination = math.atan2(math.hypot(h[0], h[1]), h[2])

    node = np.array([-h[1], h[0], 0.0])  # z x h, towards the ascending node
    node_norm = float(np.linalg.norm(node))
    if node_norm < _EQUATORIAL_TOLERANCE * h_norm:
        node_hat = np.array([1.0, 0.0, 0.0])
        raan = 0.0
    else:
        node_hat = node / node_norm
        raan = math.atan2(node[1], node[0]) % _TWO_PI

    if e < _CIRCULAR_TOLERANCE:
        perigee_hat = node_hat
        arg_perigee = 0.0
    else:
        perigee_hat = e_vec / e
        arg_perigee = _angle_about(h_hat, node_hat, perigee_hat)
    true_anomaly = _angle_about(h_hat, perigee_hat, r)
    return OrbitalElements(
        semi_major_axis_m=a,
        eccentricity=e,
        inclination_rad=inclination,
        raan_rad=raan,
        arg_perigee_rad=arg_perigee,
        true_anomaly_rad=true_anomaly,
    )


def gravity_acceleration_m_s2(
    r_m: np.ndarray, *, j2: bool = True, mu_m3_s2: float = MU_EARTH_M3_S2
) -> np.ndarray:
    """Gravitational acceleration (..., 3), m s^-2, at inertial positions r_m (..., 3), m.

    Point mass plus (if j2) the J2 oblateness term of the module docstring, with
    R = EARTH_EQUATORIAL_RADIUS_M and the constant J2.
    """
    mu = _check_mu(mu_m3_s2)
    r = np.asarray(r_m, dtype=np.float64)
    if r.shape[-1:] != (3,):
        raise SatsightError(f"r_m must have shape (..., 3); got {r.shape}")
    r_sq = np.sum(r * r, axis=-1, keepdims=True)
    r_norm = np.sqrt(r_sq)
    acceleration = -mu * r / (r_sq * r_norm)
    if j2:
        z_sq_over_r_sq = r[..., 2:3] ** 2 / r_sq
        factor = -1.5 * J2 * mu * EARTH_EQUATORIAL_RADIUS_M**2 / (r_sq * r_sq * r_norm)
        shape = np.concatenate(
            [
                np.broadcast_to(1.0 - 5.0 * z_sq_over_r_sq, r[..., :2].shape),
                3.0 - 5.0 * z_sq_over_r_sq,
            ],
            axis=-1,
        )
        acceleration = acceleration + factor * r * shape
    return acceleration


def _scalar_acceleration(
    mu: float, j2: bool
) -> Callable[[float, float, float], tuple[float, float, float]]:
    """The acceleration of `gravity_acceleration_m_s2` on Python floats, for the RK4 loop.

    Plain float arithmetic is several times faster than numpy on 3-vectors, which is what
    makes a day of 1 s steps take about a second.
    """
    k_j2 = -1.5 * J2 * mu * EARTH_EQUATORIAL_RADIUS_M**2 if j2 else 0.0

    def acceleration(x: float, y: float, z: float) -> tuple[float, float, float]:
        r_sq = x * x + y * y + z * z
        r_norm = math.sqrt(r_sq)
        k = -mu / (r_sq * r_norm)
        if j2:
            f = k_j2 / (r_sq * r_sq * r_norm)
            s = 5.0 * z * z / r_sq
            return (
                k * x + f * x * (1.0 - s),
                k * y + f * y * (1.0 - s),
                k * z + f * z * (3.0 - s),
            )
        return k * x, k * y, k * z

    return acceleration


def _propagate_rk4(
    state: np.ndarray, times_s: np.ndarray, step_s: float, mu: float, j2: bool
) -> np.ndarray:
    accel = _scalar_acceleration(mu, j2)
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
            a1x, a1y, a1z = accel(x, y, z)
            a2x, a2y, a2z = accel(x + half * vx, y + half * vy, z + half * vz)
            v2x, v2y, v2z = vx + half * a1x, vy + half * a1y, vz + half * a1z
            a3x, a3y, a3z = accel(x + half * v2x, y + half * v2y, z + half * v2z)
            v3x, v3y, v3z = vx + half * a2x, vy + half * a2y, vz + half * a2z
            a4x, a4y, a4z = accel(x + h * v3x, y + h * v3y, z + h * v3z)
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


def _propagate_dop853(state: np.ndarray, times_s: np.ndarray, mu: float, j2: bool) -> np.ndarray:
    accel = _scalar_acceleration(mu, j2)

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        ax, ay, az = accel(y[0], y[1], y[2])
        return np.array([y[3], y[4], y[5], ax, ay, az])

    t_end = float(times_s[-1])
    if t_end == 0.0:
        return np.repeat(state[None, :], times_s.size, axis=0)
    atol = np.array([DOP853_ATOL_POSITION_M] * 3 + [DOP853_ATOL_VELOCITY_M_S] * 3)
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


def propagate(
    r0_m: np.ndarray,
    v0_m_s: np.ndarray,
    times_s: np.ndarray,
    *,
    j2: bool = True,
    method: str = "rk4",
    step_s: float = 1.0,
    mu_m3_s2: float = MU_EARTH_M3_S2,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3), m, and velocities (N, 3), m/s, at times_s after the initial epoch.

    r0_m (3,), v0_m_s (3,): inertial state at t = 0. times_s (N,): ascending (repeats
    allowed), >= 0, in s from the initial epoch; 0 returns the initial state. j2: include the
    J2 oblateness acceleration (module docstring), else pure two-body.

    method="rk4": classical fixed-step fourth-order Runge-Kutta at step_s (1 s in the paper);
    before each requested time the last step is shortened so the integration lands on it
    exactly. For a 7000 km LEO at 1 s the truncation error is far below a millimetre per
    orbit. method="dop853": scipy's adaptive 8th-order Dormand-Prince (solve_ivp) with
    rtol = 1e-12 and atol = 1e-6 m on position, 1e-9 m/s on velocity, sampled at times_s;
    step_s is ignored. Raises SatsightError for non-finite input, unsorted or negative
    times, a non-positive step or an unknown method.
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
    state = np.concatenate([r0, v0])
    if method == "rk4":
        out = _propagate_rk4(state, times, step, mu, j2)
    elif method == "dop853":
        out = _propagate_dop853(state, times, mu, j2)
    else:
        raise SatsightError(f"method must be 'rk4' or 'dop853'; got {method!r}")
    return out[:, :3].copy(), out[:, 3:].copy()
