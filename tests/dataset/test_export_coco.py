"""``satsight export --format coco``: read back by pycocotools, the format's own API.

Oracles: pycocotools (``COCO`` loads each annotation file, ``mask.decode`` / ``toBbox`` /
``area`` read the RLE, ``COCOeval`` scores the ground truth given as detections, and
``mask.encode`` gives the compressed counts string the export's own encoder must
match byte for byte); an exact ray caster for the box fixture's masks; the convex closed
form for which box corners a camera sees; SciPy's quaternion convention for the
projection of the keypoints; and the detector's DN for the images.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval
from scipy.spatial.transform import Rotation

from cli_runner import run_satsight
from export_datasets import (
    CROP_SIDE_PX,
    DETECTOR,
    SIZE_PX,
    TRUNCATED_CENTERS_CAM_M,
    box_pose,
    ray_cast_box,
    render_tiny_dataset,
    write_box_dataset,
)
from satsight.dataset.export import export_dataset
from satsight.dataset.export.rle import encode_rle
from satsight.dataset.export.splits import SPLIT_NAMES, SplitRule, assign_splits
from satsight.dataset.image_files import read_png
from satsight.errors import SatsightError
from synthetic_datasets import (
    assert_peak_does_not_grow,
    export_memory_peaks,
)

#: pycocotools' Cython decoder trips numpy 2's __array__(copy=...) deprecation (its own code).
pytestmark = pytest.mark.filterwarnings(
    "ignore:__array__ implementation doesn't accept a copy keyword:DeprecationWarning"
)
RULE = SplitRule((0.5, 0.25, 0.25), seed=0)
ALL_TRAIN = SplitRule((1.0, 0.0, 0.0))
BIAS_DN = DETECTOR["bias_dn"]
SATURATION_DN = BIAS_DN + DETECTOR["full_well_e"] / DETECTOR["conversion_gain_e_per_dn"]
TOP_KEYS = {"info", "licenses", "categories", "images", "annotations"}
IMAGE_KEYS = {"id", "file_name", "width", "height", "frame_index", "q_cam_from_body",
              "t_cam_from_body_m", "K"}  # fmt: skip
ANNOTATION_KEYS = {"id", "image_id", "category_id", "bbox", "area", "iscrowd", "segmentation",
                   "keypoints", "num_keypoints"}  # fmt: skip
#: Box centres of a dataset whose third frame shows no pixel of the target (100 px out).
CENTERS_WITH_EMPTY_FRAME_CAM_M = [(0.3, -0.2, 4000.0), (-0.4, 0.1, 5000.0), (6.0, 0.0, 4000.0)]


# --- readers --------------------------------------------------------------------------------
def load_splits(export: Path) -> dict[str, COCO]:
    """split -> pycocotools' COCO of its annotation file (the splits that have one)."""
    out = {}
    for split in SPLIT_NAMES:
        path = export / "annotations" / f"instances_{split}.json"
        if path.is_file():
            out[split] = COCO(str(path))
    return out


def annotations_by_frame(export: Path) -> dict[int, tuple[str, COCO, dict, dict | None]]:
    """frame_index -> (split, its COCO, image entry, annotation or None)."""
    frames = {}
    for split, coco in load_splits(export).items():
        for image in coco.dataset["images"]:
            ann_ids = coco.getAnnIds(imgIds=[image["id"]])
            assert len(ann_ids) <= 1  # one target
            annotation = coco.loadAnns(ann_ids)[0] if ann_ids else None
            frames[image["frame_index"]] = (split, coco, image, annotation)
    return frames


def mask_box(mask: np.ndarray) -> list[int]:
    """COCO's [x, y, w, h] of a mask's pixels, pixel corners at integers: a pixel spans
    [i, i + 1), so w = last column - first column + 1."""
    rows, cols = np.nonzero(mask)
    return [int(cols.min()), int(rows.min()), int(np.ptp(cols)) + 1, int(np.ptp(rows)) + 1]


def inside(uv: list | None, width: int, height: int) -> bool:
    """A pixel position (pixel centres at integers) in the image's pixels."""
    return uv is not None and -0.5 <= uv[0] < width - 0.5 and -0.5 <= uv[1] < height - 0.5


def triples(annotation: dict) -> np.ndarray:
    return np.array(annotation["keypoints"], dtype=np.float64).reshape(-1, 3)


def labels_of(dataset: Path) -> dict:
    return json.loads((dataset / "labels.json").read_text())


# --- fixtures -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    return write_box_dataset(tmp_path_factory.mktemp("box") / "dataset", crop=True)


@pytest.fixture(scope="module")
def coco(box: Path) -> Path:
    out = box.parent / "coco"
    export_dataset(box, out, "coco", RULE)
    return out


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> Path:
    return render_tiny_dataset(tmp_path_factory.mktemp("rendered") / "dataset")


# --- the RLE encoder against pycocotools -----------------------------------------------------
def _masks() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    long_runs = np.zeros((1500, 2100), dtype=bool)
    long_runs[0, 0] = True  # a first run of length 0, then runs far above 2^15
    long_runs[700:1499, 40:2090] = True
    first_column = np.zeros((9, 4), dtype=bool)
    first_column[:, 0] = True
    return [
        np.zeros((5, 7), dtype=bool),
        np.ones((5, 7), dtype=bool),
        np.eye(6, 9, dtype=bool),
        first_column,
        rng.random((37, 53)) < 0.5,  # short runs: deltas of both signs
        rng.random((200, 300)) < 0.003,
        long_runs,
    ]


@pytest.mark.parametrize("mask", _masks(), ids=lambda m: f"{m.shape[1]}x{m.shape[0]}-{m.sum()}")
def test_rle_is_pycocotools_compressed_rle_byte_for_byte(mask: np.ndarray) -> None:
    ours = encode_rle(mask)
    theirs = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    assert ours["size"] == [int(v) for v in theirs["size"]] == list(mask.shape)
    assert ours["counts"] == theirs["counts"].decode("ascii")
    assert np.array_equal(mask_utils.decode(ours), mask)
    assert mask_utils.area(ours) == mask.sum()


# --- layout, keys and split -----------------------------------------------------------------
def test_annotation_files_load_with_the_coco_fields(coco: Path, box: Path) -> None:
    splits = load_splits(coco)
    assert set(splits) == set(SPLIT_NAMES)
    assert sorted(p.name for p in (coco / "annotations").iterdir()) == [
        f"instances_{split}.json" for split in sorted(SPLIT_NAMES)
    ]  # the part files are gone
    manifest = json.loads((box / "manifest.json").read_text())
    keypoint_count = len(manifest["target"]["keypoints_body_m"])
    for split, data in splits.items():
        assert set(data.dataset) == TOP_KEYS and data.dataset["licenses"] == []
        assert data.dataset["categories"] == [
            {
                "id": 1,
                "name": "target",  # the fixture's manifest names no target
                "supercategory": "spacecraft",
                "keypoints": [f"kp_{k}" for k in range(keypoint_count)],
                "skeleton": [],
            }
        ]
        for image in data.dataset["images"]:
            assert set(image) == IMAGE_KEYS
            assert image["id"] == image["frame_index"] + 1
            assert image["file_name"] == f"{image['frame_index']:06d}.png"
            pixels = read_png(coco / "images" / split / image["file_name"])
            assert pixels.shape == (image["height"], image["width"]) == SIZE_PX[::-1]
        for annotation in data.dataset["annotations"]:
            assert set(annotation) == ANNOTATION_KEYS
            assert annotation["id"] == annotation["image_id"] and annotation["iscrowd"] == 0
            assert annotation["category_id"] == 1
            assert len(annotation["keypoints"]) == 3 * keypoint_count
            assert isinstance(annotation["segmentation"]["counts"], str)  # compressed RLE


def test_split_folders_hold_the_seeded_split(coco: Path, box: Path) -> None:
    expected = assign_splits([f["frame_index"] for f in labels_of(box)["frames"]], RULE)
    frames = annotations_by_frame(coco)
    for split in SPLIT_NAMES:
        assert sorted(i for i, entry in frames.items() if entry[0] == split) == expected[split]
        names = sorted(int(p.stem) for p in (coco / "images" / split).iterdir())
        assert names == expected[split]
    record = json.loads((coco / "satsight_export.json").read_text())
    assert record["format"] == "coco" and record["split"]["frames"] == expected


def test_empty_splits_have_no_files(box: Path, tmp_path: Path) -> None:
    summary = export_dataset(box, tmp_path / "out", "coco", ALL_TRAIN)
    assert summary.split_sizes == {"train": 4, "val": 0, "test": 0}
    assert [p.name for p in (tmp_path / "out" / "annotations").iterdir()] == [
        "instances_train.json"
    ]
    assert [p.name for p in (tmp_path / "out" / "images").iterdir()] == ["train"]


# --- masks, boxes and areas -----------------------------------------------------------------
@pytest.mark.parametrize("centers", ["inside", "truncated", "one_empty"])
def test_masks_boxes_and_areas_are_the_ray_cast_silhouette(
    coco: Path, box: Path, tmp_path: Path, centers: str
) -> None:
    """decode(annToRLE) is the exact silhouette; toBbox, bbox and the silhouette's box
    agree; area, maskUtils.area and the pixel count agree; an image without the target
    has no annotation."""
    centers_cam_m = None
    if centers != "inside":
        centers_cam_m = (
            TRUNCATED_CENTERS_CAM_M if centers == "truncated" else CENTERS_WITH_EMPTY_FRAME_CAM_M
        )
        box = write_box_dataset(tmp_path / "d", centers_cam_m=centers_cam_m)
        coco = tmp_path / "coco"
        export_dataset(box, coco, "coco", RULE)
    frames = annotations_by_frame(coco)
    labels = labels_of(box)
    assert sorted(frames) == [f["frame_index"] for f in labels["frames"]]
    empty = 0
    for frame in labels["frames"]:
        data, annotation = frames[frame["frame_index"]][1::2]
        pose = box_pose(frame["frame_index"], *([centers_cam_m] if centers_cam_m else []))
        truth = ray_cast_box(*pose, np.array(frame["K"]), SIZE_PX) > 0
        if not truth.any():
            assert annotation is None and frame["bbox_xyxy_px"] is None
            empty += 1
            continue
        mask = mask_utils.decode(data.annToRLE(annotation)).astype(bool)
        assert np.array_equal(mask, truth)
        assert np.array_equal(mask, read_png(box / frame["files"]["object_mask_png"]) > 0)
        rle = data.annToRLE(annotation)
        assert mask_utils.toBbox(rle).tolist() == annotation["bbox"] == mask_box(truth)
        x0, y0, x1, y1 = frame["bbox_xyxy_px"]
        assert annotation["bbox"] == [x0, y0, x1 - x0 + 1, y1 - y0 + 1]
        assert mask_utils.area(rle) == annotation["area"] == truth.sum()
        assert annotation["area"] == frame["object_pixel_count"]
        if centers == "truncated":
            assert truth[:, [0, -1]].any() or truth[[0, -1], :].any()
    assert empty == (1 if centers == "one_empty" else 0)


# --- keypoints ------------------------------------------------------------------------------
def corners_seen(frame: dict, keypoints_body_m: np.ndarray) -> list[bool]:
    """Which box keypoints a camera sees, in closed form: a point of a convex box is seen
    iff one of the faces through it faces the camera (the box centre never is)."""
    R = Rotation.from_quat(frame["q_cam_from_body"], scalar_first=True).as_matrix()
    eye_body = -R.T @ np.array(frame["t_cam_from_body_m"])
    centre = keypoints_body_m.mean(axis=0)  # corners symmetric about it, plus itself
    seen = []
    for point in keypoints_body_m:
        side = np.sign(np.round(point - centre, 9))
        seen.append(bool(np.any(side * (eye_body - point) > 0)))
    return seen


def test_box_keypoint_visibility_from_depth_is_the_convex_closed_form(
    coco: Path, box: Path
) -> None:
    """The fixture's labels have no keypoints_visible: the flags come from the depth
    image. Within 5 km (a box of 25+ px) they are the closed form: v 2 for a corner seen,
    1 for one hidden; x, y are keypoints_px."""
    labels = labels_of(box)
    body = np.array(labels["target"]["keypoints_body_m"])
    frames = annotations_by_frame(coco)
    counts = {0: 0, 1: 0, 2: 0}
    for frame in labels["frames"]:
        annotation = frames[frame["frame_index"]][3]
        points = triples(annotation)
        assert annotation["num_keypoints"] == np.count_nonzero(points[:, 2])
        for k, (uv, (x, y, v)) in enumerate(zip(frame["keypoints_px"], points, strict=True)):
            if not inside(uv, *SIZE_PX):
                assert (x, y, v) == (0, 0, 0)
                continue
            assert (x, y) == tuple(uv)  # satsight's pixel positions, unchanged
            counts[int(v)] += 1
            if frame["t_cam_from_body_m"][2] < 10e3:
                assert v == (2 if corners_seen(frame, body)[k] else 1), (frame["frame_index"], k)
    assert counts[1] >= 4 and counts[2] >= 12
    notes = json.loads((coco / "satsight_export.json").read_text())["notes"]
    assert any("visibility of 4 images from their depth" in note for note in notes)


def test_without_visibility_or_depth_keypoints_in_the_image_are_v2(tmp_path: Path) -> None:
    dataset = write_box_dataset(
        tmp_path / "d", keys=("dn_png16", "object_mask_png"), centers_cam_m=TRUNCATED_CENTERS_CAM_M
    )
    summary = export_dataset(dataset, tmp_path / "out", "coco", ALL_TRAIN)
    assert "keypoint visibility unknown in 3 images" in summary.line()
    frames = annotations_by_frame(tmp_path / "out")
    outside = 0
    for frame in labels_of(dataset)["frames"]:
        points = triples(frames[frame["frame_index"]][3])
        for uv, (x, y, v) in zip(frame["keypoints_px"], points, strict=True):
            expected = (*uv, 2) if inside(uv, *SIZE_PX) else (0, 0, 0)
            assert (x, y, v) == tuple(expected)
            outside += v == 0
    assert outside >= 3  # the truncated frames have corners beyond the border


def project(image: dict, body_m: np.ndarray) -> np.ndarray:
    """Pixel positions of body points through an image entry's pose and K (SciPy's
    scalar-first quaternion: x_cam = R(q) x_body + t)."""
    R = Rotation.from_quat(image["q_cam_from_body"], scalar_first=True).as_matrix()
    p = (body_m @ R.T + image["t_cam_from_body_m"]) @ np.array(image["K"]).T
    return p[:, :2] / p[:, 2:3]


def check_rendered_keypoints(export: Path, dataset: Path, crop: bool) -> dict[int, int]:
    """Every annotation's keypoints against the view's labels; returns the count of each v."""
    labels = labels_of(dataset)
    body = np.array(labels["target"]["keypoints_body_m"])
    frames = annotations_by_frame(export)
    counts = {0: 0, 1: 0, 2: 0}
    for frame in labels["frames"]:
        view = frame["crop"] if crop else frame
        _, data, image, annotation = frames[frame["frame_index"]]
        width, height = image["width"], image["height"]
        assert np.array_equal(image["K"], view["K"])
        assert data.dataset["categories"][0]["name"] == labels["target"]["name"]
        if annotation is None:
            assert view["object_pixel_count"] == 0
            continue
        points = triples(annotation)
        seen = view["keypoints_visible"]
        for k, (uv, (x, y, v)) in enumerate(zip(view["keypoints_px"], points, strict=True)):
            if inside(uv, width, height):
                assert (x, y) == tuple(uv)
                assert v == (2 if seen[k] else 1)
            else:
                assert (x, y, v) == (0, 0, 0) and not seen[k]
            counts[int(v)] += 1
        labelled = points[:, 2] > 0
        np.testing.assert_allclose(project(image, body)[labelled], points[labelled, :2], atol=1e-6)
        assert annotation["num_keypoints"] == labelled.sum()
        full = read_png(dataset / frame["files"]["object_mask_png"]) > 0
        if crop:
            x0, y0, x1, y1 = view["box_xyxy_px"]
            full = full[y0:y1, x0:x1]
        assert np.array_equal(mask_utils.decode(data.annToRLE(annotation)), full)
        assert annotation["area"] == view["object_pixel_count"]
    return counts


def test_rendered_keypoints_follow_keypoints_visible(rendered: Path) -> None:
    out = rendered.parent / "coco"
    summary = export_dataset(rendered, out, "coco", SplitRule((0.5, 0.25, 0.25), seed=2))
    assert "visibility" not in summary.line()  # the labels' flags, for every frame
    counts = check_rendered_keypoints(out, rendered, crop=False)
    assert counts[1] >= 3 and counts[2] >= 10  # hidden and visible keypoints both seen


def test_rendered_crops_have_the_crop_intrinsics_keypoints_and_masks(rendered: Path) -> None:
    out = rendered.parent / "coco_crop"
    summary = export_dataset(rendered, out, "coco", ALL_TRAIN, crop=True)
    assert summary.crop
    for image in load_splits(out)["train"].dataset["images"]:
        assert (image["width"], image["height"]) == (48, 48)
        assert read_png(out / "images" / "train" / image["file_name"]).shape == (48, 48)
    counts = check_rendered_keypoints(out, rendered, crop=True)
    assert counts[0] >= 3 and counts[2] >= 10  # the 48 px windows cut keypoints off


def test_box_crops_are_the_ray_cast_silhouette_in_the_window(box: Path) -> None:
    out = box.parent / "coco_crop"
    export_dataset(box, out, "coco", RULE, crop=True)
    frames = annotations_by_frame(out)
    for frame in labels_of(box)["frames"]:
        crop = frame["crop"]
        _, data, image, annotation = frames[frame["frame_index"]]
        assert (image["width"], image["height"]) == (CROP_SIDE_PX, CROP_SIDE_PX)
        assert np.array_equal(image["K"], crop["K"])
        x0, y0, x1, y1 = crop["box_xyxy_px"]
        truth = ray_cast_box(*box_pose(frame["frame_index"]), np.array(frame["K"]), SIZE_PX)
        window = truth[y0:y1, x0:x1] > 0
        assert np.array_equal(mask_utils.decode(data.annToRLE(annotation)), window)
        assert annotation["bbox"] == mask_box(window)
        points = triples(annotation)
        for uv, (x, y, v) in zip(crop["keypoints_px"], points, strict=True):
            assert (x, y) == (tuple(uv) if v else (0, 0))
            assert (v > 0) == inside(uv, CROP_SIDE_PX, CROP_SIDE_PX)


# --- COCOeval: the ground truth as detections -----------------------------------------------
def evaluate(data: COCO, iou_type: str, shift_px: float = 0.0) -> np.ndarray:
    """COCOeval stats of the annotations given back as detections (score 1), boxes, masks
    and keypoints moved right by ``shift_px`` (whole pixels)."""
    detections = []
    for annotation in data.dataset["annotations"]:
        detection = {"image_id": annotation["image_id"], "category_id": 1, "score": 1.0}
        x, y, w, h = annotation["bbox"]
        if iou_type == "bbox":
            detection["bbox"] = [x + shift_px, y, w, h]
        elif iou_type == "segm":
            mask = np.roll(mask_utils.decode(data.annToRLE(annotation)), int(shift_px), axis=1)
            rle = mask_utils.encode(np.asfortranarray(mask))
            detection["segmentation"] = {"size": rle["size"], "counts": rle["counts"].decode()}
        else:
            points = triples(annotation)
            points[:, 0] += shift_px
            detection["keypoints"] = points.reshape(-1).tolist()
        detections.append(detection)
    evaluator = COCOeval(data, data.loadRes(detections), iou_type)
    if iou_type == "keypoints":
        count = len(data.dataset["categories"][0]["keypoints"])
        evaluator.params.kpt_oks_sigmas = np.full(count, 0.05)  # one per keypoint
    evaluator.evaluate()
    evaluator.accumulate()
    evaluator.summarize()
    return evaluator.stats


@pytest.mark.parametrize("source", ["box", "rendered"])
@pytest.mark.parametrize("iou_type", ["bbox", "segm", "keypoints"])
def test_cocoeval_scores_the_ground_truth_as_detections_ap_1(
    box: Path, rendered: Path, tmp_path: Path, source: str, iou_type: str
) -> None:
    """AP over IoU (OKS) 0.50:0.95 and at 0.50 and 0.75 are 1.0; boxes or keypoints
    moved by a few pixels score less, so the evaluation does look at them."""
    dataset = box if source == "box" else rendered
    export_dataset(dataset, tmp_path / "out", "coco", ALL_TRAIN)
    data = load_splits(tmp_path / "out")["train"]
    assert len(data.dataset["annotations"]) == 4
    stats = evaluate(data, iou_type)
    assert stats[:3].tolist() == [1.0, 1.0, 1.0]
    assert evaluate(data, iou_type, shift_px=4.0)[0] < 0.9


# --- images ---------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["dn16", "raw16", "linear8"])
def test_images_are_an_exact_linear_function_of_the_dn(box: Path, tmp_path: Path, mode: str):
    """dn16: DN - bias; raw16: DN; linear8: round((DN - bias) 255 / white), white the
    saturation above the bias (docs/dataset_format.md, "Exports")."""
    out = tmp_path / "out"
    export_dataset(box, out, "coco", RULE, image=mode)
    frames = annotations_by_frame(out)
    assert len(frames) == 4
    for index, (split, _, image, _) in frames.items():
        dn = read_png(box / f"images/frame_{index:06d}.png").astype(np.float64)
        value = read_png(out / "images" / split / image["file_name"])
        assert np.ptp(dn) > 30000
        if mode == "linear8":
            white = SATURATION_DN - BIAS_DN
            expected = np.clip(np.rint((dn - BIAS_DN) * 255.0 / white), 0, 255)
            assert value.dtype == np.uint8 and np.array_equal(value, expected)
        else:
            assert value.dtype == np.uint16
            assert np.array_equal(value, dn - (BIAS_DN if mode == "dn16" else 0.0))


# --- bad inputs, the command line, memory ---------------------------------------------------
def test_dataset_without_masks_is_refused_and_leaves_nothing(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("dn_png16", "depth_exr"))
    with pytest.raises(SatsightError, match=r"object_mask_png \(output 'masks'\)"):
        export_dataset(dataset, tmp_path / "out", "coco", RULE)
    assert not (tmp_path / "out").exists()
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name]


def test_cli_writes_the_coco_export_and_prints_one_line(box: Path) -> None:
    out = box.parent / "coco_cli"
    result = run_satsight(
        "export", str(box), "--format", "coco", "--out", str(out), "--split", "0.5,0.25,0.25",
        cwd=box.parent,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip().count("\n") == 0
    assert "exported 4 frames (train 2, val 1, test 1) as COCO" in result.stderr
    assert set(load_splits(out)) == set(SPLIT_NAMES)


def test_export_memory_does_not_grow_with_the_frame_count(
    datasets_with_files: tuple[Path, ...], tmp_path: Path
) -> None:
    """Datasets of N and 4N frames (records of 22 kB each as Python objects) export with
    the same memory peak, within a few bytes per frame: images and annotations are written
    entry by entry."""
    peaks = []
    for out, count, _, peak in export_memory_peaks(datasets_with_files, tmp_path, "coco"):
        annotations = json.loads((out / "annotations" / "instances_train.json").read_text())
        assert len(annotations["images"]) == len(annotations["annotations"]) == count * 8 // 10
        peaks.append(peak)
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 10, peaks[-1]
