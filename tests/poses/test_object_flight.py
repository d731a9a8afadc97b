"""Objects on their own flight: poses in the target's body frame against closed forms.

- An object on the target's own elements and attitude law sits at the target's origin,
  unturned, at every frame (the whole chain: propagation, attitude, frame change).
- An object started beside the target in RTN follows the Clohessy-Wiltshire solution
  (circular orbit, two-body) to within its linearisation's error: the neglected
  differential gravity is at most 3 n^2 |rho|^2 / r, so the drift after t is below
  3 n^2 |rho|^2 / r t^2 / 2 (8 mm for 120 m after 1500 s; 1.1 mm is seen).
- A spinning object's attitude is Exp of its rate times the time, and the rate is recovered.
- The pose carried over an exposure by its rates equals the pose propagated there, to
  within the relative acceleration the rates leave out.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from satsight.config.scenario import parse_scenario
from satsight.ephemeris.orbits import MU_EARTH_M3_S2
from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.poses.object_flight import object_poses
from satsight.poses.plan import target_states
from satsight.poses.pose_rates import rotation_from_vector

ONE_MM = 1e-3
ORBIT = {"semi_major_axis_km": 7000.0, "inclination_deg": 51.6, "raan_deg": 20.0}
BASE = {
    "name": "object-flight",
    "epoch_utc": "2025-06-21T06:00:00Z",
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "orbit": ORBIT,
    "attitude": {"law": "inertial"},
    "observer": {"mode": "fly_around", "radius_km": 0.2},
    "sampler": {"kind": "sspt", "frame_count": 4, "duration_s": 1500.0},
    "propagation": {"j2": False},
}
TIMES_S = np.array([0.0, 300.0, 750.0, 1500.0])


def _flight(target_attitude=None, **flight):
    data = copy.deepcopy(BASE)
    if target_attitude is not None:
        data["attitude"] = target_attitude
    data["objects"] = [{"name": "o", "procedural": {"satellite_class": "tango"}, "flight": flight}]
    scenario = parse_scenario(data, "test")
    return scenario.plan_request(), scenario.objects[0].flight.build()


def test_an_object_on_the_targets_orbit_and_law_sits_at_its_origin() -> None:
    lvlh = {"law": "lvlh_fixed"}
    request, flight = _flight(target_attitude=lvlh, orbit=ORBIT, attitude=lvlh)
    (poses,) = object_poses(request, [flight], TIMES_S)
    assert np.abs(poses.t_body_m).max() < 1e-6
    assert np.abs(poses.R_body_from_object - np.eye(3)).max() < 1e-12
    assert np.abs(poses.velocity_body_m_s).max() < 1e-9


def _cw_position_rtn(rho0, rho_dot0, n, t):
    """Clohessy-Wiltshire (Hill) solution, x radial, y along-track, z cross-track."""
    x0, y0, z0 = rho0
    vx, vy, vz = rho_dot0
    s, c = np.sin(n * t), np.cos(n * t)
    x = (4 - 3 * c) * x0 + s / n * vx + 2 / n * (1 - c) * vy
    y = 6 * (s - n * t) * x0 + y0 - 2 / n * (1 - c) * vx + (4 * s - 3 * n * t) / n * vy
    z = z0 * c + vz / n * s
    return np.stack([x, y, z], axis=-1)


def test_an_rtn_start_follows_the_clohessy_wiltshire_motion() -> None:
    rho0, rho_dot0 = np.array([20.0, -40.0, 30.0]), np.array([0.01, -0.02, 0.015])
    request, flight = _flight(position_rtn_m=rho0.tolist(), velocity_rtn_m_s=rho_dot0.tolist())
    (poses,) = object_poses(request, [flight], TIMES_S)
    r_t, v_t = target_states(request, TIMES_S)
    n = np.sqrt(MU_EARTH_M3_S2 / 7.0e6**3)
    expected_rtn = _cw_position_rtn(rho0, rho_dot0, n, TIMES_S)
    # The target is inertial with the identity attitude: body axes are GCRS axes.
    radial = r_t / np.linalg.norm(r_t, axis=1, keepdims=True)
    normal = np.cross(r_t, v_t)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    along = np.cross(normal, radial)
    R_gcrs_from_rtn = np.stack([radial, along, normal], axis=-1)
    expected_body = np.einsum("nij,nj->ni", R_gcrs_from_rtn, expected_rtn)
    range_m = np.linalg.norm(poses.t_body_m, axis=1).max()
    bound_m = 3 * n**2 * range_m**2 / 7.0e6 * TIMES_S**2 / 2 + ONE_MM / 100
    assert np.all(np.linalg.norm(poses.t_body_m - expected_body, axis=1) < bound_m)
    assert np.linalg.norm(poses.t_body_m[-1] - poses.t_body_m[0]) > 10.0  # it did move


def test_a_spinning_object_turns_at_its_rate() -> None:
    q0 = [np.cos(0.3), np.sin(0.3), 0.0, 0.0]
    rate_deg_s = np.array([1.0, -2.0, 3.0])
    request, flight = _flight(
        orbit=ORBIT,
        attitude={"law": "spinning", "q_ref_from_body": q0, "rate_body_deg_s": rate_deg_s.tolist()},
    )
    (poses,) = object_poses(request, [flight], TIMES_S)
    rate = np.radians(rate_deg_s)
    for k, t in enumerate(TIMES_S):
        expected = matrix_from_quaternion(np.array(q0)) @ rotation_from_vector(rate * t)
        assert np.abs(poses.R_body_from_object[k] - expected).max() < 1e-9
    assert np.abs(poses.omega_object_rad_s - rate).max() < 1e-9


@pytest.mark.parametrize("law", ["lvlh_fixed", "spinning"])
def test_the_pose_carried_over_an_exposure_matches_the_flight(law) -> None:
    attitude = {"law": law}
    if law == "spinning":
        attitude["rate_body_deg_s"] = [5.0, 0.0, 12.0]
    data = copy.deepcopy(BASE)
    data["attitude"] = {"law": "spinning", "rate_body_deg_s": [0.0, 8.0, -3.0]}
    data["objects"] = [
        {
            "name": "o",
            "debris": {"count": 3},
            "flight": {
                "position_rtn_m": [15.0, 60.0, -5.0],
                "velocity_rtn_m_s": [0.3, -0.2, 0.4],
                "attitude": attitude,
            },
        }
    ]
    scenario = parse_scenario(data, "test")
    request, flight = scenario.plan_request(), scenario.objects[0].flight.build()
    tau = 0.1
    (at, later) = (object_poses(request, [flight], TIMES_S + dt)[0] for dt in (0.0, tau))
    omega_body = np.radians([0.0, 8.0, -3.0])
    for k in range(len(TIMES_S)):
        carried = at.target_from_object(k, tau, omega_body)
        # The rates leave out the relative acceleration, differential gravity of at most
        # 3 n^2 |rho|: it moves the object by 3 n^2 |rho| tau^2 / 2 (~1 um here).
        n2 = MU_EARTH_M3_S2 / 7.0e6**3
        bound_m = 3 * n2 * np.linalg.norm(later.t_body_m[k]) * tau**2 / 2
        assert np.linalg.norm(carried.t_a_from_b_m - later.t_body_m[k]) < bound_m
        assert np.abs(carried.R_a_from_b - later.R_body_from_object[k]).max() < 1e-8


def test_object_flights_need_an_orbit_plan_and_one_start() -> None:
    data = copy.deepcopy(BASE)
    for key in ("epoch_utc", "orbit", "attitude", "observer", "sampler", "propagation"):
        data.pop(key)
    data["frames"] = [{"distance_km": 0.05}]
    data["objects"] = [
        {"name": "o", "debris": {"count": 2}, "flight": {"position_rtn_m": [0, 10, 0]}}
    ]
    with pytest.raises(SatsightError, match="frames planned from orbits"):
        parse_scenario(data, "test")
    views = parse_scenario({**data, "objects": []}, "test").plan_request()
    flight = _flight(position_rtn_m=[0, 10, 0])[1]
    with pytest.raises(SatsightError, match="frames planned from orbits"):
        object_poses(views, [flight], TIMES_S)
    bad = [
        ({"orbit": ORBIT, "position_rtn_m": [0, 1, 0]}, "exactly one"),
        ({}, "exactly one"),
        ({"orbit": ORBIT, "velocity_rtn_m_s": [0, 1, 0]}, "goes with position_rtn_m"),
    ]
    for flight, message in bad:
        with pytest.raises(SatsightError, match=message):
            _flight(**flight)
    data = copy.deepcopy(BASE)
    data["objects"] = [
        {"name": "o", "debris": {"count": 2}, "offset_m": [1, 0, 0],
         "flight": {"position_rtn_m": [0, 10, 0]}}
    ]  # fmt: skip
    with pytest.raises(SatsightError, match="leave out offset_m"):
        parse_scenario(data, "test")


def test_a_flight_beside_an_oem_target_reaches_the_files_last_instant() -> None:
    """An OEM target whose last frame is the file's last instant: the object is placed
    there too (nothing is looked up past the frames' times), and an RTN start 20 m along
    track stays about 20 m away over the two hours (natural motion carried in RTN)."""
    from satsight.config.scenario import load_scenario
    from satsight.pipeline import planned_frames

    examples = Path(__file__).resolve().parents[2] / "examples"
    data = load_scenario(examples / "oem_iss_hover.yaml").model_dump(mode="json", exclude_none=True)
    data["sampler"]["duration_s"] = 7200.0  # the file covers 16:40-18:40
    data["objects"] = [
        {"name": "o", "debris": {"count": 2}, "flight": {"position_rtn_m": [0.0, 20.0, 0.0]}}
    ]
    scenario = parse_scenario(data, "test")
    track, _ = planned_frames(scenario, scenario.target.build())
    assert track.time_s[-1] == 7200.0
    (poses,) = object_poses(
        scenario.plan_request(), [scenario.objects[0].flight.build()], track.time_s
    )
    distance = np.linalg.norm(poses.t_body_m, axis=1)
    assert np.all(np.abs(distance - 20.0) < 2.0)
