"""One frame file under validation: present, its size and SHA-256, decoded once, and the
type, shape and values its output name promises (docs/dataset_format.md).

Output names and what they hold:

- ``dn_png16``: uint16 (H, W) raw DN. ``preview_png8``: uint8 (H, W).
- ``object_mask_png``: uint8 (H, W), values 0 and 255 only.
- ``part_mask_png16``: uint16 (H, W) part ids.
- ``radiance_exr``: float32 R, G, B as (H, W, 3), W m^-2 sr^-1, finite and >= 0.
- ``depth_exr``: float32 Z (H, W), metres, finite and >= 0.
- ``normals_exr``: float32 X, Y, Z, each pixel a unit vector or exactly zero.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import imagecodecs
import numpy as np
import OpenEXR

from satsight.dataset.problems import Findings

# A stored normal is unit to float32 rounding; 1e-3 leaves room for any renormalisation.
UNIT_NORMAL_TOLERANCE = 1e-3

PNG_TYPES = {
    "dn_png16": np.uint16,
    "preview_png8": np.uint8,
    "object_mask_png": np.uint8,
    "part_mask_png16": np.uint16,
}
EXR_CHANNELS = {
    "radiance_exr": ("R", "G", "B"),
    "depth_exr": ("Z",),
    "normals_exr": ("X", "Y", "Z"),
}


def _first_pixel(bad: np.ndarray) -> str:
    """'N pixels, the first at (x, y)' for a boolean (H, W) image of bad pixels."""
    y, x = np.argwhere(bad)[0]
    return f"{int(bad.sum())} pixel(s), the first at (x={x}, y={y})"


def _decode_exr(path: Path, channels: tuple[str, ...]) -> np.ndarray:
    """The named channels of an OpenEXR file as (H, W) for one, (H, W, C) for several."""
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        stored = {name: channel.pixels for name, channel in exr.channels().items()}
    missing = [name for name in channels if name not in stored]
    if missing:
        raise ValueError(
            f"expected channels {', '.join(channels)}, found {', '.join(sorted(stored)) or 'none'}"
        )
    planes = [np.asarray(stored[name]) for name in channels]
    if any(p.dtype != np.float32 for p in planes):
        raise ValueError(
            f"expected float32 channels, found {', '.join(str(p.dtype) for p in planes)}"
        )
    return planes[0].copy() if len(planes) == 1 else np.stack(planes, axis=-1)


def _bad_values(key: str, image: np.ndarray) -> tuple[np.ndarray, str] | None:
    """(H, W) pixels breaking the value rule of output ``key``, and the rule; None if none."""
    if key == "object_mask_png":
        return (image != 0) & (image != 255), "values 0 and 255 only"
    if key == "radiance_exr":
        return ~(np.isfinite(image) & (image >= 0)).all(axis=-1), "finite radiance >= 0"
    if key == "depth_exr":
        return ~(np.isfinite(image) & (image >= 0)), "finite depth >= 0"
    if key == "normals_exr":
        with np.errstate(invalid="ignore"):
            norm = np.sqrt(np.einsum("...i,...i->...", image, image))  # float32, no copy
            unit = np.abs(norm - 1.0) <= UNIT_NORMAL_TOLERANCE
        return ~(unit | (image == 0).all(axis=-1)), "unit or zero normals"
    return None


def read_frame_file(
    root: Path,
    relative: str,
    key: str,
    shape_hw: tuple[int, int] | None,
    checksum: dict | None,
    hashes: bool,
    findings: Findings,
    frame: int | None,
) -> np.ndarray | None:
    """Check one file of a frame and return its decoded image (None when unusable).

    relative: the path relative to ``root``. key: its output name (``dn_png16`` ...).
    shape_hw: the expected (H, W) in pixels, None when unknown. checksum: the record's
    ``{sha256, size_bytes}`` for it, None when the record has none. hashes: compare SHA-256
    sums (sizes are always compared). Problems go to ``findings``.
    """

    def problem(check: str, message: str) -> None:
        findings.add(check, message, frame, relative)

    path = root / relative
    findings.ran("files")
    if not path.is_file():
        problem("files", f"expected the {key} file, found none (missing)")
        return None
    data = path.read_bytes()
    findings.ran("checksums")
    if checksum is None:
        problem("checksums", "expected an entry in the frame's checksums, found none")
    else:
        if len(data) != checksum.get("size_bytes"):
            problem(
                "checksums",
                f"expected {checksum.get('size_bytes')} bytes, found {len(data)}",
            )
        if hashes:
            digest = hashlib.sha256(data).hexdigest()
            if digest != checksum.get("sha256"):
                problem("checksums", f"expected SHA-256 {checksum.get('sha256')}, found {digest}")
    if key not in PNG_TYPES and key not in EXR_CHANNELS:
        return None
    try:
        if key in PNG_TYPES:
            image = imagecodecs.png_decode(data)
        else:
            image = _decode_exr(path, EXR_CHANNELS[key])
    except Exception as error:  # any decoder failure is a problem of the file
        kind = "PNG" if key in PNG_TYPES else "OpenEXR"
        problem(
            "files", f"expected a readable {kind} image, found one that does not decode ({error})"
        )
        return None
    expected_dtype = PNG_TYPES.get(key, np.float32)
    channels = len(EXR_CHANNELS.get(key, ()))
    expected_shape = None
    if shape_hw is not None:
        expected_shape = (*shape_hw, 3) if channels == 3 else tuple(shape_hw)
    if image.dtype != expected_dtype or (
        expected_shape is not None and image.shape != expected_shape
    ):
        want = "x".join(map(str, expected_shape)) if expected_shape else "(H, W)"
        problem(
            "files",
            f"expected {np.dtype(expected_dtype).name} {want}, found {image.dtype.name} "
            f"{'x'.join(map(str, image.shape))}",
        )
        return None
    rule = _bad_values(key, image)
    if rule is not None and rule[0].any():
        problem("files", f"expected {rule[1]}, found others in {_first_pixel(rule[0])}")
        return None
    return image
