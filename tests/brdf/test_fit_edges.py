"""`satsight fit-brdf` on tables that cannot determine a reflection model: no reflected
light, one geometry, non-finite values, too few distinct measurements.

Each is refused with one line naming the file and what is wrong, exit status 2 and no
traceback, before anything is written: a fit written earlier to the same folder stays as it
was. Tables here are SYNTHETIC (the bundled GGX example with its values changed), not
measurements of any material.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from cli_runner import invoke_satsight
from satsight.brdf.fit import check_table, fit_brdf
from satsight.brdf.measurements import measurements_from_degrees, read_brdf_csv
from satsight.brdf.metrics import fit_metrics
from satsight.errors import SatsightError

EXAMPLE = Path(str(resources.files("satsight") / "examples" / "brdf_synthetic_ggx_rgb.csv"))
COLUMNS = ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "band", "brdf_per_sr")


def _edit_rows(path: Path, edit) -> None:
    """Rewrite the example table into ``path`` with ``edit(fields)`` applied to each data row
    (fields: the comma-separated values, in the header's order)."""
    out, header = [], None
    for line in EXAMPLE.read_text(encoding="utf-8").splitlines():
        if line.startswith("#") or not line.strip():
            out.append(line)
        elif header is None:
            header = line.split(",")
            out.append(line)
        else:
            fields = dict(zip(header, line.split(","), strict=True))
            edit(fields)
            out.append(",".join(fields[h] for h in header))
    path.write_text("\n".join(out) + "\n", encoding="utf-8")


def _set(**values):
    def edit(fields):
        fields.update(values)

    return edit


def _fit(folder: Path, csv: Path, model: str = "ggx"):
    """``satsight fit-brdf`` in this interpreter (its exit status and messages as in a child
    process; test_materials_cli runs the refusal of a bad table in one)."""
    return invoke_satsight("fit-brdf", str(csv), "--model", model, "--out", "fit", cwd=folder)


def _refused_line(result) -> str:
    """Exit status 2, no traceback; the one 'error:' line."""
    assert result.returncode == 2, result.stdout + result.stderr
    output = result.stdout + result.stderr
    assert "Traceback" not in output and "math domain" not in output
    errors = [line for line in output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, output
    return errors[0]


@pytest.mark.parametrize(
    ("edit", "model", "expected"),
    [
        (_set(brdf_per_sr="0"), "ggx", "every one of the 585 brdf_per_sr values is 0"),
        (_set(brdf_per_sr="0.0e0"), "phong", "there is no reflected light to fit"),
        (
            _set(theta_i_deg="30", phi_i_deg="0", theta_o_deg="30", phi_o_deg="180"),
            "improved_phong",
            "all 585 rows measure one geometry (theta_i = 30, phi_i = 0, theta_o = 30, "
            "phi_o = 180 deg)",
        ),
    ],
)
def test_cli_refuses_a_degenerate_table_and_keeps_an_earlier_fit(
    tmp_path: Path, edit, model: str, expected: str
) -> None:
    table = tmp_path / "t.csv"
    _edit_rows(table, edit)
    # What an earlier fit of the same table wrote; a refusal must leave it as it was.
    earlier = {f"t_{model}.yaml": b"model: earlier\n", f"t_{model}_plane.png": b"\x89PNG-earlier"}
    (tmp_path / "fit").mkdir()
    for name, data in earlier.items():
        (tmp_path / "fit" / name).write_bytes(data)
    for _ in range(2):
        line = _refused_line(_fit(tmp_path, table, model))
        assert line.startswith(f"error: {table}: ") or line.startswith("error: t.csv: ")
        assert expected in line
        assert {p.name: p.read_bytes() for p in (tmp_path / "fit").iterdir()} == earlier


@pytest.mark.parametrize("value", ["nan", "NaN", "inf", "-inf"])
def test_cli_refuses_non_finite_values_naming_the_line(tmp_path: Path, value: str) -> None:
    table = tmp_path / "nan.csv"
    rows = EXAMPLE.read_text(encoding="utf-8").splitlines()
    k = next(i for i, line in enumerate(rows) if line[:1].isdigit()) + 3
    fields = rows[k].split(",")
    fields[5] = value
    rows[k] = ",".join(fields)
    table.write_text("\n".join(rows) + "\n", encoding="utf-8")
    line = _refused_line(_fit(tmp_path, table))
    assert f"nan.csv, line {k + 1}: column brdf_per_sr must be a finite number" in line
    assert not (tmp_path / "fit").exists()


def test_a_table_without_positive_values_is_refused_in_code_too() -> None:
    m = measurements_from_degrees(
        [0.0, 30.0, 60.0] * 4, [0.0] * 12, [10.0, 20.0, 40.0, 70.0] * 3, [180.0] * 12,
        [0.0] * 12, ["V"] * 12, path="zeros",
    )  # fmt: skip
    with pytest.raises(SatsightError, match=r"^zeros: every one of the 12 brdf_per_sr"):
        fit_brdf(m, "phong")
    # Small negative values (noise after a background subtraction) alone are no light either.
    noisy = measurements_from_degrees(
        [0.0, 30.0, 60.0] * 4, [0.0] * 12, [10.0, 20.0, 40.0, 70.0] * 3, [180.0] * 12,
        [-1e-4] * 12, ["V"] * 12, path="noise",
    )  # fmt: skip
    with pytest.raises(SatsightError, match=r"no reflected light"):
        fit_brdf(noisy, "phong")


def test_nan_and_one_geometry_in_code_name_the_row() -> None:
    angles = ([30.0] * 6, [0.0] * 6, [0.0, 10.0, 20.0, 30.0, 40.0, 50.0], [180.0] * 6)
    values = [0.1, 0.2, np.nan, 0.4, 0.3, 0.2]
    m = measurements_from_degrees(*angles, values, ["V"] * 6, path="mem")
    with pytest.raises(SatsightError, match=r"^mem, row 2: brdf_per_sr is nan \(1 non-finite"):
        check_table(m)
    bad_angle = measurements_from_degrees(
        [30.0] * 6, [0.0] * 6, [0.0, 10.0, np.inf, 30.0, 40.0, 50.0], [180.0] * 6,
        [0.1] * 6, ["V"] * 6, path="mem",
    )  # fmt: skip
    with pytest.raises(SatsightError, match=r"^mem, row 2: theta_o_deg is inf"):
        check_table(bad_angle)
    # One geometry written three ways (phi 0 / 360, any phi at theta 0): still one.
    same = measurements_from_degrees(
        [0.0, 0.0, 0.0] * 3, [0.0, 90.0, 200.0] * 3, [40.0] * 9, [0.0, 360.0, -360.0] * 3,
        [0.5] * 9, ["V"] * 9, path="same",
    )  # fmt: skip
    with pytest.raises(SatsightError, match=r"^same: all 9 rows measure one geometry"):
        fit_brdf(same, "phong")


def test_repeated_geometries_do_not_count_as_more_measurements() -> None:
    # Phong in one channel has 3 parameters: 3 distinct geometries repeated 10 times are
    # 30 rows but cannot determine them; a fourth geometry can.
    theta_o = [10.0, 30.0, 50.0] * 10
    m = measurements_from_degrees(
        [30.0] * 30, [0.0] * 30, theta_o, [180.0] * 30, [0.2] * 30, ["V"] * 30, path="rep"
    )
    with pytest.raises(SatsightError) as error:
        fit_brdf(m, "phong")
    assert str(error.value) == (
        "rep: the 30 rows hold only 3 distinct (geometry, channel) measurements, which cannot "
        "determine the 3 parameters of the phong model (repeating a geometry adds no "
        "information about the lobe's shape); measure more incidence and viewing angles"
    )
    four = measurements_from_degrees(
        [30.0] * 31, [0.0] * 31, [*theta_o, 70.0], [180.0] * 31, [0.2] * 31, ["V"] * 31
    )
    assert fit_brdf(four, "phong").n_measurements == 31


def test_one_dark_channel_among_lit_ones_is_fitted(tmp_path: Path) -> None:
    """A channel with no light (a black band) is a valid measurement: reflectance 0."""
    table = tmp_path / "dark_blue.csv"

    def edit(fields):
        if fields["band"] == "B":
            fields["brdf_per_sr"] = "0"

    _edit_rows(table, edit)
    fit = fit_brdf(read_brdf_csv(table), "ggx")
    assert fit.parameters["base"][2] < 0.01 < fit.parameters["base"][0]
    assert math.isfinite(fit.metrics.psnr_db)


def test_psnr_without_a_peak_is_minus_infinity_not_an_error() -> None:
    m = measurements_from_degrees([30.0] * 2, [0.0] * 2, [10.0, 20.0], [180.0] * 2, [0.0] * 2, "VV")
    metrics = fit_metrics(m, np.array([0.1, 0.1]))
    assert metrics.psnr_db == -math.inf and metrics.mse_sr2 == pytest.approx(0.01)
    assert fit_metrics(m, np.zeros(2)).psnr_db == math.inf


def test_header_columns_are_the_formats() -> None:
    header = next(
        line
        for line in EXAMPLE.read_text(encoding="utf-8").splitlines()
        if not line.startswith("#")
    )
    assert tuple(header.split(",")[:6]) == COLUMNS
