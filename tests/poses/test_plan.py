"""Frame plans from scenarios: geometry checked against independent constructions."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from satsight.config.scenario import load_scenario, parse_scenario
from satsight.constants import AU_M
from satsight.ephemeris.orbits import orbital_period_s, propagate, state_from_elements
from satsight.ephemeris.sun_moon import sun_position_gcrs_m
from satsight.ephemeris.time import epoch_times
from satsight.errors import SatsightError
from satsight.frame_light import frame_light
from satsight.frames.orbital import lvlh_from_inertial
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.lighting.solar_spectrum import band_irradiance_w_m2
from satsight.poses.distance_intervals import APPROACH_INTERVALS_KM
from satsight.poses.plan import frames_to_render, plan_track
from satsight.poses.rssf import fibonacci_sphere
from satsight.poses.views import View

CENTER_M = np.array([0.4, -0.3, 1.1])  # a bounding-box centre off the body origin
ONE_MM = 1e-3
MICRORAD = 1e-6
# LVLH axes (x = T, y = -N, z = -R) written in RTN: the body frame of an LVLH-fixed target
# with the identity offset, so R_rtn_from_body has these columns.
R_RTN_FROM_BODY = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

BASE = {
    "name": "plan-test",
    "epoch_utc": "2025-06-21T06:00:00Z",
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "orbit": {"semi_major_axis_km": 7000.0, "inclination_deg": 97.9, "raan_deg": 10.0},
    "observer": {"mode": "fly_around", "radius_km": 1.0},
    "sampler": {"kind": "sspt", "step_deg": 5.0},
    "earth": {"albedo": 0.3},
}


def scenario_with(**changes):
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    return parse_scenario(data, "test")


def body_from_cam(track, i: int) -> np.ndarray:
    return matrix_from_quaternion(track.q_cam_from_body[i]).T


def target_states(scenario, times_s):
    """The target's orbit as the planner flies it: J2 about the true pole from the epoch
    (the propagation itself is tested in tests/ephemeris)."""
    r0, v0 = state_from_elements(scenario.orbit.build())
    return propagate(r0, v0, times_s, j2=scenario.propagation.j2, epoch=scenario.epoch_utc)


def test_fly_around_frames_every_5_degrees_look_at_the_box_centre() -> None:
    scenario = scenario_with()
    track = plan_track(scenario.plan_request(), CENTER_M)
    period = orbital_period_s(7000e3)
    assert len(track) == 72
    np.testing.assert_allclose(track.time_s, np.arange(72) * period / 72, rtol=0, atol=1e-9)
    R = matrix_from_quaternion(track.q_cam_from_body)
    center_cam = R @ CENTER_M + track.t_cam_from_body_m
    # The box centre sits on the boresight at the planned range.
    np.testing.assert_allclose(center_cam[:, :2], 0.0, atol=ONE_MM)
    np.testing.assert_allclose(center_cam[:, 2], track.range_m, rtol=1e-12)
    # CW circle of 1 km; J2 makes the natural orbit breathe by ~1 % (measured 0.4-0.8 %).
    assert np.all(np.abs(track.range_m - 1000.0) < 20.0)
    np.testing.assert_allclose(np.linalg.norm(track.rho_rtn_m, axis=1), track.range_m, rtol=1e-9)
    assert set(track.interval) == {"5-0.5 km"}


@pytest.mark.parametrize(
    "changes",
    [{}, {"observer": None, "sampler": {"kind": "rssf", "frame_count": 14}}],
    ids=["sspt", "rssf"],
)
def test_inertial_camera_attitude_and_state_agree_with_the_geometry(changes) -> None:
    """q_cam_from_gcrs, the camera's GCRS state and the body-frame pose tell one story: the
    Sun and the box centre seen in camera axes through either route."""
    scenario = scenario_with(**changes)
    track = plan_track(scenario.plan_request(), CENTER_M)
    assert track.has_sky
    r, v = target_states(scenario, track.time_s)
    sun = sun_position_gcrs_m(epoch_times(scenario.epoch_utc, track.time_s))
    for i in range(len(track)):
        R_cam_from_gcrs = track.R_cam_from_gcrs(i)
        np.testing.assert_allclose(R_cam_from_gcrs @ R_cam_from_gcrs.T, np.eye(3), atol=1e-12)
        # The Earth's centre seen from the box centre, through the inertial attitude.
        R_cam_from_body = track.cam_from_body(i).R_a_from_b
        center_cam = R_cam_from_body @ CENTER_M + track.t_cam_from_body_m[i]
        center_gcrs = track.camera_position_gcrs_m[i] + R_cam_from_gcrs.T @ center_cam
        earth = -center_gcrs / np.linalg.norm(center_gcrs)
        np.testing.assert_allclose(
            R_cam_from_gcrs @ earth, track.earth_from_target_cam[i], atol=MICRORAD
        )
        to_sun = (sun[i] - center_gcrs) / np.linalg.norm(sun[i] - center_gcrs)
        np.testing.assert_allclose(
            R_cam_from_gcrs @ to_sun, track.sun_from_target_cam[i], atol=MICRORAD
        )
        # The box centre is the target's orbit point plus its body offset (1.2 m).
        assert np.linalg.norm(center_gcrs - r[i]) == pytest.approx(
            np.linalg.norm(CENTER_M), abs=ONE_MM
        )
    # The camera moves with orbital speed; an RSSF camera shares the target's velocity.
    speed = np.linalg.norm(track.camera_velocity_gcrs_m_s, axis=1)
    assert np.all(np.abs(speed - np.linalg.norm(v, axis=1)) < 5.0)
    if "sampler" in changes:
        np.testing.assert_array_equal(track.camera_velocity_gcrs_m_s, v)


def test_fly_around_without_j2_is_a_closed_circle() -> None:
    scenario = scenario_with(propagation={"j2": False})
    track = plan_track(scenario.plan_request(), CENTER_M)
    # Two-body: the energy-matched CW circle closes; its range departs from 1 km only by
    # the second-order terms (3/2) rho^2 / a ~ 0.2 m, measured 1.2 m.
    assert np.all(np.abs(track.range_m - 1000.0) < 1.5)


def test_lvlh_fixed_target_sees_the_earth_along_body_z() -> None:
    scenario = scenario_with()
    track = plan_track(scenario.plan_request(), CENTER_M)
    r, _ = target_states(scenario, track.time_s)
    for i in range(0, len(track), 9):
        earth_body = body_from_cam(track, i) @ track.earth_from_target_cam[i]
        # Nadir is LVLH +z; the box centre is 1 m off the orbit point, 1.5e-7 rad at 7000 km.
        np.testing.assert_allclose(earth_body, [0.0, 0.0, 1.0], atol=MICRORAD)
        # Box centre to the Earth's centre: the orbit radius less the centre's 1.1 m offset
        # along nadir (+z_body).
        assert track.earth_distance_m[i] == pytest.approx(
            np.linalg.norm(r[i]) - CENTER_M[2], abs=ONE_MM
        )


def test_sun_direction_in_the_body_frame_matches_an_lvlh_construction() -> None:
    scenario = scenario_with()
    track = plan_track(scenario.plan_request(), CENTER_M)
    r, v = target_states(scenario, track.time_s)
    sun = sun_position_gcrs_m(epoch_times(scenario.epoch_utc, track.time_s))
    expected = np.einsum("nij,nj->ni", lvlh_from_inertial(r, v), sun - r)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    got = np.stack([body_from_cam(track, i) @ track.sun_from_target_cam[i] for i in range(72)])
    np.testing.assert_allclose(got, expected, atol=MICRORAD)
    np.testing.assert_allclose(track.sun_distance_m, np.linalg.norm(sun - r, axis=1), rtol=1e-9)


def test_orbit_normal_roll_puts_image_x_along_the_orbit_normal() -> None:
    track = plan_track(scenario_with().plan_request(), CENTER_M)
    normal_rtn = np.array([0.0, 0.0, 1.0])
    for i in range(len(track)):
        R_rtn_from_cam = R_RTN_FROM_BODY @ body_from_cam(track, i)
        z, x = R_rtn_from_cam[:, 2], R_rtn_from_cam[:, 0]
        projected = normal_rtn - (normal_rtn @ z) * z
        projected /= np.linalg.norm(projected)
        # The observer's orbit normal differs from the target's by ~rho / r = 1.4e-4 rad.
        assert np.arccos(np.clip(x @ projected, -1, 1)) < 5e-4


def test_hover_ahead_reproduces_the_papers_initial_view() -> None:
    """Boresight along -T, image x along N, so image down (+y) is -R: Earth below."""
    scenario = scenario_with(
        observer={"mode": "hover", "range_km": 100.0},
        sampler={"kind": "sspt", "frame_count": 5},
    )
    track = plan_track(scenario.plan_request(), CENTER_M)
    for i in range(len(track)):
        R_rtn_from_cam = R_RTN_FROM_BODY @ body_from_cam(track, i)
        # The chord to a point 100 km ahead on the orbit dips by 100/7000/2 rad = 0.007.
        np.testing.assert_allclose(R_rtn_from_cam[:, 2], [0.0, -1.0, 0.0], atol=0.01)
        # x follows the observer's own orbit normal, which J2 turns by ~3e-6 rad from the
        # target's over the 100 km between them.
        np.testing.assert_allclose(R_rtn_from_cam[:, 0], [0.0, 0.0, 1.0], atol=1e-5)
        np.testing.assert_allclose(R_rtn_from_cam[:, 1], [-1.0, 0.0, 0.0], atol=0.01)
    # Same orbit, energy matched: the range stays at the 100 km chord to within the J2
    # short-period breathing (measured 0.45 %).
    assert np.all(np.abs(track.range_m - 100e3) < 1e3)
    assert set(track.interval) == {"hover 100 km"}


def test_approach_passes_through_every_interval_geometrically() -> None:
    scenario = scenario_with(
        observer={"mode": "approach", "revolutions": 2, "schedule": "geometric"},
        sampler={"kind": "sspt", "frame_count": 61},
    )
    track = plan_track(scenario.plan_request(), CENTER_M)
    assert track.range_m[0] == pytest.approx(50e3, rel=1e-9)
    assert track.range_m[-1] == pytest.approx(0.5e3, rel=1e-9)
    ratios = track.range_m[1:] / track.range_m[:-1]
    np.testing.assert_allclose(ratios, (0.5 / 50.0) ** (1 / 60), rtol=1e-9)
    visited = list(dict.fromkeys(track.interval))
    assert visited == [f"{far:g}-{near:g} km" for far, near in APPROACH_INTERVALS_KM]
    assert track.time_s[-1] == pytest.approx(2 * orbital_period_s(7000e3), rel=1e-12)


def test_approach_balanced_over_the_intervals_by_default() -> None:
    scenario = scenario_with(
        observer={"mode": "approach"},
        sampler={"kind": "sspt", "frame_count": 60},
    )
    track = plan_track(scenario.plan_request(), CENTER_M)
    names, counts = np.unique(track.interval, return_counts=True)
    # 60 uniform frames over six equal time spans: 10 each (an edge frame counts for the
    # interval it is the near edge of).
    assert len(names) == 6 and set(counts) == {10}
    assert counts.sum() == 60


def test_fly_by_closest_approach_is_the_miss_distance_mid_pass() -> None:
    scenario = scenario_with(
        observer={"mode": "fly_by", "miss_distance_km": 0.5, "start_along_track_km": 3.0},
        sampler={"kind": "sspt", "frame_count": 101},
        propagation={"j2": False},
    )
    track = plan_track(scenario.plan_request(), CENTER_M)
    closest = int(np.argmin(track.range_m))
    assert closest == pytest.approx(50, abs=1)
    # CW's co-elliptic pass in the full two-body dynamics: the linear initial state leaves a
    # radial oscillation of the second order, ~3 y0^2 / (2 a) = 1.9 m in amplitude
    # (measured: the radial offset stays within 500-504.4 m).
    assert track.range_m[closest] == pytest.approx(500.0, abs=6.0)
    assert track.rho_rtn_m[0, 1] == pytest.approx(3000.0, rel=0.01)
    assert track.rho_rtn_m[-1, 1] == pytest.approx(-3000.0, rel=0.02)


def test_observer_on_its_own_elements_matches_a_phase_shifted_target() -> None:
    elements = {"semi_major_axis_km": 7000.0, "inclination_deg": 97.9, "raan_deg": 10.0}
    shift_deg = math.degrees(2.0 / 7000.0)
    scenario = scenario_with(
        observer={
            "mode": "elements",
            "orbit": {**elements, "true_anomaly_deg": shift_deg},
        },
        sampler={"kind": "sspt", "frame_count": 20},
        propagation={"j2": False},
    )
    track = plan_track(scenario.plan_request(), np.zeros(3))
    # Same circular orbit, 2 km of arc ahead: a constant chord 2 a sin(theta / 2).
    chord = 2 * 7000e3 * math.sin(math.radians(shift_deg) / 2)
    np.testing.assert_allclose(track.range_m, chord, rtol=1e-7)


def test_rssf_views_are_balanced_seeded_and_lattice_spaced() -> None:
    scenario = scenario_with(observer=None, sampler={"kind": "rssf", "frame_count": 70})
    track = plan_track(scenario.plan_request(), CENTER_M)
    again = plan_track(scenario.plan_request(), CENTER_M)
    other = plan_track(
        scenario_with(
            observer=None, sampler={"kind": "rssf", "frame_count": 70, "seed": 6}
        ).plan_request(),
        CENTER_M,
    )
    np.testing.assert_array_equal(track.q_cam_from_body, again.q_cam_from_body)
    np.testing.assert_array_equal(track.t_cam_from_body_m, again.t_cam_from_body_m)
    assert not np.allclose(track.t_cam_from_body_m, other.t_cam_from_body_m)
    assert np.all(track.time_s == 0.0)
    names, counts = np.unique(track.interval, return_counts=True)
    assert len(names) == 7 and set(counts) == {10}
    for (far, near), name in [*((iv, f"{iv[0]:g}-{iv[1]:g} km") for iv in APPROACH_INTERVALS_KM)]:
        ranges = track.range_m[np.array(track.interval) == name]
        assert np.all((ranges >= near * 1e3) & (ranges <= far * 1e3))
    hover = track.range_m[np.array(track.interval) == "hover 100 km"]
    np.testing.assert_allclose(hover, 100e3, rtol=1e-12)
    # Camera directions about the box centre, in the body frame: within an interval they
    # are a rotated Fibonacci lattice, as far apart as the lattice's nearest neighbours.
    R = matrix_from_quaternion(track.q_cam_from_body)
    camera_body = -np.einsum("nji,nj->ni", R, track.t_cam_from_body_m)
    directions = camera_body - CENTER_M
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    lattice = fibonacci_sphere(10)
    lattice_min = np.min(np.arccos(np.clip(lattice @ lattice.T, -1, 1))[~np.eye(10, dtype=bool)])
    for name in names:
        d = directions[np.array(track.interval) == name]
        angles = np.arccos(np.clip(d @ d.T, -1, 1))[~np.eye(10, dtype=bool)]
        assert np.min(angles) == pytest.approx(lattice_min, abs=1e-9)


def test_visibility_policies() -> None:
    # The approach example's orbit goes through the Earth's shadow at this epoch.
    base = {
        "observer": {"mode": "approach", "revolutions": 2},
        "sampler": {"kind": "sspt", "frame_count": 80},
        "orbit": {"semi_major_axis_km": 7078.0, "inclination_deg": 98.2, "raan_deg": 120.0},
        "epoch_utc": "2025-09-01T00:00:00Z",
    }
    flagged = scenario_with(**base)
    track = plan_track(flagged.plan_request(), CENTER_M)
    assert 0 < track.eclipsed.sum() < len(track)
    np.testing.assert_array_equal(track.eclipsed, track.sunlit_fraction < 1.0 - 1e-9)
    np.testing.assert_array_equal(
        frames_to_render(flagged.plan_request(), track), np.arange(len(track))
    )
    skip = scenario_with(**base, visibility={"on_fail": "skip"})
    np.testing.assert_array_equal(
        frames_to_render(skip.plan_request(), plan_track(skip.plan_request(), CENTER_M)),
        np.flatnonzero(track.visible),
    )
    keep = scenario_with(**base, visibility={"on_fail": "keep"})
    kept = plan_track(keep.plan_request(), CENTER_M)
    assert kept.visible.all()
    np.testing.assert_array_equal(kept.sunlit_fraction, track.sunlit_fraction)


def test_frame_light_scales_the_sun_by_distance_and_shadow() -> None:
    scenario = scenario_with(
        observer={"mode": "approach", "revolutions": 2},
        sampler={"kind": "sspt", "frame_count": 80},
        orbit={"semi_major_axis_km": 7078.0, "inclination_deg": 98.2, "raan_deg": 120.0},
        epoch_utc="2025-09-01T00:00:00Z",
    )
    track = plan_track(scenario.plan_request(), CENTER_M)
    at_1_au = band_irradiance_w_m2(scenario.sun.band_nm, scenario.sun.spectrum, 1.0)
    for i in (int(np.argmin(track.eclipsed)), int(np.argmax(track.eclipsed))):
        light = frame_light(scenario, track, i)
        sun = light.sun
        full = at_1_au * (AU_M / track.sun_distance_m[i]) ** 2
        assert sun.irradiance_w_m2 == pytest.approx(full * track.sunlit_fraction[i], rel=1e-12)
        assert light.sun_irradiance_w_m2 == sun.irradiance_w_m2
        np.testing.assert_array_equal(sun.direction_body, light.sun_direction_body)
        np.testing.assert_allclose(
            sun.direction_body, body_from_cam(track, i) @ track.sun_from_target_cam[i]
        )
        if not track.eclipsed[i]:
            # Sunlit: the target sees part of the Earth's day side.
            assert np.all(light.sh_radiance_w_m2_sr[0] > 0.0)


def test_views_in_the_body_frame_keep_their_poses() -> None:
    from satsight.cli import example_scenario_path

    scenario = load_scenario(example_scenario_path())
    track = plan_track(scenario.plan_request(), CENTER_M)
    sun_body = scenario.sun.build().direction_body
    for i, frame in enumerate(scenario.frames):
        pose = frame.build().cam_from_body(CENTER_M)
        np.testing.assert_allclose(track.cam_from_body(i).R_a_from_b, pose.R_a_from_b, atol=1e-12)
        np.testing.assert_allclose(track.t_cam_from_body_m[i], pose.t_a_from_b_m, atol=1e-9)
        np.testing.assert_allclose(track.sun_from_target_cam[i], pose.R_a_from_b @ sun_body)
        assert track.range_m[i] == pytest.approx(frame.distance_km * 1e3, rel=1e-12)
    assert isinstance(scenario.frames[0].build(), View)
    assert track.visible.all() and np.all(np.isnan(track.rho_rtn_m))
    # Views in the body frame have no sky.
    assert not track.has_sky and np.all(np.isnan(track.q_cam_from_gcrs))
    with pytest.raises(SatsightError, match="no inertial camera attitude"):
        track.R_cam_from_gcrs(0)


def test_frame_count_over_a_closed_orbit_leaves_out_the_repeated_view() -> None:
    track = plan_track(
        scenario_with(sampler={"kind": "sspt", "frame_count": 12}).plan_request(), CENTER_M
    )
    period = orbital_period_s(7000e3)
    np.testing.assert_allclose(track.time_s, np.arange(12) * period / 12, atol=1e-9)
    with_duration = scenario_with(sampler={"kind": "sspt", "frame_count": 12, "duration_s": period})
    assert plan_track(with_duration.plan_request(), CENTER_M).time_s[-1] == pytest.approx(
        period, abs=1e-9
    )


def test_a_camera_inside_the_earth_or_the_target_is_refused() -> None:
    from satsight.errors import SatsightError

    below = scenario_with(
        observer={"mode": "relative_rtn", "position_rtn_km": [-900.0, 0.0, 0.0]},
        sampler={"kind": "sspt", "frame_count": 3},
    )
    with pytest.raises(SatsightError, match="inside the Earth"):
        plan_track(below.plan_request(), CENTER_M)
    same_orbit = scenario_with(
        observer={"mode": "elements", "orbit": BASE["orbit"]},
        sampler={"kind": "sspt", "frame_count": 3},
    )
    with pytest.raises(SatsightError, match="inside its bounding sphere"):
        plan_track(same_orbit.plan_request(), CENTER_M, target_radius_m=5.0)
