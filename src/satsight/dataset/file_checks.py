"""One frame file under validation: present, its size and SHA-256, decoded once, and the
type, shape and values its output name promises (docs/dataset_format.md).

Output names and what they hold:

- ``dn_png16``: uint16 (H, W) raw DN. ``preview_png8``: uint8 (H, W).
- ``object_mask_png``: uint8 (H, W), values 0 and 255 only.
- ``part_mask_png16``: uint16 (H, W) part ids.
- ``background_mask_png``: uint8 (H, W), 0 space, 1 the Earth, 2 the Moon.
- ``object_id_png``: uint8 (H, W) object ids; ``amodal_mask_png``: uint8, 0 and 255 only.
- ``radiance_exr``: float32 R, G, B, each (H, W), W m^-2 sr^-1, finite and >= 0.
- ``depth_exr``: float32 Z (H, W), metres, finite and >= 0.
- ``normals_exr``: float32 X, Y, Z, each pixel a unit vector or exactly zero.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import imagecodecs
import numpy as np

from satsight.dataset.image_files import exr_channels
from satsight.dataset.problems import Findings

# A stored normal is unit to float32 rounding; 1e-3 leaves room for any renormalisation.
UNIT_NORMAL_TOLERANCE = 1e-3

PNG_TYPES = {
    "dn_png16": np.uint16,
    "preview_png8": np.uint8,
    "object_mask_png": np.uint8,
    "part_mask_png16": np.uint16,
    "background_mask_png": np.uint8,
    "object_id_png": np.uint8,
    "amodal_mask_png": np.uint8,
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


def _decode_exr(path: Path, channels: tuple[str, ...]) -> list[np.ndarray]:
    """The named channels of an OpenEXR file, each an (H, W) float32 plane over the whole
    image (``exr_channels``: 0 outside the data window, half floats widened)."""
    stored = exr_channels(path, separate=True)
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
    return planes


def _finite_non_negative(planes: list[np.ndarray]) -> np.ndarray | None:
    """(H, W) pixels with a channel negative, NaN or infinite; None when there are none."""
    # Fast path: min and max are single passes, and a NaN makes the comparison fail.
    if all(p.size == 0 or (p.min() >= 0 and p.max() < np.inf) for p in planes):
        return None
    bad = np.zeros(planes[0].shape, dtype=bool)
    for plane in planes:
        bad |= ~((plane >= 0) & (plane < np.inf))
    return bad


def _bad_values(key: str, planes: list[np.ndarray]) -> tuple[np.ndarray | None, str] | None:
    """(H, W) pixels breaking the value rule of output ``key`` (None: no pixel does), and the
    rule; None when the output has no value rule."""
    if key in ("object_mask_png", "amodal_mask_png"):
        # 0 and 255 are exactly the values that wrap to 1 and 0 when one is added.
        bad = (planes[0] + np.uint8(1)) > 1
        return (bad if bad.any() else None), "values 0 and 255 only"
    if key == "background_mask_png":
        bad = planes[0] > 2
        return (bad if bad.any() else None), "values 0 (space), 1 (Earth) and 2 (Moon) only"
    if key == "radiance_exr":
        return _finite_non_negative(planes), "finite radiance >= 0"
    if key == "depth_exr":
        return _finite_non_negative(planes), "finite depth >= 0"
    if key == "normals_exr":
        x, y, z = planes
        squared = x * x
        squared += y * y
        squared += z * z
        low, high = (1.0 - UNIT_NORMAL_TOLERANCE) ** 2, (1.0 + UNIT_NORMAL_TOLERANCE) ** 2
        with np.errstate(invalid="ignore"):
            bad = ~((squared == 0) | ((squared >= low) & (squared <= high)))
        return (bad if bad.any() else None), "unit or zero normals"
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
) -> np.ndarray | tuple[np.ndarray, ...] | None:
    """Check one file of a frame and return its decoded image: (H, W) for a one-channel
    file, a tuple of (H, W) planes for several (R, G, B; X, Y, Z); None when unusable.

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
            planes = [imagecodecs.png_decode(data)]
        else:
            planes = _decode_exr(path, EXR_CHANNELS[key])
    except Exception as error:  # any decoder failure is a problem of the file
        kind = "PNG" if key in PNG_TYPES else "OpenEXR"
        problem(
            "files", f"expected a readable {kind} image, found one that does not decode ({error})"
        )
        return None
    del data
    expected_dtype = np.dtype(PNG_TYPES.get(key, np.float32))
    if any(p.dtype != expected_dtype or p.ndim != 2 for p in planes) or (
        shape_hw is not None and any(p.shape != tuple(shape_hw) for p in planes)
    ):
        want = "x".join(map(str, shape_hw)) if shape_hw is not None else "(H, W)"
        found = ", ".join(f"{p.dtype.name} {'x'.join(map(str, p.shape))}" for p in planes)
        names = f" channels {', '.join(EXR_CHANNELS[key])}" if key in EXR_CHANNELS else ""
        problem("files", f"expected {expected_dtype.name} {want}{names}, found {found}")
        return None
    rule = _bad_values(key, planes)
    if rule is not None and rule[0] is not None:
        problem("files", f"expected {rule[1]}, found others in {_first_pixel(rule[0])}")
        return None
    return planes[0] if len(planes) == 1 else tuple(planes)
