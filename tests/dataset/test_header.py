"""The labels.json header, built from plain values: its keys, in order, and what they hold."""

from __future__ import annotations

import copy
import hashlib
from pathlib import Path

import numpy as np
import pytest

from qe_oracle import solar_qe
from satsight.config.scenario import parse_scenario
from satsight.dataset.header import (
    CONVENTIONS,
    FarCamera,
    TargetDescription,
    labels_header,
    sensor_summary,
)
from satsight.dataset.preview import PreviewStretch
from satsight.pipeline import build_sensor
from satsight.render.settings import RenderSettings
from satsight.scene.procedural import generate_satellite

SCENARIO = {
    "name": "header",
    "camera": {"width_px": 64, "height_px": 48},
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "frames": [{"distance_km": 1.0, "azimuth_deg": 0.0, "elevation_deg": 0.0}],
}
KEYS = [
    "satsight_version",
    "scenario",
    "frame_count",
    "plan_indices",
    "render_variant",
    "conventions",
    "outputs",
    "camera",
    "sun",
    "render_settings",
    "sensor",
    "preview",
    "environment_light",
    "target",
]


def _header(mesh_file: Path | None = None, far: bool = False) -> dict:
    scenario = parse_scenario(SCENARIO)
    sensor = build_sensor(scenario)
    mesh = generate_satellite("two_wings", 1)
    keypoints = np.zeros((3, 3))
    return labels_header(
        scenario_name="header",
        plan_indices=np.array([0, 2, 5]),
        render_variant="llvm_ad_rgb",
        outputs={"files": ["dn"]},
        file_keys=("dn_png16",),
        camera=sensor.camera,
        sensor=sensor,
        sun_spectrum="astm_e490",
        band_nm=(450.0, 900.0),
        render_settings=RenderSettings(sh_order=3),
        preview=PreviewStretch("gamma"),
        target=TargetDescription(mesh, keypoints, "corners", mesh_file),
        far=FarCamera("wide_field", 2e4, sensor.camera, sensor) if far else None,
    )


def test_the_header_holds_its_keys_in_order() -> None:
    header = _header()
    assert list(header) == KEYS
    assert header["frame_count"] == 3 and header["plan_indices"] == [0, 2, 5]
    assert header["conventions"] is CONVENTIONS
    assert header["camera"]["image_size_px"] == [64, 48]
    assert header["outputs"] == {"files": ["dn"], "file_keys": ["dn_png16"]}
    assert header["environment_light"]["sh_order"] == 3
    assert header["preview"]["stretch"] == "gamma"
    assert header["target"]["keypoints"]["count"] == 3
    assert header["target"]["mesh_file_sha256"] is None


def test_the_sensor_states_its_quantum_efficiency_and_where_it_comes_from() -> None:
    """Default: the CCD231-84 curve's photon-weighted mean over the band in E-490 sunlight
    (oracle from the data files; 1e-5: its quadrature against the library's, < 3e-6), and
    each third's; the detector's own entry stays null. A number in the scenario: that number,
    labelled as an override."""
    summary = _header()["sensor"]
    assert summary["quantum_efficiency"] == pytest.approx(solar_qe(450.0, 900.0), rel=1e-5)
    assert summary["quantum_efficiency_source"].startswith("CCD231-84 curve")
    thirds = [solar_qe(750.0, 900.0), solar_qe(600.0, 750.0), solar_qe(450.0, 600.0)]
    np.testing.assert_allclose(summary["channel_quantum_efficiency_rgb"], thirds, rtol=1e-5)
    assert summary["detector"]["quantum_efficiency"] is None
    data = copy.deepcopy(SCENARIO)
    data["camera"]["detector"] = {"quantum_efficiency": 0.72}
    fixed = sensor_summary(build_sensor(parse_scenario(data)))
    assert fixed["quantum_efficiency"] == 0.72
    assert fixed["quantum_efficiency_source"] == "scalar override"
    assert fixed["channel_quantum_efficiency_rgb"] == [0.72, 0.72, 0.72]


def test_a_mesh_file_and_a_far_camera_are_described(tmp_path: Path) -> None:
    mesh_file = tmp_path / "target.obj"
    mesh_file.write_bytes(b"v 0 0 0\n")
    header = _header(mesh_file, far=True)
    assert list(header) == [*KEYS, "far_camera"]
    expected = hashlib.sha256(b"v 0 0 0\n").hexdigest()
    assert header["target"]["mesh_file_sha256"] == expected
    far = header["far_camera"]
    assert far["preset"] == "wide_field" and far["switch_range_m"] == 2e4
    assert far["camera"] == header["camera"] and far["sensor"] == header["sensor"]
