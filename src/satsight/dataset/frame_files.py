"""One frame's files: encoded on worker threads, written under temporary names, renamed.

Layout (frame index k as six digits; see docs/dataset_format.md)::

    images/frame_k.png          16-bit raw digital numbers (bias included)
    previews/frame_k.png        8-bit display stretch of the DN image (outputs.preview_stretch)
    radiance/frame_k.exr        float32 radiance, W m^-2 sr^-1 (channels R, G, B)
    depth/frame_k.exr           float32 depth along +z_cam in metres (channel Z), 0 = none
    normals/frame_k.exr         half-float unit normals in the camera frame (X, Y, Z)
                                (the three EXRs over their data windows, 0 outside)
    masks/frame_k_object.png    8-bit object mask (255 = target)
    masks/frame_k_parts.png     16-bit part ids (0 = background, part index + 1)
    masks/frame_k_background.png  8-bit body behind the target (0 space, 1 Earth, 2 Moon)
    masks/frame_k_object_ids.png  8-bit object ids (0 background, 1 target, 2.. objects), and
    masks/frame_k_amodal.png      8-bit amodal target mask (255: its whole silhouette),
                                  both only when the scene holds objects besides the target
    crop/<same folders>/...     the same files cut to the crop window, when asked for

Files are only ever renamed into place whole, so a reader never sees a half-written file.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from satsight.dataset.image_files import encode_png, write_exr
from satsight.dataset.journal import bytes_checksum, file_checksum, temporary_name
from satsight.dataset.preview import PreviewStretch
from satsight.errors import SatsightError
from satsight.render.buffers import RadianceImage
from satsight.sensor.chain import DnImage

#: File key -> (folder, file name suffix) of each output file.
FILE_LAYOUT: dict[str, tuple[str, str]] = {
    "dn_png16": ("images", ".png"),
    "preview_png8": ("previews", ".png"),
    "radiance_exr": ("radiance", ".exr"),
    "depth_exr": ("depth", ".exr"),
    "normals_exr": ("normals", ".exr"),
    "object_mask_png": ("masks", "_object.png"),
    "part_mask_png16": ("masks", "_parts.png"),
    "background_mask_png": ("masks", "_background.png"),
    "object_id_png": ("masks", "_object_ids.png"),
    "amodal_mask_png": ("masks", "_amodal.png"),
}
#: Files written beside the object mask when the scene holds other objects.
OBJECT_FILE_KEYS = ("object_id_png", "amodal_mask_png")
CROP_FOLDER = "crop"


def frame_stem(index: int) -> str:
    return f"frame_{index:06d}"


def relative_path(key: str, index: int, crop: bool = False) -> str:
    """Path of frame ``index``'s file ``key`` relative to the dataset folder (POSIX)."""
    folder, suffix = FILE_LAYOUT[key]
    path = f"{folder}/{frame_stem(index)}{suffix}"
    return f"{CROP_FOLDER}/{path}" if crop else path


@dataclass(frozen=True)
class FrameArrays:
    """What a frame's files are made of: the render's images and the detector's readout;
    with other objects in the scene, the object ids (H, W) uint8 and the target's amodal
    mask (H, W) bool (``satsight.dataset.object_labels``)."""

    image: RadianceImage
    dn_image: DnImage
    object_id: np.ndarray | None = None
    amodal_mask: np.ndarray | None = None

    def for_files(self, keys: tuple[str, ...]) -> FrameArrays:
        """The arrays without the radiance (0.2 GB a 4096 x 4112 frame) when no file of
        ``keys`` is made of it, so that a frame waiting for its files holds only theirs."""
        if "radiance_exr" in keys or self.image.radiance_w_m2_sr is None:
            return self
        return replace(self, image=self.image.without_radiance())

    @cached_property
    def surface_window(self) -> tuple[int, int, int, int]:
        """The data window of the depth and normals files: the pixels that see a surface
        (part id > 0; ``nonzero_window``), found once for both."""
        return nonzero_window(self.image.part_id)

    def exr_window(self, key: str) -> tuple[int, int, int, int] | None:
        """The data window of the EXR file ``key``: radiance over its non-zero pixels (all
        of them with the Earth or the Moon behind the target), depth and normals over
        ``surface_window``."""
        if key == "radiance_exr":
            return nonzero_window(self.image.radiance_w_m2_sr)
        return self.surface_window if key in WINDOWED_EXR else None

    def window(self, box: tuple[int, int, int, int] | None) -> FrameArrays:
        """The same arrays cut to ``box`` = (x0, y0, x1, y1), exclusive ends (None: all)."""
        if box is None:
            return self
        x0, y0, x1, y1 = box
        cut = np.s_[y0:y1, x0:x1]
        image, dn = self.image, self.dn_image
        return FrameArrays(
            RadianceImage(
                None if image.radiance_w_m2_sr is None else image.radiance_w_m2_sr[cut],
                image.depth_m[cut],
                image.part_id[cut],
                None if image.normals_cam is None else image.normals_cam[cut],
                background_id=None if image.background_id is None else image.background_id[cut],
                target_part_count=image.target_part_count,
            ),
            DnImage(
                dn.dn[cut],
                dn.exposure_time_s,
                dn.saturated_pixel_count,
                dn.star_count,
                dn.bias_dn,
                dn.full_well_dn,
            ),
            None if self.object_id is None else self.object_id[cut],
            None if self.amodal_mask is None else self.amodal_mask[cut],
        )


def _png_bytes(key: str, arrays: FrameArrays, preview: PreviewStretch) -> bytes:
    image, dn = arrays.image, arrays.dn_image
    if key == "dn_png16":
        # Raw DN is mostly read noise: unfiltered rows compress as well as filtered ones
        # (within 1 %) and encode 3x faster.
        return encode_png(dn.dn, noisy=True)
    if key == "preview_png8":
        # The stretch shows the read noise: unfiltered rows, as for raw DN (0.07 against
        # 0.15 s a 4096 x 4112 frame, 3.6 against 4.1 MB).
        return encode_png(preview.apply(dn.dn, dn.bias_dn, dn.full_well_dn), noisy=True)
    if key == "object_mask_png":
        return encode_png(image.object_mask.astype(np.uint8) * np.uint8(255))
    if key == "part_mask_png16":
        return encode_png(np.ascontiguousarray(image.part_id))
    if key == "background_mask_png":
        return encode_png(np.ascontiguousarray(image.background_mask()))
    if key == "object_id_png":
        return encode_png(np.ascontiguousarray(arrays.object_id, dtype=np.uint8))
    if key == "amodal_mask_png":
        return encode_png(arrays.amodal_mask.astype(np.uint8) * np.uint8(255))
    raise KeyError(key)


#: EXR files stored over a data window (the pixels outside it are 0), and their half-float
#: channels.
WINDOWED_EXR = ("radiance_exr", "depth_exr", "normals_exr")
HALF_EXR_CHANNELS = {"normals_exr": ("X", "Y", "Z")}


def nonzero_window(values: np.ndarray) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the smallest box holding every pixel of an (H, W) or (H, W, C)
    image with a value whose bits are not all 0 (-0.0 counts as a value), empty
    (0, 0, 0, 0) when there is none."""
    height, width = values.shape[:2]
    bits = np.ascontiguousarray(values).view(f"u{values.itemsize}").reshape(height, width, -1)
    rows = np.flatnonzero(bits.reshape(height, -1).any(axis=1))
    if rows.size == 0:
        return 0, 0, 0, 0
    cols = np.flatnonzero(bits[rows[0] : rows[-1] + 1].any(axis=(0, 2)))
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def _exr_channels(key: str, arrays: FrameArrays) -> dict[str, np.ndarray]:
    image = arrays.image
    if key == "radiance_exr":
        return {"RGB": image.radiance_w_m2_sr}
    if key == "depth_exr":
        return {"Z": image.depth_m}
    if key == "normals_exr":
        normals = image.normals_cam
        return {"X": normals[..., 0], "Y": normals[..., 1], "Z": normals[..., 2]}
    raise KeyError(key)


def _write_file(
    root: Path,
    relative: str,
    key: str,
    arrays: FrameArrays,
    preview: PreviewStretch,
    exr_compression: str = "rle",
) -> dict:
    """Encode and write one file through a temporary name; its checksum."""
    path = root / relative
    tmp = temporary_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if key.endswith("_exr"):
            window = arrays.exr_window(key)
            half = HALF_EXR_CHANNELS.get(key, ())
            write_exr(tmp, _exr_channels(key, arrays), window, half, exr_compression)
            checksum = file_checksum(tmp)
        else:
            data = _png_bytes(key, arrays, preview)
            checksum = bytes_checksum(data)
            tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        raise SatsightError(
            f"could not write {path}: {error.strerror or error}; the frames committed so far "
            "are kept: free space or fix the folder, then run again with --resume"
        ) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return checksum


def write_frame_files(
    root: Path,
    index: int,
    arrays: FrameArrays,
    keys: tuple[str, ...],
    crop_box: tuple[int, int, int, int] | None,
    full_frame: bool,
    submit: Callable[..., object] | Executor | None = None,
    preview: PreviewStretch | None = None,
    exr_compression: str = "rle",
) -> tuple[dict, dict, dict]:
    """Write frame ``index``'s files; return (files, crop files, checksums by path).

    keys: the file keys to write. crop_box: (x0, y0, x1, y1) of the crop window, or None
    for no crop. full_frame: whether to write the full frame's files. submit: an executor
    to encode the files in parallel (their encoders release the GIL), or None for serial.
    preview: the 8-bit previews' stretch (None: the default, ``PreviewStretch()``).
    exr_compression: the EXR files' compression (``image_files.EXR_COMPRESSIONS``).
    With objects in the scene (``arrays.object_id``), the masks come with
    ``OBJECT_FILE_KEYS``.
    """
    preview = PreviewStretch() if preview is None else preview
    if arrays.object_id is not None and "object_mask_png" in keys:
        keys = tuple(keys) + tuple(k for k in OBJECT_FILE_KEYS if k not in keys)
    jobs: list[tuple[str, str, bool]] = []
    if full_frame:
        jobs += [(key, relative_path(key, index), False) for key in keys]
    if crop_box is not None:
        jobs += [(key, relative_path(key, index, crop=True), True) for key in keys]
    cropped = None if crop_box is None else arrays.window(crop_box)

    def run(job: tuple[str, str, bool]) -> dict:
        key, relative, is_crop = job
        chosen = cropped if is_crop else arrays
        return _write_file(root, relative, key, chosen, preview, exr_compression)

    if submit is None:
        results = [run(job) for job in jobs]
    else:
        futures = [submit.submit(run, job) for job in jobs]
        results = [future.result() for future in futures]
    files = {key: rel for key, rel, is_crop in jobs if not is_crop}
    crop_files = {key: rel for key, rel, is_crop in jobs if is_crop}
    checksums = {rel: checksum for (_, rel, _), checksum in zip(jobs, results, strict=True)}
    return files, crop_files, dict(sorted(checksums.items()))
