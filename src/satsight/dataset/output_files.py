"""Which files each output of a dataset writes per frame (see docs/dataset_format.md)."""

from __future__ import annotations

#: Output names (a scenario's ``outputs.files``) and the file keys each one writes.
OUTPUT_FILE_KEYS: dict[str, tuple[str, ...]] = {
    "dn": ("dn_png16",),
    "preview": ("preview_png8",),
    "radiance": ("radiance_exr",),
    "depth": ("depth_exr",),
    "normals": ("normals_exr",),
    "masks": ("object_mask_png", "part_mask_png16", "background_mask_png"),
}
