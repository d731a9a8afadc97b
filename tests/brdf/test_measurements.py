"""Reading measured BRDF tables: the documented format, and errors that name the line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.brdf.measurements import (
    measurements_from_degrees,
    read_brdf_csv,
    write_brdf_csv,
)
from satsight.errors import SatsightError

GOOD = """\
# material: test plate
# licence: CC0-1.0

theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,brdf_per_sr
30,0,30,180,R,1.5
30,0,30,180,G,1.25
# a comment between rows
30,0,60,180,R,0.1
0,0,45,90,G,0.05
"""


def _write(tmp_path, text: str, name: str = "table.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_reads_the_documented_format(tmp_path):
    m = read_brdf_csv(_write(tmp_path, GOOD))
    assert m.size == 4
    assert m.channel_kind == "band"
    assert m.channel_names == ("R", "G")
    np.testing.assert_array_equal(m.channel, [0, 1, 0, 1])
    np.testing.assert_allclose(m.theta_i_rad, np.radians([30, 30, 30, 0]))
    np.testing.assert_allclose(m.phi_o_rad, np.radians([180, 180, 180, 90]))
    np.testing.assert_array_equal(m.brdf_per_sr, [1.5, 1.25, 0.1, 0.05])
    np.testing.assert_array_equal(m.line_numbers, [5, 6, 8, 9])
    assert m.metadata == {"material": "test plate", "licence": "CC0-1.0"}
    assert m.uncertainty_per_sr is None


def test_specular_geometry_gives_mirror_directions(tmp_path):
    m = read_brdf_csv(_write(tmp_path, GOOD))
    wi, wo = m.wi(), m.wo()
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0)
    np.testing.assert_allclose(wo[0], wi[0] * [-1.0, -1.0, 1.0], atol=1e-15)


def test_columns_in_any_order_aliases_wavelengths_and_uncertainty(tmp_path):
    text = (
        "brdf_sr^-1,wavelength_nm,theta_o_deg,phi_o_deg,theta_i_deg,phi_i_deg,"
        "uncertainty_per_sr,note\n"
        "0.3,550,10,180,10,0,0.01,ignored\n"
        "0.2,650.0,10,180,10,0,0.02,\n"
    )
    m = read_brdf_csv(_write(tmp_path, text))
    assert m.channel_kind == "wavelength_nm"
    assert m.channel_names == ("550", "650")
    np.testing.assert_array_equal(m.brdf_per_sr, [0.3, 0.2])
    np.testing.assert_array_equal(m.uncertainty_per_sr, [0.01, 0.02])


def test_write_read_round_trip(tmp_path):
    m = measurements_from_degrees(
        [10.0, 20.0],
        [0.0, 5.0],
        [15.5, 70.25],
        [180.0, -90.0],
        [0.123456789, 2.5],
        ["450", "550"],
        channel_kind="wavelength_nm",
        uncertainty_per_sr=[0.01, 0.02],
        metadata={"source": "made in code"},
    )
    back = read_brdf_csv(write_brdf_csv(tmp_path / "t.csv", m))
    for name in ("theta_i_rad", "phi_i_rad", "theta_o_rad", "phi_o_rad"):
        np.testing.assert_allclose(getattr(back, name), getattr(m, name), rtol=1e-9)
    np.testing.assert_allclose(back.brdf_per_sr, m.brdf_per_sr, rtol=1e-8)
    np.testing.assert_allclose(back.uncertainty_per_sr, m.uncertainty_per_sr)
    assert back.channel_names == m.channel_names
    assert back.metadata == {"source": "made in code"}


HEADER = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,brdf_per_sr\n"
ROW = "30,0,30,180,R,1.5\n"


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        ("theta_i_deg,phi_i_deg,theta_o_deg,band,brdf_per_sr\n" + ROW, 1, "missing column"),
        ("# only a comment\ntheta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band\n", 2, "brdf_per_sr"),
        (HEADER + ROW + "30,0,abc,180,R,1.0\n", 3, "theta_o_deg must be a number"),
        (HEADER + ROW + ROW + "30,0,30,180,R,x\n", 4, "brdf_per_sr must be a number"),
        (HEADER + "30,0,30,180,R,nan\n", 2, "finite"),
        (HEADER + "90,0,30,180,R,1.0\n", 2, "angle out of range: theta_i_deg"),
        (HEADER + "-5,0,30,180,R,1.0\n", 2, "angle out of range: theta_i_deg"),
        (HEADER + "30,0,95,180,R,1.0\n", 2, "angle out of range: theta_o_deg"),
        (HEADER + "30,400,30,180,R,1.0\n", 2, "angle out of range: phi_i_deg"),
        (HEADER + "\n" + ROW + "30,0,30,180,R,-0.01\n", 4, "negative BRDF"),
        (HEADER + "30,0,30\n", 2, "expected at least 6"),
        (HEADER + "30,0,30,180,,1.0\n", 2, "empty band"),
        (
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,brdf_per_sr\n"
            "30,0,30,180,-550,1.0\n",
            2,
            "wavelength_nm must be > 0",
        ),
        (
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,wavelength_nm,brdf_per_sr\n" + ROW,
            1,
            "both wavelength_nm and band",
        ),
        (
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,brdf_per_sr\n30,0,30,180,1.0\n",
            1,
            "neither of wavelength_nm and band",
        ),
        (
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,brdf_per_sr,uncertainty_per_sr\n"
            "30,0,30,180,R,1.0,0\n",
            2,
            "uncertainty_per_sr must be > 0",
        ),
        ("theta_i_deg,theta_i_deg,phi_i_deg\n", 1, "appears twice"),
    ],
)
def test_malformed_rows_name_file_and_line(tmp_path, text, line, fragment):
    path = _write(tmp_path, text, "bad_table.csv")
    with pytest.raises(SatsightError) as err:
        read_brdf_csv(path)
    message = str(err.value)
    assert str(path) in message
    assert f"line {line}:" in message
    assert fragment in message


@pytest.mark.parametrize(
    ("text", "fragment"),
    [("", "empty file"), ("# just comments\n\n", "empty file"), (HEADER, "no data rows")],
)
def test_empty_files_are_rejected(tmp_path, text, fragment):
    path = _write(tmp_path, text, "empty.csv")
    with pytest.raises(SatsightError, match=fragment) as err:
        read_brdf_csv(path)
    assert str(path) in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(SatsightError, match="no such file"):
        read_brdf_csv(tmp_path / "absent.csv")


def test_angles_are_radians_inside(tmp_path):
    m = read_brdf_csv(_write(tmp_path, HEADER + "45,90,60,270,R,1.0\n"))
    assert m.theta_i_rad[0] == pytest.approx(math.pi / 4)
    assert m.phi_o_rad[0] == pytest.approx(1.5 * math.pi)
