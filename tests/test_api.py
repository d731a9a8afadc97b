"""The Python interface: frames rendered to arrays equal the frames a dataset run writes,
overrides are validated, arrays have their documented shapes, types and units, and an
opened dataset gives its frames in order."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from scipy.spatial.transform import Rotation

import satsight
from dataset_files import footprint_box_mask
from satsight.config.scenario import RenderConfig
from satsight.dataset.reader import open_dataset as open_reader
from tolerances import ONE_MM, ONE_UM

WIDTH_PX, HEIGHT_PX, CROP_PX = 80, 64, 32
DISTANCES_KM = (2.0, 3.0, 4.5)
BOX_EXTENTS_M = (2.0, 1.0, 0.6)


def scenario_dict(mesh_path: Path | str) -> dict:
    """A box of 2 x 1 x 0.6 m seen from 2-4.5 km in an 80 x 64 px frame, with 32 px crops."""
    angles = [(30.0, 20.0, 10.0), (120.0, -35.0, 0.0), (250.0, 60.0, -40.0)]
    return {
        "name": "api-test",
        "seed": 3,
        "camera": {"preset": "wide_field", "width_px": WIDTH_PX, "height_px": HEIGHT_PX},
        "target": {"mesh": {"path": str(mesh_path), "materials": {"geometry_0": "white_paint"}}},
        "sun": {"azimuth_deg": 60.0, "elevation_deg": 25.0},
        "frames": [
            {"distance_km": d, "azimuth_deg": az, "elevation_deg": el, "roll_deg": roll}
            for d, (az, el, roll) in zip(DISTANCES_KM, angles, strict=True)
        ],
        "render": {"bounces": 1},
        "outputs": {"crop": {"size_px": CROP_PX}},
    }


@pytest.fixture(scope="module")
def mesh_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("mesh") / "box.glb"
    trimesh.creation.box(extents=BOX_EXTENTS_M).export(path)
    return path


@pytest.fixture(scope="module")
def scenario(mesh_path: Path) -> satsight.Scenario:
    return satsight.load_scenario(scenario_dict(mesh_path))


@pytest.fixture(scope="module")
def dataset(scenario, tmp_path_factory) -> satsight.Dataset:
    return satsight.generate(scenario, tmp_path_factory.mktemp("generated") / "ds")


@pytest.fixture(scope="module")
def simulator(scenario) -> satsight.Simulator:
    return satsight.Simulator(scenario)


@pytest.fixture(scope="module")
def rendered(simulator) -> list[satsight.Frame]:
    return list(simulator.frames())


def without_files(record: dict) -> dict:
    """A dataset frame record less what only a written frame has (its files)."""
    labels = {k: v for k, v in record.items() if k not in ("files", "checksums")}
    if "crop" in labels:
        labels["crop"] = {k: v for k, v in labels["crop"].items() if k != "files"}
    return labels


# --- import --------------------------------------------------------------------------------
def test_import_satsight_loads_nothing_heavy() -> None:
    code = (
        "import sys, satsight\n"
        "heavy = ('mitsuba', 'drjit', 'pydantic', 'numpy')\n"
        "print([m for m in heavy if m in sys.modules])\n"
        "satsight.load_scenario\n"
        "print([m for m in heavy if m in sys.modules])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, after = out.stdout.splitlines()
    assert before == "[]"
    assert "mitsuba" not in after and "drjit" not in after  # the renderer loads with a frame


def test_unknown_names_are_attribute_errors() -> None:
    with pytest.raises(AttributeError, match="render_frame"):
        satsight.render_frame  # noqa: B018


# --- rendered frames are the dataset's frames ----------------------------------------------
def test_rendered_frames_equal_the_generated_frames(rendered, dataset) -> None:
    assert len(rendered) == len(dataset) == len(DISTANCES_KM)
    for frame, stored in zip(rendered, dataset, strict=True):
        assert frame.labels == without_files(stored.labels)
        np.testing.assert_array_equal(frame.dn, stored.dn())
        np.testing.assert_array_equal(frame.object_mask, stored.object_mask())
        np.testing.assert_array_equal(frame.part_id, stored.part_id())
        np.testing.assert_array_equal(frame.background_mask, stored.background_mask())
        np.testing.assert_array_equal(frame.depth_m, stored.depth_m())
        np.testing.assert_array_equal(frame.radiance_w_m2_sr, stored.radiance_w_m2_sr())
        # Normals are stored as half floats (docs/dataset_format.md): 2^-11 relative.
        np.testing.assert_allclose(
            stored.normals_cam(), frame.normals_cam, rtol=2.0**-11, atol=2.0**-25
        )
        x0, y0, x1, y1 = frame.crop_xyxy_px
        assert [x0, y0, x1, y1] == frame.labels["crop"]["box_xyxy_px"]
        np.testing.assert_array_equal(frame.dn[y0:y1, x0:x1], stored.dn(crop=True))
        np.testing.assert_array_equal(frame.depth_m[y0:y1, x0:x1], stored.depth_m(crop=True))


def test_frames_render_lazily_in_the_order_asked(simulator, rendered, monkeypatch) -> None:
    calls = []
    render = simulator.engine.render
    monkeypatch.setattr(simulator.engine, "render", lambda i: calls.append(i) or render(i))
    frames = simulator.frames([2, 0])
    assert calls == []
    first = next(frames)
    assert calls == [2] and first.index == 2
    second = next(frames)
    assert calls == [2, 0] and second.index == 0
    assert second.labels == rendered[0].labels
    np.testing.assert_array_equal(second.dn, rendered[0].dn)
    assert next(frames, None) is None


def test_bad_indices_fail_before_any_rendering(simulator, monkeypatch) -> None:
    calls = []
    monkeypatch.setattr(simulator.engine, "render", calls.append)
    with pytest.raises(satsight.SatsightError, match=r"frame 3 is not among .* 3 frames"):
        simulator.frames([0, 3])
    with pytest.raises(satsight.SatsightError, match="frame -1"):
        simulator.render(-1)
    with pytest.raises(satsight.SatsightError, match="integer"):
        simulator.render(1.0)
    assert calls == []


def test_render_frames_takes_a_mapping_and_overrides(mesh_path, rendered) -> None:
    frames = satsight.render_frames(
        scenario_dict(mesh_path), indices=[1], overrides={"render.bounces": 1}
    )
    (frame,) = frames
    assert frame.labels == rendered[1].labels


# --- arrays: shapes, types, units -----------------------------------------------------------
def test_frame_arrays_have_their_documented_shapes_and_types(rendered) -> None:
    for frame in rendered:
        h, w = HEIGHT_PX, WIDTH_PX
        assert frame.dn.shape == (h, w) and frame.dn.dtype == np.uint16
        assert frame.radiance_w_m2_sr.shape == (h, w, 3)
        assert frame.radiance_w_m2_sr.dtype == np.float32
        assert frame.depth_m.shape == (h, w) and frame.depth_m.dtype == np.float32
        assert frame.object_mask.shape == (h, w) and frame.object_mask.dtype == bool
        assert frame.part_id.shape == (h, w) and frame.part_id.dtype == np.uint16
        assert frame.normals_cam.shape == (h, w, 3) and frame.normals_cam.dtype == np.float32
        assert frame.background_mask.shape == (h, w) and frame.background_mask.dtype == np.uint8
        assert frame.q_cam_from_body.shape == (4,) and frame.t_cam_from_body_m.shape == (3,)
        assert frame.K.shape == (3, 3)
        json.dumps(frame.labels, allow_nan=False)  # plain JSON, as labels.json holds


def test_frame_geometry_is_in_metres_and_pixels(rendered) -> None:
    for frame, distance_km in zip(rendered, DISTANCES_KM, strict=True):
        mask = frame.object_mask
        assert 0 < mask.sum() < mask.size
        np.testing.assert_array_equal(mask, frame.depth_m > 0)
        np.testing.assert_array_equal(mask, frame.part_id > 0)
        # The view looks at the box centre (the body origin) from distance_km.
        t = frame.t_cam_from_body_m
        assert np.linalg.norm(t) == pytest.approx(distance_km * 1e3, abs=ONE_UM)
        # Every visible surface lies between the nearest and farthest box corner (metres).
        corners_depth_m = np.array(frame.labels["box_keypoints_depth_m"][:8])
        depth = frame.depth_m[mask]
        assert corners_depth_m.min() - ONE_MM <= depth.min()
        assert depth.max() <= corners_depth_m.max() + ONE_MM
        # The pose and K project the body origin to the principal point, and the corners to
        # their labelled pixels (SciPy's scalar-first quaternions as the oracle).
        q = frame.q_cam_from_body
        assert np.linalg.norm(q) == pytest.approx(1.0) and q[0] >= 0
        R = Rotation.from_quat(q, scalar_first=True).as_matrix()
        half = np.array(BOX_EXTENTS_M) / 2
        corners_body = np.array(
            [[sx, sy, sz] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)]
        )
        corners_cam = corners_body * half @ R.T + t
        uvw = corners_cam @ frame.K.T
        np.testing.assert_allclose(
            uvw[:, :2] / uvw[:, 2:], np.array(frame.labels["box_keypoints_px"][:8]), atol=1e-6
        )
        center = frame.K @ t
        np.testing.assert_allclose(
            center[:2] / center[2], [(WIDTH_PX - 1) / 2, (HEIGHT_PX - 1) / 2], atol=1e-6
        )
        # Normals are unit vectors facing the camera on the target, zero elsewhere.
        normals = frame.normals_cam
        np.testing.assert_allclose(np.linalg.norm(normals[mask], axis=-1), 1.0, atol=1e-5)
        assert np.all(normals[~mask] == 0)


def test_radiance_and_dn_are_the_lit_target(rendered) -> None:
    for frame in rendered:
        mask = frame.object_mask
        radiance = frame.radiance_w_m2_sr
        assert np.all(radiance >= 0)
        # No Earth, Moon or stars in this scenario: light off the mask only where a small
        # target's pixels were integrated over their area (its footprint label's box).
        off = ~mask & ~footprint_box_mask(mask.shape, frame.labels["target_footprint"])
        assert np.all(radiance[off] == 0)
        assert radiance[mask].max() > 0
        bias_dn = np.median(frame.dn[~mask])
        assert np.median(frame.dn[mask]) > bias_dn + 100


# --- scenarios and overrides ---------------------------------------------------------------
def test_override_replaces_values_and_keeps_the_rest(scenario) -> None:
    changed = satsight.override(
        scenario,
        {"camera.width_px": 40, "frames.1.distance_km": 5.0, "render": {"bounces": 0}},
    )
    assert changed.camera.width_px == 40 and changed.frames[1].distance_km == 5.0
    assert changed.render == RenderConfig(bounces=0)  # a mapping replaces its section
    assert scenario.camera.width_px == WIDTH_PX and scenario.render.bounces == 1  # unchanged
    before, after = scenario.model_dump(), changed.model_dump()
    before["camera"].pop("width_px"), after["camera"].pop("width_px")
    for document in (before, after):
        document["frames"][1].pop("distance_km"), document.pop("render")
    assert before == after


def test_override_creates_absent_sections(scenario) -> None:
    assert satsight.override(scenario, {"outputs.crop": None}).outputs.crop is None
    bare = satsight.override(scenario, {"outputs.crop": None})
    assert satsight.override(bare, {"outputs.crop.size_px": 16}).outputs.crop.size_px == 16


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"camera.widht_px": 40}, r"camera\.widht_px: unknown key"),
        ({"camera.optcs.f_number": 4}, r"camera\.optcs: unknown key"),
        ({"camera.width_px": 0}, r"camera\.width_px: .*greater than or equal to 1.*got 0"),
        ({"sun.band_nm": [900, 450]}, r"sun: .*band_nm"),
        ({"outputs.crop.size_px": 128}, r"outputs\.crop\.size_px \(128\) exceeds the image"),
        ({"frames.3.distance_km": 1.0}, r"frames\.3 names no item .*0 to 2"),
        ({"camera.preset.focal_length_m": 1.0}, r"camera\.preset is a value"),
        ({"camera..width_px": 1}, r"section keys joined by dots"),
        ({"sampler": {"kind": "rssf", "frame_count": 3}}, r"either 'frames'.*or 'sampler'"),
    ],
)
def test_bad_overrides_name_the_key(scenario, overrides, message) -> None:
    with pytest.raises(satsight.SatsightError, match=message):
        satsight.override(scenario, overrides)


def test_scenario_sources_agree(scenario, mesh_path, tmp_path: Path) -> None:
    # A YAML file beside its mesh, naming it by a relative path.
    (tmp_path / "box.glb").write_bytes(mesh_path.read_bytes())
    yaml_path = tmp_path / "scenario.yaml"
    yaml_path.write_text(yaml.safe_dump(scenario_dict("box.glb")), encoding="utf-8")
    from_file = satsight.load_scenario(yaml_path)
    assert from_file.target.mesh.path == (tmp_path / "box.glb").resolve()
    assert from_file.model_dump(exclude={"target"}) == scenario.model_dump(exclude={"target"})
    assert satsight.load_scenario(str(yaml_path)) == from_file
    assert satsight.load_scenario(scenario) is scenario
    overridden = satsight.load_scenario(yaml_path, overrides={"seed": 9})
    assert overridden == satsight.override(from_file, {"seed": 9}) and overridden.seed == 9
    with pytest.raises(satsight.SatsightError, match="YAML file's path, a mapping"):
        satsight.load_scenario(42)
    with pytest.raises(satsight.SatsightError, match=r"target: required key is missing"):
        satsight.load_scenario({"frames": [{"distance_km": 1.0}]})


# --- datasets -------------------------------------------------------------------------------
def test_an_opened_dataset_gives_its_frames_in_order(dataset) -> None:
    opened = satsight.open_dataset(dataset.root)
    reader = open_reader(dataset.root)
    assert opened.complete and len(opened) == reader.frame_count == len(DISTANCES_KM)
    assert [frame.index for frame in opened] == list(range(len(DISTANCES_KM)))
    assert [frame.labels for frame in opened] == list(reader.frames)
    assert opened[-1].index == 2 and [f.index for f in opened[1:]] == [1, 2]
    assert opened.header["scenario"] == "api-test"
    assert opened[0].path("dn_png16") == dataset.root / "images" / "frame_000000.png"


def test_generate_keeps_the_dataset_rules(scenario, dataset) -> None:
    journal = (dataset.root / "journal.jsonl").read_bytes()
    with pytest.raises(satsight.SatsightError, match="holds a complete dataset"):
        satsight.generate(scenario, dataset.root)
    with pytest.raises(satsight.SatsightError, match="not both"):
        satsight.generate(scenario, dataset.root, overwrite=True, resume=True)
    again = satsight.generate(scenario, dataset.root, resume=True)
    assert again.complete and len(again) == len(dataset)
    assert (dataset.root / "journal.jsonl").read_bytes() == journal  # nothing re-rendered


def test_missing_files_and_crops_are_named(scenario, tmp_path: Path) -> None:
    lean = satsight.generate(
        scenario,
        tmp_path / "lean",
        overrides={"frames": scenario_frames(scenario)[:1], "outputs": {"files": ["dn"]}},
    )
    frame = lean[0]
    assert frame.dn().shape == (HEIGHT_PX, WIDTH_PX)
    with pytest.raises(satsight.SatsightError, match=r"depth_m\(\) needs depth_exr.*outputs"):
        frame.depth_m()
    with pytest.raises(satsight.SatsightError, match=r"object_mask\(\) needs object_mask_png"):
        frame.object_mask()
    with pytest.raises(satsight.SatsightError, match="has no crop"):
        frame.dn(crop=True)


def scenario_frames(scenario) -> list[dict]:
    return [view.model_dump() for view in scenario.frames]


def test_export_dataset_writes_the_split_asked_for(dataset, tmp_path: Path) -> None:
    summary = satsight.export_dataset(dataset, tmp_path / "bop", "bop", split=(1.0, 0.0, 0.0))
    assert summary.split_sizes == {"train": 3, "val": 0, "test": 0}
    record = json.loads((tmp_path / "bop" / "satsight_export.json").read_text(encoding="utf-8"))
    assert record["format"] == "bop" and record["split"]["frames"]["train"] == [0, 1, 2]
    by_path = satsight.export_dataset(
        str(dataset.root), tmp_path / "speedplus", "speedplus", split=(0, 1, 0), seed=4
    )
    assert by_path.format == "speedplus" and by_path.split_sizes["val"] == 3
    with pytest.raises(satsight.SatsightError, match="sum"):
        satsight.export_dataset(dataset, tmp_path / "x", "bop", split=(0.5, 0.1, 0.1))


def assert_close_tree(found, expected, where: str = "labels") -> None:
    """Equal structure; numbers equal to 1e-9 relative (a pose through a quaternion and
    back differs in the last bits), everything else exactly."""
    if isinstance(expected, dict):
        assert isinstance(found, dict) and found.keys() == expected.keys(), where
        for key in expected:
            assert_close_tree(found[key], expected[key], f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(found, list) and len(found) == len(expected), where
        for k, (a, b) in enumerate(zip(found, expected, strict=True)):
            assert_close_tree(a, b, f"{where}[{k}]")
    elif isinstance(expected, float) and not isinstance(found, bool):
        assert found == pytest.approx(expected, rel=1e-9, abs=1e-9), where
    else:
        assert found == expected, where


def test_frames_given_as_poses_render_as_the_same_views(scenario, rendered) -> None:
    """The poses of the view frames, given back as q_cam_from_body / t_cam_from_body_m,
    render the same pixels and labels."""
    poses = [
        {"q_cam_from_body": f.labels["q_cam_from_body"],
         "t_cam_from_body_m": f.labels["t_cam_from_body_m"]}
        for f in rendered
    ]  # fmt: skip
    again = list(satsight.render_frames(satsight.override(scenario, {"frames": poses})))
    for frame, view in zip(again, rendered, strict=True):
        np.testing.assert_array_equal(frame.dn, view.dn)
        np.testing.assert_array_equal(frame.object_mask, view.object_mask)
        labels = {k: v for k, v in frame.labels.items() if k != "view"}
        assert_close_tree(labels, {k: v for k, v in view.labels.items() if k != "view"})
        assert frame.labels["view"] == {"azimuth_deg": 0.0, "elevation_deg": 0.0,
                                        "roll_deg": 0.0, **poses[frame.index]}  # fmt: skip
