"""Other objects in the scene, end to end on small frames (96 px, two-wing target).

A square plate placed on the line from the target to the camera hides part of it: the
target's visible mask loses exactly the amodal pixels where the plate is seen, and the
amodal mask (a labels-only render of the target alone) equals the object mask of the same
frame rendered without the plate (same pixel-centre rays). A plate on the line to the Sun
shadows the target: pixels whose surface point sees the plate towards the Sun (an
analytic ray-square test from the depth buffer) darken, the others keep their radiance.
A scenario without objects dumps as before (no ``objects`` key).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from satsight.config.scenario import parse_scenario
from satsight.dataset.export import export_dataset
from satsight.dataset.export.splits import SplitRule
from satsight.dataset.image_files import read_png
from satsight.frames.quaternion import quaternion_from_axis_angle
from satsight.pipeline import FrameEngine
from satsight.run.generation import generate_dataset

SIZE_PX = 96
PLATE_SIDE_M = 2.0

BASE = {
    "name": "objects",
    "seed": 3,
    "camera": {"preset": "high_resolution", "width_px": SIZE_PX, "height_px": SIZE_PX,
               "focal_length_m": 0.02, "pixel_pitch_um": 15.0,
               "optics": {"aperture_diameter_m": 0.005}},
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "sun": {"azimuth_deg": 100.0, "elevation_deg": 20.0},
    "frames": [{"distance_km": 0.04, "azimuth_deg": 20.0, "elevation_deg": 10.0}],
    "render": {"bounces": 0, "samples_per_pixel": 1, "environment": "off"},
}  # fmt: skip


def _plate_obj(folder) -> str:
    half = PLATE_SIDE_M / 2
    path = folder / "plate.obj"
    path.write_text(
        f"v {-half} {-half} 0\nv {half} {-half} 0\nv {half} {half} 0\nv {-half} {half} 0\n"
        "f 1 2 3\nf 1 3 4\n"
    )
    return str(path)


def _facing(normal: np.ndarray) -> list[float]:
    """q_target_from_object turning the plate's +z onto ``normal``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, normal)
    angle = np.arccos(np.clip(z @ normal, -1, 1))
    return quaternion_from_axis_angle(axis / np.linalg.norm(axis), angle).tolist()


@pytest.fixture(scope="module")
def plain(llvm_variant):
    engine = FrameEngine(parse_scenario(BASE, "test"))
    frame = engine.render(0)
    return engine, frame


def _with_plate(folder, center_m, normal, distance_m) -> FrameEngine:
    plate = {
        "name": "plate",
        "mesh": {"path": _plate_obj(folder), "materials": {"plate": "lambert_white"}},
        "offset_m": (center_m + distance_m * normal).tolist(),
        "q_target_from_object": _facing(normal),
    }
    return FrameEngine(parse_scenario({**BASE, "objects": [plate]}, "test"))


def test_a_plate_before_the_target_hides_exactly_the_pixels_where_it_is_seen(
    plain, tmp_path
) -> None:
    engine, frame = plain
    center = engine.mesh.center_m
    camera_body = frame.cam_from_body.inverse().t_a_from_b_m
    to_camera = (camera_body - center) / np.linalg.norm(camera_body - center)
    occluded = _with_plate(tmp_path, center + np.array([0.0, 0.5, 0.3]), to_camera, 12.0)
    record, arrays, _ = occluded.finish(occluded.render(0))
    ids, amodal = arrays.object_id, arrays.amodal_mask
    visible = arrays.image.object_mask
    # The amodal mask is the target's silhouette without the plate: the same rays.
    assert np.array_equal(amodal, frame.image.object_mask)
    assert np.array_equal(visible, ids == 1)
    assert not np.any(visible & ~amodal)
    hidden = amodal & (ids == 2)
    assert hidden.sum() > 50  # the plate crosses the target
    assert amodal.sum() - visible.sum() == hidden.sum()
    occlusion = record["occlusion"]
    assert occlusion["amodal_pixel_count"] == amodal.sum()
    assert occlusion["visible_pixel_count"] == visible.sum() < amodal.sum()
    assert occlusion["visib_fract"] == visible.sum() / amodal.sum()
    (plate,) = record["objects"]
    assert plate["name"] == "plate" and plate["object_id"] == 2
    assert plate["pixel_count"] == np.count_nonzero(ids == 2)
    # Nothing hides the plate: its amodal pixels are its visible ones.
    assert plate["amodal_pixel_count"] == plate["pixel_count"] and plate["visib_fract"] == 1.0
    assert record["object_pixel_count"] == visible.sum()


def _shadowed_by_plate(engine, frame, image, center_m, normal, distance_m, radius_m) -> np.ndarray:
    """(H, W) bool: target pixels whose surface point, looking towards the Sun, meets the
    plate's plane within ``radius_m`` of its centre."""
    camera = engine.camera
    v, u = np.nonzero(image.object_mask)
    z = image.depth_m[v, u].astype(np.float64)
    K = camera.K
    points_cam = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=1)
    points = frame.cam_from_body.inverse().apply(points_cam)
    sun = frame.light.sun_direction_body
    plate_center = center_m + distance_m * normal
    s = ((plate_center - points) @ normal) / (sun @ normal)
    hit = points + s[:, None] * sun - plate_center
    e1 = np.cross(normal, [0.0, 0.0, 1.0])
    e1 = e1 / np.linalg.norm(e1) if np.linalg.norm(e1) > 1e-6 else np.array([1.0, 0.0, 0.0])
    e2 = np.cross(normal, e1)
    inside = (s > 0) & (np.hypot(hit @ e1, hit @ e2) < radius_m)
    shadowed = np.zeros(image.shape, dtype=bool)
    shadowed[v[inside], u[inside]] = True
    return shadowed


def test_a_plate_between_the_sun_and_the_target_shadows_it(plain, tmp_path) -> None:
    engine, frame = plain
    center, sun = engine.mesh.center_m, frame.light.sun_direction_body
    distance = 8.0
    lit = frame.image
    shaded_engine = _with_plate(tmp_path, center, sun, distance)
    shaded = shaded_engine.render(0).image
    both = lit.object_mask & shaded.object_mask
    assert both.sum() > 0.9 * lit.object_mask.sum()  # the plate hides little from the camera
    # The square's turn about its normal is left open: the disc inscribed in it (0.1 m
    # inside) is in its shadow.
    half = PLATE_SIDE_M / 2
    expected = _shadowed_by_plate(engine, frame, lit, center, sun, distance, half - 0.1) & both
    assert expected.sum() > 20
    before = lit.radiance_w_m2_sr.sum(axis=2)
    after = shaded.radiance_w_m2_sr.sum(axis=2)
    lit_pixels = expected & (before > 0)
    assert lit_pixels.sum() > 20
    # Direct sunlight only (no bounces, no environment): a shadowed pixel goes dark.
    assert np.all(after[lit_pixels] <= 1e-6 * before[lit_pixels].max())


def test_a_scenario_without_objects_dumps_without_the_key() -> None:
    scenario = parse_scenario(BASE, "test")
    assert "objects" not in scenario.model_dump(mode="json")
    with_plate = parse_scenario(
        {**BASE, "objects": [{"name": "d", "debris": {"count": 3}}]}, "test"
    )
    assert with_plate.model_dump(mode="json")["objects"][0]["debris"]["count"] == 3


def _export(scenario, folder, export_format: str) -> dict:
    """Generate a one-frame dataset of ``scenario`` in ``folder/dataset``, export it to
    ``folder/export_format`` (every frame in train); the frame's record."""
    dataset = folder / "dataset"
    assert generate_dataset(scenario, dataset).complete
    record = json.loads((dataset / "labels.json").read_text(encoding="utf-8"))["frames"][0]
    export_dataset(dataset, folder / export_format, export_format, SplitRule((1.0, 0.0, 0.0)))
    return record


def _bop_export(scenario, folder) -> tuple[dict, np.ndarray, np.ndarray, dict]:
    """A one-frame dataset of ``scenario`` exported to BOP: the frame's record, its BOP
    ``mask`` and ``mask_visib`` and its scene_gt_info entry."""
    record = _export(scenario, folder, "bop")
    scene = folder / "bop" / "train" / "000000"
    mask = read_png(scene / "mask" / "000000_000000.png") > 0
    visib = read_png(scene / "mask_visib" / "000000_000000.png") > 0
    (info,) = json.loads((scene / "scene_gt_info.json").read_text(encoding="utf-8"))["0"]
    return record, mask, visib, info


def test_the_bop_export_keeps_the_amodal_and_the_visible_mask(plain, tmp_path) -> None:
    """A plate partly hides the target: BOP's ``mask`` is the amodal mask, which is the
    whole frame's mask of the same scene without the plate, ``mask_visib`` the visible
    pixels, and ``visib_fract`` their ratio, the silhouette cut off by the image border
    counted in both scenes alike."""
    engine, frame = plain
    center = engine.mesh.center_m
    camera_body = frame.cam_from_body.inverse().t_a_from_b_m
    to_camera = (camera_body - center) / np.linalg.norm(camera_body - center)
    occluded = _with_plate(tmp_path, center + np.array([0.0, 0.5, 0.3]), to_camera, 12.0)
    record, mask, visib, info = _bop_export(occluded.scenario, tmp_path / "plate")
    _, bare_mask, bare_visib, bare_info = _bop_export(engine.scenario, tmp_path / "bare")
    occlusion = record["occlusion"]
    assert np.array_equal(mask, bare_mask) and np.array_equal(bare_mask, bare_visib)
    assert mask.sum() == occlusion["amodal_pixel_count"]
    assert visib.sum() == occlusion["visible_pixel_count"] == info["px_count_visib"]
    assert not np.any(visib & ~mask) and visib.sum() < mask.sum()
    assert info["px_count_all"] == bare_info["px_count_all"] >= mask.sum()
    assert info["bbox_obj"] == bare_info["bbox_obj"]
    assert info["visib_fract"] == pytest.approx(visib.sum() / info["px_count_all"], rel=1e-15)
    assert bare_info["visib_fract"] > info["visib_fract"]


def test_randomised_materials_keep_the_objects_in_the_scene(plain, tmp_path) -> None:
    """A frame whose materials are randomised renders the merged scene still: the plate
    before the target hides the same pixels (materials change no geometry)."""
    engine, frame = plain
    center = engine.mesh.center_m
    camera_body = frame.cam_from_body.inverse().t_a_from_b_m
    to_camera = (camera_body - center) / np.linalg.norm(camera_body - center)
    occluded = _with_plate(tmp_path, center + np.array([0.0, 0.5, 0.3]), to_camera, 12.0)
    varied = FrameEngine(
        parse_scenario(
            {**occluded.scenario.model_dump(mode="json", exclude_none=True),
             "randomize": {"materials": True}}, "test"
        )
    )  # fmt: skip
    record, arrays, _ = varied.finish(varied.render(0))
    _, plain_arrays, _ = occluded.finish(occluded.render(0))
    assert set(record["randomized"]) == {"materials", "textures"}  # the crinkle drawn anew
    assert np.array_equal(arrays.object_id, plain_arrays.object_id)
    assert np.count_nonzero(arrays.object_id == 2) > 50


@pytest.mark.filterwarnings(
    "ignore:__array__ implementation doesn't accept a copy keyword:DeprecationWarning"
)
def test_the_coco_export_annotates_every_object_it_sees(plain, tmp_path) -> None:
    """A plate partly hides the target: pycocotools reads two categories (the target with
    its keypoints, the plate without), and the image's two annotations decode to the
    object-id image's pixels of each (the target's visible pixels); their ids are
    image id x 256 + object id; COCOeval scores the annotations given back as detections
    AP 1 for boxes and masks in both categories."""
    from pycocotools import mask as mask_utils
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    engine, frame = plain
    center = engine.mesh.center_m
    camera_body = frame.cam_from_body.inverse().t_a_from_b_m
    to_camera = (camera_body - center) / np.linalg.norm(camera_body - center)
    occluded = _with_plate(tmp_path, center + np.array([0.0, 0.5, 0.3]), to_camera, 12.0)
    record = _export(occluded.scenario, tmp_path, "coco")
    ids = read_png(tmp_path / "dataset" / record["files"]["object_id_png"])
    data = COCO(str(tmp_path / "coco" / "annotations" / "instances_train.json"))
    target, plate = data.loadCats([1, 2])
    assert plate["name"] == "plate" and plate["supercategory"] == "object"
    assert plate["keypoints"] == [] and len(target["keypoints"]) > 0
    annotations = {a["category_id"]: a for a in data.loadAnns(data.getAnnIds(imgIds=[1]))}
    assert set(annotations) == {1, 2}
    for object_id, annotation in annotations.items():
        assert annotation["id"] == 256 + object_id
        seen = ids == object_id
        assert np.array_equal(mask_utils.decode(data.annToRLE(annotation)) > 0, seen)
        assert annotation["area"] == np.count_nonzero(seen)
        assert annotation["bbox"] == mask_utils.toBbox(data.annToRLE(annotation)).tolist()
    assert annotations[1]["area"] == record["occlusion"]["visible_pixel_count"]
    assert annotations[2]["num_keypoints"] == 0 and annotations[1]["num_keypoints"] > 0
    for iou_type in ("bbox", "segm"):
        detections = [
            {
                "image_id": a["image_id"],
                "category_id": a["category_id"],
                "score": 1.0,
                "bbox": a["bbox"],
                "segmentation": a["segmentation"],
            }
            for a in annotations.values()
        ]
        evaluator = COCOeval(data, data.loadRes(detections), iou_type)
        evaluator.evaluate()
        evaluator.accumulate()
        evaluator.summarize()
        assert evaluator.stats[0] == pytest.approx(1.0, abs=1e-12)
