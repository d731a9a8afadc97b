"""The WGS-84 reference ellipsoid: its axes, and geometry in the Earth-fixed frame (ITRS).

The ellipsoid is (x^2 + y^2) / a^2 + z^2 / b^2 = 1 in the ITRS (x towards the Greenwich
meridian on the equator, z towards the north pole), lengths in m, with a = 6 378 137 m and
1/f = 298.257223563, so b = a (1 - f) = 6 356 752.314 m, 21.4 km less than a (NIMA
TR8350.2, 3rd ed., 2000, Table 3.1). The ITRS realisation and the WGS-84 frame agree to a
few centimetres, far below anything this package resolves.

Positions here are ITRS vectors, (N, 3) float64 in m; turn GCRS ones into ITRS with the
Earth's orientation (``x_itrs = R_itrs_from_gcrs @ x_gcrs``, e.g. skyfield's
``skyfield.framelib.itrs.rotation_at(t)``).
"""

from __future__ import annotations

import numpy as np

from satsight.constants import (
    WGS84_SEMI_MAJOR_AXIS_M,
    WGS84_SEMI_MINOR_AXIS_M,
)

_A = WGS84_SEMI_MAJOR_AXIS_M
_B = WGS84_SEMI_MINOR_AXIS_M
# First and second eccentricity squared, and a^2 - b^2.
_E2 = 1.0 - (_B / _A) ** 2
_EP2 = (_A / _B) ** 2 - 1.0
_A2_MINUS_B2 = (_A - _B) * (_A + _B)

#: The map x_unit = x_itrs * UNIT_SPHERE_SCALE takes the ellipsoid onto the unit sphere. It
#: is linear, so it keeps lines straight, keeps which side of the surface a point lies on
#: and maps a ray that meets the ellipsoid onto one that meets the sphere.
UNIT_SPHERE_SCALE = np.array([1.0 / _A, 1.0 / _A, 1.0 / _B])


def ellipsoid_level(position_itrs_m: np.ndarray) -> np.ndarray:
    """(x^2 + y^2) / a^2 + z^2 / b^2 of each row of (N, 3): < 1 inside, 1 on the surface."""
    unit = position_itrs_m * UNIT_SPHERE_SCALE
    return np.sum(unit * unit, axis=-1)


def geodetic_height_m(position_itrs_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic height, m (N,), and the ellipsoid's outward unit normal there (N, 3).

    position_itrs_m: (N, 3), ITRS, m. The geodetic height is the signed distance from the
    point to the ellipsoid along the surface normal through it (positive outside); outside
    the ellipsoid it is the distance to the nearest surface point. The normal (N, 3) is the
    ellipsoid's unit normal at that foot point: the direction of geodetic latitude phi and
    longitude lambda, (cos phi cos lambda, cos phi sin lambda, sin phi).

    Closed form of Heikkinen (1982), "Geschlossene Formeln zur Berechnung räumlicher
    geodätischer Koordinaten aus rechtwinkligen Koordinaten", Z. Vermess. 107, 207-211 (the
    exact solution of the quartic for the foot point; no iteration). Valid everywhere
    except within about 43 km of the Earth's centre, where the nearest surface point stops
    being unique; accurate to well below a millimetre for points outside and near the
    surface (tested against a numerical minimisation).
    """
    p = np.asarray(position_itrs_m, dtype=np.float64)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    r = np.hypot(x, y)
    z2 = z * z
    f_ = 54.0 * _B * _B * z2
    g = r * r + (1.0 - _E2) * z2 - _E2 * _A2_MINUS_B2
    c = _E2 * _E2 * f_ * r * r / (g * g * g)
    s = np.cbrt(1.0 + c + np.sqrt(c * c + 2.0 * c))
    k = s + 1.0 / s + 1.0
    big_p = f_ / (3.0 * k * k * g * g)
    q = np.sqrt(1.0 + 2.0 * _E2 * _E2 * big_p)
    radicand = (
        0.5 * _A * _A * (1.0 + 1.0 / q)
        - big_p * (1.0 - _E2) * z2 / (q * (1.0 + q))
        - 0.5 * big_p * r * r
    )
    r0 = -(big_p * _E2 * r) / (1.0 + q) + np.sqrt(np.maximum(radicand, 0.0))
    du = r - _E2 * r0
    u = np.sqrt(du * du + z2)
    v = np.sqrt(du * du + (1.0 - _E2) * z2)
    z0 = _B * _B * z / (_A * v)
    height = u * (1.0 - _B * _B / (_A * v))
    # tan(phi) = (z + e'^2 z0) / r, so the normal is parallel to (x, y, z + e'^2 z0).
    normal = np.stack([x, y, z + _EP2 * z0], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return height, normal
