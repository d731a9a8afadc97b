"""Both camera modes in one scenario: the wide-field camera beyond a switch range, the
high-resolution one within it (the paper switches at 20 km), on one detector."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.config.scenario import parse_scenario
from satsight.dataset.reader import open_dataset
from satsight.dataset.validate import validate_dataset
from satsight.run.generation import generate_dataset

SIZE_PX = 96
SCENARIO = {
    "name": "dual-mode",
    "seed": 2,
    "camera": {
        "preset": "high_resolution",
        "width_px": SIZE_PX,
        "height_px": SIZE_PX,
        "far": {"preset": "wide_field", "switch_range_km": 20},
    },
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "frames": [
        {"distance_km": 30.0, "azimuth_deg": 20, "elevation_deg": 10},
        {"distance_km": 19.0, "azimuth_deg": 20, "elevation_deg": 10},
        {"distance_km": 25.0, "azimuth_deg": 120, "elevation_deg": -10},
    ],
    "render": {"bounces": 0},
    "outputs": {"files": ["dn", "masks"]},
}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("modes") / "dataset"
    generate_dataset(parse_scenario(SCENARIO, "test"), out)
    return out


def test_each_frame_records_the_camera_that_took_it(dataset: Path) -> None:
    opened = open_dataset(dataset)
    high = PinholeCamera.high_resolution().with_size(SIZE_PX, SIZE_PX)
    wide = PinholeCamera.wide_field().with_size(SIZE_PX, SIZE_PX)
    expected = ["far", "primary", "far"]  # 30 and 25 km beyond the 20 km switch, 19 within
    for frame, mode in zip(opened.frames, expected, strict=True):
        assert frame["camera_mode"] == mode
        camera = wide if mode == "far" else high
        np.testing.assert_allclose(frame["K"], camera.K, rtol=1e-12)
    header = opened.header
    assert header["far_camera"]["switch_range_m"] == 20_000.0
    np.testing.assert_allclose(header["far_camera"]["camera"]["K"], wide.K, rtol=1e-12)
    np.testing.assert_allclose(header["camera"]["K"], high.K, rtol=1e-12)
    # The far frames are seen through the wide-field optics (f/7), the near ones at f/10.
    assert header["far_camera"]["sensor"]["f_number"] == pytest.approx(7.0)
    assert header["sensor"]["f_number"] == pytest.approx(10.0)


def test_the_target_is_smaller_in_the_wide_field_frames(dataset: Path) -> None:
    """The same view at 30 km through f = 0.7 m and at 19 km through f = 3 m: the mask areas
    scale with (f / d)^2. The far mask is ~12 px across, so its pixel count is uncertain by
    about its perimeter over its area (~25 %)."""
    frames = open_dataset(dataset).frames
    far, near = frames[0]["object_pixel_count"], frames[1]["object_pixel_count"]
    assert far > 0 and near > 0
    expected_ratio = ((0.7 / 30.0) / (3.0 / 19.0)) ** 2
    assert far / near == pytest.approx(expected_ratio, rel=0.25)


def test_a_dual_mode_dataset_validates(dataset: Path) -> None:
    report = validate_dataset(dataset)
    assert report.ok, [str(p) for p in report.findings.problems]


def test_a_single_camera_scenario_records_no_mode() -> None:
    single = {**SCENARIO, "camera": {"preset": "wide_field", "width_px": 64, "height_px": 64}}
    scenario = parse_scenario(single, "test")
    assert scenario.camera.far_mode() is None
