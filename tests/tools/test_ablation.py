"""Ablation metrics against closed forms, and ``satsight ablate`` end to end."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.colors import to_rgba

from figure_checks import figure_pixels, has_colour
from satsight.camera.pinhole import PinholeCamera
from satsight.cli import main
from satsight.config.scenario import Scenario
from satsight.errors import SatsightError
from satsight.scene.obj_export import write_obj
from satsight.scene.procedural import generate_satellite
from satsight.tools.ablation import (
    FITTED_VARIANTS,
    VARIANTS,
    ablation_camera,
    fitted_phong_meshes,
    image_metrics,
    run_ablation,
)


def _image(rng, shape=(6, 5)) -> np.ndarray:
    image = rng.uniform(0.5, 2.0, size=(*shape, 3))
    image[0] = 0.0  # a background row
    return image


def test_identical_images_have_zero_error():
    ref = _image(np.random.default_rng(1))
    m = image_metrics(ref, ref.copy())
    assert m.mse_w2_m4_sr2 == 0.0 and m.psnr_db == math.inf and m.mean_angular_error_deg == 0.0


def test_brightness_scaling_changes_mse_but_not_the_angle():
    ref = _image(np.random.default_rng(2))
    k = 1.3
    m = image_metrics(ref, k * ref)
    used = np.linalg.norm(ref, axis=-1) > 0
    expected_mse = (k - 1.0) ** 2 * np.mean(ref[used] ** 2)
    assert m.mse_w2_m4_sr2 == pytest.approx(expected_mse, rel=1e-12)
    assert m.psnr_db == pytest.approx(10 * math.log10(ref.max() ** 2 / expected_mse), rel=1e-12)
    assert m.mean_angular_error_deg == pytest.approx(0.0, abs=1e-5)


def test_orthogonal_colours_are_ninety_degrees_apart():
    ref = np.zeros((2, 2, 3))
    img = np.zeros((2, 2, 3))
    ref[..., 0] = 1.0
    img[..., 1] = 1.0
    assert image_metrics(ref, img).mean_angular_error_deg == pytest.approx(90.0)


def test_metrics_refuse_mismatched_or_empty_images():
    with pytest.raises(SatsightError, match=r"images must both be \(H, W, 3\)"):
        image_metrics(np.ones((2, 2, 3)), np.ones((2, 3, 3)))
    with pytest.raises(SatsightError, match="neither image sees the target"):
        image_metrics(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)))


def test_ablation_camera_keeps_the_field_of_view():
    camera = PinholeCamera.high_resolution()
    small = ablation_camera(camera, 512)
    assert small.width_px == 512
    assert small.fov_x_rad == pytest.approx(camera.fov_x_rad, rel=1e-12)
    assert small.fov_y_rad == pytest.approx(camera.fov_y_rad, rel=2e-3)


# The two-wing satellite's eleven materials folded into five of different kinds: a bare
# metal, a metallised film, a white diffuser, a dark dielectric and glossy cells. Each
# material costs a least-squares fit of both Phong forms to its GGX BRDF (most of the run
# time); five kinds still set every variant far above the noise floor (at the settings of
# ``ablation_run``: 17x the exact variant's MSE or more, against the 5x asked for below).
FIVE_MATERIALS = {
    "brushed_aluminium": "brushed_aluminium",
    "titanium_hinge": "brushed_aluminium",
    "black_metal": "brushed_aluminium",
    "mli_gold": "mli_silver",
    "white_paint": "antenna_white",
    "antenna_white": "antenna_white",
    "black_crinkle": "cfrp",
    "optical_lens": "cfrp",
    "cfrp": "cfrp",
    "solar_cell": "solar_cell",
    "panel_substrate": "solar_cell",
}


def _five_material_target(folder: Path) -> dict:
    """A scenario's ``target`` section: the two-wing satellite (seed 2) written as OBJ into
    ``folder``, every file material replaced by its built-in of ``FIVE_MATERIALS``."""
    obj_path, _ = write_obj(generate_satellite("two_wings", seed=2), folder / "two_wings.obj")
    return {"mesh": {"path": str(obj_path), "materials": FIVE_MATERIALS}}


@pytest.fixture(scope="module")
def ablation_run(tmp_path_factory) -> tuple[Path, dict[str, list[np.ndarray]]]:
    """``satsight ablate`` on a one-frame scenario: its output folder, and the radiance
    images (W m^-2 sr^-1) that ``run_ablation`` rendered for it, by run name."""
    root = tmp_path_factory.mktemp("ablate")
    scenario = {
        "name": "ablation-test",
        "target": _five_material_target(root),
        "sun": {"azimuth_deg": 30.0, "elevation_deg": 40.0},
        "earth": {"azimuth_deg": 0.0, "elevation_deg": -70.0, "altitude_km": 500.0},
        "frames": [{"distance_km": 0.06, "azimuth_deg": 20.0, "elevation_deg": 30.0}],
        "render": {"bounces": 1},
    }
    config = root / "scenario.yaml"
    config.write_text(yaml.safe_dump(scenario), encoding="utf-8")
    out = root / "out"
    images: dict[str, list[np.ndarray]] = {}

    def keeping_images(*args, **kwargs):
        result = run_ablation(*args, **kwargs)
        images.update(result.images)
        return result

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("satsight.tools.ablation.run_ablation", keeping_images)
        main(["ablate", str(config), "--out", str(out), "--spp", "32", "--reference-spp", "256",
              "--width", "48"])  # fmt: skip
    return out, images


@pytest.fixture(scope="module")
def ablation_dir(ablation_run) -> Path:
    return ablation_run[0]


def _colour_angle_deg(reference: np.ndarray, image: np.ndarray) -> float:
    """Mean angle between the RGB vectors of two (H, W, 3) images over the pixels where both
    are non-zero, from the chord between the unit vectors: 2 asin(|a/|a| - b/|b||/2)."""
    reference, image = reference.astype(np.float64), image.astype(np.float64)
    a_norm = np.linalg.norm(reference, axis=-1)
    b_norm = np.linalg.norm(image, axis=-1)
    both = (a_norm > 0) & (b_norm > 0)
    a = reference[both] / a_norm[both][:, None]
    b = image[both] / b_norm[both][:, None]
    chord = np.linalg.norm(a - b, axis=-1)
    return float(np.degrees(2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0))).mean())


def test_ablate_writes_table_and_figure(ablation_run):
    ablation_dir, images = ablation_run
    with (ablation_dir / "ablation.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["variant"] for row in rows] == list(VARIANTS)
    (reference,) = images["reference"]
    for row in rows:
        mse = float(row["mse_w2_m4_sr2"])
        assert mse > 0.0
        # The table's angle is the colour angle of the rendered images, computed here by
        # another formula (the chord between unit vectors, not atan2 of cross and dot).
        (image,) = images[row["variant"]]
        expected_deg = _colour_angle_deg(reference, image)
        angle_deg = float(row["mean_angular_error_deg"])
        assert angle_deg == pytest.approx(expected_deg, rel=1e-9, abs=1e-12)
        assert int(row["frames"]) == 1
    # Three rows of panels, one column per run (reference and variants), 3 x 8.5 inches each
    # at 110 dpi; the metrics' bars in tab:blue.
    figure = figure_pixels(
        ablation_dir / "ablation.png", (round(3.0 * (len(VARIANTS) + 1) * 110), round(8.5 * 110))
    )
    assert has_colour(figure, to_rgba("tab:blue"))
    fits = json.loads((ablation_dir / "phong_fits.json").read_text(encoding="utf-8"))["fits"]
    assert {row["model"] for row in fits} == set(FITTED_VARIANTS.values())
    for row in fits:
        assert all(kd + ks <= 1.0 for kd, ks in zip(row["kd_rgb"], row["ks_rgb"], strict=True))


def test_fitted_variants_render_with_coefficients_fitted_to_each_part(llvm_variant, tmp_path):
    """improved_phong and phong render every part with the coefficients fitted to its GGX
    material (the renderer's per-part tables hold them); the *_mapped variants and the
    reference keep the scenario's materials. Five materials over the satellite's 19 parts:
    each fit follows its part's own material."""
    from satsight.brdf.reference_fit import fit_phong_to_ggx
    from satsight.render.settings import DIRECT_SUN_ONLY
    from satsight.render.surface import SurfaceModel

    scenario = Scenario.model_validate(
        {
            "name": "fitted",
            "target": _five_material_target(tmp_path),
            "frames": [{"distance_km": 0.05}],
        }
    )
    mesh = scenario.target.build()
    meshes, fits = fitted_phong_meshes(mesh, "schlick")
    assert set(meshes) == set(FITTED_VARIANTS) and set(fits) == set(mesh.part_materials)
    for variant, model in FITTED_VARIANTS.items():
        parts = [meshes[variant].part_material(i) for i in range(len(mesh.part_names))]
        expected = [fit_phong_to_ggx(mesh.part_material(i)).fits[model].coefficients
                    for i in range(len(mesh.part_names))]  # fmt: skip
        assert [m.phong for m in parts] == expected
        assert all(m.phong != m.mapped_phong_coefficients for m in parts)
        surface = SurfaceModel(parts, DIRECT_SUN_ONLY.with_(brdf=model))
        kd = np.array(surface._params.kd).T  # (parts, 3)
        np.testing.assert_allclose(kd, [c.kd_rgb for c in expected], rtol=1e-6, atol=1e-7)
        g = np.array(surface._params.g)
        np.testing.assert_allclose(g, [c.gloss_exponent_g for c in expected], rtol=1e-6)
    assert all(m.phong is None for m in mesh.materials.values())


def test_ablate_ranks_the_noise_floor_first(ablation_dir: Path):
    """The exact model at fewer samples differs from the reference only by noise, and with
    common random numbers that noise is small: it has the smallest MSE and colour-angle
    error, and every changed model stands clearly above it."""
    with (ablation_dir / "ablation.csv").open(encoding="utf-8") as handle:
        rows = {row["variant"]: row for row in csv.DictReader(handle)}
    angle = {name: float(row["mean_angular_error_deg"]) for name, row in rows.items()}
    mse = {name: float(row["mse_w2_m4_sr2"]) for name, row in rows.items()}
    assert angle["exact"] == min(angle.values())
    for name in VARIANTS:
        if name != "exact":
            assert mse[name] > 5.0 * mse["exact"], (name, mse)


def test_common_random_numbers_make_exact_equal_the_reference_at_equal_samples(tmp_path):
    """Reference and variants of a frame share its seed: at equal sample counts the exact
    variant is the reference, bit for bit."""
    scenario = Scenario.model_validate(
        {
            "name": "crn",
            "target": _five_material_target(tmp_path),
            "sun": {"azimuth_deg": 10.0, "elevation_deg": 50.0},
            "frames": [{"distance_km": 0.05, "azimuth_deg": 40.0, "elevation_deg": 20.0}],
            "render": {"bounces": 1},
        }
    )
    result = run_ablation(scenario, samples_per_pixel=4, reference_samples_per_pixel=4, width_px=32)
    assert result.images["exact"][0].tobytes() == result.images["reference"][0].tobytes()
    assert result.rows[-1]["variant"] == "exact"
    assert result.rows[-1]["mse_w2_m4_sr2"] == 0.0


def test_ablate_refuses_reference_below_variant_samples(tmp_path: Path):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["ablate", "examples/first_light.yaml", "--out", str(out), "--spp", "8",
              "--reference-spp", "4"])  # fmt: skip
    assert stop.value.code == 2
    assert not out.exists()


def test_orbital_scenario_ablates_its_lit_frames_only(tmp_path):
    """Frames in the umbra that see only the Earth's night side are black: left out. The
    example's orbits with the five-material satellite as target (which frames are lit does
    not depend on the target's materials, and its fits are those of the tests above)."""
    from satsight.cli import example_scenario_path
    from satsight.config.scenario import load_scenario
    from satsight.config.target import TargetConfig
    from satsight.poses.plan import plan_track

    scenario = load_scenario(example_scenario_path().parent / "fly_by.yaml")
    target = TargetConfig.model_validate(_five_material_target(tmp_path))
    scenario = scenario.model_copy(update={"target": target})
    track = plan_track(scenario.plan_request(), scenario.target.build().center_m)
    dark = track.sunlit_fraction[:8] == 0.0
    assert dark.any()  # the example's pass crosses the umbra
    planned: list[int] = []
    result = run_ablation(
        scenario,
        samples_per_pixel=1,
        reference_samples_per_pixel=2,
        width_px=128,  # the 7 m target spans up to 9 pixels at the pass's 5 km
        max_frames=8,
        on_plan=planned.append,
    )
    assert planned[0] == len(result.images["reference"]) < 8
    assert all(row["frames"] == planned[0] for row in result.rows)
