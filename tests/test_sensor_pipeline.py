"""A dataset planned from orbits, end to end through the sensor: DN frames with stars.

A small wide-field fly-around (1024 x 1024 px crops of the 0.7 m camera, four frames, a
fixed 50 ms exposure so that the stars stand well above the read noise, the target then
overexposed, so without blooming) is generated once;
every check reads the files it wrote.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from qe_oracle import blackbody_qe
from satsight.cli import main
from satsight.config.scenario import load_scenario, parse_scenario
from satsight.dataset.image_files import read_png
from satsight.pipeline import build_sensor, expose_frame, planned_frames
from satsight.render.buffers import RadianceImage
from satsight.sensor.star_catalog import load_star_catalog
from satsight.sensor.star_field import DEFAULT_STAMP_RADIUS_PX, stars_in_view

SCENARIO = {
    "name": "stars-e2e",
    "seed": 4,
    "epoch_utc": "2025-06-21T06:00:00Z",
    "camera": {
        "preset": "wide_field",
        "width_px": 1024,
        "height_px": 1024,
        "exposure": {"mode": "fixed", "time_s": 0.05},
        "detector": {"blooming": False},  # the overexposed target would bloom over stars
    },
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 3}},
    "orbit": {"semi_major_axis_km": 7000.0, "inclination_deg": 97.9},
    "observer": {"mode": "fly_around", "radius_km": 1.0},
    "sampler": {"kind": "sspt", "frame_count": 4, "start_s": 600.0, "duration_s": 2400.0},
    "visibility": {"on_fail": "keep"},
    "stars": {"v_mag_limit": 9.9},
    "render": {"bounces": 0},
}
BOX_RADIUS_PX = 4  # a 9 x 9 box holds > 98 % of a star's light at f/7 with 15 um pixels
SIGMA = 5.0


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("stars")
    config = folder / "scenario.yaml"
    config.write_text(yaml.safe_dump(SCENARIO), encoding="utf-8")
    out = folder / "dataset"
    main(["generate", str(config), "--out", str(out)])
    return out


@pytest.fixture(scope="module")
def labels(dataset: Path) -> dict:
    return json.loads((dataset / "labels.json").read_text(encoding="utf-8"))


def test_frames_carry_sensor_and_star_labels(labels) -> None:
    assert len(labels["frames"]) == 4
    assert labels["sensor"]["optics"]["aperture_diameter_m"] == 0.1
    for frame in labels["frames"]:
        assert frame["sensor"]["exposure_time_s"] == 0.05
        assert frame["star_count"] == len(frame["stars"])
    assert sum(frame["star_count"] for frame in labels["frames"]) > 0


def test_stars_appear_at_their_labelled_pixels_with_their_photon_count(dataset, labels) -> None:
    """The DN summed around each labelled star, less the bias, times the gain, is the
    star's mean photo-electrons QE N within the noise of that sum, QE the star's own
    (labelled; checked against its black body in the next test)."""
    detector = labels["sensor"]["detector"]
    gain, bias = detector["conversion_gain_e_per_dn"], detector["bias_dn"]
    pixel_var_e2 = detector["read_noise_e"] ** 2 + gain**2 / 12
    checked = 0
    for frame in labels["frames"]:
        dn = read_png(dataset / frame["files"]["dn_png16"]).astype(np.float64)
        mask = read_png(dataset / frame["files"]["object_mask_png"]) > 0
        stars = frame["stars"]
        full_well_dn = bias + detector["full_well_e"] / gain
        bloomed = np.any(dn >= 0.97 * full_well_dn, axis=0)
        for star in stars:
            x, y = round(star["x_px"]), round(star["y_px"])
            r = BOX_RADIUS_PX
            if not (r <= x < dn.shape[1] - r and r <= y < dn.shape[0] - r):
                continue  # the box would leave the frame
            box = (slice(y - r, y + r + 1), slice(x - r, x + r + 1))
            if mask[box].any():
                continue  # the target's light falls in the box
            if np.any(bloomed[box[1]]):
                continue  # the overexposed target's charge blooms down these columns
            others = [
                s
                for s in stars
                if s is not star and max(abs(s["x_px"] - x), abs(s["y_px"] - y)) < 2 * r
            ]
            if others:
                continue  # a neighbour's light falls in the box
            electrons = float(np.sum(dn[box] - bias)) * gain
            expected = star["quantum_efficiency"] * star["photons"]
            sigma = math.sqrt(expected + dn[box].size * pixel_var_e2)
            # The 9 x 9 box misses under 2 % of the light (the PSF's far wings).
            assert abs(electrons - 0.99 * expected) < SIGMA * sigma + 0.01 * expected, star
            checked += 1
    assert checked >= 3


def test_star_labels_are_the_catalogue_stars_in_view_less_those_behind_the_target(
    labels, dataset
) -> None:
    """Recompute each frame's stars without the target's mask: those whose centre falls on
    the target are the ones counted as hidden by it, the rest are the labelled stars, each
    with the QE of its black body (the curve's photon-weighted mean over the band, from the
    data files; 1e-5: that quadrature against the library's, < 1e-6)."""
    scenario = load_scenario(dataset / "scenario.yaml")
    sensor = build_sensor(scenario)
    track, indices = planned_frames(scenario, scenario.target.build())
    catalog = load_star_catalog(scenario.stars.v_mag_limit)
    compared = 0
    for frame, plan_index in zip(labels["frames"], indices, strict=True):
        mask = read_png(dataset / frame["files"]["object_mask_png"]) > 0
        stars = stars_in_view(
            catalog,
            track.R_cam_from_gcrs(plan_index),
            sensor.camera,
            track.epoch_utc[plan_index],
            track.camera_velocity_gcrs_m_s[plan_index],
            band_nm=sensor.band_nm,
            margin_px=DEFAULT_STAMP_RADIUS_PX + 0.5,
        )
        x, y = np.rint(stars.x_px).astype(int), np.rint(stars.y_px).astype(int)
        inside = (x >= 0) & (x < mask.shape[1]) & (y >= 0) & (y < mask.shape[0])
        on_target = np.zeros(len(stars), dtype=bool)
        on_target[inside] = mask[y[inside], x[inside]]
        # Stars behind the Earth or the Moon are not in this unoccluded list either way.
        assert frame["stars_hidden_by_target"] == int(on_target.sum())
        visible_ids = set(stars.source_id[~on_target].tolist())
        if frame["stars_hidden_by_earth_or_moon"] == 0:
            assert {s["source_id"] for s in frame["stars"]} == visible_ids
        temperature_k = dict(zip(stars.source_id.tolist(), stars.temperature_k, strict=True))
        drawn = [s for s in frame["stars"] if s["source_id"] in temperature_k]
        if drawn:
            own = np.array([temperature_k[s["source_id"]] for s in drawn])
            np.testing.assert_allclose(
                [s["quantum_efficiency"] for s in drawn],
                blackbody_qe(*sensor.band_nm, own),
                rtol=1e-5,
            )
        compared += frame["stars_hidden_by_earth_or_moon"] == 0
    assert compared >= 2
    # One frame looks past the Earth: its stars are hidden by it.
    assert sum(f["stars_hidden_by_earth_or_moon"] for f in labels["frames"]) > 0


def test_no_star_is_drawn_on_the_target(dataset, labels) -> None:
    for frame in labels["frames"]:
        mask = read_png(dataset / frame["files"]["object_mask_png"]) > 0
        for star in frame["stars"]:
            x, y = round(star["x_px"]), round(star["y_px"])
            if 0 <= x < mask.shape[1] and 0 <= y < mask.shape[0]:
                assert not mask[y, x]


def test_views_given_in_the_body_frame_get_no_stars() -> None:
    data = copy.deepcopy(SCENARIO)
    for key in ("epoch_utc", "orbit", "observer", "sampler", "visibility", "stars"):
        data.pop(key)
    data["camera"]["width_px"] = data["camera"]["height_px"] = 32
    data["frames"] = [{"distance_km": 1.0, "azimuth_deg": 0.0, "elevation_deg": 0.0}]
    scenario = parse_scenario(data, "test")
    mesh = scenario.target.build()
    track, _ = planned_frames(scenario, mesh)
    assert not track.has_sky
    sensor = build_sensor(scenario)
    blank = RadianceImage(
        radiance_w_m2_sr=np.zeros((32, 32, 3), np.float32),
        depth_m=np.zeros((32, 32), np.float32),
        part_id=np.zeros((32, 32), np.uint16),
        normals_cam=np.zeros((32, 32, 3), np.float32),
    )
    dn_image, sensor_labels = expose_frame(
        scenario, sensor, track, 0, blank, track.cam_from_body(0).apply(mesh.center_m)
    )
    assert sensor_labels["star_count"] == 0 and "stars" not in sensor_labels
    # Nothing but the bias and the read noise on the frame.
    noise_dn = sensor.detector.read_noise_e / sensor.detector.conversion_gain_e_per_dn
    assert abs(float(dn_image.dn.mean()) - sensor.detector.bias_dn) < 5 * noise_dn / 32 + 0.1
