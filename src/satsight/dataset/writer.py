"""Writes one frame's files and the dataset's labels.json.

Layout of a dataset folder (frame index k as six digits)::

    images/frame_k.png          16-bit digital numbers read out by the detector (raw DN,
                                bias included: what the camera would send down)
    previews/frame_k.png        8-bit display stretch of the DN image (labels.json "preview")
    radiance/frame_k.exr        float32 radiance, W m^-2 sr^-1 (channels R, G, B)
    depth/frame_k.exr           float32 depth along +z_cam in metres (channel Z), 0 = none
    normals/frame_k.exr         float32 unit normals in the camera frame (X, Y, Z)
    masks/frame_k_object.png    8-bit object mask (255 = target)
    masks/frame_k_parts.png     16-bit part ids (0 = background, part index + 1)
    labels.json                 camera, target, conventions and per-frame labels
    model/target.obj (+ .mtl)   the target mesh in its body frame, metres
    contact_sheet.png           thumbnails of every frame
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from satsight.dataset.image_files import write_exr, write_png
from satsight.dataset.preview import dn_preview_uint8
from satsight.render.buffers import RadianceImage
from satsight.sensor.chain import DnImage

FRAME_FOLDERS = ("images", "previews", "radiance", "depth", "normals", "masks")
LABELS_FORMAT = "satsight-labels"
LABELS_VERSION = 2


def frame_stem(index: int) -> str:
    return f"frame_{index:06d}"


def write_frame(root: Path, index: int, image: RadianceImage, dn_image: DnImage) -> dict:
    """Write the image files of frame ``index`` under ``root``; return their relative paths."""
    stem = frame_stem(index)
    for folder in FRAME_FOLDERS:
        (root / folder).mkdir(exist_ok=True)
    files = {
        "dn_png16": f"images/{stem}.png",
        "preview_png8": f"previews/{stem}.png",
        "radiance_exr": f"radiance/{stem}.exr",
        "depth_exr": f"depth/{stem}.exr",
        "normals_exr": f"normals/{stem}.exr",
        "object_mask_png": f"masks/{stem}_object.png",
        "part_mask_png16": f"masks/{stem}_parts.png",
    }
    write_png(root / files["dn_png16"], dn_image.dn)
    write_png(
        root / files["preview_png8"],
        dn_preview_uint8(dn_image.dn, dn_image.bias_dn, dn_image.full_well_dn),
    )
    write_exr(root / files["radiance_exr"], {"RGB": image.radiance_w_m2_sr})
    write_exr(root / files["depth_exr"], {"Z": image.depth_m})
    normals = image.normals_cam
    write_exr(
        root / files["normals_exr"],
        {"X": normals[..., 0], "Y": normals[..., 1], "Z": normals[..., 2]},
    )
    write_png(root / files["object_mask_png"], image.object_mask.astype(np.uint8) * 255)
    write_png(root / files["part_mask_png16"], image.part_id)
    return {"files": files}


def write_labels(root: Path, document: dict) -> Path:
    """Write labels.json (UTF-8, indented)."""
    path = root / "labels.json"
    payload = {"format": LABELS_FORMAT, "version": LABELS_VERSION, **document}
    path.write_text(json.dumps(payload, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return path
