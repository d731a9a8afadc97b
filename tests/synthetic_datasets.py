"""Large synthetic datasets for the memory tests of validate, stats and export.

``write_synthetic_dataset`` copies one real frame record of a small rendered dataset
``count`` times, each copy a frame of its own: its frame and plan index changed, its pose
turned about the optical axis and moved along it, and every label that follows from the
pose recomputed (keypoints and box keypoints, their depths, the range; the crop's
keypoints), so that ``satsight validate`` finds it clean (``keypoints_visible`` is left
out: it would need the depth image of the moved pose). Its files are either none (labels
only) or the template frame's, shared by every frame (images are written once, not ``count`` times).
The dataset is closed as ``generate`` closes one (``finalize_dataset``); no record is held.

The memory tests run a pass over two such datasets, of N and 4N frames, and check that its
tracemalloc peak does not grow with the frame count (``assert_peak_does_not_grow``).
"""

from __future__ import annotations

import json
import shutil
import tracemalloc
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from satsight.dataset.journal import file_checksum, record_line, sorted_journal_frames
from satsight.dataset.manifest import finalize_dataset, write_manifest
from satsight.frames.quaternion import (
    canonical_quaternion,
    matrix_from_quaternion,
    quaternion_from_axis_angle,
    quaternion_multiply,
)
from satsight.scene.mesh import TargetMesh
from satsight.scene.obj_export import write_obj

#: Frame counts of the two labels-only datasets of the memory tests (tests/dataset/
#: conftest.py), records of about 21 kB each as Python objects: a pass holding them all
#: would peak about 13 MB higher on the second than on the first. From about 600 frames
#: on, validate's read buffers (labels.json and the journal are read in 1 MiB chunks) are
#: full and its peak stays flat; below, it rises with the files' size.
LABELS_ONLY_FRAME_COUNTS = (600, 1200)
#: Frame counts (N, 4N) of the two datasets with files: an export writes images for each
#: frame, so fewer (a pass holding every record would peak about 7 MB higher on the second).
WITH_FILES_FRAME_COUNTS = (100, 400)
#: What a memory peak may rise by for each frame added, as a fraction of one frame record
#: held as Python objects. The passes keep a few numbers per frame (journal offsets and
#: lengths, a seen flag, a few floats for histograms: under 200 bytes, 1 % of a record);
#: a pass that holds every record rises by a whole record per frame, ten times this.
GROWTH_PER_FRAME_OF_A_RECORD = 0.1
#: What a memory peak may differ by between two runs whatever their frame counts: which
#: records (a window of 8 on validate's threads, 21 kB each) and images are in flight when
#: it is reached, a few hundred kB.
PEAK_JITTER_BYTES = 512 * 1024


def _pixels(points_cam: np.ndarray, K: np.ndarray) -> np.ndarray:
    """(..., N, 2) pixels of (..., N, 3) camera-frame points through K, as the labels."""
    projected = points_cam @ K.T
    return projected[..., :2] / projected[..., 2:]


def moved_poses(record: dict, keypoints_body_m: np.ndarray, count: int) -> dict:
    """The pose of ``record`` for each of ``count`` frames, and the labels that follow from
    it: frame i is turned about the optical axis by 360° × i / count and moved along it by
    up to 10 % of its range. Arrays with one row per frame."""
    angles = 2 * np.pi * np.arange(count) / count
    turns = np.stack([quaternion_from_axis_angle(np.array([0.0, 0.0, 1.0]), a) for a in angles])
    q0 = np.array(record["q_cam_from_body"])
    q = np.stack([canonical_quaternion(quaternion_multiply(turn, q0)) for turn in turns])
    R = np.stack([matrix_from_quaternion(turn) for turn in turns])
    t = R @ np.array(record["t_cam_from_body_m"])
    t[:, 2] *= 1.0 + 0.1 * np.arange(count) / count
    R_pose = np.stack([matrix_from_quaternion(v) for v in q])
    points_cam = keypoints_body_m @ R_pose.transpose(0, 2, 1) + t[:, None, :]
    K = np.array(record["K"])
    poses = {"q": q, "t": t, "points_cam": points_cam, "pixels": _pixels(points_cam, K)}
    if "crop" in record:
        x0, y0 = record["crop"]["box_xyxy_px"][:2]
        K_crop = K.copy()
        K_crop[0, 2] -= x0
        K_crop[1, 2] -= y0
        poses["crop_pixels"] = _pixels(points_cam, K_crop)
    return poses


def moved_record(record: dict, poses: dict, index: int) -> dict:
    """``record`` as frame ``index``, with its pose and labels from ``poses``."""
    points_cam = poses["points_cam"][index]
    if (points_cam[:, 2] <= 0).any():
        raise ValueError("a keypoint behind the camera: choose a template frame further away")
    out = {
        **record,
        "frame_index": index,
        "plan_index": index,
        "q_cam_from_body": poses["q"][index].tolist(),
        "t_cam_from_body_m": poses["t"][index].tolist(),
        "range_m": float(np.linalg.norm(poses["t"][index])),
        "phase_angle_deg": 180.0 * ((index * 0.618034) % 1.0),
    }
    out.pop("keypoints_visible", None)
    crop = None if "crop" not in record else {**record["crop"]}
    if crop is not None:
        crop.pop("keypoints_visible", None)
        out["crop"] = crop
    start = 0
    for name, size in poses["sets"]:
        part = slice(start, start + size)
        out[f"{name}_px"] = poses["pixels"][index][part].tolist()
        out[f"{name}_depth_m"] = points_cam[part, 2].tolist()
        if crop is not None:
            crop[f"{name}_px"] = poses["crop_pixels"][index][part].tolist()
        start += size
    return out


def write_synthetic_dataset(
    root: Path,
    template: Path,
    count: int,
    files: tuple[str, ...] = (),
    edit: Callable[[dict], None] | None = None,
    model: TargetMesh | None = None,
) -> Path:
    """A complete dataset of ``count`` frames in ``root`` made from the first frame of
    the dataset in ``template``; returns root.

    files: the template frame's outputs (``preview_png8``, ...) every frame shares (their
    files copied once); none: a labels-only dataset. edit(record): a change made to each
    record after it is built (to break it). model: the target's mesh, written as the
    dataset's model (and summarised in its header) instead of the template's; the
    keypoints stay the template's.
    """
    root.mkdir(parents=True)
    manifest = json.loads((template / "manifest.json").read_text(encoding="utf-8"))
    with open(template / "journal.jsonl", "rb") as journal:
        first = json.loads(journal.readline())
    manifest.update(frame_count=count, plan_indices=list(range(count)), shard=None)
    manifest["outputs"] = {**manifest["outputs"], "contact_sheet": False}
    shutil.copytree(template / "model", root / "model")
    if model is not None:
        for path in (root / "model").iterdir():
            path.unlink()
        write_obj(model, root / "model" / "target.obj")
        manifest["target"] = {**manifest["target"], **model.summary()}
    write_manifest(root, manifest)
    record = {**first, "files": {}, "checksums": {}}
    if "crop" in record:
        record["crop"] = {**record["crop"], "files": {}}
    for key in files:
        relative = first["files"][key]
        (root / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(template / relative, root / relative)
        record["files"][key] = relative
        record["checksums"][relative] = file_checksum(root / relative)
    target = manifest["target"]
    sets = [
        (name, np.array(target[f"{name}_body_m"], dtype=np.float64))
        for name in ("keypoints", "box_keypoints")
        if f"{name}_body_m" in target
    ]
    poses = moved_poses(record, np.vstack([points for _, points in sets]), count)
    poses["sets"] = [(name, len(points)) for name, points in sets]

    def lines() -> Iterator[bytes]:
        for index in range(count):
            moved = moved_record(record, poses, index)
            if edit is not None:
                edit(moved)
            yield record_line(moved)

    finalize_dataset(root, manifest, lines())
    return root


def held_records_bytes(root: Path, sample: int = 200) -> float:
    """The memory every frame record of a closed dataset would take as Python objects,
    held at once: that of its first ``sample`` records, measured, scaled to all. Call it
    outside any other tracemalloc measurement."""
    frames = sorted_journal_frames(root)
    sample = min(sample, len(frames))
    tracemalloc.start()
    held = [frames[i] for i in range(sample)]
    size, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    del held
    return size * len(frames) / sample


Result = TypeVar("Result")


def traced_peak(run: Callable[[], Result]) -> tuple[Result, int]:
    """What ``run()`` returns, and the peak of the memory Python allocated while it ran
    (bytes, tracemalloc: the objects alive at the peak, the interpreter's own excluded)."""
    tracemalloc.start()
    try:
        result = run()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak


@dataclass(frozen=True)
class MemoryPeak:
    """The memory peak (bytes) of a pass over a dataset of ``frames`` frames whose records
    take ``records_bytes`` held at once as Python objects (``held_records_bytes``)."""

    frames: int
    peak_bytes: int
    records_bytes: float

    @property
    def record_bytes(self) -> float:
        """One frame record held as Python objects, on average (bytes)."""
        return self.records_bytes / self.frames

    def __str__(self) -> str:
        return (
            f"peak {self.peak_bytes / 1e6:.2f} MB for {self.frames} frames, whose records "
            f"take {self.records_bytes / 1e6:.1f} MB held at once"
        )


def assert_peak_does_not_grow(small: MemoryPeak, large: MemoryPeak) -> None:
    """The peak of a pass does not grow with the frame count: from ``small`` to ``large``
    it rises by at most ``GROWTH_PER_FRAME_OF_A_RECORD`` of a record per frame added, plus
    ``PEAK_JITTER_BYTES``.

    A pass holding every record would rise by a whole record per frame added; the frame
    counts must leave it at least three times the allowance, or the check proves nothing.
    """
    added = large.frames - small.frames
    allowed = added * large.record_bytes * GROWTH_PER_FRAME_OF_A_RECORD + PEAK_JITTER_BYTES
    holding_all = added * large.record_bytes
    assert holding_all > 3 * allowed, (
        f"{small.frames} and {large.frames} frames are too close for a pass holding every "
        f"record ({holding_all / 1e6:.1f} MB more) to exceed {allowed / 1e6:.1f} MB"
    )
    growth = large.peak_bytes - small.peak_bytes
    assert growth <= allowed, (
        f"the peak grew by {growth / 1e6:.2f} MB from {small.frames} to {large.frames} "
        f"frames, more than the {allowed / 1e6:.2f} MB allowed: {small}; {large}"
    )


def export_memory_peaks(
    datasets: tuple[Path, ...], out_root: Path, format_name: str
) -> Iterator[tuple[Path, int, object, MemoryPeak]]:
    """Export each dataset (80/10/10 split, preview images) under ``out_root`` with its
    memory peak traced; yields (export folder, frame count, export summary, MemoryPeak)."""
    from satsight.dataset.export import export_dataset
    from satsight.dataset.export.splits import SplitRule

    rule = SplitRule((0.8, 0.1, 0.1))
    for dataset in datasets:
        count = json.loads((dataset / "complete.json").read_text())["frame_count"]
        records_bytes = held_records_bytes(dataset)
        out = out_root / f"{format_name}_{count}"
        summary, peak = traced_peak(
            lambda dataset=dataset, out=out: export_dataset(
                dataset, out, format_name, rule, image="preview"
            )
        )
        train = count * 8 // 10
        assert summary.split_sizes == {"train": train, "val": count // 10, "test": count // 10}
        yield out, count, summary, MemoryPeak(count, peak, records_bytes)
