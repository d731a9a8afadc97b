"""The command line end to end: the demo dataset on disk, and the error paths.

The full demo (six 4096 x 4112 frames) runs once per module; every check of its files
reads what it wrote.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.colors import to_rgba
from scipy.ndimage import binary_dilation, binary_erosion, maximum_filter

from cli_runner import invoke_satsight, run_satsight
from dataset_files import footprint_box_mask
from figure_checks import figure_pixels, has_colour
from qe_oracle import blackbody_qe, solar_qe
from satsight.camera.pinhole import PinholeCamera
from satsight.cli import example_scenario_path, main
from satsight.config.scenario import load_scenario
from satsight.dataset.image_files import read_exr, read_png
from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.lighting.solar_spectrum import photon_weighted_wavelength_m
from satsight.scene.loading import load_mesh

FRAME_COUNT = 6
HEIGHT_PX, WIDTH_PX = 4112, 4096
DEPTH_MEDIAN_RTOL = 0.03  # the target is a few metres deep at >= 800 m
# Normals are stored as half floats: each component within 2^-11 of its value, so a unit
# normal's length within 2^-11 of 1 (sum c dc <= 2^-11 sum c^2), plus float32 rounding.
UNIT_NORMAL_ATOL = 2.0**-11 + 1e-6
FILE_KEYS = (
    "dn_png16",
    "preview_png8",
    "radiance_exr",
    "depth_exr",
    "normals_exr",
    "object_mask_png",
    "part_mask_png16",
    "background_mask_png",
)
TOP_LEVEL_KEYS = {
    "format",
    "version",
    "satsight_version",
    "scenario",
    "render_variant",
    "conventions",
    "camera",
    "sun",
    "render_settings",
    "sensor",
    "preview",
    "environment_light",
    "target",
    "frames",
    "frame_count",
    "plan_indices",
    "outputs",
    "scenario_sha256",
    "shard",
}


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "dataset"
    main(["demo", "--out", str(out)])
    return out


@pytest.fixture(scope="module")
def labels(demo_dir: Path) -> dict:
    return json.loads((demo_dir / "labels.json").read_text(encoding="utf-8"))


# --- the demo dataset ---------------------------------------------------------------------
def test_demo_writes_six_frames_and_closes_the_dataset(demo_dir: Path, labels) -> None:
    assert len(labels["frames"]) == FRAME_COUNT
    assert [f["frame_index"] for f in labels["frames"]] == list(range(FRAME_COUNT))
    assert [p.name for p in demo_dir.parent.iterdir()] == ["dataset"]
    names = {p.name for p in demo_dir.iterdir()}
    assert {"manifest.json", "journal.jsonl", "labels.json", "complete.json"} <= names
    journal = (demo_dir / "journal.jsonl").read_text(encoding="utf-8").splitlines()
    assert [json.loads(line) for line in journal] == labels["frames"]
    assert not [p for p in demo_dir.rglob(".*") if ".tmp-" in p.name]
    for folder in ("images", "previews", "radiance", "depth", "normals", "masks"):
        assert len(list((demo_dir / folder).iterdir())) == FRAME_COUNT * (
            3 if folder == "masks" else 1
        )


def test_labels_top_level(labels) -> None:
    assert set(labels) == TOP_LEVEL_KEYS
    assert labels["format"] == "satsight-dataset"
    assert labels["version"] == 3
    assert labels["frame_count"] == FRAME_COUNT and labels["shard"] is None
    assert labels["outputs"]["files"] == ["dn", "preview", "radiance", "depth", "normals", "masks"]
    assert labels["scenario"] == "first-light"
    assert labels["render_variant"] in ("llvm_ad_rgb", "cuda_ad_rgb")
    preset = PinholeCamera.high_resolution()
    camera = labels["camera"]
    np.testing.assert_array_equal(camera["K"], preset.K)
    assert camera["image_size_px"] == [WIDTH_PX, HEIGHT_PX]
    assert camera["focal_length_m"] == 3.0
    assert camera["pixel_pitch_m"] == 15e-6
    for key in ("units", "quaternion", "pose", "camera_frame", "pixel_origin", "depth"):
        assert labels["conventions"][key]
    parts = labels["target"]["parts"]
    assert len(parts) >= 2
    assert [p["part_id"] for p in parts] == list(range(1, len(parts) + 1))
    assert all(p["name"] and p["material"] and p["triangle_count"] > 0 for p in parts)
    assert labels["target"]["name"] == "two_wings_dish-seed3"
    assert len(labels["target"]["box_keypoints_body_m"]) == 9
    assert len(labels["target"]["keypoints_body_m"]) == 11  # surface keypoints by default
    assert labels["target"]["keypoints"]["method"] == "surface"
    az, el = np.radians(40.0), np.radians(35.0)
    for frame in labels["frames"]:
        np.testing.assert_allclose(
            frame["sun_direction_body"],
            [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)],
            atol=1e-12,
        )
        assert frame["plan"]["visible"] and frame["plan"]["epoch_utc"] is None


def test_model_contact_sheet_and_scenario_copy(demo_dir: Path, labels) -> None:
    # The six frames as thumbnails, three to a row, 4.2 x 4.8 inches each at 100 dpi.
    figure_pixels(demo_dir / "contact_sheet.png", (3 * 420, 2 * 480))
    assert (demo_dir / "model" / "target.obj").is_file()
    assert (demo_dir / "model" / "target.mtl").is_file()
    mesh = load_mesh(demo_dir / "model" / "target.obj")
    assert mesh.part_names == tuple(p["name"] for p in labels["target"]["parts"])
    np.testing.assert_allclose(mesh.bounds_m, labels["target"]["bounds_m"], atol=1e-6)
    copy = load_scenario(demo_dir / "scenario.yaml")
    assert copy == load_scenario(example_scenario_path())


@pytest.mark.parametrize("index", range(FRAME_COUNT))
def test_frame_files(demo_dir: Path, labels, index: int) -> None:
    frame = labels["frames"][index]
    files = frame["files"]
    assert set(files) == set(FILE_KEYS)
    for key in FILE_KEYS:
        assert (demo_dir / files[key]).is_file(), files[key]
    camera = PinholeCamera.high_resolution()
    part_count = len(labels["target"]["parts"])

    object_mask = read_png(demo_dir / files["object_mask_png"])
    assert object_mask.dtype == np.uint8
    assert object_mask.shape == (HEIGHT_PX, WIDTH_PX)
    assert set(np.unique(object_mask).tolist()) == {0, 255}
    on = object_mask > 0
    assert int(on.sum()) == frame["object_pixel_count"] > 0
    assert mask_bbox_xyxy_px(on) == frame["bbox_xyxy_px"]

    # Radiance: float32 EXR, light only on the target.
    radiance = read_exr(demo_dir / files["radiance_exr"])
    assert set(radiance) == {"RGB"}
    radiance = radiance["RGB"]
    assert radiance.dtype == np.float32
    assert radiance.shape == (HEIGHT_PX, WIDTH_PX, 3)
    # Off the target: empty space (0) or the sunlit Earth / Moon behind it, whose Lambertian
    # radiance is at most albedo E / pi (albedo <= 1, E the in-band solar irradiance).
    off = radiance[~on]
    assert off.min() >= 0.0 and off.max() <= 1400.0 / math.pi
    # Pixels with light, radiance.max(axis=2) > 0 taken channel by channel (a reduction
    # over the last axis of a 4096 x 4112 x 3 image is several times slower).
    lit = np.maximum(np.maximum(radiance[..., 0], radiance[..., 1]), radiance[..., 2]) > 0
    # The background mask: 0 on the target, a body (1 Earth, 2 Moon) under every lit pixel
    # off it, and the Earth's and Moon's pixels those the exposure labels count.
    background = read_png(demo_dir / files["background_mask_png"])
    assert background.dtype == np.uint8 and background.shape == (HEIGHT_PX, WIDTH_PX)
    assert set(np.unique(background).tolist()) <= {0, 1, 2}
    assert not background[on].any()
    # Light off the mask comes from a body behind, or from a small target's pixels whose
    # radiance was integrated over their area (the projected box of its footprint label).
    integrated = footprint_box_mask(on.shape, frame["target_footprint"])
    assert background[~on & lit & ~integrated].all()
    regions = frame["sensor"]["regions"]
    assert regions["target"]["pixel_count"] == frame["object_pixel_count"]
    for value, name in ((1, "earth"), (2, "moon")):
        assert regions[name]["pixel_count"] == np.count_nonzero(background == value)
        assert regions[name]["saturated_pixel_count"] <= regions[name]["pixel_count"]
    assert (
        sum(r["saturated_pixel_count"] for r in regions.values())
        <= frame["sensor"]["saturated_pixel_count"]
    )
    _check_photometry(labels, frame, radiance, on, background > 0)
    _check_dn_image(demo_dir, labels, frame, radiance, on, lit)
    del radiance

    # Depth: 0 exactly off the target, positive on it, about the range to the box centre.
    depth = read_exr(demo_dir / files["depth_exr"])
    assert set(depth) == {"Z"}
    depth = depth["Z"]
    assert depth.dtype == np.float32
    assert depth.shape == (HEIGHT_PX, WIDTH_PX)
    assert np.all(depth[~on] == 0.0)
    assert np.all(depth[on] > 0.0)
    assert float(np.median(depth[on])) == pytest.approx(
        frame["range_to_center_m"], rel=DEPTH_MEDIAN_RTOL
    )
    assert frame["range_to_center_m"] == pytest.approx(
        labels["frames"][index]["view"]["distance_km"] * 1e3, rel=1e-12
    )
    del depth

    # Part ids: 1..parts on the target, 0 elsewhere.
    parts = read_png(demo_dir / files["part_mask_png16"])
    assert parts.dtype == np.uint16
    assert parts.shape == (HEIGHT_PX, WIDTH_PX)
    np.testing.assert_array_equal(parts > 0, on)
    assert parts[on].min() >= 1
    assert parts[on].max() <= part_count

    # Normals: unit on the target, zero off it, facing the camera.
    normals = read_exr(demo_dir / files["normals_exr"])
    # Plain X, Y, Z channels, as the README documents (not a "XYZ.R" group).
    assert set(normals) == {"X", "Y", "Z"}
    normals = np.stack([normals["X"], normals["Y"], normals["Z"]], axis=-1)
    assert normals.dtype == np.float32
    assert normals.shape == (HEIGHT_PX, WIDTH_PX, 3)
    n_on = normals[on].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(n_on, axis=1), 1.0, rtol=0, atol=UNIT_NORMAL_ATOL)
    assert not normals[~on].any()
    v, u = np.nonzero(on)
    rays = camera.ray_directions_cam(np.stack([u, v], axis=1).astype(np.float64))
    # Facing the camera, to the stored precision (|r . dn| <= |dn| <= 2^-11).
    assert np.all(np.einsum("ij,ij->i", rays, n_on) <= UNIT_NORMAL_ATOL)

    # The box centre keypoint lies on the optical axis (views look at the box centre).
    np.testing.assert_allclose(
        frame["box_keypoints_px"][8], [camera.cx_px, camera.cy_px], rtol=0, atol=1e-6
    )


def _check_photometry(
    labels: dict, frame: dict, radiance: np.ndarray, on: np.ndarray, body: np.ndarray
) -> None:
    """The target's in-band irradiance at the camera: the sum of the in-band radiance times
    each pixel's solid angle (p / f)^2 cos^3(theta) over the pixels whose footprint meets
    the target's projected box, but for those near the Earth's disc and not near the target;
    its V-equivalent magnitude -26.76 - 2.5 log10(E / E_sun) with the Sun at 1 AU.
    on: the object mask; body: the pixels whose centre sees the Earth or the Moon."""
    corners = np.array(frame["box_keypoints_px"][:8])
    x0, y0 = np.floor(corners.min(axis=0) + 0.5).astype(int)
    x1, y1 = np.floor(corners.max(axis=0) + 0.5).astype(int) + 1
    window = np.s_[y0:y1, x0:x1]
    summed = np.ones((y1 - y0, x1 - x0), dtype=bool)
    if body.any():  # the Earth is drawn
        # The pixels within one pixel of a pixel that sees it are left out, unless within
        # one pixel of the mask. Two 3 x 3 dilations:
        # the window's pixels depend on those within 2 pixels of it, and the dilations run
        # on that neighbourhood alone (cut at the image's edges, as the whole image is).
        square = np.ones((3, 3), dtype=bool)
        top, left = max(y0 - 2, 0), max(x0 - 2, 0)
        near = np.s_[top : y1 + 2, left : x1 + 2]
        ring = binary_dilation(on[near], structure=square)
        summed = (ring | ~binary_dilation(body[near], structure=square))[
            y0 - top : y1 - top, x0 - left : x1 - left
        ]
    K = np.array(labels["camera"]["K"])
    v, u = np.mgrid[window]
    cos3 = (1.0 + ((u - K[0, 2]) / K[0, 0]) ** 2 + ((v - K[1, 2]) / K[1, 1]) ** 2) ** -1.5
    band = radiance[window].astype(np.float64) @ np.array(labels["sensor"]["channel_weights_rgb"])
    p_over_f = labels["camera"]["pixel_pitch_m"] / labels["camera"]["focal_length_m"]
    irradiance = float(np.sum(np.where(summed, band, 0.0) * cos3)) * p_over_f**2
    assert irradiance > 0
    assert frame["target_irradiance_w_m2"] == pytest.approx(irradiance, rel=1e-5)
    magnitude = -26.76 - 2.5 * math.log10(irradiance / frame["sun_irradiance_w_m2"])
    assert frame["target_v_magnitude_equivalent"] == pytest.approx(magnitude, abs=1e-5)


def _check_dn_image(
    demo_dir: Path,
    labels: dict,
    frame: dict,
    radiance: np.ndarray,
    on: np.ndarray,
    lit: np.ndarray,
) -> None:
    """The raw DN frame against the radiance it was exposed from, in closed form (on: the
    object mask; lit: the pixels with radiance above 0)."""
    sensor = labels["sensor"]
    detector, optics = sensor["detector"], sensor["optics"]
    dn = read_png(demo_dir / frame["files"]["dn_png16"])
    assert dn.dtype == np.uint16
    assert dn.shape == (HEIGHT_PX, WIDTH_PX)
    preview = read_png(demo_dir / frame["files"]["preview_png8"])
    assert preview.dtype == np.uint8 and preview.shape == dn.shape
    exposure_s = frame["sensor"]["exposure_time_s"]
    assert exposure_s > 0
    gain = detector["conversion_gain_e_per_dn"]
    bias = detector["bias_dn"]
    # Empty sky beyond the blur's reach (the frame kernel's radius) of the target and of the
    # Earth or Moon behind it: bias plus read noise (dark current over ms is ~1e-6 e-).
    reach_px = sensor["frame_kernel"]["margin_px"]
    sky = dn[~maximum_filter(on | lit, size=2 * reach_px + 1)].astype(np.float64)
    read_sigma_dn = math.hypot(detector["read_noise_e"] / gain, math.sqrt(1 / 12))
    if sky.size >= 1000:  # frames where the Earth fills the background have no empty sky
        sem = read_sigma_dn / math.sqrt(sky.size)
        assert abs(sky.mean() - bias) < 6 * sem + 0.01
        assert sky.std() == pytest.approx(read_sigma_dn, rel=0.02)
    # The target, in closed form: electrons = E_e A t with E_e = pi L_e tau / (4 N^2) the
    # focal-plane photo-electron irradiance and L_e the photo-electron radiance of the three
    # channels. Per channel: its power over h c / lambda_c, lambda_c the photon-weighted
    # wavelength of its third of the band in the E-490 spectrum, times QE_c, the detector
    # curve's photon-weighted mean over that third (from the data files).
    # Away from the target's edges and from saturated pixels, beyond the PSF's reach (it
    # moves light only locally) and the one pixel at the end of each blooming trail. Those
    # pixels lie in the target's box, and depend on the saturated pixels up to 4 rows and 3
    # columns beyond it: the masks are made on that neighbourhood alone (cut at the image's
    # edges, as the whole image is; the mask is empty beyond the box).
    x_min, y_min, x_max, y_max = frame["bbox_xyxy_px"]
    box = np.s_[max(y_min - 4, 0) : y_max + 5, max(x_min - 3, 0) : x_max + 4]
    saturated = dn[box] >= 0.97 * (bias + detector["full_well_e"] / gain)
    near_saturated = binary_dilation(saturated, structure=np.ones((9, 7), dtype=bool))
    inner = binary_erosion(on[box], iterations=3) & ~near_saturated
    # ... and beyond the PSF's reach of a background brighter than the target (the Earth or
    # Moon behind it), whose light the PSF's wings carry into the target's pixels: on a
    # dark target before the sunlit Earth that adds over 1 % to the sum. A frame whose
    # target lies wholly within that reach has no pixel left to check the sum on.
    y0, x0 = box[0].start, box[1].start
    wy, wx = max(y0 - reach_px, 0), max(x0 - reach_px, 0)
    wide = np.s_[wy : box[0].stop + reach_px, wx : box[1].stop + reach_px]
    level = radiance[on].sum(axis=-1).mean()
    bright = (radiance[wide].sum(axis=-1) > level) & ~on[wide]
    behind = maximum_filter(bright, size=2 * reach_px + 1)
    inner &= ~behind[y0 - wy : y0 - wy + inner.shape[0], x0 - wx : x0 - wx + inner.shape[1]]
    if not inner.any() and behind[y0 - wy :, x0 - wx :].any():
        return
    assert inner.sum() > 300
    edges = np.linspace(*sensor["band_nm"], 4)
    lambda_rgb_m = [photon_weighted_wavelength_m((edges[k], edges[k + 1])) for k in (2, 1, 0)]
    qe_rgb = [solar_qe(edges[k], edges[k + 1]) for k in (2, 1, 0)]
    electron_radiance = radiance[box][inner].astype(np.float64) @ (
        np.array(sensor["channel_weights_rgb"])
        * np.array(lambda_rgb_m)
        * np.array(qe_rgb)
        / (6.62607015e-34 * 299792458.0)
    )  # photo-electrons s^-1 m^-2 sr^-1
    focal = np.pi * electron_radiance * optics["transmission"] / (4.0 * sensor["f_number"] ** 2)
    expected_e = focal * detector["pixel_pitch_m"] ** 2 * exposure_s
    # Measured 0.9956-1.0005 over the six frames; PRNU (1 %) and shot noise average out
    # to < 0.1 % over these pixel counts, the rest is light the PSF moves across the edge.
    measured_e = (dn[box][inner].astype(np.float64) - bias) * gain
    assert measured_e.sum() == pytest.approx(expected_e.sum(), rel=0.01)


# --- error paths and the other commands -----------------------------------------------------
# One check of each command runs it in a child process (run_satsight), as a user would; the
# others in this interpreter (invoke_satsight: the same exit status and messages, without
# starting Python again).
def test_unknown_key_exits_2_naming_the_key_and_writes_nothing(tmp_path: Path) -> None:
    data = yaml.safe_load(example_scenario_path().read_text(encoding="utf-8"))
    data["frames"][1]["distanse_km"] = 3.0
    config = tmp_path / "typo.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    out = tmp_path / "never"
    result = run_satsight("generate", str(config), "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "frames.1.distanse_km" in result.stderr
    assert "unknown key" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["typo.yaml"]


def test_non_empty_output_folder_without_overwrite_exits_2_untouched(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    out.mkdir()
    (out / "keep.txt").write_text("precious", encoding="utf-8")
    result = run_satsight("demo", "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "not empty" in result.stderr and "--overwrite" in result.stderr
    assert "Traceback" not in result.stderr
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert (out / "keep.txt").read_text(encoding="utf-8") == "precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset"]


def test_overwrite_refuses_a_folder_that_is_not_a_dataset(tmp_path: Path) -> None:
    out = tmp_path / "documents"
    out.mkdir()
    (out / "thesis.tex").write_text("precious", encoding="utf-8")
    result = invoke_satsight("demo", "--out", str(out), "--overwrite", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "only satsight datasets" in result.stderr
    assert "Traceback" not in result.stderr
    assert [p.name for p in out.iterdir()] == ["thesis.tex"]


def test_unwritable_output_exits_2_without_traceback(tmp_path: Path) -> None:
    """An operating-system error (here: a folder under /proc cannot be created) is reported
    as a message, not a traceback."""
    result = run_satsight("satellite", "one_wing", "--out", "/proc/satsight-x/y.obj", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert "error" in result.stderr


def test_missing_scenario_file_exits_2(tmp_path: Path) -> None:
    result = invoke_satsight("generate", "absent.yaml", "--out", "x", cwd=tmp_path)
    assert result.returncode == 2
    assert "scenario file not found" in result.stderr
    assert "Traceback" not in result.stderr


def test_satellite_writes_obj_and_mtl(tmp_path: Path) -> None:
    out = tmp_path / "models" / "X.obj"
    result = invoke_satsight(
        "satellite", "four_panels", "--seed", "2", "--out", str(out), cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert out.is_file()
    assert out.with_suffix(".mtl").is_file()
    obj = out.read_text(encoding="utf-8")
    assert "mtllib X.mtl" in obj
    assert obj.count("\nf ") > 100
    mesh = load_mesh(out)
    assert len(mesh.part_names) >= 2
    assert 2.0 <= float(mesh.extent_m.max()) <= 10.0


def test_unknown_satellite_class_exits_2(tmp_path: Path) -> None:
    out = tmp_path / "X.obj"
    result = invoke_satsight("satellite", "nope", "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2
    assert "nope" in result.stderr and "two_wings" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_bench_prints_json(tmp_path: Path) -> None:
    result = run_satsight(
        "bench", "--frames", "5", "--sizes", "64x64", "--radiative-sizes", "48x48", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["benchmark"] == "render"
    assert report["variant"] in ("llvm_ad_rgb", "cuda_ad_rgb")
    stages = [entry["stage"] for entry in report["results"]]
    assert stages[:3] == [
        "render_direct_sun",
        "sun_unshadowed_sh_1_bounce",
        "sun_sampled_sh_2_bounces",
    ]
    assert stages.count("scaling_bounces") == 4 and stages.count("scaling_samples") == 3
    direct = report["results"][0]
    assert (direct["width_px"], direct["height_px"], direct["bounces"]) == (64, 64, 0)
    assert all(entry["width_px"] == 48 for entry in report["results"][1:])
    for entry in report["results"]:
        assert entry["frames_timed"] == 5
        assert entry["median_s"] > 0
        assert entry["min_s"] <= entry["median_s"] <= entry["max_s"]


@pytest.mark.parametrize("sizes", ["64", "64x", "0x64", "axb"])
def test_bench_bad_sizes_exit_2(tmp_path: Path, sizes: str) -> None:
    result = invoke_satsight("bench", "--sizes", sizes, cwd=tmp_path)
    assert result.returncode == 2
    assert "--sizes must look like" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    "args",
    [["--dataset", "3", "--cluster-scaling", "3"], ["--cluster-scaling", "2"]],
    ids=["both", "too-few-frames"],
)
def test_bench_refuses_two_modes_or_too_few_frames(tmp_path: Path, args: list) -> None:
    result = invoke_satsight("bench", *args, cwd=tmp_path)
    assert result.returncode == 2
    assert "not both" in result.stderr or "x>=3" in result.stderr
    assert "Traceback" not in result.stderr


# --- satsight camera ---------------------------------------------------------------------------
def test_camera_command_reports_limiting_magnitudes_and_plots_the_mtf(tmp_path: Path) -> None:
    out = tmp_path / "camera"
    result = invoke_satsight("camera", "--out", str(out), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "limiting V at SNR 5" in result.stdout
    report = json.loads((out / "camera.json").read_text(encoding="utf-8"))
    assert report["f_number"] == pytest.approx(10.0)
    assert report["ifov_urad"] == pytest.approx(5.0)
    limits = [row["v_mag"] for row in report["limiting_magnitude_snr5"]]
    # Read-noise limited (a few photo-electrons against 5 e- rms): the signal needed is
    # fixed, so the limit moves 2.5 mag per decade of exposure; shot noise bends it a little.
    steps = np.diff(limits)
    assert np.all(steps > 2.3) and np.all(steps <= 2.5 + 1e-9)
    reference = report["reference_exposure"]
    assert 1e-4 < reference["exposure_time_s"] < 1e-2
    # The detector's QE: the curve's photon-weighted mean for sunlight over the band (the
    # target), and for the 5772 K black body of the limiting-magnitude star.
    assert report["quantum_efficiency"] == pytest.approx(solar_qe(450.0, 900.0), rel=1e-5)
    assert report["quantum_efficiency_source"].startswith("CCD231-84 curve")
    star_qe = float(blackbody_qe(450.0, 900.0, np.array([5772.0]))[0])
    for row in [reference, *report["limiting_magnitude_snr5"]]:
        assert row["star_quantum_efficiency"] == pytest.approx(star_qe, rel=1e-5)
    # 7 x 4.5 inches at 100 dpi: the diffraction, pixel and jitter curves in the colour
    # cycle's first three colours, the system MTF in black.
    figure = figure_pixels(out / "system_mtf.png", (700, 450))
    for colour in ("C0", "C1", "C2", "k"):
        assert has_colour(figure, to_rgba(colour)), colour


def test_camera_command_rejects_a_bad_scenario(tmp_path: Path) -> None:
    config = tmp_path / "bad.yaml"
    config.write_text("camera: {optics: {transmission: 2}}\n", encoding="utf-8")
    result = run_satsight("camera", str(config), "--out", str(tmp_path / "c"), cwd=tmp_path)
    assert result.returncode == 2
    assert "transmission" in result.stderr and "Traceback" not in result.stderr
