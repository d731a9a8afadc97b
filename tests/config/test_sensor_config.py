"""The camera's sensor keys: defaults, overrides and the messages for bad values."""

from __future__ import annotations

import copy

import pytest
import yaml

from cli_runner import invoke_satsight
from satsight.config.scenario import parse_scenario
from satsight.errors import SatsightError
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.optics import DEFAULT_APERTURE_DIAMETER_M

STATIC = {
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "frames": [{"distance_km": 1.0, "azimuth_deg": 0.0, "elevation_deg": 0.0}],
}


def scenario(**camera):
    data = copy.deepcopy(STATIC)
    data["camera"] = camera
    return parse_scenario(data, "test")


@pytest.mark.parametrize("preset", ["high_resolution", "wide_field"])
def test_defaults_give_the_preset_optics_and_the_ccd231_detector(preset) -> None:
    camera = scenario(preset=preset).camera
    optics = camera.build_optics()
    assert optics.aperture_diameter_m == DEFAULT_APERTURE_DIAMETER_M[preset]
    assert optics.focal_length_m == camera.build().focal_length_m
    assert camera.build_detector() == DetectorParameters(pixel_pitch_m=camera.build().pixel_pitch_m)
    assert camera.exposure.mode == "auto"


def test_overrides_reach_the_built_optics_and_detector() -> None:
    camera = scenario(
        pixel_pitch_um=12.0,
        optics={"aperture_diameter_m": 0.25, "obscuration_ratio": 0.3, "jitter_rms_urad": 1.5},
        detector={"read_noise_e": 3.0, "blooming": False},
        exposure={"mode": "fixed", "time_s": 0.05},
    ).camera
    optics, detector = camera.build_optics(), camera.build_detector()
    assert optics.f_number == pytest.approx(3.0 / 0.25)
    assert optics.obscuration_ratio == 0.3
    assert optics.jitter_rms_rad == pytest.approx(1.5e-6)
    assert detector.pixel_pitch_m == pytest.approx(12e-6)
    assert detector.read_noise_e == 3.0 and detector.blooming is False


def test_quantum_efficiency_is_the_curve_unless_a_number_is_given() -> None:
    """Unset or null: None, the detector's QE curve; a number in (0, 1]: that scalar."""
    assert scenario().camera.build_detector().quantum_efficiency is None
    nulled = scenario(detector={"quantum_efficiency": None}).camera.build_detector()
    assert nulled.quantum_efficiency is None
    fixed = scenario(detector={"quantum_efficiency": 0.75}).camera.build_detector()
    assert fixed.quantum_efficiency == 0.75
    for bad in (0.0, 1.2):
        with pytest.raises(SatsightError, match=r"camera\.detector\.quantum_efficiency"):
            scenario(detector={"quantum_efficiency": bad})


def test_defocus_blur_reaches_the_built_optics_in_metres() -> None:
    camera = scenario(optics={"defocus_blur_um": 45.0}).camera
    assert camera.build_optics().defocus_blur_diameter_m == pytest.approx(45e-6)
    assert scenario().camera.build_optics().defocus_blur_diameter_m == 0.0
    with pytest.raises(SatsightError, match=r"camera\.optics\.defocus_blur_um"):
        scenario(optics={"defocus_blur_um": -1.0})


@pytest.mark.parametrize(
    ("camera", "message"),
    [
        ({"optics": {"transmission": 80}}, "camera.optics.transmission"),
        ({"optics": {"aperture_diameter_m": 5.0}}, "f-number"),
        ({"detector": {"bias_dn": 70000}}, "bias_dn"),
        ({"detector": {"adc_bits": 20}}, "camera.detector.adc_bits"),
        ({"detector": {"dark_current_e_per_s": 0.0}}, "dsnu_e_per_s > 0 needs"),
        ({"exposure": {"min_time_s": 2.0, "max_time_s": 1.0}}, "must not exceed"),
        ({"exposure": {"mode": "manual"}}, "camera.exposure.mode"),
        ({"detector": {"gain": 2.0}}, "unknown key"),
    ],
)
def test_bad_sensor_values_name_the_key(camera, message) -> None:
    with pytest.raises(SatsightError, match=message.replace(".", r"\.")) as info:
        scenario(**camera)
    # One bad value, one message: a single line, or the heading and one line for the key.
    lines = str(info.value).splitlines()
    assert len(lines) == 1 or (lines[0] == "test: the scenario is not valid:" and len(lines) == 2)


@pytest.mark.parametrize(
    ("detector", "message"),
    [
        ({"adc_bits": 20}, "camera.detector.adc_bits"),  # refused by the key's bounds
        ({"bias_dn": 70000}, "bias_dn must be in [0, 65535) DN"),  # by the detector model
    ],
)
def test_a_bad_sensor_value_stops_the_command_with_a_message(tmp_path, detector, message) -> None:
    data = copy.deepcopy(STATIC)
    data["camera"] = {"detector": detector}
    config = tmp_path / "bad_sensor.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = invoke_satsight("plan", str(config), "--no-plots", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
    assert "Traceback" not in result.stderr


def test_stars_need_frames_planned_from_orbits() -> None:
    data = copy.deepcopy(STATIC)
    data["stars"] = {"v_mag_limit": 8.0}
    with pytest.raises(SatsightError, match="stars only apply to frames planned from orbits"):
        parse_scenario(data, "test")
