"""The README's recipe for smaller images of the paper's field (Camera, "Smaller images of
the same field"): its snippet is the bundled example's camera, keeps the field of view, and
the figures the README gives for it are what the sensor model computes."""

from __future__ import annotations

import math
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml

from satsight.config.scenario import load_scenario, parse_scenario
from satsight.pipeline import build_sensor
from satsight.sensor.camera_report import reference_exposure_s
from satsight.sensor.detector import photons_per_pixel
from satsight.sensor.mtf import band_wavelengths_m, diffraction_mtf, pixel_mtf, system_mtf

EXAMPLES = Path(str(resources.files("satsight") / "examples"))
README = Path(__file__).parents[1] / "README.md"


def readme_snippet() -> dict:
    section = README.read_text(encoding="utf-8").split("### Smaller images of the same field")[1]
    block = re.search(r"```yaml\n(.*?)```", section, re.DOTALL)
    assert block is not None
    return yaml.safe_load(block.group(1))


def sensors(preset: str):
    """The paper's camera and the recipe's, on the bundled first_light scenario."""
    data = yaml.safe_load((EXAMPLES / "first_light.yaml").read_text(encoding="utf-8"))
    paper = parse_scenario({**data, "camera": {"preset": preset}}, "paper")
    small = parse_scenario(
        {**data, "camera": {**readme_snippet()["camera"], "preset": preset}}, "small"
    )
    return build_sensor(paper), build_sensor(small)


def test_snippet_is_the_bundled_example_camera() -> None:
    example = load_scenario(EXAMPLES / "first_light_1024px.yaml")
    assert (
        example.camera.model_dump()
        == parse_scenario(
            {**yaml.safe_load((EXAMPLES / "first_light.yaml").read_text()), **readme_snippet()}, "x"
        ).camera.model_dump()
    )


@pytest.mark.parametrize(
    ("preset", "optics_mtf", "system_mtf_at_nyquist"),
    [("high_resolution", (0.716, 0.928), (0.456, 0.591)),
     ("wide_field", (0.800, 0.950), (0.510, 0.605))],
)  # fmt: skip
def test_same_field_and_the_readme_figures(preset, optics_mtf, system_mtf_at_nyquist) -> None:
    paper, small = sensors(preset)
    assert small.camera.fov_x_rad == pytest.approx(paper.camera.fov_x_rad, rel=1e-12)
    assert small.camera.fov_y_rad == pytest.approx(paper.camera.fov_y_rad, rel=1e-12)
    assert small.camera.ifov_rad == pytest.approx(4 * paper.camera.ifov_rad, rel=1e-12)
    for sensor, optics_expected, system_expected in zip(
        (paper, small), optics_mtf, system_mtf_at_nyquist, strict=True
    ):
        pitch = sensor.camera.pixel_pitch_m
        nyquist = 1 / (2 * pitch)
        lam = band_wavelengths_m(sensor.band_nm)
        optics = np.mean([diffraction_mtf(nyquist, w, sensor.optics.f_number) for w in lam])
        assert optics == pytest.approx(optics_expected, abs=5e-4)
        assert float(pixel_mtf(nyquist, pitch)) == pytest.approx(2 / math.pi)
        system = float(system_mtf(nyquist, sensor.optics, pitch, lam))
        assert system == pytest.approx(system_expected, abs=5e-4)
    # An extended target: 16 times the photons per pixel; the same full well, so the auto
    # exposure is 16 times shorter.
    photons = [
        float(photons_per_pixel(1.0, s.detector.pixel_area_m2, 1e-3, s.photon_energy_j))
        for s in (paper, small)
    ]
    assert photons[1] == pytest.approx(16 * photons[0], rel=1e-12)
    assert small.detector.full_well_e == paper.detector.full_well_e
    assert reference_exposure_s(small) == pytest.approx(reference_exposure_s(paper) / 16)
