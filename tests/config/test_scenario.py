"""Scenario files: validation messages that name the bad key, and unit conversions."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from satsight.camera.pinhole import PinholeCamera
from satsight.cli import example_scenario_path
from satsight.config.camera import CameraConfig
from satsight.config.lighting import SunConfig
from satsight.config.scenario import FrameConfig, Scenario, load_scenario, parse_scenario
from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.errors import SatsightError
from satsight.scene.procedural import SATELLITE_CLASSES

ATOL = 1e-12

MINIMAL = {
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "frames": [{"distance_km": 1.0}, {"distance_km": 2.0, "azimuth_deg": 30.0}],
}


def _minimal(**changes) -> dict:
    data = copy.deepcopy(MINIMAL)
    data.update(changes)
    return data


def _error_lines(data: object) -> str:
    with pytest.raises(SatsightError, match=r"^test\.yaml: ") as info:
        parse_scenario(data, "test.yaml")
    return str(info.value)


# --- the bundled example ------------------------------------------------------------------
def test_bundled_example_validates() -> None:
    scenario = load_scenario(example_scenario_path())
    assert isinstance(scenario, Scenario)
    assert scenario.name == "first-light"
    assert len(scenario.frames) == 6
    assert scenario.target.procedural is not None
    assert scenario.target.procedural.satellite_class == "two_wings_dish"
    assert scenario.target.mesh is None
    assert scenario.frames[1].roll_deg == 30.0
    assert scenario.camera.build() == PinholeCamera.high_resolution()


def test_minimal_scenario_takes_documented_defaults() -> None:
    scenario = parse_scenario(MINIMAL)
    assert scenario.name == "scenario"
    assert scenario.seed == 0
    assert scenario.camera.preset == "high_resolution"
    assert scenario.sun.azimuth_deg == 45.0
    assert scenario.sun.elevation_deg == 30.0
    assert scenario.render.supersampling == 1
    assert scenario.render.variant == "auto"
    assert scenario.frames[0].elevation_deg == 0.0
    assert scenario.frames[0].roll_deg == 0.0


# --- messages naming the bad key ----------------------------------------------------------
def test_unknown_key_names_its_dotted_path() -> None:
    data = _minimal()
    data["frames"][1]["distanse_km"] = 3.0
    message = _error_lines(data)
    assert message.startswith("test.yaml: the scenario is not valid:")
    line = next(ln for ln in message.splitlines() if "distanse_km" in ln)
    assert "frames.1.distanse_km" in line
    assert "unknown key" in line


def test_unknown_top_level_key_is_an_error() -> None:
    message = _error_lines(_minimal(framez=[]))
    assert "framez: unknown key" in message


def test_negative_distance_names_the_field_and_value() -> None:
    data = _minimal()
    data["frames"][0]["distance_km"] = -1.0
    message = _error_lines(data)
    line = next(ln for ln in message.splitlines() if "distance_km" in ln)
    assert "frames.0.distance_km" in line
    assert "(got -1.0)" in line
    assert "frames.1" not in message


def test_missing_frames_says_required() -> None:
    data = _minimal()
    del data["frames"]
    message = _error_lines(data)
    assert "no frames: give a list of 'frames', or a 'sampler'" in message


def test_empty_frame_list_is_refused() -> None:
    message = _error_lines(_minimal(frames=[]))
    assert "frames:" in message


@pytest.mark.parametrize(
    "target",
    [
        {"procedural": {"satellite_class": "two_wings"}, "mesh": {"path": "sat.obj"}},
        {},
    ],
    ids=["both", "neither"],
)
def test_target_needs_exactly_one_of_procedural_or_mesh(target) -> None:
    message = _error_lines(_minimal(target=target))
    assert "target: give exactly one of 'procedural' or 'mesh'" in message


def test_unknown_satellite_class_lists_valid_classes() -> None:
    message = _error_lines(_minimal(target={"procedural": {"satellite_class": "three_wings"}}))
    line = next(ln for ln in message.splitlines() if "three_wings" in ln)
    assert line.lstrip().startswith("- target.procedural:")
    for name in SATELLITE_CLASSES:
        assert name in line


def test_top_level_must_be_a_mapping() -> None:
    with pytest.raises(SatsightError, match="expected a mapping"):
        parse_scenario([1, 2, 3], "list.yaml")


# --- files ----------------------------------------------------------------------------------
def test_invalid_yaml_is_a_satsight_error(tmp_path: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("frames: [ {distance_km: 1.0\nname: x\n", encoding="utf-8")
    with pytest.raises(SatsightError, match="not valid YAML"):
        load_scenario(path)


def test_missing_file_is_a_satsight_error(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.yaml"
    with pytest.raises(SatsightError, match="scenario file not found") as info:
        load_scenario(path)
    assert str(path) in str(info.value)


def test_relative_mesh_path_resolves_against_the_yaml_folder(tmp_path: Path) -> None:
    folder = tmp_path / "scenarios"
    folder.mkdir()
    data = _minimal(target={"mesh": {"path": "models/sat.obj", "scale_m": 0.001}})
    path = folder / "mesh.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scenario = load_scenario(path)
    assert scenario.target.mesh.path == (folder / "models" / "sat.obj").resolve()
    assert scenario.target.mesh.path.is_absolute()
    assert scenario.target.mesh.scale_m == 0.001
    assert scenario.target.procedural is None
    # The rest of the scenario is unchanged.
    assert [f.distance_km for f in scenario.frames] == [1.0, 2.0]


def test_absolute_mesh_path_is_kept(tmp_path: Path) -> None:
    absolute = tmp_path / "elsewhere" / "sat.glb"
    data = _minimal(target={"mesh": {"path": str(absolute)}})
    path = tmp_path / "abs.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    assert load_scenario(path).target.mesh.path == absolute


# --- builds ----------------------------------------------------------------------------------
def test_camera_override_keeps_optics_and_recentres_principal_point() -> None:
    camera = CameraConfig(preset="wide_field", width_px=512).build()
    assert camera.focal_length_m == 0.7
    assert camera.pixel_pitch_m == 15e-6
    assert camera.width_px == 512
    assert camera.height_px == 4112
    assert camera.cx_px == (512 - 1) / 2.0
    assert camera.cy_px == (4112 - 1) / 2.0
    np.testing.assert_allclose(
        camera.K,
        [[0.7 / 15e-6, 0.0, 255.5], [0.0, 0.7 / 15e-6, 2055.5], [0.0, 0.0, 1.0]],
        rtol=0,
        atol=ATOL,
    )


def test_camera_pixel_pitch_is_given_in_micrometres() -> None:
    camera = CameraConfig(pixel_pitch_um=7.5, focal_length_m=1.5).build()
    assert camera.pixel_pitch_m == pytest.approx(7.5e-6, rel=1e-15)
    assert camera.focal_length_m == 1.5
    assert (camera.width_px, camera.height_px) == (4096, 4112)


@pytest.mark.parametrize(
    ("azimuth_deg", "elevation_deg"), [(0.0, 0.0), (90.0, 0.0), (40.0, 35.0), (-120.0, -60.0)]
)
def test_sun_direction_is_unit_and_matches_angles(azimuth_deg, elevation_deg) -> None:
    sun = SunConfig(azimuth_deg=azimuth_deg, elevation_deg=elevation_deg, irradiance_w_m2=1361.0)
    light = sun.build()
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    expected = [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
    np.testing.assert_allclose(light.direction_body, expected, rtol=0, atol=ATOL)
    assert np.linalg.norm(light.direction_body) == pytest.approx(1.0, abs=ATOL)
    assert light.irradiance_w_m2 == 1361.0


def test_sun_elevation_out_of_range_is_refused() -> None:
    message = _error_lines(_minimal(sun={"elevation_deg": 91.0}))
    assert "sun.elevation_deg" in message


def test_frame_build_converts_km_and_degrees() -> None:
    view = FrameConfig(
        distance_km=2.5, azimuth_deg=90.0, elevation_deg=-30.0, roll_deg=45.0
    ).build()
    assert view.distance_m == 2500.0
    assert view.azimuth_rad == pytest.approx(math.pi / 2, abs=ATOL)
    assert view.elevation_rad == pytest.approx(-math.pi / 6, abs=ATOL)
    assert view.roll_rad == pytest.approx(math.pi / 4, abs=ATOL)


Q_TURN = (math.cos(0.3), 0.0, math.sin(0.3), 0.0)  # 0.6 rad about y


def test_frame_given_as_a_pose_is_that_pose() -> None:
    frame = FrameConfig(q_cam_from_body=Q_TURN, t_cam_from_body_m=(1.0, -2.0, 3000.0))
    pose = frame.cam_from_body(np.array([5.0, 5.0, 5.0]))  # the box centre plays no part
    np.testing.assert_allclose(pose.q_a_from_b, Q_TURN, atol=ATOL)
    np.testing.assert_allclose(pose.t_a_from_b_m, [1.0, -2.0, 3000.0], atol=ATOL)
    scenario = parse_scenario(
        _minimal(frames=[{"q_cam_from_body": list(Q_TURN), "t_cam_from_body_m": [0, 0, 900]}])
    )
    assert scenario.frames[0].t_cam_from_body_m == (0.0, 0.0, 900.0)


@pytest.mark.parametrize(
    ("frame", "says"),
    [({"q_cam_from_body": [1, 0, 0, 0]}, "needs both"),
     ({"q_cam_from_body": [1, 0, 0, 0], "t_cam_from_body_m": [0, 0, 9], "distance_km": 1},
      "not both"),
     ({"q_cam_from_body": [1, 0, 0, 0.1], "t_cam_from_body_m": [0, 0, 9]}, "unit quaternion"),
     ({"q_cam_from_body": [1, 0, 0, 0], "t_cam_from_body_m": [0, 0, -9]}, "behind the camera"),
     ({"azimuth_deg": 10}, "needs distance_km")],
)  # fmt: skip
def test_bad_pose_frames_are_refused(frame: dict, says: str) -> None:
    assert says in _error_lines(_minimal(frames=[frame]))


# --- light and render settings -----------------------------------------------------------------
def test_sun_irradiance_comes_from_the_spectrum_over_the_band() -> None:
    """Defaults: ASTM E-490 over 450-900 nm at 1 AU (about 671.5 W m^-2); the 5778 K black
    body scaled to 1366.1 W m^-2 gives about 648.7 W m^-2; inverse square in distance."""
    e490 = SunConfig().in_band_irradiance_w_m2
    assert e490 == pytest.approx(671.5, rel=5e-3)
    blackbody = SunConfig(spectrum="blackbody_5778k").in_band_irradiance_w_m2
    assert blackbody == pytest.approx(648.7, rel=5e-3)
    assert SunConfig(distance_au=2.0).in_band_irradiance_w_m2 == pytest.approx(e490 / 4.0)
    assert SunConfig(irradiance_w_m2=500.0).build().irradiance_w_m2 == 500.0


def test_reversed_band_names_the_key() -> None:
    message = _error_lines(_minimal(sun={"band_nm": [900, 450]}))
    assert "sun" in message and "band_nm" in message


def test_earth_and_moon_positions_in_metres() -> None:
    scenario = parse_scenario(
        _minimal(
            earth={"azimuth_deg": 0.0, "elevation_deg": -90.0, "altitude_km": 500.0},
            moon={"azimuth_deg": 90.0, "elevation_deg": 0.0, "distance_km": 384400.0},
        )
    )
    earth = scenario.earth.center_from_target_m()
    np.testing.assert_allclose(earth, [0.0, 0.0, -(EARTH_MEAN_RADIUS_M + 5e5)], atol=1e-6)
    np.testing.assert_allclose(scenario.moon.center_from_target_m(), [0, 3.844e8, 0], atol=1e-3)


def test_render_block_builds_render_settings() -> None:
    scenario = parse_scenario(
        _minimal(
            render={
                "brdf": "improved_phong",
                "sh_order": 6,
                "sun_model": "sh",
                "environment": "unshadowed",
                "bounces": 3,
                "samples_per_pixel": 8,
            }
        )
    )
    settings = scenario.render.settings()
    assert (settings.brdf, settings.sh_order, settings.sun) == ("improved_phong", 6, "sh")
    assert (settings.environment, settings.bounces, settings.samples_per_pixel) == (
        "unshadowed",
        3,
        8,
    )


@pytest.mark.parametrize(
    ("render", "key"),
    [({"brdf": "blinn"}, "render.brdf"), ({"sh_order": 9}, "render.sh_order")],
)
def test_bad_render_settings_name_the_key(render, key) -> None:
    assert key in _error_lines(_minimal(render=render))
