"""Domain randomisation end to end: every group varies from frame to frame and is written
in the labels, the labels follow the drawn pose, the drawn sensor reaches the DN, and the
same scenario gives the same bytes twice and on two Dask workers."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import maximum_filter
from scipy.spatial.transform import Rotation
from scipy.stats import norm

from dataset_files import file_hashes
from satsight.config.scenario import parse_scenario
from satsight.dataset.reader import open_dataset
from satsight.dataset.stats import dataset_stats
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.pipeline import FrameEngine
from satsight.run.generation import generate_dataset
from satsight.scene.band_reflectance import library_materials
from satsight.scene.material_families import swap_candidates
from satsight.scene.material_library import LIBRARY_PREFIX

FRAMES = 4
SIZE_PX = (192, 144)
GROUPS = ("materials", "sun", "earth", "sensor", "pose")


def scenario_dict(exposure: dict | None = None) -> dict:
    """Four views of the two-wing satellite at 20 km (about 20 px across on the wide-field
    camera), every group randomised; a uniform Earth from GEO, out of view (its map is
    tested elsewhere)."""
    frames = [
        {"distance_km": 20.0, "azimuth_deg": 35.0 * i, "elevation_deg": 10.0 * i - 15.0}
        for i in range(FRAMES)
    ]
    camera = {"preset": "wide_field", "width_px": SIZE_PX[0], "height_px": SIZE_PX[1]}
    if exposure is not None:
        camera["exposure"] = exposure
    return {
        "name": "randomized",
        "seed": 11,
        "camera": camera,
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
        "earth": {"elevation_deg": -80.0, "altitude_km": 36000.0, "surface": "uniform"},
        "frames": frames,
        "render": {"bounces": 1},
        "randomize": {
            "materials": True,
            "sun": True,
            # The Earth stays out of view (behind the target: test_the_earth_moves_behind...).
            "earth": {"surface_map_probability": 0.0, "behind_probability": 0.0},
            "sensor": True,
            "pose": True,
        },
    }


@pytest.fixture(scope="module")
def engine_records() -> tuple[FrameEngine, list[dict], list]:
    engine = FrameEngine(parse_scenario(scenario_dict({"mode": "fixed", "time_s": 0.0005})))
    records, images = [], []
    for i in range(FRAMES):
        record, arrays, _ = engine.finish(engine.render(i))
        records.append(record)
        images.append(arrays)
    return engine, records, images


def _numbers(record: dict, group: str) -> dict[str, float]:
    values = record["randomized"][group]
    if group == "materials":
        return {
            f"{m}.{k}": v for m, d in values.items() for k, v in d.items() if isinstance(v, float)
        }
    return {k: v for k, v in values.items() if isinstance(v, float)}


def test_every_group_varies_from_frame_to_frame_and_is_recorded(engine_records) -> None:
    engine, records, _ = engine_records
    for record in records:
        # The MLI crinkle is drawn anew each frame (materials.reseed_textures).
        assert set(record["randomized"]) == {*GROUPS, "textures"}
        assert record["randomized"]["textures"] == {"reseeded_parts": ["bus_mli"]}
        assert set(record["randomized"]["materials"]) == set(engine.mesh.part_materials)
    for group in GROUPS:
        names = _numbers(records[0], group)
        assert names, group
        for name in names:
            values = [_numbers(r, group)[name] for r in records]
            if name == "behind_offset_rad":  # 0: the Earth stays put here (tested below)
                continue
            if not name.endswith(("roughness", "ior")) or "scale" in name or "shift" in name:
                assert len(set(values)) == FRAMES, (group, name, values)


def test_the_labels_follow_the_drawn_pose(engine_records) -> None:
    """The labelled pose is the planned one with the target turned about its box centre
    and the camera rolled about its boresight, built here with scipy's rotations."""
    engine, records, _ = engine_records
    c = engine.mesh.center_m
    for i, record in enumerate(records):
        planned = engine.track.cam_from_body(int(engine.plan_indices[i]))
        pose = record["randomized"]["pose"]
        jitter = Rotation.from_rotvec(
            np.asarray(pose["jitter_axis_body"]) * pose["attitude_jitter_rad"]
        ).as_matrix()
        roll = Rotation.from_rotvec([0.0, 0.0, -pose["roll_rad"]]).as_matrix()
        R = roll @ planned.R_a_from_b @ jitter
        t = roll @ (planned.R_a_from_b @ (c - jitter @ c) + planned.t_a_from_b_m)
        np.testing.assert_allclose(
            matrix_from_quaternion(np.asarray(record["q_cam_from_body"])), R, atol=1e-12
        )
        np.testing.assert_allclose(record["t_cam_from_body_m"], t, rtol=0, atol=1e-9)
        # The box centre stays on the boresight (the views look at it).
        np.testing.assert_allclose(record["box_keypoints_px"][-1][:2], [
            (SIZE_PX[0] - 1) / 2, (SIZE_PX[1] - 1) / 2], atol=1e-6)  # fmt: skip
        # The Sun keeps its place in the sky while the target turns under it and the
        # camera rolls: in the plan's camera frame it is the plan's direction turned by the
        # drawn jitter angle alone.
        sun_planned_cam = roll.T @ np.asarray(record["sun_direction_cam"])
        planned_sun = engine.track.sun_from_target_cam[int(engine.plan_indices[i])]
        angle = math.atan2(
            np.linalg.norm(np.cross(sun_planned_cam, planned_sun)), sun_planned_cam @ planned_sun
        )
        assert angle == pytest.approx(record["randomized"]["sun"]["direction_jitter_rad"], abs=1e-9)
        np.testing.assert_allclose(
            R @ np.asarray(record["sun_direction_body"]), record["sun_direction_cam"], atol=1e-9
        )


def test_the_drawn_sensor_reaches_the_dn(engine_records) -> None:
    """Fixed exposure: the time is 0.5 ms x the drawn factor; the empty sky is bias plus
    the drawn read noise over the drawn gain, rounded to whole DN, within its sampling
    error."""
    engine, records, images = engine_records
    bias = engine.sensor.detector.bias_dn
    for record, arrays in zip(records, images, strict=True):
        drawn = record["randomized"]["sensor"]
        assert record["sensor"]["exposure_time_s"] == pytest.approx(
            0.0005 * drawn["exposure_factor"], rel=1e-14
        )
        dn = arrays.dn_image.dn.astype(np.float64)
        lit = arrays.image.radiance_w_m2_sr.max(axis=2) > 0
        # Beyond the blur's reach: the frame kernel's 20 px plus the drawn defocus (<= 1 px)
        # and jitter (<= 0.4 px at 4 sigma), with room to spare; not in a column with a
        # saturated pixel (blooming spills along columns).
        full = dn >= bias + 0.97 * (arrays.dn_image.full_well_dn - bias)
        sky = dn[~maximum_filter(lit, size=81) & ~full.any(axis=0)[None, :]]
        assert sky.size > 10000
        sigma = _rounded_gaussian_std_dn(drawn["read_noise_e"] / drawn["conversion_gain_e_per_dn"])
        # The sample standard deviation's standard error is sigma / sqrt(2 n).
        assert sky.std() == pytest.approx(sigma, rel=5 / math.sqrt(2 * sky.size))
        assert abs(sky.mean() - bias) < 5 * sigma / math.sqrt(sky.size)


def _rounded_gaussian_std_dn(sigma_dn: float) -> float:
    """Standard deviation of round(x), x normal with mean 0 (the bias is whole) and
    ``sigma_dn``: the exact sum over the DN values, not Sheppard's sqrt(s^2 + 1/12), which
    is 2 % off at s = 0.47 DN."""
    k = np.arange(-60, 61)
    p = norm.cdf((k + 0.5) / sigma_dn) - norm.cdf((k - 0.5) / sigma_dn)
    return float(math.sqrt(np.sum(p * k**2)))


def test_the_sun_irradiance_label_follows_the_drawn_scale(engine_records) -> None:
    engine, records, _ = engine_records
    base = engine.scenario.sun.in_band_irradiance_w_m2
    for record in records:
        scale = record["randomized"]["sun"]["irradiance_scale"]
        assert record["sun_irradiance_w_m2"] == pytest.approx(base * scale, rel=1e-12)
        assert 0.0 < record["randomized"]["sun"]["direction_jitter_rad"] <= math.radians(5.0)


@pytest.fixture(scope="module")
def randomized_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("randomized") / "dataset"
    return generate_dataset(parse_scenario(scenario_dict()), out).out_dir


def test_the_same_scenario_gives_the_same_bytes_twice_and_on_two_workers(
    randomized_dataset: Path, tmp_path: Path
) -> None:
    scenario = parse_scenario(scenario_dict())
    first = file_hashes(randomized_dataset)
    assert file_hashes(generate_dataset(scenario, tmp_path / "b").out_dir) == first
    assert file_hashes(generate_dataset(scenario, tmp_path / "c", workers=2).out_dir) == first


def test_stats_histogram_every_drawn_value(randomized_dataset: Path) -> None:
    """One histogram per randomised number, each counting every frame (each material's
    draws pooled over the materials), with the labels' own extremes."""
    stats = dataset_stats(open_dataset(randomized_dataset))
    histograms = stats["histograms"]
    journal = (randomized_dataset / "journal.jsonl").read_text(encoding="utf-8")
    frames = [json.loads(line) for line in journal.splitlines()]
    materials = len(frames[0]["randomized"]["materials"])
    for group in GROUPS:
        for key in ("exposure_factor", "roll_rad", "irradiance_scale", "albedo_scale"):
            name = f"randomized.{group}.{key}"
            if name in histograms:
                values = [f["randomized"][group][key] for f in frames]
                assert sum(histograms[name]["counts"]) == FRAMES
                assert histograms[name]["min"] == min(values)
                assert histograms[name]["max"] == max(values)
                assert histograms[name]["missing"] == 0
    assert {"randomized.sensor.exposure_factor", "randomized.pose.roll_rad"} <= set(histograms)
    pooled = histograms["randomized.materials.roughness_scale"]
    assert sum(pooled["counts"]) == FRAMES * materials
    assert histograms["randomized.pose.roll_rad"]["unit"] == "rad"
    assert histograms["randomized.sensor.read_noise_e"]["unit"] == "e-"


def test_swapped_materials_come_from_their_family_and_are_rendered(engine_records) -> None:
    """A swapped material is another library material of its family, and the frame's
    recorded values are that material's, varied by the drawn factors."""
    engine, records, _ = engine_records
    swaps = 0
    for record in records:
        for name, values in record["randomized"]["materials"].items():
            swapped = values["library_material"]
            if swapped is None:
                continue
            swaps += 1
            assert swapped in swap_candidates(name)
            library = library_materials([swapped], engine.scenario.sun.band_nm)
            base = library[LIBRARY_PREFIX + swapped]
            assert values["roughness"] == pytest.approx(
                min(1.0, max(0.02, base.roughness * values["roughness_scale"])), rel=1e-12
            )
    # 4 frames x 9 materials with a family of two or more, each swapped with p = 0.25:
    # none at all would happen with probability 0.75^36 = 3e-5.
    assert swaps > 0


def test_each_frame_renders_its_own_crinkle(engine_records) -> None:
    """The renderers of two frames hold the bus's MLI normal map drawn from each frame's
    own texture seed: different wrinkles, the other parts' textures the same."""
    engine, _, _ = engine_records
    variation = engine.variation
    meshes = []
    for plan in (0, 1):
        draws = variation.draw(plan)
        meshes.append(variation.renderer(engine.renderer, draws).mesh)
    k = engine.mesh.part_names.index("bus_mli")
    first, second = (m.part_textures[k].normal.pixels for m in meshes)
    assert not np.array_equal(first, second)
    assert not np.array_equal(first, engine.mesh.part_textures[k].normal.pixels)


def test_the_earth_moves_behind_the_target_on_hand_placed_views() -> None:
    """With behind_probability 1 the Earth's centre lies within 0.8 of its angular radius
    of each frame's line of sight (a uniform Earth from GEO: 8.7 deg), as recorded, and
    the frame shows the Earth all around the target (background id 1 on every pixel of a
    ring 3 px outside its mask); the target's own pixels and pose do not change."""
    from scipy import ndimage

    from satsight.constants import EARTH_MEAN_RADIUS_M
    from satsight.randomization.ranges import EARTH_BEHIND_CAP_FRACTION

    base = scenario_dict({"mode": "fixed", "time_s": 0.0005})
    base["randomize"] = {"earth": {"surface_map_probability": 0.0, "behind_probability": 1.0}}
    engine = FrameEngine(parse_scenario(base, "test"))
    plain = FrameEngine(parse_scenario({**base, "randomize": {}}, "test"))
    radius = math.asin(EARTH_MEAN_RADIUS_M / (EARTH_MEAN_RADIUS_M + 36_000e3))
    for i in range(2):
        frame = engine.render(i)
        record, _, _ = engine.finish(frame)
        earth = record["randomized"]["earth"]
        assert earth["behind"] is True
        assert 0.0 <= earth["behind_offset_rad"] <= EARTH_BEHIND_CAP_FRACTION * radius
        (body,) = [b for b in frame.light.bodies if b.name == "earth"]
        to_earth_cam = frame.cam_from_body.R_a_from_b @ (body.center_body_m - engine.mesh.center_m)
        off_axis = math.acos(to_earth_cam[2] / np.linalg.norm(to_earth_cam))
        assert off_axis == pytest.approx(earth["behind_offset_rad"], abs=2e-4)
        mask = frame.image.object_mask
        ring = ndimage.binary_dilation(mask, iterations=4) & ~ndimage.binary_dilation(
            mask, iterations=2
        )
        assert ring.sum() > 20 and np.all(frame.image.background_id[ring] == 1)
        bare = plain.render(i)
        assert np.array_equal(bare.image.object_mask, mask)
        assert not np.any(bare.image.background_id == 1)  # the scenario's Earth: out of view


def test_a_drawn_cloud_cover_reaches_the_frames_earth_map() -> None:
    """``cloud_fraction: [0.6, 0.65]`` draws one of its two levels per frame; the frame's
    Earth is lit from the map built for that cover (its description holds it), recorded
    under ``randomized.earth.cloud_fraction``, and each map keeps the Bond albedo 0.30 as
    its area mean (the cloud albedo is calibrated per cover; 16-bit map values)."""
    from satsight.lighting.earth_surface import BOND_ALBEDO, map_mean_albedo

    base = scenario_dict({"mode": "fixed", "time_s": 0.0005})
    base["earth"] = {**base["earth"], "surface": "map"}
    base["randomize"] = {
        "earth": {"surface_map_probability": 1.0, "behind_probability": 0.0,
                  "cloud_fraction": [0.6, 0.65]},
    }  # fmt: skip
    engine = FrameEngine(parse_scenario(base, "test"))
    seen = {}
    for i in range(FRAMES):
        frame = engine.render(i)
        record, _, _ = engine.finish(frame)
        cover = record["randomized"]["earth"]["cloud_fraction"]
        assert cover in (0.6, 0.65)
        (earth,) = [b for b in frame.light.bodies if b.name == "earth"]
        assert f'"cloud_fraction": {cover}' in earth.albedo_map.description
        assert map_mean_albedo(earth.albedo_map) == pytest.approx(BOND_ALBEDO, abs=1e-4)
        seen[cover] = earth.albedo_map.albedo_rgb
    assert set(seen) == {0.6, 0.65}  # the seeded draws give both levels in four frames
    assert not np.array_equal(seen[0.6], seen[0.65])
