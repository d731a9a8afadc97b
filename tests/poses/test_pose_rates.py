"""The plan's pose rates (``satsight.poses.pose_rates``) against the planned motion itself.

A fly-by planned with frames 0.1 s apart around its closest approach: the rotation between
neighbouring frames (propagated orbits, pointed anew at each frame; SciPy's rotation vector)
is the recorded rate times 0.1 s, and the pose at +0.1 s from a frame's rates is the next
frame's. A spinning target's recorded body rate is its law's rate.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from satsight.config.scenario import parse_scenario
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.poses.plan import plan_track
from satsight.poses.pose_rates import (
    pose_at_offset,
    poses_at_offsets,
    rotation_from_vector,
    rotation_vector,
    rotations_from_vectors,
    track_at_offset,
)

STEP_S = 0.1
# Frames 0.1 s apart ~100 m from the target at closest approach: the camera turns at
# ~5.5e-4 rad/s (the co-elliptic drift). The plan's differences move both craft along their
# velocities without acceleration, so they miss the turn of the roll reference (the orbit
# normal) under J2: |r x a_J2| / |r x v| ~ 7e6 m x 1e-2 m/s^2 / 5.3e10 m^2/s ~ 1.3e-6 rad/s
# (5e-8 rad over half a 0.2 s exposure).
RATE_ATOL_RAD_S = 1.5e-6
# The pose 0.1 s on from the rates: the rotation's neglected alpha dt^2 / 2 < 1e-9 rad; the
# translation's neglected acceleration (differential gravity ~ n^2 rho ~ 1e-4 m/s^2, the
# frame's turn w^2 rho ~ 3e-5 m/s^2) x dt^2 / 2 ~ 1e-6 m.
ANGLE_TOL_RAD = 5e-6
TRANSLATION_TOL_M = 1e-4


def _fly_by(start_s: float, attitude: dict) -> dict:
    return {
        "name": "rates",
        "seed": 1,
        "epoch_utc": "2025-03-20T12:00:00Z",
        "camera": {"preset": "high_resolution", "width_px": 64, "height_px": 64},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
        "orbit": {"semi_major_axis_km": 6878.0, "eccentricity": 0.001, "inclination_deg": 51.6,
                  "raan_deg": 30.0, "arg_perigee_deg": 0.0, "true_anomaly_deg": 0.0},
        "attitude": attitude,
        "observer": {"mode": "fly_by", "miss_distance_km": 0.1, "start_along_track_km": 1.0},
        "sampler": {"kind": "sspt", "start_s": start_s, "duration_s": 1.0, "step_s": STEP_S},
        "visibility": {"on_fail": "flag"},
        "stars": {"enabled": False},
    }  # fmt: skip


def _track(start_s: float, attitude: dict | None = None):
    scenario = parse_scenario(_fly_by(start_s, attitude or {"law": "lvlh_fixed"}), "test")
    return plan_track(scenario.plan_request(), np.zeros(3))


@pytest.fixture(scope="module")
def fly_by():
    # The closest approach of the pass, from a coarse plan of it.
    coarse = parse_scenario(_fly_by(0.0, {"law": "lvlh_fixed"}), "test")
    sampler = coarse.sampler.model_copy(update={"duration_s": None, "step_s": None,
                                                "frame_count": 400})  # fmt: skip
    track = plan_track(coarse.model_copy(update={"sampler": sampler}).plan_request(), np.zeros(3))
    closest = float(track.time_s[np.argmin(track.range_m)])
    return _track(closest - 0.5)


def test_the_camera_rate_is_the_turn_between_neighbouring_frames(fly_by) -> None:
    R_gcrs_from_cam = np.swapaxes(matrix_from_quaternion(fly_by.q_cam_from_gcrs), -1, -2)
    turn = Rotation.from_matrix(np.swapaxes(R_gcrs_from_cam[:-1], -1, -2) @ R_gcrs_from_cam[1:])
    measured = turn.as_rotvec() / STEP_S
    recorded = 0.5 * (fly_by.omega_cam_rad_s[:-1] + fly_by.omega_cam_rad_s[1:])
    assert np.linalg.norm(measured, axis=1).min() > 1e-4  # the camera does turn
    np.testing.assert_allclose(recorded, measured, rtol=0, atol=RATE_ATOL_RAD_S)
    # The translation's rate: central differences of the planned frames.
    dt_m = fly_by.t_cam_from_body_m[2:] - fly_by.t_cam_from_body_m[:-2]
    np.testing.assert_allclose(fly_by.t_dot_cam_from_body_m_s[1:-1], dt_m / (2 * STEP_S), atol=1e-4)


def test_the_pose_a_step_on_from_the_rates_is_the_next_frame(fly_by) -> None:
    for k in range(len(fly_by) - 1):
        R, t = pose_at_offset(fly_by, k, STEP_S)
        R_next = matrix_from_quaternion(fly_by.q_cam_from_body[k + 1])
        angle = np.linalg.norm(Rotation.from_matrix(R.T @ R_next).as_rotvec())
        assert angle < ANGLE_TOL_RAD
        np.testing.assert_allclose(t, fly_by.t_cam_from_body_m[k + 1], atol=TRANSLATION_TOL_M)


def test_a_spinning_target_records_its_law_s_rate(fly_by) -> None:
    rate_deg_s = (3.0, -20.0, 7.0)
    track = _track(float(fly_by.time_s[0]), {"law": "spinning", "rate_body_deg_s": rate_deg_s})
    np.testing.assert_allclose(
        track.omega_body_rad_s, np.tile(np.radians(rate_deg_s), (len(track), 1)), atol=1e-12
    )


def test_views_in_the_body_frame_do_not_move() -> None:
    scenario = parse_scenario(
        {
            "name": "still",
            "camera": {"preset": "high_resolution", "width_px": 64, "height_px": 64},
            "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
            "frames": [{"distance_km": 0.1}],
        },
        "test",
    )
    track = plan_track(scenario.plan_request(), np.zeros(3))
    for name in ("omega_cam_rad_s", "omega_body_rad_s", "t_dot_cam_from_body_m_s"):
        assert not np.any(getattr(track, name))


def test_poses_at_many_offsets_are_those_at_each(fly_by) -> None:
    offsets = np.linspace(-0.1, 0.1, 17)
    for k in (0, len(fly_by) // 2, len(fly_by) - 1):
        R, t = poses_at_offsets(fly_by, k, offsets)
        assert R.shape == (17, 3, 3) and t.shape == (17, 3)
        R0 = matrix_from_quaternion(fly_by.q_cam_from_body[k])
        for i, tau in enumerate(offsets):
            # The module's formula, with scipy's exponential map.
            turn_cam = Rotation.from_rotvec(-fly_by.omega_cam_rad_s[k] * tau).as_matrix()
            turn_body = Rotation.from_rotvec(fly_by.omega_body_rad_s[k] * tau).as_matrix()
            np.testing.assert_allclose(R[i], turn_cam @ R0 @ turn_body, rtol=0, atol=1e-14)
            t_expected = fly_by.t_cam_from_body_m[k] + fly_by.t_dot_cam_from_body_m_s[k] * tau
            np.testing.assert_allclose(t[i], t_expected, rtol=1e-15, atol=1e-12)
            R_one, t_one = pose_at_offset(fly_by, k, tau)
            assert np.array_equal(R_one, R[i]) and np.array_equal(t_one, t[i])
        assert np.array_equal(R[8], matrix_from_quaternion(fly_by.q_cam_from_body[k]))  # tau 0


def test_rotation_vectors_round_trip_through_the_exponential_map() -> None:
    rng = np.random.default_rng(4)
    for w in rng.normal(size=(20, 3)):
        w = w / np.linalg.norm(w) * rng.uniform(0.0, 3.0)
        R = rotation_from_vector(w)
        np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), atol=1e-12)
        q = Rotation.from_rotvec(w).as_quat(scalar_first=True)
        np.testing.assert_allclose(rotation_vector(q), w, atol=1e-12)
    many = rng.normal(size=(50, 3)) * rng.uniform(0.0, 1.0, size=(50, 1))
    many[7] = 0.0  # the identity
    many[9] = 1e-16
    np.testing.assert_allclose(
        rotations_from_vectors(many), Rotation.from_rotvec(many).as_matrix(), rtol=0, atol=1e-12
    )
    assert np.array_equal(rotations_from_vectors(many)[7], np.eye(3))


def test_the_sun_turns_in_body_axes_with_the_target_alone() -> None:
    # A direction fixed in inertial axes (the Sun) seen from the body frame at tau: turned
    # by -w_b tau when the target spins, unmoved when only the camera turns.
    scenario = parse_scenario(
        {
            "name": "sun",
            "camera": {"preset": "high_resolution", "width_px": 64, "height_px": 64},
            "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
            "sun": {"azimuth_deg": 40.0, "elevation_deg": 25.0},
            "frames": [{"distance_km": 0.1, "azimuth_deg": 30.0, "elevation_deg": 10.0}],
        },
        "test",
    )
    track = plan_track(scenario.plan_request(), np.zeros(3))

    def sun_body(moving, tau: float) -> np.ndarray:
        moved = track_at_offset(moving, 0, tau)
        return matrix_from_quaternion(moved.q_cam_from_body[0]).T @ moved.sun_from_target_cam[0]

    w_body, w_cam, tau = np.array([0.1, -0.3, 0.2]), np.array([0.02, 0.05, -0.4]), 0.1
    spinning = dataclasses.replace(track, omega_body_rad_s=w_body[None, :])
    turning = dataclasses.replace(track, omega_cam_rad_s=w_cam[None, :])
    start = sun_body(track, 0.0)
    expected = Rotation.from_rotvec(-w_body * tau).apply(start)
    np.testing.assert_allclose(sun_body(spinning, tau), expected, atol=1e-12)
    np.testing.assert_allclose(sun_body(turning, tau), start, atol=1e-12)
