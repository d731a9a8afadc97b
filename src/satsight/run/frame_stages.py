"""The stages of a frame after rendering, shared by the local run and the Dask workers:
labels, optics and detector (``sense_frame``), then the frame's files (``write_frame``)."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from satsight.dataset.contact_sheet import (
    contact_sheet_frames,
    keep_thumbnail,
    thumbnail_source,
)
from satsight.dataset.frame_files import FrameArrays, write_frame_files
from satsight.pipeline import FrameEngine, RenderedFrame

# Threads that encode one frame's files (PNG and EXR encoders release the GIL).
ENCODER_THREADS = 3


@dataclass
class SensedFrame:
    """A frame after labels, optics and detector: its record (without files) and arrays."""

    record: dict
    arrays: FrameArrays
    crop_box: tuple | None
    sensor_s: float


def sense_frame(engine: FrameEngine, frame: RenderedFrame) -> SensedFrame:
    """Labels, optics and detector of a rendered frame."""
    t0 = time.perf_counter()
    record, arrays, box = engine.finish(frame)
    arrays = arrays.for_files(engine.file_keys())
    return SensedFrame(record, arrays, box, time.perf_counter() - t0)


def write_frame(
    engine: FrameEngine, root: Path, sensed: SensedFrame, encoders: ThreadPoolExecutor | None
) -> tuple[dict, dict[str, float]]:
    """Write a sensed frame's files; its journal record and stage times (s)."""
    t0 = time.perf_counter()
    outputs = engine.scenario.outputs
    preview = outputs.build_preview()
    record = sensed.record
    files, crop_files, checksums = write_frame_files(
        root,
        record["frame_index"],
        sensed.arrays,
        outputs.file_keys(),
        sensed.crop_box,
        outputs.crop is None or outputs.crop.full_frame,
        encoders,
        preview,
        outputs.exr_compression,
    )
    record["files"] = files
    if "crop" in record:
        record["crop"]["files"] = crop_files
    record["checksums"] = checksums
    if outputs.contact_sheet and record["frame_index"] in contact_sheet_frames(engine.frame_count):
        source = thumbnail_source(record)
        if source is not None:
            arrays = sensed.arrays.window(sensed.crop_box) if source[1] else sensed.arrays
            dn = arrays.dn_image
            keep_thumbnail(root, record, dn.dn, dn.bias_dn, dn.full_well_dn, preview)
    return record, {"sensor": sensed.sensor_s, "files": time.perf_counter() - t0}
