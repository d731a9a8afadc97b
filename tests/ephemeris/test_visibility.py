"""Line of sight, Earth shadow and viewing angles, against closed forms and constructions.

Oracles used here share no code with the module: distances from explicit geometry, lens
areas from a 1-D numerical integral of chord lengths, the exact occulted solid angle on the
sphere from a numerical integral, asymptotic lens areas near tangency, shadow entry and exit
times from root finding on a propagated orbit, and a triangle's angle sum.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from satsight.constants import AU_M, EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.occultation import (
    DEFAULT_ATMOSPHERE_MARGIN_M,
    earth_occults,
    los_clearance_m,
)
from satsight.ephemeris.orbits import (
    MU_EARTH_M3_S2,
    OrbitalElements,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.ephemeris.shadow import (
    SUN_RADIUS_M,
    beta_angle_rad,
    cylindrical_eclipse_duration_s,
    in_cylindrical_shadow,
    sunlit_fraction,
)
from satsight.ephemeris.sun_moon import sun_position_gcrs_m
from satsight.ephemeris.time import epoch_times
from satsight.ephemeris.visibility import (
    FrameVisibility,
    VisibilityLimits,
    assess_visibility,
    phase_angle_rad,
    sun_boresight_angle_rad,
)
from satsight.errors import SatsightError
from tolerances import ONE_MS, ONE_UM

R_EARTH = EARTH_EQUATORIAL_RADIUS_M
KM = 1e3
ORBIT_RADIUS_M = 7000.0 * KM
X, Y, Z = np.eye(3)

# Tolerances, named in their units.
TWENTY_MICROSECONDS = 2e-5  # s
ANGLE_ROUNDING_RAD = 1e-14  # rad: float64 rounding of an atan2 of O(1) inputs
# rad: direction of a 10 km offset added to a 7000 km position, whose rounding (~1e-9 m)
# turns the offset by up to ~1e-13 rad.
OFFSET_ANGLE_ROUNDING_RAD = 1e-12
FRACTION_ROUNDING = 1e-12  # of the solar disc: rounding in a lens area


def rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues' formula)."""
    k = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle_rad) * cross + (1.0 - math.cos(angle_rad)) * cross @ cross


# An arbitrary orientation, so that no test relies on coordinate axes.
TILT = rotation(np.array([0.3, -0.5, 0.8]), 1.234)


# --- line of sight ---------------------------------------------------------------------


@pytest.mark.parametrize("altitude_m", [0.0, 400.0 * KM, 35_786.0 * KM, -2000.0 * KM])
def test_tangent_segment_clearance_is_the_tangent_altitude(altitude_m: float) -> None:
    # A segment perpendicular to the radius R + h at its foot, reaching past it on both
    # sides by unequal lengths: its closest point is the foot, at altitude h.
    foot = (R_EARTH + altitude_m) * Y
    a = TILT @ (foot - 3000.0 * KM * X)
    b = TILT @ (foot + 1234.5 * KM * X)
    assert los_clearance_m(a, b) == pytest.approx(altitude_m, abs=ONE_UM)
    assert los_clearance_m(b, a) == pytest.approx(altitude_m, abs=ONE_UM)


def test_chord_between_two_satellites_on_one_orbit() -> None:
    # Two points 10 deg either side of x on a 7000 km circle: the chord's midpoint is the
    # closest point, at r cos(10 deg) from the centre.
    r = ORBIT_RADIUS_M
    angle = math.radians(10.0)
    a = TILT @ (r * np.array([math.cos(angle), math.sin(angle), 0.0]))
    b = TILT @ (r * np.array([math.cos(angle), -math.sin(angle), 0.0]))
    expected = r * math.cos(angle) - R_EARTH
    assert los_clearance_m(a, b) == pytest.approx(expected, abs=ONE_UM)


def test_clearance_at_an_end_point_when_the_segment_points_away() -> None:
    # From a point at altitude h the segment heads outwards (a . d > 0): the nearest point
    # of the segment is a itself, although the infinite line passes lower.
    h = 500.0 * KM
    a = TILT @ ((R_EARTH + h) * X)
    b = TILT @ ((R_EARTH + h + 1000.0 * KM) * X + 500.0 * KM * Y)
    assert los_clearance_m(a, b) == pytest.approx(h, abs=ONE_UM)
    assert los_clearance_m(b, a) == pytest.approx(h, abs=ONE_UM)
    assert los_clearance_m(a, a) == pytest.approx(h, abs=ONE_UM)


def test_segment_through_the_centre_has_clearance_minus_radius() -> None:
    a = TILT @ (-2.0 * R_EARTH * X)
    b = TILT @ (3.0 * R_EARTH * X)
    assert los_clearance_m(a, b) == pytest.approx(-R_EARTH, abs=ONE_UM)


def test_clearance_matches_dense_sampling_of_random_segments() -> None:
    rng = np.random.default_rng(20240611)
    a = rng.uniform(-2.0, 2.0, (40, 3)) * R_EARTH
    b = rng.uniform(-2.0, 2.0, (40, 3)) * R_EARTH
    clearance = los_clearance_m(a, b, body_radius_m=R_EARTH)
    assert clearance.shape == (40,)
    t = np.linspace(0.0, 1.0, 20_001)
    points = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    sampled = np.linalg.norm(points, axis=-1).min(axis=1) - R_EARTH
    # The sampled minimum is never below the true one, and above it by at most what half a
    # sample spacing along the segment can add: sqrt(d^2 + (s/2)^2) - d <= s/2 and
    # <= (s/2)^2 / (2 d), with d the true closest distance.
    half_spacing = 0.5 * np.linalg.norm(b - a, axis=1) / (t.size - 1)
    closest = clearance + R_EARTH
    excess_bound = np.minimum(half_spacing, half_spacing**2 / (2.0 * closest))
    assert np.all(sampled - clearance >= -ONE_UM)
    assert np.all(sampled - clearance <= excess_bound + ONE_UM)


def test_clearance_shapes_broadcast_and_scalars() -> None:
    a = ORBIT_RADIUS_M * X
    b = np.array([-ORBIT_RADIUS_M * X, ORBIT_RADIUS_M * X + 10.0 * KM * Y])
    clearance = los_clearance_m(a, b)
    assert isinstance(clearance, np.ndarray)
    assert clearance.shape == (2,)
    np.testing.assert_allclose(clearance, [-R_EARTH, ORBIT_RADIUS_M - R_EARTH], atol=1e-6)
    assert isinstance(los_clearance_m(a, b[1]), float)


def test_earth_occults_opposite_sides_but_not_neighbours() -> None:
    r = ORBIT_RADIUS_M
    assert earth_occults(TILT @ (r * X), TILT @ (-r * X))
    assert not earth_occults(TILT @ (r * X), TILT @ (r * X + 10.0 * KM * Y))
    flags = earth_occults(TILT @ (r * X), np.array([TILT @ (-r * X), TILT @ (r * Y)]))
    # 90 deg apart on a 7000 km circle: the chord passes at r cos 45 deg = 4950 km from the
    # centre, through the Earth.
    np.testing.assert_array_equal(flags, [True, True])
    assert flags.dtype == bool


@pytest.mark.parametrize(("offset_m", "blocked"), [(+1.0, False), (-1.0, True)])
def test_grazing_line_of_sight_against_the_margin(offset_m: float, blocked: bool) -> None:
    # A line tangent to the sphere at 1 m above or below the default margin (100 km).
    foot = (R_EARTH + DEFAULT_ATMOSPHERE_MARGIN_M + offset_m) * Y
    observer = TILT @ (foot - 2500.0 * KM * X)
    target = TILT @ (foot + 2500.0 * KM * X)
    assert earth_occults(observer, target) is blocked
    assert earth_occults(observer, target, margin_m=0.0) is False


@pytest.mark.parametrize(
    ("a", "b", "match"),
    [
        (np.zeros(2), np.zeros(3), r"shape \(3,\) or a stack \(N, 3\)"),
        (np.zeros((4, 3)), np.zeros((5, 3)), "4 rows but b_m has 5"),
        (np.array([np.nan, 0.0, 0.0]), np.zeros(3), "finite"),
        (np.zeros((2, 3, 3)), np.zeros(3), "shape"),
    ],
)
def test_bad_vectors_are_rejected(a: np.ndarray, b: np.ndarray, match: str) -> None:
    with pytest.raises(SatsightError, match=match):
        los_clearance_m(a, b)


def test_negative_margin_and_radius_are_rejected() -> None:
    with pytest.raises(SatsightError, match="margin_m"):
        earth_occults(X * 7e6, Y * 7e6, margin_m=-1.0)
    with pytest.raises(SatsightError, match="body_radius_m"):
        los_clearance_m(X * 7e6, Y * 7e6, body_radius_m=0.0)


# --- cylindrical shadow ----------------------------------------------------------------

SUN_AT_1_AU = AU_M * X


def test_cylindrical_shadow_membership() -> None:
    sun = TILT @ SUN_AT_1_AU
    behind = -ORBIT_RADIUS_M * X
    points = np.array(
        [
            behind,  # on the axis behind the Earth
            behind + (R_EARTH - 1.0) * Y,  # 1 m inside the cylinder
            behind + (R_EARTH + 1.0) * Z,  # 1 m outside
            -behind,  # on the day side, on the axis
            -behind + 0.5 * R_EARTH * Y,  # day side, within R of the axis
        ]
    )
    inside = in_cylindrical_shadow(points @ TILT.T, sun)
    np.testing.assert_array_equal(inside, [True, True, False, False, False])
    assert in_cylindrical_shadow(TILT @ behind, sun) is True


# --- sunlit fraction: constructed geometry ---------------------------------------------


def geometry_with_disc_angles(a_rad: float, b_rad: float, c_rad: float) -> tuple:
    """Target and Sun positions (m) seen from which the Sun's disc has apparent radius a,
    the Earth's b, and their centres are c apart (all rad)."""
    earth_distance = R_EARTH / math.sin(b_rad)
    sun_distance = SUN_RADIUS_M / math.sin(a_rad)
    target = earth_distance * X
    # The direction to the Sun, c from the direction to the Earth's centre (-x).
    to_sun = np.array([-math.cos(c_rad), math.sin(c_rad), 0.0])
    sun = target + sun_distance * to_sun
    return TILT @ target, TILT @ sun


def flat_lens_area(a: float, b: float, c: float) -> float:
    """Area common to discs of radii a (centre 0) and b (centre c on the x axis), from the
    integral over x of the length of the vertical chord inside both discs."""

    def both(x: float) -> float:
        half_a = math.sqrt(max((a - x) * (a + x), 0.0))
        half_b = math.sqrt(max((b - c + x) * (b + c - x), 0.0))
        return 2.0 * min(half_a, half_b)

    lo, hi = max(-a, c - b), min(a, c + b)
    if hi <= lo:
        return 0.0
    # The integrand has a kink where the two half-chords are equal (the circles cross).
    kink = (c * c + a * a - b * b) / (2.0 * c)
    points = [kink] if lo < kink < hi else None
    value, _ = quad(both, lo, hi, points=points, limit=400, epsabs=1e-15 * a * a, epsrel=1e-13)
    return value


def spherical_covered_fraction(a: float, b: float, c: float) -> float:
    """Solid angle of the solar disc (a cap of radius a) inside the Earth's (a cap of radius
    b whose centre is c away), over the solar disc's solid angle: the exact occulted
    fraction on the sky. A direction at polar angle rho, azimuth phi about the Sun's centre is
    at angle gamma from the Earth's centre with cos gamma = cos rho cos c + sin rho sin c cos
    phi (spherical law of cosines); a ray hits the Earth when gamma < b."""

    def covered_azimuth(rho: float) -> float:
        if rho == 0.0:
            return 2.0 * math.pi if c < b else 0.0
        cos_phi = (math.cos(b) - math.cos(rho) * math.cos(c)) / (math.sin(rho) * math.sin(c))
        return 2.0 * math.acos(min(1.0, max(-1.0, cos_phi))) * math.sin(rho)

    value, _ = quad(covered_azimuth, 0.0, a, limit=400, epsabs=1e-16, epsrel=1e-12)
    return value / (2.0 * math.pi * (1.0 - math.cos(a)))


SUN_DISC_RAD = math.asin(SUN_RADIUS_M / AU_M)  # apparent solar radius at 1 AU, 4.65 mrad
EARTH_DISC_LEO_RAD = math.asin(R_EARTH / ORBIT_RADIUS_M)  # seen from 7000 km, 65.7 deg


def test_full_sun_and_umbra_are_exact() -> None:
    sun = TILT @ SUN_AT_1_AU
    assert sunlit_fraction(TILT @ (ORBIT_RADIUS_M * X), sun) == 1.0
    assert sunlit_fraction(TILT @ (ORBIT_RADIUS_M * Y), sun) == 1.0  # terminator, outside
    assert sunlit_fraction(TILT @ (-ORBIT_RADIUS_M * X), sun) == 0.0
    assert isinstance(sunlit_fraction(TILT @ (-ORBIT_RADIUS_M * X), sun), float)


@pytest.mark.parametrize(
    ("a", "b", "c"),
    [
        (SUN_DISC_RAD, EARTH_DISC_LEO_RAD, EARTH_DISC_LEO_RAD),  # Sun's centre on the limb
        (SUN_DISC_RAD, EARTH_DISC_LEO_RAD, EARTH_DISC_LEO_RAD + 0.9 * SUN_DISC_RAD),
        (SUN_DISC_RAD, EARTH_DISC_LEO_RAD, EARTH_DISC_LEO_RAD - 0.9 * SUN_DISC_RAD),
        (SUN_DISC_RAD, 0.15, 0.15 + 0.3 * SUN_DISC_RAD),  # seen from geostationary distance
        (SUN_DISC_RAD, SUN_DISC_RAD, 0.7 * SUN_DISC_RAD),  # equal discs (umbra's tip)
        (SUN_DISC_RAD, 0.6 * SUN_DISC_RAD, 0.8 * SUN_DISC_RAD),  # smaller Earth, partly in
    ],
)
def test_sunlit_fraction_is_one_minus_the_flat_lens_ratio(a: float, b: float, c: float) -> None:
    target, sun = geometry_with_disc_angles(a, b, c)
    expected = 1.0 - flat_lens_area(a, b, c) / (math.pi * a * a)
    assert 0.0 < expected < 1.0
    # The construction reproduces a, b, c to rounding (1e-15 rad on c ~ 1 rad, i.e. 2e-13
    # of the solar disc's radius) and the quadrature asks for 1e-13 of the disc's area.
    # Measured: 4e-15.
    assert sunlit_fraction(target, sun) == pytest.approx(expected, abs=FRACTION_ROUNDING)


def test_antumbra_fraction_is_one_minus_the_disc_area_ratio() -> None:
    # Far behind the Earth, beyond the umbra's tip (~1.38e9 m), on the axis: the Earth's disc
    # lies inside the Sun's, centred (c = 0), so the fraction is 1 - (b/a)^2.
    distance = 3.0e9
    target = TILT @ (-distance * X)
    sun = TILT @ SUN_AT_1_AU
    a = math.asin(SUN_RADIUS_M / (AU_M + distance))
    b = math.asin(R_EARTH / distance)
    assert b < a
    assert sunlit_fraction(target, sun) == pytest.approx(1.0 - (b / a) ** 2, abs=1e-14)


def thin_lens_fraction(a: float, b: float, depth: float, inner: bool) -> float:
    """Leading-order area, over pi a^2, of the thin lens common to discs of radii a and b
    overlapping by a depth h (inner=False), or of the sliver of disc a sticking out of a
    larger disc b by h (inner=True): (4 sqrt 2 / 3) h^(3/2) sqrt(a b / (b +- a)). A circular
    segment of sagitta s has half-chord k = sqrt(2 rho s) and area (4/3) k s to leading order;
    the two sagittas (same chord) add up to h, or differ by h for the sliver."""
    reduced = a * b / (b - a if inner else b + a)
    return 4.0 * math.sqrt(2.0) / 3.0 * depth**1.5 * math.sqrt(reduced) / (math.pi * a * a)


@pytest.mark.parametrize("depth_rad", [1e-6, 1e-8, 1e-10])
def test_near_contact_the_fraction_follows_the_thin_lens_law(depth_rad: float) -> None:
    # First contact: the Earth's disc dips h into the Sun's; umbra edge: the Sun's disc
    # sticks h out of the Earth's. The leading-order law has a relative error of order
    # h / a (<= 2e-4 here); a lens formula with arccos of arguments near 1 would lose the
    # 1e-9 to 1e-15 deficits entirely in rounding (errors of ~1e-5 of the disc).
    a, b = SUN_DISC_RAD, EARTH_DISC_LEO_RAD
    relative = 2.0 * depth_rad / a + 1e-6
    target, sun = geometry_with_disc_angles(a, b, a + b - depth_rad)
    deficit = 1.0 - sunlit_fraction(target, sun)
    assert deficit == pytest.approx(thin_lens_fraction(a, b, depth_rad, False), rel=relative)
    target, sun = geometry_with_disc_angles(a, b, b - a + depth_rad)
    lit = sunlit_fraction(target, sun)
    assert lit == pytest.approx(thin_lens_fraction(a, b, depth_rad, True), rel=relative)


def test_flat_disc_error_stays_within_the_limb_curvature_bound() -> None:
    # Exact occulted fraction on the sphere vs the flat-disc model across the penumbra. The
    # flat model places the Earth's limb correctly on the line of centres but gives it the
    # curvature 1/b of a plane circle instead of cot b (a small circle of radius b on the
    # sphere): the covered area differs by at most (1/b - cot b) a^3 / 3, i.e. a fraction
    # (1/b - cot b) a / (3 pi) of the disc, reached when the limb crosses the Sun's centre.
    for b in (EARTH_DISC_LEO_RAD, math.asin(R_EARTH / 42_164e3)):
        a = SUN_DISC_RAD
        bound = (1.0 / b - 1.0 / math.tan(b)) * a / (3.0 * math.pi)
        worst = 0.0
        for c in np.linspace(b - a, b + a, 17)[1:-1]:
            target, sun = geometry_with_disc_angles(a, b, float(c))
            exact = 1.0 - spherical_covered_fraction(a, b, float(c))
            worst = max(worst, abs(sunlit_fraction(target, sun) - exact))
        assert worst <= 1.001 * bound
        assert worst >= 0.9 * bound  # the bound is the actual size of the approximation


def test_fraction_falls_monotonically_across_the_shadow_edge() -> None:
    # Points 7000 km behind the Earth's centre (along -sun), moving in towards the axis.
    sun = TILT @ SUN_AT_1_AU
    offsets = np.linspace(R_EARTH + 60.0 * KM, R_EARTH - 60.0 * KM, 2001)
    points = (-ORBIT_RADIUS_M * X + offsets[:, None] * Y) @ TILT.T
    fraction = sunlit_fraction(points, sun)
    assert fraction[0] == 1.0
    assert fraction[-1] == 0.0
    assert np.all(np.diff(fraction) <= 0.0)
    penumbra = (fraction > 0.0) & (fraction < 1.0)
    assert np.all(np.diff(fraction[penumbra]) < 0.0)


def test_sunlit_fraction_rejects_points_inside_the_earth() -> None:
    with pytest.raises(SatsightError, match="outside the Earth"):
        sunlit_fraction(0.5 * R_EARTH * X, SUN_AT_1_AU)
    with pytest.raises(SatsightError, match="outside the Sun"):
        sunlit_fraction(ORBIT_RADIUS_M * X, ORBIT_RADIUS_M * X + 0.5 * SUN_RADIUS_M * Y)


# --- angles ----------------------------------------------------------------------------


def test_beta_angle_of_constructed_orbits() -> None:
    el = OrbitalElements.from_km_deg(7000.0, 0.0, 51.6, 30.0, 0.0, 40.0)
    r, v = state_from_elements(el)
    normal = np.cross(r, v) / np.linalg.norm(np.cross(r, v))
    in_plane = r / np.linalg.norm(r)
    assert beta_angle_rad(r, v, AU_M * in_plane) == pytest.approx(0.0, abs=ANGLE_ROUNDING_RAD)
    assert beta_angle_rad(r, v, AU_M * normal) == pytest.approx(math.pi / 2, abs=1e-8)
    assert beta_angle_rad(r, v, -AU_M * normal) == pytest.approx(-math.pi / 2, abs=1e-8)
    betas = np.radians([-70.0, -20.0, 0.0, 35.0, 89.0])
    suns = AU_M * (np.cos(betas)[:, None] * in_plane + np.sin(betas)[:, None] * normal)
    np.testing.assert_allclose(beta_angle_rad(r, v, suns), betas, atol=ANGLE_ROUNDING_RAD)
    with pytest.raises(SatsightError, match="no orbit plane"):
        beta_angle_rad(r, 2.0 * r, AU_M * X)


def test_phase_and_sun_boresight_angles_on_constructed_geometry() -> None:
    target = TILT @ (ORBIT_RADIUS_M * X)
    sun = target + TILT @ (AU_M * X)
    towards_sun = target + TILT @ (10.0 * KM * X)
    beside = target + TILT @ (10.0 * KM * Y)
    behind = target - TILT @ (10.0 * KM * X)
    phase = phase_angle_rad(target, np.array([towards_sun, beside, behind]), sun)
    np.testing.assert_allclose(phase, [0.0, math.pi / 2, math.pi], atol=OFFSET_ANGLE_ROUNDING_RAD)
    boresight = sun_boresight_angle_rad(np.array([towards_sun, beside, behind]), target, sun)
    # The observer between target and Sun looks away from the Sun (pi); beside, the Sun is
    # 10 km / 1 AU off the perpendicular; behind, the Sun is straight ahead (0).
    expected_beside = math.pi / 2 + math.atan2(10.0 * KM, AU_M)
    np.testing.assert_allclose(
        boresight, [math.pi, expected_beside, 0.0], atol=OFFSET_ANGLE_ROUNDING_RAD
    )
    assert isinstance(phase_angle_rad(target, beside, sun), float)


def test_phase_boresight_and_sun_angle_sum_to_pi() -> None:
    # The three angles of the triangle target-observer-Sun sum to pi; the one at the Sun is
    # computed here independently.
    rng = np.random.default_rng(7)
    target = rng.normal(size=(50, 3)) * 7000.0 * KM
    observer = target + rng.normal(size=(50, 3)) * 50.0 * KM
    sun = rng.normal(size=(50, 3)) * 1000.0 * KM + AU_M * X
    u, w = target - sun, observer - sun
    at_sun = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.sum(u * w, axis=1))
    total = phase_angle_rad(target, observer, sun) + sun_boresight_angle_rad(observer, target, sun)
    np.testing.assert_allclose(total + at_sun, math.pi, atol=1e-12)


def test_angles_reject_coincident_points() -> None:
    with pytest.raises(SatsightError, match="zero vector"):
        phase_angle_rad(ORBIT_RADIUS_M * X, ORBIT_RADIUS_M * X, SUN_AT_1_AU)
    with pytest.raises(SatsightError, match="zero vector"):
        sun_boresight_angle_rad(ORBIT_RADIUS_M * X, ORBIT_RADIUS_M * X, SUN_AT_1_AU)


# --- eclipse of a circular orbit -------------------------------------------------------


def test_closed_form_duration_limits() -> None:
    r = ORBIT_RADIUS_M
    period = orbital_period_s(r)
    # beta = 0: arccos(sqrt(1 - R^2/r^2)) = arcsin(R/r).
    at_zero = period / math.pi * math.asin(R_EARTH / r)
    assert cylindrical_eclipse_duration_s(r, 0.0) == pytest.approx(at_zero, rel=1e-14)
    # T = 2 pi sqrt(r^3 / mu): a quarter of the gravitational parameter doubles it.
    quarter_mu = cylindrical_eclipse_duration_s(r, 0.0, mu_m3_s2=0.25 * MU_EARTH_M3_S2)
    assert quarter_mu == pytest.approx(2.0 * at_zero, rel=1e-14)
    beta_star = math.asin(R_EARTH / r)
    assert cylindrical_eclipse_duration_s(r, beta_star + 1e-9) == 0.0
    assert cylindrical_eclipse_duration_s(r, -math.pi / 2) == 0.0
    below = cylindrical_eclipse_duration_s(r, np.array([beta_star - 1e-6, -0.3, 0.3]))
    assert below.shape == (3,)
    assert 0.0 < below[0] < 0.01 * period  # shrinks to zero at beta*
    assert below[1] == below[2]  # even in beta
    with pytest.raises(SatsightError, match="radius_m"):
        cylindrical_eclipse_duration_s(0.9 * R_EARTH, 0.0)
    with pytest.raises(SatsightError, match="beta_rad"):
        cylindrical_eclipse_duration_s(r, 2.0)


def circular_orbit_with_sun_at_beta(beta_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 7000 km circular orbit (i = 51.6 deg, RAAN = 30 deg) starting at its point nearest
    the Sun, and a Sun at 1 AU, fixed in direction, at beta_rad above the orbit plane."""
    r0, v0 = state_from_elements(OrbitalElements.from_km_deg(7000.0, 0.0, 51.6, 30.0, 0.0, 0.0))
    normal = np.cross(r0, v0) / np.linalg.norm(np.cross(r0, v0))
    sun = AU_M * (math.cos(beta_rad) * r0 / np.linalg.norm(r0) + math.sin(beta_rad) * normal)
    return r0, v0, sun


def crossings(
    r0: np.ndarray, v0: np.ndarray, step_s: float, function
) -> tuple[list[float], list[float]]:
    """Times in one period where function(positions (N, 3)) -> (N,) goes from > 0 to <= 0
    (entries) and from <= 0 to > 0 (exits): sign changes on a step_s grid, each refined by
    brentq on states propagated from the grid point before it."""
    period = orbital_period_s(ORBIT_RADIUS_M)
    times = np.append(np.arange(0.0, period, step_s), period)
    r, v = propagate(r0, v0, times, j2=False, method="dop853")
    values = function(r)
    entries: list[float] = []
    exits: list[float] = []
    for k in np.flatnonzero((values[:-1] > 0.0) != (values[1:] > 0.0)):

        def g(tau: float, k: int = k) -> float:
            if tau == 0.0:
                return float(values[k])
            position, _ = propagate(r[k], v[k], [tau], j2=False, method="dop853")
            return float(function(position)[0])

        tau = brentq(g, 0.0, times[k + 1] - times[k], xtol=1e-9, rtol=1e-15)
        (entries if values[k] > 0.0 else exits).append(float(times[k] + tau))
    return entries, exits


def cylinder_function(sun: np.ndarray):
    """Distance outside the shadow cylinder, m: |r_perp| - R behind the Earth, |r| - R in
    front (continuous across the terminator plane, negative exactly in the shadow)."""
    s = sun / np.linalg.norm(sun)

    def distance(r: np.ndarray) -> np.ndarray:
        along = r @ s
        across = np.linalg.norm(r - along[:, None] * s, axis=1)
        return np.where(along < 0.0, across, np.linalg.norm(r, axis=1)) - R_EARTH

    return distance


@pytest.mark.parametrize("beta_deg", [20.0, 55.0])
def test_propagated_cylindrical_eclipse_matches_the_closed_form(beta_deg: float) -> None:
    # Two-body motion and a Sun fixed in direction: exactly the closed form's assumptions,
    # so the only differences are the integrator (DOP853 at 1e-12, mm over an orbit, i.e.
    # sub-microsecond timing) and brentq's 1e-9 s tolerance.
    beta = math.radians(beta_deg)
    r0, v0, sun = circular_orbit_with_sun_at_beta(beta)
    assert beta_angle_rad(r0, v0, sun) == pytest.approx(beta, abs=ANGLE_ROUNDING_RAD)
    (entry,), (exit_,) = crossings(r0, v0, 10.0, cylinder_function(sun))
    expected = cylindrical_eclipse_duration_s(ORBIT_RADIUS_M, beta)
    assert exit_ - entry == pytest.approx(expected, abs=ONE_MS)
    # Symmetric about the point opposite the Sun, half a period after the start.
    period = orbital_period_s(ORBIT_RADIUS_M)
    assert 0.5 * (entry + exit_) == pytest.approx(0.5 * period, abs=ONE_MS)
    # The module's membership test agrees with the crossing times.
    times = np.array([entry - 0.01, entry + 0.01, exit_ - 0.01, exit_ + 0.01])
    r, _ = propagate(r0, v0, times, j2=False, method="dop853")
    np.testing.assert_array_equal(in_cylindrical_shadow(r, sun), [False, True, True, False])


def test_no_eclipse_above_the_critical_beta() -> None:
    beta = math.radians(70.0)  # above arcsin(R / r) = 65.7 deg
    r0, v0, sun = circular_orbit_with_sun_at_beta(beta)
    period = orbital_period_s(ORBIT_RADIUS_M)
    r, _ = propagate(r0, v0, np.arange(0.0, period, 10.0), j2=False, method="dop853")
    assert cylindrical_eclipse_duration_s(ORBIT_RADIUS_M, beta) == 0.0
    assert not np.any(in_cylindrical_shadow(r, sun))
    assert np.all(sunlit_fraction(r, sun) == 1.0)


@pytest.mark.parametrize("beta_deg", [0.0, 20.0, 55.0])
def test_conical_shadow_contacts_on_a_circular_orbit(beta_deg: float) -> None:
    beta = math.radians(beta_deg)
    r0, v0, sun = circular_orbit_with_sun_at_beta(beta)
    period = orbital_period_s(ORBIT_RADIUS_M)
    mean_motion = 2.0 * math.pi / period
    # Levels just inside 1 and 0: near contact the deficit grows like h^(3/2) (see the thin
    # lens law), so 1e-12 of the disc is reached ~1e-10 rad, ~1e-7 s, after the contact.
    (pen_in,), (pen_out,) = crossings(
        r0, v0, 10.0, lambda r: sunlit_fraction(r, sun) - (1.0 - 1e-12)
    )
    (umb_in,), (umb_out,) = crossings(r0, v0, 10.0, lambda r: sunlit_fraction(r, sun) - 1e-12)
    (cyl_in,), (cyl_out,) = crossings(r0, v0, 10.0, cylinder_function(sun))
    assert pen_in < cyl_in < umb_in < umb_out < cyl_out < pen_out

    # Closed form. With theta the angle from the point nearest the Sun, the angle c0 between
    # s and the direction to the Earth's centre obeys cos c0 = -cos(beta) cos(theta). Seen
    # from the target, the Sun at distance d is off s by the parallax r_perp / d, which to
    # first order in r / d lowers the Sun-Earth separation to c = c0 - (r / d) sin c0, and
    # puts the Sun at d + r cos c0, so its apparent radius is asin(R_sun / (d + r cos c0)).
    # Contacts are at c = b + a (first contact) and c = b - a (umbra): solved for c0, then
    # theta = arccos(-cos(c0) / cos(beta)) and t = theta / n.
    b = EARTH_DISC_LEO_RAD
    ratio = ORBIT_RADIUS_M / AU_M

    def contact_time(sign: float) -> float:
        c0 = b
        for _ in range(4):  # fixed point: the corrections are 1e-5 of c0
            a = math.asin(SUN_RADIUS_M / (AU_M + ORBIT_RADIUS_M * math.cos(c0)))
            c0 = b + sign * a + ratio * math.sin(c0)
        return math.acos(-math.cos(c0) / math.cos(beta)) / mean_motion

    # Left out: second order in r / d ((r / d)^2 = 2e-9 rad in c, i.e. 2 to 5 microseconds
    # at these rates) and the time from each contact to the module's level (1e-7 s). The
    # parallax correction itself is 0.04 to 0.09 s. Allowed 20 microseconds.
    tolerance = TWENTY_MICROSECONDS
    assert pen_in == pytest.approx(contact_time(+1.0), abs=tolerance)
    assert umb_in == pytest.approx(contact_time(-1.0), abs=tolerance)
    assert period - pen_out == pytest.approx(contact_time(+1.0), abs=tolerance)
    assert period - umb_out == pytest.approx(contact_time(-1.0), abs=tolerance)

    # Penumbra crossing, to first order: the band 2a wide in c crossed at the rate
    # dc/dt = n cos(beta) sin(theta) / sin(c) at the cylinder's edge c = b, i.e.
    # 2a sin b / (n sqrt(cos^2 beta - cos^2 b)): 8.6 s at beta = 0, 9.3 s at 20 deg, 19.7 s
    # at 55 deg (grazing). Linearising c(t) across a band centred on c = b errs only in
    # second order of the band's width (relative 2e-5 at 55 deg); allowed 1e-3.
    a = SUN_DISC_RAD
    theta_edge = math.acos(-math.cos(b) / math.cos(beta))
    rate = mean_motion * math.cos(beta) * math.sin(theta_edge) / math.sin(b)
    first_order = 2.0 * a / rate
    for crossing in (umb_in - pen_in, pen_out - umb_out):
        assert crossing == pytest.approx(first_order, rel=1e-3)
        assert 3.0 < crossing < 25.0

    # Spot checks of the module's fraction just outside and inside each contact.
    times = np.array([pen_in - 0.01, pen_in + 0.01, umb_in - 0.01, umb_in + 0.01])
    r, _ = propagate(r0, v0, times, j2=False, method="dop853")
    f = sunlit_fraction(r, sun)
    assert f[0] == 1.0
    assert 0.99 < f[1] < 1.0
    assert 0.0 < f[2] < 0.01
    assert f[3] == 0.0


def test_real_sun_eclipse_time_matches_the_cylindrical_closed_form() -> None:
    # A 7000 km circular orbit with the DE421 Sun from 2025-01-15T06:00Z (beta ~ 23 deg),
    # started at the point nearest the Sun half an orbit later, so the eclipse falls in the
    # middle of the orbit. The time integral of the shadowed fraction (1 - sunlit fraction)
    # over one orbit then equals the cylindrical duration at the mid-eclipse beta, except:
    # * the Sun moves (~1 deg/day): in the orbit plane the anti-Sun direction advances at
    #   omega, so the object crosses the shadow at n - omega, not n: a factor n / (n - omega),
    #   +0.34 s here;
    # * parallax: seen from the target the Sun is off s by r_perp / AU, which lowers c by
    #   R^2 / (r d_sun sin c) at both edges: +2 R^2 / (r d_sun) / (n cos(beta) sin(theta))
    #   with theta the edge's angle from the point nearest the Sun, +0.09 s here;
    # * the penumbra is not symmetric about its middle c = b (the covered fraction there is
    #   1/2 - O(a / b)) and the 1 s trapezoid rule errs at the contact kinks: ~0.01 s each.
    # Allowed: 0.05 s against the closed form with the first two corrections (measured
    # 0.01 s) and 2 s against the bare closed form (measured 0.42 s).
    epoch = "2025-01-15T06:00:00Z"
    period = orbital_period_s(ORBIT_RADIUS_M)
    n = 2.0 * math.pi / period
    r_node, v_node = state_from_elements(
        OrbitalElements.from_km_deg(7000.0, 0.0, 51.6, 60.0, 0.0, 0.0)
    )
    p = r_node / np.linalg.norm(r_node)
    h = np.cross(r_node, v_node) / np.linalg.norm(np.cross(r_node, v_node))
    q = np.cross(h, p)
    sun_mid = sun_position_gcrs_m(epoch_times(epoch, [0.5 * period]))[0]
    u_sun_deg = math.degrees(math.atan2(sun_mid @ q, sun_mid @ p))
    r0, v0 = state_from_elements(
        OrbitalElements.from_km_deg(7000.0, 0.0, 51.6, 60.0, 0.0, u_sun_deg)
    )
    times = np.linspace(0.0, period, int(period) + 1)
    sun = sun_position_gcrs_m(epoch_times(epoch, times))
    r, v = propagate(r0, v0, times, j2=False, method="dop853")
    fraction = sunlit_fraction(r, sun)
    assert np.all((fraction >= 0.0) & (fraction <= 1.0))
    assert fraction[0] == 1.0
    assert fraction[times.size // 2] == 0.0
    assert np.any((fraction > 0.0) & (fraction < 1.0))
    shadowed = 1.0 - fraction
    shadow_time = float(np.sum(0.5 * (shadowed[1:] + shadowed[:-1]) * np.diff(times)))

    mid = times.size // 2
    beta = float(beta_angle_rad(r[mid], v[mid], sun[mid]))
    assert 0.2 < abs(beta) < 0.6
    closed_form = cylindrical_eclipse_duration_s(ORBIT_RADIUS_M, beta)
    azimuth = np.unwrap(np.arctan2(sun @ q, sun @ p))
    omega = (azimuth[mid + 1] - azimuth[mid - 1]) / (times[mid + 1] - times[mid - 1])
    b = EARTH_DISC_LEO_RAD
    sin_theta = math.sqrt(1.0 - (math.cos(b) / math.cos(beta)) ** 2)
    sun_distance = float(np.linalg.norm(sun[mid]))
    parallax_s = 2.0 * R_EARTH**2 / (ORBIT_RADIUS_M * sun_distance)
    parallax_s /= n * math.cos(beta) * sin_theta
    corrected = closed_form * n / (n - omega) + parallax_s
    assert shadow_time == pytest.approx(corrected, abs=0.05)
    assert shadow_time == pytest.approx(closed_form, abs=2.0)


# --- limits and per-frame summary ------------------------------------------------------


def test_default_limits() -> None:
    limits = VisibilityLimits()
    assert limits.atmosphere_margin_m == 100e3
    assert limits.min_sunlit_fraction == 1.0
    assert limits.sun_exclusion_rad == pytest.approx(math.radians(30.0))
    assert limits.min_phase_angle_rad == 0.0
    assert limits.max_phase_angle_rad == pytest.approx(math.radians(150.0))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"atmosphere_margin_m": -1.0}, "atmosphere_margin_m must be >= 0"),
        ({"atmosphere_margin_m": math.inf}, "finite"),
        ({"min_sunlit_fraction": 1.5}, r"min_sunlit_fraction must lie in \[0, 1\]"),
        ({"min_sunlit_fraction": -0.1}, "min_sunlit_fraction"),
        ({"sun_exclusion_rad": -0.1}, r"sun_exclusion_rad must lie in \[0, pi\]"),
        ({"sun_exclusion_rad": 30.0}, "give angles in radians"),
        ({"max_phase_angle_rad": 4.0}, "max_phase_angle_rad"),
        ({"min_phase_angle_rad": 2.0, "max_phase_angle_rad": 1.0}, "must not exceed"),
        ({"min_phase_angle_rad": "abc"}, "finite number"),
    ],
)
def test_limits_validation(kwargs: dict, match: str) -> None:
    with pytest.raises(SatsightError, match=match):
        VisibilityLimits(**kwargs)


def test_assess_visibility_flags_each_condition() -> None:
    r = ORBIT_RADIUS_M
    sun_x = AU_M * X
    sun_z = AU_M * Z
    rows = [
        # (target, observer, sun): expected (occulted, eclipsed, excluded, phase)
        (r * X, r * X + 10 * KM * Y, sun_x),  # visible: phase 90, boresight 90
        (r * X, -r * X, sun_z),  # through the Earth; phase 90, boresight 90
        (-r * X, -r * X + 10 * KM * Y, sun_x),  # in the umbra
        (r * X, r * X - 10 * KM * Y + 1 * KM * X, sun_x),  # phase 84, boresight 96 deg
    ]
    target = np.array([row[0] for row in rows]) @ TILT.T
    observer = np.array([row[1] for row in rows]) @ TILT.T
    sun = np.array([row[2] for row in rows]) @ TILT.T
    result = assess_visibility(target, observer, sun)
    assert isinstance(result, FrameVisibility)
    np.testing.assert_array_equal(result.earth_occulted, [False, True, False, False])
    np.testing.assert_array_equal(result.eclipsed, [False, False, True, False])
    np.testing.assert_array_equal(result.sun_excluded, [False, False, False, False])
    np.testing.assert_array_equal(result.phase_rejected, [False, False, False, False])
    np.testing.assert_array_equal(result.visible, [True, False, False, True])
    np.testing.assert_allclose(result.sunlit_fraction, [1.0, 1.0, 0.0, 1.0])
    np.testing.assert_allclose(result.los_clearance_m[1], -R_EARTH, atol=1e-6)
    np.testing.assert_allclose(result.phase_angle_rad[:3], math.pi / 2, atol=1e-4)
    with pytest.raises(ValueError, match="read-only"):
        result.eclipsed[0] = True


def test_sun_exclusion_and_phase_flags() -> None:
    # Looking towards the Sun: the camera 10 km behind the target on the Sun line, offset
    # sideways by 2 km (boresight 11.3 deg off the Sun, phase 168.7 deg); and the camera
    # between target and Sun (phase 0, boresight 180 deg).
    target = TILT @ (ORBIT_RADIUS_M * X)
    sun = TILT @ (AU_M * X)
    against_sun = target + TILT @ (-10.0 * KM * X + 2.0 * KM * Y)
    sun_behind = target + TILT @ (10.0 * KM * X)
    observer = np.array([against_sun, sun_behind])
    default = assess_visibility(target, observer, sun)
    np.testing.assert_array_equal(default.sun_excluded, [True, False])
    np.testing.assert_array_equal(default.phase_rejected, [True, False])
    # Loosen one test at a time.
    no_phase = assess_visibility(
        target, observer, sun, VisibilityLimits(max_phase_angle_rad=math.pi)
    )
    np.testing.assert_array_equal(no_phase.sun_excluded, [True, False])
    np.testing.assert_array_equal(no_phase.phase_rejected, [False, False])
    no_exclusion = VisibilityLimits(sun_exclusion_rad=0.0)
    only_phase = assess_visibility(target, observer, sun, no_exclusion)
    np.testing.assert_array_equal(only_phase.sun_excluded, [False, False])
    np.testing.assert_array_equal(only_phase.phase_rejected, [True, False])
    min_phase = VisibilityLimits(min_phase_angle_rad=math.radians(10.0))
    np.testing.assert_array_equal(
        assess_visibility(target, observer, sun, min_phase).phase_rejected, [True, True]
    )


def test_penumbra_counts_as_eclipsed_only_below_the_threshold() -> None:
    # A target with the Sun's centre on the Earth's limb (fraction ~ 0.5).
    target, sun = geometry_with_disc_angles(SUN_DISC_RAD, EARTH_DISC_LEO_RAD, EARTH_DISC_LEO_RAD)
    observer = target + TILT @ (10.0 * KM * Z)
    fraction = sunlit_fraction(target, sun)
    assert 0.4 < fraction < 0.6
    assert assess_visibility(target, observer, sun).eclipsed[0]
    relaxed = VisibilityLimits(min_sunlit_fraction=0.3)
    assert not assess_visibility(target, observer, sun, relaxed).eclipsed[0]
    disabled = VisibilityLimits(min_sunlit_fraction=0.0)
    umbra = TILT @ (-ORBIT_RADIUS_M * X)
    umbra_sun = TILT @ SUN_AT_1_AU
    assert assess_visibility(umbra, umbra + 10.0 * KM * Z, umbra_sun).eclipsed[0]
    assert not assess_visibility(umbra, umbra + 10.0 * KM * Z, umbra_sun, disabled).eclipsed[0]


def test_single_vectors_give_length_one_arrays() -> None:
    result = assess_visibility(ORBIT_RADIUS_M * X, ORBIT_RADIUS_M * X + 5.0 * KM * Y, AU_M * X)
    for name in ("los_clearance_m", "sunlit_fraction", "sun_boresight_angle_rad"):
        assert getattr(result, name).shape == (1,)
    assert result.visible.shape == (1,)
    assert result.visible[0]
    with pytest.raises(SatsightError, match="VisibilityLimits"):
        assess_visibility(X * 7e6, Y * 7e6, AU_M * X, limits={"atmosphere_margin_m": 0.0})


def test_assess_visibility_can_take_the_drawn_sphere_instead_of_the_ellipsoid() -> None:
    """``earth_sphere_radius_m`` makes the Earth that sphere for the line of sight and the
    shadow, whatever the orientation says. In the equatorial plane (ITRS = GCRS here) the
    ellipsoid's limb is a = R1 + 7.1 km, so the two models part by closed forms."""
    from satsight.constants import EARTH_MEAN_RADIUS_M

    identity = np.eye(3)
    # A line of sight whose lowest point is 10 km above the mean sphere, in the equator.
    h = 10.0 * KM
    low = (EARTH_MEAN_RADIUS_M + h) * X
    observer, target = low - 2000.0 * KM * Y, low + 2000.0 * KM * Y
    sun = AU_M * Y  # far from both ends' shadows
    on_sphere = assess_visibility(
        target, observer, sun, R_itrs_from_gcrs=identity, earth_sphere_radius_m=EARTH_MEAN_RADIUS_M
    )
    on_ellipsoid = assess_visibility(target, observer, sun, R_itrs_from_gcrs=identity)
    assert on_sphere.los_clearance_m[0] == pytest.approx(h, abs=ONE_UM)
    assert on_ellipsoid.los_clearance_m[0] == pytest.approx(
        EARTH_MEAN_RADIUS_M + h - R_EARTH, abs=1e-3
    )
    # A target behind the Earth whose line to the Sun's centre passes 1 km above the mean
    # sphere: more than half the solar disc shows over the sphere's limb, less than half over
    # the ellipsoid's (which stands 6.1 km above that line).
    sun_far = AU_M * X
    target_shadow = -2000.0 * KM * X + (EARTH_MEAN_RADIUS_M + 1.0 * KM) * Y
    # The line from the target to the Sun's centre is nearly parallel to x: its distance from
    # the centre is |p x u|; solve the small tilt so that it is R1 + 1 km.
    u = (sun_far - target_shadow) / np.linalg.norm(sun_far - target_shadow)
    miss = float(np.linalg.norm(np.cross(target_shadow, u)))
    target_shadow = target_shadow * (EARTH_MEAN_RADIUS_M + 1.0 * KM) / miss
    fraction_sphere = assess_visibility(
        target_shadow,
        target_shadow + 10.0 * KM * Z,
        sun_far,
        R_itrs_from_gcrs=identity,
        earth_sphere_radius_m=EARTH_MEAN_RADIUS_M,
    ).sunlit_fraction[0]
    fraction_ellipsoid = assess_visibility(
        target_shadow, target_shadow + 10.0 * KM * Z, sun_far, R_itrs_from_gcrs=identity
    ).sunlit_fraction[0]
    assert 0.5 < fraction_sphere < 1.0
    assert 0.0 < fraction_ellipsoid < 0.5
    with pytest.raises(SatsightError, match="earth_sphere_radius_m must be a finite length"):
        assess_visibility(target, observer, sun, earth_sphere_radius_m=-1.0)
