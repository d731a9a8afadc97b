"""Classical orbital elements and inertial state vectors, and conversions between them.

Frame: positions and velocities are in GCRS (the Earth-centred inertial frame of
:mod:`satsight.ephemeris.orbits`); the inclination and the node are measured from the GCRS
z axis and x axis, not from the true equator of date (the two differ by precession and
nutation, 0.14 deg at 2025). Positions in m, velocities in m/s, angles in rad; float64.

Only closed (elliptical, ``0 <= e < 1``) orbits are supported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError

# Earth's gravitational parameter GM, m^3 s^-2, including the mass of the atmosphere:
# IERS Conventions (2010), Technical Note 36, Table 1.1; the EGM96 / WGS-84 (G1150) value,
# as tabulated in Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed.,
# Appendix D (Table D-1).
MU_EARTH_M3_S2 = 3.986004418e14

# Below these, an orbit is treated as circular (|e|) or equatorial (|h_xy| / |h|), and the
# angles that are undefined there follow the conventions of `elements_from_state`.
_CIRCULAR_TOLERANCE = 1e-11
_EQUATORIAL_TOLERANCE = 1e-11

_TWO_PI = 2.0 * math.pi


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
