"""What an exporter reads from a dataset: each frame's pose, intrinsics and images.

A frame is exported either whole or as its crop (``--crop``, or automatically when the
dataset keeps only crops). ``ExportFrame`` holds what the exporters need in the chosen
view: the pose ``x_cam = R(q_cam_from_body) @ x_body + t_cam_from_body_m`` (metres; the
same for a crop, whose camera frame is the full frame's), the 3x3 intrinsics K in that
view's pixels (pixel (0, 0) is the centre of the top-left pixel), its size and its files.

A dataset of 10^6 frames holds several GB of records: an export never holds them all.
``scan_frames`` reads them once for their frame indices and the views they have;
``ExportFrames`` then reads one split's records from the journal on each pass over it.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.image_files import read_exr, read_png
from satsight.dataset.journal import JournalFrames
from satsight.dataset.output_files import OUTPUT_FILE_KEYS
from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError

#: The scenario's ``outputs.files`` name that writes each file key (for error messages).
OUTPUT_OF_KEY = {key: name for name, keys in OUTPUT_FILE_KEYS.items() for key in keys}


@dataclass(frozen=True)
class ExportFrame:
    """One frame as an exporter sees it (full frame, or its crop when ``crop``).

    frame_index: the frame's number in the dataset. q_cam_from_body: (4,) scalar-first
    Hamilton quaternion. t_cam_from_body_m: (3,) metres, camera frame (OpenCV axes).
    K: (3, 3) intrinsics of this view, pixels. size_px: (W, H). files: file key ->
    absolute path of this view's files. crop: whether this view is the frame's crop.
    camera_mode: the camera that took it (``primary``, or ``far`` beyond the switch range).
    keypoints_px: (N, 2) the target's keypoints in this view's pixels (NaN at or behind
    the camera), or None when the record has none. keypoints_visible: (N,) bool, this
    view's flags, or None when the record has none. keypoints_depth_m: (N,) depth along
    +z_cam (metres; the same for a crop), or None. objects: (object_id, name) of each
    further object of the scene (the record's ``objects``; empty without them).
    """

    frame_index: int
    q_cam_from_body: np.ndarray
    t_cam_from_body_m: np.ndarray
    K: np.ndarray
    size_px: tuple[int, int]
    files: dict[str, Path]
    crop: bool
    camera_mode: str = "primary"
    keypoints_px: np.ndarray | None = None
    keypoints_visible: np.ndarray | None = None
    keypoints_depth_m: np.ndarray | None = None
    objects: tuple[tuple[int, str], ...] = ()


@dataclass(frozen=True)
class FrameTable:
    """What one pass over a dataset's records tells an export.

    frame_indices: the frame indices, sorted, each once. positions: where the record of
    each lies in ``dataset.frames`` (of several records of one frame index, the last).
    crop: whether to export the crops.
    """

    frame_indices: np.ndarray
    positions: np.ndarray
    crop: bool

    def positions_of(self, frame_indices: list[int]) -> np.ndarray:
        """Positions in ``dataset.frames`` of the records of these frame indices."""
        wanted = np.asarray(frame_indices, dtype=np.int64)
        return self.positions[np.searchsorted(self.frame_indices, wanted)]


def scan_frames(dataset: Dataset, crop_requested: bool) -> FrameTable:
    """Read every record once: the frame indices, and whether to export the crops (asked
    for, or the only images the dataset keeps). A few integers per frame are kept."""
    indices = array("q")
    with_crop = 0
    crop_only = False
    for frame in dataset.frames:
        cropped = bool((frame.get("crop") or {}).get("files"))
        bare = not frame.get("files")
        if bare and not cropped:
            raise SatsightError(
                f"{dataset.root}: frame {frame['frame_index']} has neither full-frame files "
                "nor a crop; the dataset is damaged: regenerate it"
            )
        with_crop += cropped
        crop_only |= bare
        indices.append(int(frame["frame_index"]))
    if not indices:
        raise SatsightError(f"{dataset.root} holds no frames; there is nothing to export")
    by_index = np.array(indices, dtype=np.int64)
    order = np.lexsort((np.arange(len(by_index)), by_index))
    last = np.ones(len(order), dtype=bool)
    last[:-1] = by_index[order[1:]] != by_index[order[:-1]]
    table = FrameTable(by_index[order[last]], order[last], False)
    if not (crop_requested or crop_only):
        return table
    if not with_crop:
        raise SatsightError(
            f"--crop: {dataset.root} has no crops; generate it with outputs.crop "
            "(e.g. outputs: {crop: {size_px: 256}}) or export the full frames without --crop"
        )
    if with_crop < len(indices):
        raise SatsightError(
            f"--crop: only {with_crop} of {len(indices)} frames of {dataset.root} have a "
            "crop; export the full frames without --crop"
        )
    return FrameTable(table.frame_indices, table.positions, True)


def records_at(frames: Sequence[dict], positions: np.ndarray) -> Iterator[dict]:
    """The records at ``positions`` of a dataset's frames, one at a time (a journal is
    read through one open file)."""
    if isinstance(frames, JournalFrames):
        yield from frames.records_at(positions)
        return
    for position in positions:
        yield frames[int(position)]


class ExportFrames:
    """One split's frames as ``ExportFrame``s (whole, or their crops when ``crop``), in
    the order of ``positions``; each pass over them reads their records anew, one at a
    time."""

    def __init__(self, dataset: Dataset, positions: np.ndarray, crop: bool):
        self.dataset, self.positions, self.crop = dataset, positions, crop

    def __len__(self) -> int:
        return len(self.positions)

    def __iter__(self) -> Iterator[ExportFrame]:
        for record in records_at(self.dataset.frames, self.positions):
            yield export_frame(self.dataset, record, self.crop)


def export_frame(dataset: Dataset, record: dict, crop: bool) -> ExportFrame:
    """The ``ExportFrame`` of a frame record, whole or cropped."""
    view = record["crop"] if crop else record
    files = {key: dataset.root / rel for key, rel in dataset.files(record, crop).items()}
    if crop:
        x0, y0, x1, y1 = (int(v) for v in view["box_xyxy_px"])
        size = (x1 - x0, y1 - y0)
    else:
        size = (int(record["image_size_px"][0]), int(record["image_size_px"][1]))
    return ExportFrame(
        frame_index=int(record["frame_index"]),
        q_cam_from_body=np.asarray(record["q_cam_from_body"], dtype=np.float64),
        t_cam_from_body_m=np.asarray(record["t_cam_from_body_m"], dtype=np.float64),
        K=np.asarray(view["K"], dtype=np.float64),
        size_px=size,
        files=files,
        crop=crop,
        camera_mode=str(record.get("camera_mode", "primary")),
        keypoints_px=_points_px(view.get("keypoints_px")),
        keypoints_visible=None
        if view.get("keypoints_visible") is None
        else np.asarray(view["keypoints_visible"], dtype=bool),
        keypoints_depth_m=None
        if record.get("keypoints_depth_m") is None
        else np.asarray(record["keypoints_depth_m"], dtype=np.float64),
        objects=tuple((int(o["object_id"]), str(o["name"])) for o in record.get("objects") or ()),
    )


def _points_px(points: list | None) -> np.ndarray | None:
    """(N, 2) pixel positions of a record's list (null: NaN), or None without a list."""
    if points is None:
        return None
    rows = [(np.nan, np.nan) if p is None else p for p in points]
    return np.asarray(rows, dtype=np.float64).reshape(len(rows), 2)


def require_file(frame: ExportFrame, key: str, purpose: str) -> Path:
    """The path of a file the export needs, or a SatsightError saying how to get it."""
    path = frame.files.get(key)
    view = "crop" if frame.crop else "frame"
    if path is None:
        raise SatsightError(
            f"{purpose} needs {key} (output '{OUTPUT_OF_KEY[key]}'), which {view} "
            f"{frame.frame_index} lacks; regenerate the dataset with '{OUTPUT_OF_KEY[key]}' "
            "in outputs.files"
        )
    if not path.is_file():
        raise SatsightError(f"{path} is missing: the dataset is damaged; regenerate it")
    return path


def read_mask(frame: ExportFrame, purpose: str) -> np.ndarray:
    """The frame's object mask as a boolean (H, W) array (True on the target)."""
    image = read_png(require_file(frame, "object_mask_png", purpose))
    return _grey(image, frame, np.uint8) > 0


def read_amodal_mask(frame: ExportFrame) -> np.ndarray | None:
    """The target's amodal mask (its whole silhouette, also where another object of the
    scene hides it) as a boolean (H, W) array, when the view has one (datasets with
    ``objects``); None otherwise, the target then being hidden by nothing but itself."""
    path = frame.files.get("amodal_mask_png")
    if path is None:
        return None
    if not path.is_file():
        raise SatsightError(f"{path} is missing: the dataset is damaged; regenerate it")
    return _grey(read_png(path), frame, np.uint8) > 0


def read_object_ids(frame: ExportFrame, purpose: str) -> np.ndarray:
    """The view's object ids (H, W) uint8: 0 space, 1 the target, 2.. the objects."""
    return _grey(read_png(require_file(frame, "object_id_png", purpose)), frame, np.uint8)


def read_depth_m(frame: ExportFrame, purpose: str) -> np.ndarray:
    """Depth along +z_cam in metres, float64 (H, W); 0 where no surface."""
    path = require_file(frame, "depth_exr", purpose)
    channels = read_exr(path)
    if "Z" not in channels:
        raise SatsightError(f"{path} has no channel Z (depth in metres); regenerate it")
    depth = _grey(np.asarray(channels["Z"], dtype=np.float64), frame, np.float64)
    if not np.all(np.isfinite(depth)) or np.any(depth < 0):
        raise SatsightError(f"{path} holds negative or non-finite depths: it is damaged")
    return depth


def _grey(image: np.ndarray, frame: ExportFrame, dtype: type) -> np.ndarray:
    """Check a single-channel image of the frame's size and type."""
    width, height = frame.size_px
    if image.shape != (height, width) or image.dtype != dtype:
        raise SatsightError(
            f"{'crop' if frame.crop else 'frame'} {frame.frame_index}: expected a "
            f"{width} x {height} {np.dtype(dtype).name} image, found shape {image.shape} "
            f"{image.dtype}; the dataset is damaged: regenerate it"
        )
    return image
