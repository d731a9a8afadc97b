"""Star trails (``satsight.sensor.frame_stars``): a camera turning at w about its y axis
during an exposure T moves each star along image x by w T f px (f the focal length in
pixels; 1 + (u / f)^2 more at u px off-centre, < 0.2 % here). The trail is the mean of n
stamps at the midpoints of n strata, so along x the star's photon distribution gains the
variance of n evenly spaced points over L, L^2 (1 - 1 / n^2) / 12, and keeps its photons.

A 256 px camera with a 5 cm f/4 lens (15 um pixels, f = 3333 px, a 4.4 degree field) on the
fly-around of ``tests/test_pipeline.py``: some tens of catalogue stars in view.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from satsight.config.scenario import parse_scenario
from satsight.pipeline import FrameEngine
from satsight.sensor.frame_stars import add_frame_stars, star_trail_offsets_s

SIZE_PX = 256
F_PX = 0.05 / 15e-6
EXPOSURE_S = 0.1
TRAIL_PX = 12.0
OMEGA_RAD_S = TRAIL_PX / (EXPOSURE_S * F_PX)
V_MAG_LIMIT = 7.5
# Around each star: the trail's half length, the stamp and a margin.
WINDOW_PX = 24
# Another star's light stays this far (px) from its own: window + half a trail + stamp.
ISOLATION_PX = 48


SCENARIO = {
    "name": "trails",
    "seed": 2,
    "epoch_utc": "2025-06-21T06:00:00Z",
    "camera": {"preset": "wide_field", "focal_length_m": 0.05,
               "optics": {"aperture_diameter_m": 0.0125},
               "width_px": SIZE_PX, "height_px": SIZE_PX},
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 3}},
    "orbit": {"semi_major_axis_km": 7000.0, "eccentricity": 0.0,
              "inclination_deg": 97.9, "raan_deg": 0.0, "arg_perigee_deg": 0.0,
              "true_anomaly_deg": 0.0},
    "attitude": {"law": "lvlh_fixed"},
    "observer": {"mode": "fly_around", "radius_km": 1.0, "camera_roll": "orbit_normal"},
    "sampler": {"kind": "sspt", "step_deg": 60.0},
    "visibility": {"on_fail": "flag"},
}  # fmt: skip


@pytest.fixture(scope="module")
def engine() -> FrameEngine:
    return FrameEngine(parse_scenario(SCENARIO, "test"))


def _stars(engine: FrameEngine, index: int, omega_cam: np.ndarray):
    track = engine.track.select(np.array([index]))
    track = dataclasses.replace(track, omega_cam_rad_s=omega_cam[None, :])
    irradiance = np.zeros((SIZE_PX, SIZE_PX), dtype=np.float32)
    mask = np.zeros((SIZE_PX, SIZE_PX), dtype=bool)
    labels = add_frame_stars(
        engine.sensor, track, 0, irradiance, mask, track.t_cam_from_body_m[0], EXPOSURE_S,
        V_MAG_LIMIT, 100e3,
    )  # fmt: skip
    return irradiance.astype(np.float64), labels


def _isolated(labels: dict) -> list[tuple[float, float]]:
    """Star positions (x, y) with no other star's light in their window (none within
    ``ISOLATION_PX``) and the whole window inside the frame."""
    xy = np.array([(s["x_px"], s["y_px"]) for s in labels["stars"]]).reshape(-1, 2)
    keep = []
    for i, (x, y) in enumerate(xy):
        others = np.delete(xy, i, axis=0)
        alone = others.size == 0 or np.min(np.abs(others - (x, y)).max(axis=1)) > ISOLATION_PX
        inside = WINDOW_PX <= min(x, y) and max(x, y) <= SIZE_PX - 1 - WINDOW_PX
        if alone and inside:
            keep.append((float(x), float(y)))
    return keep


def _moments_x(image: np.ndarray) -> tuple[float, float]:
    """Photon-weighted mean column and variance along x (px, px^2) of a window."""
    profile = image.sum(axis=0)
    columns = np.arange(profile.size, dtype=np.float64)
    mean = float(np.sum(profile * columns) / profile.sum())
    return mean, float(np.sum(profile * (columns - mean) ** 2) / profile.sum())


def test_stars_trail_along_the_camera_s_turn_and_keep_their_photons(engine) -> None:
    counts = [len(_isolated(_stars(engine, i, np.zeros(3))[1])) for i in range(len(engine.track))]
    index = int(np.argmax(counts))
    still, labels = _stars(engine, index, np.zeros(3))
    trailed, trailed_labels = _stars(engine, index, np.array([0.0, OMEGA_RAD_S, 0.0]))
    n = len(star_trail_offsets_s(np.array([0.0, OMEGA_RAD_S, 0.0]), F_PX, EXPOSURE_S))
    assert n == int(np.ceil(TRAIL_PX / 0.5))
    stars = _isolated(labels)
    assert len(stars) >= 3
    for x, y in stars:
        xi, yi = round(x), round(y)
        window = (
            slice(yi - WINDOW_PX, yi + WINDOW_PX + 1),
            slice(xi - WINDOW_PX, xi + WINDOW_PX + 1),
        )
        a, b = still[window], trailed[window]
        assert b.sum() == pytest.approx(a.sum(), rel=1e-5)
        (_, v0), (m1, v1) = _moments_x(a), _moments_x(b)
        u = x - (SIZE_PX - 1) / 2
        expected = TRAIL_PX * (1.0 + (u / F_PX) ** 2)
        # This lens' PSF is narrower than a pixel: a stamp's variance along x is 0 to 1/4 px^2
        # and its centroid up to 0.3 px off by its sub-pixel phase, so the still's and the
        # trail's pixelation carry a few px^2 against L^2 = 144 px^2 (2.5 % on L), and the
        # trail's centre (phases averaged) is the star's mid-exposure position within 0.15 px.
        assert np.sqrt(12.0 * (v1 - v0) / (1.0 - 1.0 / n**2)) == pytest.approx(expected, rel=0.025)
        assert m1 == pytest.approx(x - (xi - WINDOW_PX), abs=0.15)
    assert trailed_labels["star_count"] == labels["star_count"]
