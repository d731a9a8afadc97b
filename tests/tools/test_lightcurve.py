"""Light curves (``satsight lightcurve``) against the exact light of a convex Lambertian
polyhedron.

A convex body whose faces are Lambertian (albedo rho) sends, from a distant Sun of
irradiance E along s, the intensity I = (rho E / pi) sum_f A_f max(n_f.s, 0) max(n_f.v, 0)
towards a distant viewer along v (no face shadows another), so the irradiance at range d is
I / d^2. The light-curve camera places the body at the centre of its own small image; its
finite range (d = 300 R) tilts each face's view direction by at most R / d and changes the
distances by as much, which moves E by ~(R / d) relative at most (0.3 %); the silhouette's
pixelisation with 16 samples per pixel adds < 0.1 %. Tolerance: 0.5 %.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from matplotlib.colors import to_rgba

from cli_runner import run_satsight
from figure_checks import figure_pixels, has_colour
from satsight.config.scenario import parse_scenario
from satsight.tools.lightcurve import run_lightcurve

ALBEDO = 0.5
SUN_W_M2 = 1000.0
RADIUS_M = 1.0
RANGE_M = 300.0
ELEVATIONS_DEG = (90.0, 60.0, 30.0, 0.0, -30.0)  # the Sun at the zenith: phase 0 ... 120 deg


def _write_icosphere(folder: Path) -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS_M)
    (folder / "ball.mtl").write_text(
        f"newmtl grey\nKd {ALBEDO} {ALBEDO} {ALBEDO}\nPm 0\nPr 1\nNi 1.0\n", encoding="utf-8"
    )
    lines = ["mtllib ball.mtl", "o ball", "usemtl grey"]
    lines += [f"v {x:.12f} {y:.12f} {z:.12f}" for x, y, z in sphere.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in sphere.faces]
    (folder / "ball.obj").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return sphere


def _scenario(folder: Path) -> dict:
    return {
        "name": "lambert-ball",
        "camera": {"preset": "wide_field", "width_px": 64, "height_px": 64},
        "target": {"mesh": {"path": str(folder / "ball.obj"), "crease_angle_deg": 0}},
        "sun": {"azimuth_deg": 0, "elevation_deg": 90, "irradiance_w_m2": SUN_W_M2},
        "frames": [
            {"distance_km": RANGE_M / 1e3, "azimuth_deg": 0, "elevation_deg": e}
            for e in ELEVATIONS_DEG
        ],
        "render": {"environment": "off", "bounces": 0, "samples_per_pixel": 16},
    }


def _exact_irradiance_w_m2(sphere: trimesh.Trimesh, elevation_deg: float) -> float:
    s = np.array([0.0, 0.0, 1.0])
    e = math.radians(elevation_deg)
    v = np.array([math.cos(e), 0.0, math.sin(e)])  # towards the viewer (azimuth 0 on +x)
    n, area = sphere.face_normals, sphere.area_faces
    intensity = (
        ALBEDO * SUN_W_M2 / math.pi * np.sum(area * np.maximum(n @ s, 0.0) * np.maximum(n @ v, 0.0))
    )
    return float(intensity / RANGE_M**2)


def test_light_curve_of_a_lambertian_polyhedron_is_exact(tmp_path: Path, llvm_variant) -> None:
    sphere = _write_icosphere(tmp_path)
    curve = run_lightcurve(parse_scenario(_scenario(tmp_path), "test"), size_px=64)
    assert len(curve.rows) == len(ELEVATIONS_DEG)
    for row, elevation in zip(curve.rows, ELEVATIONS_DEG, strict=True):
        expected = _exact_irradiance_w_m2(sphere, elevation)
        assert row["phase_angle_deg"] == pytest.approx(90.0 - elevation, abs=0.2)
        assert row["target_irradiance_w_m2"] == pytest.approx(expected, rel=5e-3)
        # V-equivalent: -26.76 - 2.5 log10(E / E_sun) with the Sun at 1 AU.
        magnitude = -26.76 - 2.5 * math.log10(row["target_irradiance_w_m2"] / SUN_W_M2)
        assert row["v_magnitude_equivalent"] == pytest.approx(magnitude, abs=1e-6)
    # The curve falls with the phase angle, as a Lambert sphere's does.
    irradiance = curve.column("target_irradiance_w_m2")
    assert np.all(np.diff(irradiance) < 0)


def test_lightcurve_command_writes_csv_and_plot(tmp_path: Path) -> None:
    _write_icosphere(tmp_path)
    config = tmp_path / "ball.yaml"
    config.write_text(yaml.safe_dump(_scenario(tmp_path)), encoding="utf-8")
    result = run_satsight(
        "lightcurve", str(config), "--size-px", "32", "--spp", "1", "--out", "lc", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    with open(tmp_path / "lc" / "lightcurve.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(ELEVATIONS_DEG)
    assert all(float(r["target_irradiance_w_m2"]) > 0 for r in rows)
    # Two panels, 9 x 6 inches at 110 dpi: magnitude in C0 blue, phase angle in orange.
    figure = figure_pixels(tmp_path / "lc" / "lightcurve.png", (9 * 110, 6 * 110))
    assert has_colour(figure, to_rgba("C0")) and has_colour(figure, to_rgba("tab:orange"))
    bad = run_satsight("lightcurve", str(config), "--size-px", "8", cwd=tmp_path)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
