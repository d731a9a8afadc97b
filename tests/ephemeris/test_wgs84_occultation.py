"""Line of sight and the inside-the-Earth test with the WGS-84 ellipsoid.

Oracles share no code with the module: lines built tangent to a level surface of the
geodetic height (a point on a surface normal, moving across it: its lowest height is known
exactly), a nested numerical minimisation of the distance to the meridian ellipse, and
ray-ellipsoid quadratics for whether a segment enters the Earth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from satsight.constants import AU_M, WGS84_SEMI_MAJOR_AXIS_M, WGS84_SEMI_MINOR_AXIS_M
from satsight.ephemeris.occultation import (
    DEFAULT_ATMOSPHERE_MARGIN_M,
    earth_occults,
    inside_earth,
    los_clearance_m,
)
from satsight.ephemeris.visibility import assess_visibility
from satsight.ephemeris.wgs84 import geodetic_height_m
from satsight.errors import SatsightError
from tolerances import ONE_MM

A = WGS84_SEMI_MAJOR_AXIS_M
B = WGS84_SEMI_MINOR_AXIS_M
KM = 1e3
X, Y, Z = np.eye(3)

ROTATION = Rotation.from_euler("zxz", [0.4, -1.1, 2.5]).as_matrix()  # an arbitrary Earth


def gcrs(points_itrs: np.ndarray) -> np.ndarray:
    """ITRS points (..., 3) expressed in GCRS for R_itrs_from_gcrs = ROTATION."""
    return np.asarray(points_itrs) @ ROTATION  # rows: R.T @ p


def surface_point_and_normal(lat_rad: float, lon_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Point of the ellipsoid at geodetic latitude/longitude and its unit normal."""
    e2 = 1.0 - (B / A) ** 2
    n_radius = A / math.sqrt(1.0 - e2 * math.sin(lat_rad) ** 2)
    point = np.array(
        [
            n_radius * math.cos(lat_rad) * math.cos(lon_rad),
            n_radius * math.cos(lat_rad) * math.sin(lon_rad),
            n_radius * (1.0 - e2) * math.sin(lat_rad),
        ]
    )
    normal = np.array(
        [
            math.cos(lat_rad) * math.cos(lon_rad),
            math.cos(lat_rad) * math.sin(lon_rad),
            math.sin(lat_rad),
        ]
    )
    return point, normal


def distance_to_ellipsoid(p: np.ndarray) -> float:
    """Distance from an outside point to the ellipsoid: minimised over the meridian
    ellipse (a cos u, b sin u) near the point's geocentric latitude."""
    rho, z = math.hypot(p[0], p[1]), p[2]
    psi = math.atan2(z, rho)
    result = minimize_scalar(
        lambda u: math.hypot(A * math.cos(u) - rho, B * math.sin(u) - z),
        bounds=(psi - 0.02, psi + 0.02),
        method="bounded",
        options={"xatol": 1e-13},
    )
    return float(result.fun)


def lowest_height_along(a: np.ndarray, b: np.ndarray) -> float:
    result = minimize_scalar(
        lambda t: distance_to_ellipsoid(a + t * (b - a)),
        bounds=(0.0, 1.0),
        method="bounded",
        options={"xatol": 1e-10},
    )
    ends = min(distance_to_ellipsoid(a), distance_to_ellipsoid(b))
    return min(float(result.fun), ends)


def test_polar_line_clears_the_ellipsoid_but_not_the_sphere() -> None:
    # A horizontal line 110 km above the north pole: the sphere of radius a stands 21.4 km
    # higher there, so it puts the line at 88.6 km, below the 100 km margin.
    h = 110.0 * KM
    over_pole = (np.array([-1500.0 * KM, 0.0, B + h]), np.array([1500.0 * KM, 0.0, B + h]))
    over_equator = (np.array([A + h, -1500.0 * KM, 0.0]), np.array([A + h, 1500.0 * KM, 0.0]))
    for a, b in (over_pole, over_equator):
        got = los_clearance_m(gcrs(a), gcrs(b), R_itrs_from_gcrs=ROTATION)
        assert got == pytest.approx(h, abs=ONE_MM)
        assert not earth_occults(gcrs(a), gcrs(b), R_itrs_from_gcrs=ROTATION)
    assert los_clearance_m(*over_pole) == pytest.approx(B + h - A, abs=ONE_MM)
    assert earth_occults(*over_pole)
    assert los_clearance_m(*over_equator) == pytest.approx(h, abs=ONE_MM)
    assert not earth_occults(*over_equator)
    assert DEFAULT_ATMOSPHERE_MARGIN_M == 100.0 * KM


@pytest.mark.parametrize("height_m", [0.5 * KM, 100.0 * KM, 2000.0 * KM, 30000.0 * KM])
def test_lines_across_a_surface_normal_have_its_height_as_clearance(height_m: float) -> None:
    # The geodetic height is convex along a line and its gradient at q + h n is n, so a
    # line through q + h n perpendicular to n has its lowest point there, at height h.
    rng = np.random.default_rng(7)
    starts, ends = [], []
    for _ in range(12):
        lat, lon = rng.uniform(-math.pi / 2, math.pi / 2), rng.uniform(-math.pi, math.pi)
        q, n = surface_point_and_normal(lat, lon)
        across = np.cross(n, rng.normal(size=3))
        across /= np.linalg.norm(across)
        before, after = rng.uniform(0.1, 3.0, size=2) * 1000.0 * KM
        starts.append(q + height_m * n - before * across)
        ends.append(q + height_m * n + after * across)
    got = los_clearance_m(gcrs(starts), gcrs(ends), R_itrs_from_gcrs=ROTATION)
    np.testing.assert_allclose(got, height_m, rtol=0.0, atol=ONE_MM)


def test_clearance_matches_a_nested_numerical_minimisation() -> None:
    rng = np.random.default_rng(11)
    directions = rng.normal(size=(2, 24, 3))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    radii = rng.uniform(6600.0, 9000.0, size=(2, 24, 1)) * KM
    a, b = directions * radii
    got = los_clearance_m(gcrs(a), gcrs(b), R_itrs_from_gcrs=ROTATION)
    # Whether each segment enters the ellipsoid, from its own quadratic.
    scale = np.array([1.0 / A, 1.0 / A, 1.0 / B])
    p, d = a * scale, (b - a) * scale
    qa, qb, qc = np.sum(d * d, 1), 2.0 * np.sum(p * d, 1), np.sum(p * p, 1) - 1.0
    disc = qb * qb - 4.0 * qa * qc
    root = np.sqrt(np.maximum(disc, 0.0))
    t1, t2 = (-qb - root) / (2 * qa), (-qb + root) / (2 * qa)
    enters = (disc > 0.0) & (t2 > 0.0) & (t1 < 1.0)
    assert 3 < np.count_nonzero(enters) < 21  # both kinds present
    np.testing.assert_array_equal(got < 0.0, enters)
    for k in np.flatnonzero(~enters):
        assert got[k] == pytest.approx(lowest_height_along(a[k], b[k]), abs=ONE_MM)
    # Inside: b (rho - 1), within a factor a / b of the true depth (> 0 and < b).
    assert np.all(got[enters] > -B)


def test_segment_through_the_centre_and_the_geodetic_height() -> None:
    a, b = np.array([0.0, 0.0, 7000.0 * KM]), np.array([0.0, 0.0, -7000.0 * KM])
    got = los_clearance_m(gcrs(a), gcrs(b), R_itrs_from_gcrs=ROTATION)
    assert got == pytest.approx(-B, abs=ONE_MM)
    # geodetic_height_m against the numerical distance at a few outside points.
    points = np.array([[0.0, 0.0, B + 10.0 * KM], [A + 5.0, 0.0, 0.0], [4e6, 3e6, 5e6]])
    heights, normals = geodetic_height_m(points)
    for point, height in zip(points, heights, strict=True):
        assert height == pytest.approx(distance_to_ellipsoid(point), abs=ONE_MM)
    np.testing.assert_allclose(normals[0], Z, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-15)


def test_inside_the_earth_near_the_pole() -> None:
    above_pole = np.array([0.0, 0.0, B + 10.0 * KM])  # 10 km up, but 11.4 km inside a
    below_equator = np.array([A - 10.0 * KM, 0.0, 0.0])
    points = np.stack([above_pole, -above_pole, below_equator, 7000.0 * KM * Y])
    np.testing.assert_array_equal(
        inside_earth(gcrs(points), R_itrs_from_gcrs=ROTATION), [False, False, True, False]
    )
    np.testing.assert_array_equal(inside_earth(points), [True, True, True, False])
    assert inside_earth(gcrs(above_pole), ROTATION) is False
    # One rotation per row.
    stack = np.stack([ROTATION, np.eye(3)])
    np.testing.assert_array_equal(
        inside_earth(np.stack([gcrs(above_pole), below_equator]), stack), [False, True]
    )


def test_assess_visibility_uses_the_ellipsoid() -> None:
    h = 110.0 * KM
    observer = gcrs(np.array([-1500.0 * KM, 0.0, B + h]))
    target = gcrs(np.array([1500.0 * KM, 0.0, B + h]))
    sun = gcrs(AU_M * X)
    with_shape = assess_visibility(target, observer, sun, R_itrs_from_gcrs=ROTATION)
    sphere = assess_visibility(target, observer, sun)
    assert with_shape.los_clearance_m[0] == pytest.approx(h, abs=ONE_MM)
    assert not with_shape.earth_occulted[0]
    assert sphere.earth_occulted[0]


def test_radius_with_the_ellipsoid_is_refused() -> None:
    with pytest.raises(SatsightError, match="body_radius_m"):
        los_clearance_m(7e6 * X, 7e6 * Y, body_radius_m=6.4e6, R_itrs_from_gcrs=np.eye(3))
    with pytest.raises(SatsightError, match="rows"):
        los_clearance_m(
            np.stack([7e6 * X] * 2), 7e6 * Y, R_itrs_from_gcrs=np.stack([np.eye(3)] * 3)
        )
