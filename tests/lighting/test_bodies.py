"""Light from sunlit Lambertian spheres (Earth, Moon): radiance, irradiance, SH projection.

References used here, each derived or computed independently of satsight.lighting.bodies:

* Sub-solar plate (closed form derived below): a target at altitude h straight above the
  sub-solar point (Sun behind the target), plate facing nadir.
* Far field: a Lambertian sphere at zero phase has the intensity (2/3) rho E R^2 (W sr^-1),
  so at distance D the irradiance is (2/3) rho E (R/D)^2.
* A uniform disc of radiance L and angular radius alpha fully above a plate's horizon,
  its axis at angle beta from the plate's normal: E = pi L sin^2(alpha) cos(beta).
* A surface integral over the sphere's lit, visible part (nested scipy quad), for geometries
  where the terminator crosses the disc.
* SH truncation of the clamped cosine (Ramamoorthi & Hanrahan 2001): for a point source
  on the normal, the degree-l_max irradiance is sum_{l <= l_max} (2l + 1) A_l / (4 pi)
  times the exact one: 17/16, 31/32, 261/256, 505/512 for l_max = 2, 4, 6, 8.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import quad

from satsight.errors import SatsightError
from satsight.lighting import bodies as B
from satsight.lighting import sh
from satsight.lighting.light_field import LightField

R_EARTH = 6_371_008.8  # m, IUGG mean radius
R_MOON = 1_737_400.0  # m, IAU mean radius
MOON_DISTANCE_M = 384_400e3
E_SUN = 671.5  # W m^-2, in-band 450-900 nm at 1 AU
RHO = 0.3
REL_CLOSED_FORM = 1e-6
NADIR = np.array([0.0, 0.0, -1.0])  # the Earth lies along -z from the target in these tests


def _sun(angle_from_zenith_deg: float) -> np.ndarray:
    """Sun direction at an angle from the target's zenith (+z), in the x-z plane."""
    a = math.radians(angle_from_zenith_deg)
    return np.array([math.sin(a), 0.0, math.cos(a)])


def _earth_below(altitude_m: float) -> np.ndarray:
    return np.array([0.0, 0.0, -(R_EARTH + altitude_m)])


# Closed form: irradiance on a nadir-facing plate above the sub-solar point.
#
# Body centre O at the origin, target T at (0, 0, D), D = R + h, a = R / D; the Sun along
# +z (behind the target). A surface point P at angle gamma from the sub-target point, x =
# cos(gamma), has outward normal n_P, Lambert radiance L = rho E x / pi (the visible cap,
# x >= a, is entirely on the day side), distance s^2 = R^2 + D^2 - 2 R D x, and:
#   cos(theta_plate) = (D - R x) / s        (plate normal -z, towards O)
#   cos(theta_surf)  = (D x - R) / s        (between n_P and P -> T)
#   d Omega          = dA cos(theta_surf) / s^2,   dA = R^2 dx dphi.
# E = integral L cos(theta_plate) d Omega
#   = 2 rho E R^2 integral_a^1 x (D - R x)(D x - R) / (R^2 + D^2 - 2 R D x)^2 dx
#   = 2 rho E a^2 integral_a^1 x (1 - a x)(x - a) / (1 + a^2 - 2 a x)^2 dx.
# With u = 1 + a^2 - 2 a x, b = 1 - a^2, c = 1 + a^2 the integrand becomes
#   (c - u)(b^2 - u^2) / (16 a^3 u^2) du  over u in [(1 - a)^2, b],
# whose antiderivative is F(u) = -c b^2 / u - c u - b^2 ln(u) + u^2 / 2; hence
#   E = rho E / (8 a) [F(b) - F((1 - a)^2)]
#     = rho E [a (1 + a^2) / 2 + (1 - a)^2 / 4 - (1 - a^2)^2 artanh(a) / (4 a)].
# Checks: a -> 1 (h -> 0) gives rho E (an infinite lit plane); a -> 0 gives
# (2/3) rho E a^2 (1 + 3a/4 - a^2/5 + ...), the far-field limit.
def _subsolar_nadir_irradiance(rho: float, e_sun: float, radius_m: float, d_m: float) -> float:
    a = radius_m / d_m
    return (
        rho
        * e_sun
        * (a * (1 + a * a) / 2 + (1 - a) ** 2 / 4 - (1 - a * a) ** 2 * math.atanh(a) / (4 * a))
    )


def _surface_integral_irradiance(
    altitude_m: float, sun: np.ndarray, plate: np.ndarray, rho: float = RHO
) -> float:
    """E = integral over the lit, visible cap of L cos(theta_plate) cos(theta_surf) / s^2 dA.

    Parametrised on the sphere: x = cos of the angle from the sub-target point, azimuth phi;
    target at (0, 0, D) above the body centre. For each x the lit arc of phi is solved in
    closed form (n . s = 0 is r (s_x cos(phi) + s_y sin(phi)) + x s_z = 0), so the nested
    adaptive quad never meets the terminator's kink. The plate's horizon must not cut the
    disc (true for the geometries used).
    """
    d = R_EARTH + altitude_m
    sx, sy, sz = sun / np.linalg.norm(sun)
    px, py, pz = plate / np.linalg.norm(plate)
    rho_s = math.hypot(sx, sy)
    phi0 = math.atan2(sy, sx)

    def integrand(phi: float, x: float) -> float:
        r_sin = math.sqrt(1.0 - x * x)
        nx, ny, nz = r_sin * math.cos(phi), r_sin * math.sin(phi), x
        vx, vy, vz = R_EARTH * nx, R_EARTH * ny, R_EARTH * nz - d  # target -> surface point
        s2 = vx * vx + vy * vy + vz * vz
        s = math.sqrt(s2)
        lit = max(nx * sx + ny * sy + nz * sz, 0.0)
        cos_plate = max((vx * px + vy * py + vz * pz) / s, 0.0)
        cos_surf = -(vx * nx + vy * ny + vz * nz) / s
        return rho * E_SUN * lit / math.pi * cos_plate * cos_surf / s2 * R_EARTH**2

    def ring(x: float) -> float:
        r_sin = math.sqrt(1.0 - x * x)
        if rho_s * r_sin == 0.0:
            half = math.pi if x * sz > 0.0 else 0.0
        else:
            arg = -x * sz / (r_sin * rho_s)  # lit where cos(phi - phi0) > arg
            half = math.pi if arg <= -1.0 else 0.0 if arg >= 1.0 else math.acos(arg)
        if half == 0.0:
            return 0.0
        value, _ = quad(integrand, phi0 - half, phi0 + half, args=(x,), epsabs=0, epsrel=1e-12)
        return value

    lo = R_EARTH / d
    # Where the terminator enters the ring of constant x: x = sqrt(s_x^2 + s_y^2).
    breaks = [rho_s] if lo < rho_s < 1.0 else None
    value, _ = quad(ring, lo, 1.0, points=breaks, epsabs=0, epsrel=1e-11, limit=200)
    return value


@pytest.mark.parametrize("altitude_m", [1e3, 400e3, 2_000e3, 20_200e3, 36_000e3, 1e8])
def test_subsolar_nadir_plate_matches_closed_form(altitude_m: float) -> None:
    e = B.body_irradiance_w_m2(NADIR, _earth_below(altitude_m), R_EARTH, _sun(0), RHO, E_SUN)
    expected = _subsolar_nadir_irradiance(RHO, E_SUN, R_EARTH, R_EARTH + altitude_m)
    assert e.shape == (3,)
    np.testing.assert_allclose(e, expected, rtol=REL_CLOSED_FORM)


def test_closed_form_limits() -> None:
    # The derivation's own checks: an infinite plane near the surface, the far field.
    assert _subsolar_nadir_irradiance(RHO, E_SUN, R_EARTH, R_EARTH * (1 + 1e-9)) == (
        pytest.approx(RHO * E_SUN, rel=1e-6)
    )
    a = 1e-2
    far = (2.0 / 3.0) * RHO * E_SUN * a * a
    assert _subsolar_nadir_irradiance(RHO, E_SUN, a, 1.0) == pytest.approx(
        far * (1 + 0.75 * a - 0.2 * a * a), rel=1e-6
    )


@pytest.mark.parametrize("distance_m", [1e9, 1e10, 1e11])
def test_far_field_is_a_lambert_sphere_at_zero_phase(distance_m: float) -> None:
    e = B.body_irradiance_w_m2(NADIR, [0, 0, -distance_m], R_EARTH, _sun(0), RHO, E_SUN)[0]
    a = R_EARTH / distance_m
    ratio = e / ((2.0 / 3.0) * RHO * E_SUN * a * a)
    # ratio = 1 + 3a/4 - a^2/5 + ... (the series of the closed form above).
    assert abs(ratio - 1.0) < a
    assert ratio == pytest.approx(1.0 + 0.75 * a, abs=a * a)


def test_full_moon_far_field() -> None:
    # The sunlit Moon straight behind the target's Sun-facing side: intensity (2/3) rho E R^2.
    moon = np.array([0.0, 0.0, MOON_DISTANCE_M])
    sun = np.array([0.0, 0.0, -1.0])  # the Moon's sub-solar point faces the target
    e = B.body_irradiance_w_m2([0, 0, 1.0], moon, R_MOON, sun, 0.12, E_SUN)[0]
    a = R_MOON / MOON_DISTANCE_M
    assert e == pytest.approx((2.0 / 3.0) * 0.12 * E_SUN * a * a * (1 + 0.75 * a), rel=1e-5)


@pytest.mark.parametrize(
    ("altitude_m", "sun", "plate"),
    [
        (400e3, [1.0, 0.0, 0.2], [0.0, 0.0, -1.0]),  # terminator across the disc
        (36_000e3, [1.0, 1.0, 1.0], [0.0, 1.0, -1.0]),  # GEO, gibbous Earth, tilted plate
        (20_200e3, [0.0, -1.0, -0.5], [0.2, 0.0, -1.0]),  # crescent Earth
        (800e3, [1.0, 0.0, -0.17], [0.0, 0.0, -1.0]),  # dusk: a sliver near the limb
    ],
)
def test_irradiance_with_terminator_matches_a_surface_integral(
    altitude_m: float, sun: list[float], plate: list[float]
) -> None:
    expected = _surface_integral_irradiance(altitude_m, np.array(sun), np.array(plate))
    centre = _earth_below(altitude_m)
    e = B.body_irradiance_w_m2(np.array(plate), centre, R_EARTH, sun, RHO, E_SUN)
    assert expected > 0.0
    # The terminator's kink limits the cone quadrature to order n_nodes^-2.
    np.testing.assert_allclose(e, expected, rtol=1e-5)
    fine = B.body_irradiance_w_m2(np.array(plate), centre, R_EARTH, sun, RHO, E_SUN, n_nodes=1024)
    np.testing.assert_allclose(fine, expected, rtol=2e-7)


@pytest.mark.parametrize(("radius_m", "distance_m"), [(R_EARTH, R_EARTH + 400e3), (R_MOON, 4e8)])
def test_cone_quadrature_weights_integrate_a_uniform_disc(
    radius_m: float, distance_m: float
) -> None:
    # A disc of uniform radiance L: E = pi L sin^2(alpha) cos(beta) on a plate whose
    # normal is beta off the disc's axis, the disc fully above its horizon.
    centre = np.array([0.3, -0.4, -0.866]) * distance_m / np.linalg.norm([0.3, -0.4, -0.866])
    axis = centre / distance_m
    sin_a = radius_m / distance_m
    cos_a = math.sqrt(1.0 - sin_a**2)
    dirs, weights, normals = B._cone_quadrature(centre, radius_m, 32)
    assert np.all(dirs @ axis >= cos_a - 1e-12)
    assert float(np.sum(weights)) == pytest.approx(2 * math.pi * (1 - cos_a), rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    # Each node sees the sphere: the hit point lies on the sphere's near side.
    assert np.all(np.einsum("ij,ij->i", normals, -dirs) > 0.0)
    beta = 0.5 * (math.pi / 2 - math.asin(sin_a))  # leaves the whole disc above the horizon
    perp = np.cross(axis, [1.0, 0.0, 0.0])
    perp /= np.linalg.norm(perp)
    plate = math.cos(beta) * axis + math.sin(beta) * perp
    e = float(np.sum(weights * np.maximum(dirs @ plate, 0.0)))
    assert e == pytest.approx(math.pi * sin_a**2 * math.cos(beta), rel=1e-12)


def test_radiance_is_lambertian_at_the_first_hit() -> None:
    centre = _earth_below(1_000e3)
    sun = _sun(35.0)
    rng = np.random.default_rng(7)
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    albedo = (0.1, 0.2, 0.4)
    radiance = B.body_radiance_w_m2_sr(dirs, centre, R_EARTH, sun, albedo, E_SUN)
    assert radiance.shape == (2000, 3)
    # Independent intersection: |t w - c|^2 = R^2, nearest root t > 0.
    b = dirs @ centre
    disc = b * b - (centre @ centre - R_EARTH**2)
    hit = (disc >= 0) & (b > 0)  # the sphere lies ahead of the target, not behind
    t = b[hit] - np.sqrt(disc[hit])
    normal = (t[:, None] * dirs[hit] - centre) / R_EARTH
    expected = np.maximum(normal @ sun, 0.0)[:, None] * np.asarray(albedo) * E_SUN / math.pi
    np.testing.assert_allclose(radiance[hit], expected, rtol=1e-9, atol=1e-9)
    assert np.all(radiance[~hit] == 0.0)
    assert hit.sum() > 100 and (~hit).sum() > 100
    # Straight down: the sub-target point, at 35 degrees from the sub-solar point.
    down = B.body_radiance_w_m2_sr(NADIR[None, :], centre, R_EARTH, sun, 1.0, E_SUN)
    np.testing.assert_allclose(down, E_SUN * math.cos(math.radians(35.0)) / math.pi, rtol=1e-12)


def test_earthshine_vanishes_behind_the_terminator() -> None:
    # 400 km over the night side: the visible cap (19.8 deg around the sub-target point)
    # lies wholly beyond the terminator for the Sun 120 or 180 deg from the zenith.
    centre = _earth_below(400e3)
    for sun in (_sun(180.0), _sun(120.0)):
        dirs, _, _ = B._cone_quadrature(centre, R_EARTH, 16)
        assert np.all(B.body_radiance_w_m2_sr(dirs, centre, R_EARTH, sun, RHO, E_SUN) == 0.0)
        assert np.all(B.earthshine_sh(centre, sun, E_SUN, l_max=4) == 0.0)
        normals, _ = sh.sphere_quadrature(6)
        assert np.all(B.body_irradiance_w_m2(normals, centre, R_EARTH, sun, RHO, E_SUN) == 0.0)
    # At 90 + 19.8 - 5 degrees a sliver of the cap is lit again.
    assert np.any(B.earthshine_sh(centre, _sun(104.0), E_SUN) != 0.0)


def _sh_irradiance_errors(
    centre: np.ndarray, radius_m: float, sun: np.ndarray
) -> tuple[list[float], list[float]]:
    """Relative L2 error over all normals; max error over normals facing the body / max E."""
    normals, weights = sh.sphere_quadrature(24)
    exact = B.body_irradiance_w_m2(normals, centre, radius_m, sun, RHO, E_SUN)[:, 0]
    axis = centre / np.linalg.norm(centre)
    facing = normals @ axis >= 0.5  # within 60 degrees of the body's centre
    l2, facing_max = [], []
    for l_max in (2, 4, 6, 8):
        coeffs = B.body_sh(centre, radius_m, sun, RHO, E_SUN, l_max=l_max)
        approx = sh.evaluate(sh.irradiance_coeffs(coeffs), normals)[:, 0]
        err = approx - exact
        l2.append(math.sqrt(np.sum(weights * err**2) / np.sum(weights * exact**2)))
        facing_max.append(float(np.max(np.abs(err[facing])) / np.max(exact)))
    return l2, facing_max


GEOMETRIES = {
    "leo_subsolar": (_earth_below(400e3), R_EARTH, _sun(0.0)),
    "leo_terminator": (_earth_below(400e3), R_EARTH, _sun(90.0)),
    "leo_dusk": (_earth_below(800e3), R_EARTH, _sun(100.0)),
    "geo_gibbous": (_earth_below(35_786e3), R_EARTH, _sun(60.0)),
    "moon_crescent": (np.array([MOON_DISTANCE_M, 0.0, 0.0]), R_MOON, _sun(30.0)),
}


@pytest.mark.parametrize("name", GEOMETRIES)
def test_sh_irradiance_converges_with_order(name: str) -> None:
    centre, radius, sun = GEOMETRIES[name]
    l2, facing_max = _sh_irradiance_errors(centre, radius, sun)
    # By Parseval the L2 error of a truncated expansion cannot grow with l_max; every band
    # of a disc carries energy, so it falls strictly.
    assert all(later < earlier for earlier, later in itertools.pairwise(l2))
    # Normals facing the body: a point source on the normal is off by 1/32 at l_max = 4; a
    # lit sliver at the limb of a large disc is the worst of these geometries (3.5 %).
    assert facing_max[1] < 0.04


def test_sh_matches_the_point_source_limit_for_a_distant_body() -> None:
    # The Moon's disc (0.26 deg) fully lit on the normal: E_sh / E = sum (2l+1) A_l / 4pi.
    moon = np.array([0.0, 0.0, MOON_DISTANCE_M])
    sun = np.array([0.0, 0.0, -1.0])
    exact = B.body_irradiance_w_m2([0, 0, 1.0], moon, R_MOON, sun, 0.12, E_SUN)[0]
    for l_max, factor in ((2, 17 / 16), (4, 31 / 32), (6, 261 / 256), (8, 505 / 512)):
        coeffs = B.body_sh(moon, R_MOON, sun, 0.12, E_SUN, l_max=l_max)
        e_sh = sh.evaluate(sh.irradiance_coeffs(coeffs), np.array([0.0, 0.0, 1.0]))[0]
        assert e_sh / exact == pytest.approx(factor, rel=2e-5)


def test_albedo_scales_each_channel() -> None:
    centre, sun = _earth_below(700e3), _sun(50.0)
    grey = B.earthshine_sh(centre, sun, E_SUN, albedo=1.0)
    colour = B.earthshine_sh(centre, sun, E_SUN, albedo=(0.2, 0.3, 0.4))
    atol = 1e-13 * float(np.max(np.abs(grey)))  # coefficients that vanish by symmetry
    np.testing.assert_allclose(colour, grey * np.array([0.2, 0.3, 0.4]), rtol=1e-13, atol=atol)
    assert B.earthshine_sh(centre, sun, E_SUN).shape == (25, 3)
    np.testing.assert_allclose(
        B.earthshine_sh(centre, sun, E_SUN), grey * 0.30, rtol=1e-13, atol=atol
    )


def test_occultation_geometry() -> None:
    earth = _earth_below(400e3)
    # Behind the Earth's centre, behind its limb (angular radius 70.2 deg), beside it.
    assert B.occulted_by([0, 0, -MOON_DISTANCE_M], earth, R_EARTH)
    limb = math.asin(R_EARTH / np.linalg.norm(earth))
    for angle, hidden in ((limb - 0.01, True), (limb + 0.01, False), (math.pi / 2, False)):
        point = MOON_DISTANCE_M * np.array([math.sin(angle), 0.0, -math.cos(angle)])
        assert B.occulted_by(point, earth, R_EARTH) is hidden
    # A point nearer than the Earth's surface is not hidden.
    assert not B.occulted_by([0, 0, -100e3], earth, R_EARTH)
    assert not B.occulted_by([0, 0, MOON_DISTANCE_M], earth, R_EARTH)


def test_moon_behind_the_earth_adds_nothing() -> None:
    earth, sun = _earth_below(400e3), _sun(30.0)
    hidden_moon = np.array([0.0, 0.0, -MOON_DISTANCE_M])
    assert np.all(B.moonshine_sh(hidden_moon, sun, E_SUN, earth_center_from_target_m=earth) == 0)
    assert np.any(B.moonshine_sh(hidden_moon, sun, E_SUN) != 0)  # without the Earth
    field = B.environment_light_field(
        sun, E_SUN, earth_center_from_target_m=earth, moon_center_from_target_m=hidden_moon
    )
    np.testing.assert_array_equal(field.sh_radiance_w_m2_sr, B.earthshine_sh(earth, sun, E_SUN))


def test_light_field_assembly_is_additive() -> None:
    earth, sun = _earth_below(600e3), _sun(40.0)
    moon = MOON_DISTANCE_M * np.array([0.0, 0.8, 0.6])  # above the horizon, visible
    extra = np.linspace(0.0, 1.0, 9)  # one grey coefficient vector, l_max = 2
    field = B.environment_light_field(
        sun,
        E_SUN,
        earth_center_from_target_m=earth,
        earth_albedo=(0.3, 0.32, 0.35),
        moon_center_from_target_m=moon,
        extra_sh=extra,
        l_max=2,
    )
    assert isinstance(field, LightField)
    assert field.sh_radiance_w_m2_sr.shape == (9, 3)
    assert field.l_max == 2
    expected = (
        B.earthshine_sh(earth, sun, E_SUN, albedo=(0.3, 0.32, 0.35), l_max=2)
        + B.moonshine_sh(moon, sun, E_SUN, l_max=2)
        + extra[:, None]
    )
    np.testing.assert_allclose(field.sh_radiance_w_m2_sr, expected, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(field.sun_direction_body, sun, atol=1e-15)
    assert field.sun_irradiance_w_m2 == E_SUN
    # The Moon adds light: its l = 0 coefficient is positive.
    assert np.all(B.moonshine_sh(moon, sun, E_SUN, l_max=2)[0] > 0)


def test_light_field_defaults_and_sunlight_at_the_target() -> None:
    sun = _sun(150.0)
    empty = B.environment_light_field(sun, E_SUN)
    assert empty.sh_radiance_w_m2_sr.shape == (25, 3)
    assert np.all(empty.sh_radiance_w_m2_sr == 0.0)
    # A target in the penumbra gets less sunlight than the sunlit Earth it sees.
    earth = _earth_below(20_000e3)
    field = B.environment_light_field(
        sun, E_SUN, earth_center_from_target_m=earth, sun_irradiance_at_target_w_m2=300.0
    )
    assert field.sun_irradiance_w_m2 == 300.0
    np.testing.assert_array_equal(field.sh_radiance_w_m2_sr, B.earthshine_sh(earth, sun, E_SUN))
    assert np.any(field.sh_radiance_w_m2_sr != 0.0)


@pytest.mark.parametrize("altitude_m", [400e3, 20_000e3, 30_000e3])
def test_no_earthshine_inside_the_earths_shadow_cylinder(altitude_m: float) -> None:
    # Inside the cylinder of radius R behind the Earth, a visible point n (n . t > R) cannot
    # be lit: n . t = (n . s)(t . s) + n_perp . t_perp < 0 + R when n . s >= 0, t . s < 0 and
    # |t_perp| < R. Here the Sun is 10 degrees from the nadir, |t_perp| = D sin(10 deg) < R.
    earth = _earth_below(altitude_m)
    sun = _sun(170.0)
    assert np.linalg.norm(earth) * math.sin(math.radians(10.0)) < R_EARTH
    assert np.all(B.earthshine_sh(earth, sun, E_SUN) == 0.0)


def test_bad_inputs_are_refused() -> None:
    sun = _sun(0.0)
    with pytest.raises(SatsightError, match="inside the body"):
        B.earthshine_sh([0.0, 0.0, -1e6], sun, E_SUN)
    with pytest.raises(SatsightError, match="extra_sh"):
        B.environment_light_field(sun, E_SUN, extra_sh=np.zeros((16, 3)), l_max=4)
    with pytest.raises(SatsightError, match="albedo"):
        B.earthshine_sh(_earth_below(400e3), sun, E_SUN, albedo=(0.3, 0.3))
    with pytest.raises(SatsightError, match="sun irradiance"):
        B.earthshine_sh(_earth_below(400e3), sun, -1.0)
    with pytest.raises(SatsightError, match="sun_direction"):
        B.earthshine_sh(_earth_below(400e3), [0.0, 0.0, 0.0], E_SUN)
    with pytest.raises(SatsightError, match="directions"):
        B.body_radiance_w_m2_sr(np.zeros((4, 2)), _earth_below(400e3), R_EARTH, sun, RHO, E_SUN)
