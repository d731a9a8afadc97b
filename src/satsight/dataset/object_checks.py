"""Checks of a frame whose scene holds other objects (``satsight.dataset.object_labels``):
the object-id mask against the object mask and the amodal mask, and the ``occlusion`` and
``objects`` records against the pixels."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from satsight.dataset.labels import mask_bbox_xyxy_px


def check_object_masks(
    frame: dict, images: dict, problem: Callable[[str, str, str | None], None]
) -> bool:
    """Run the checks when the frame has an object-id mask; whether it had one.

    problem(check, message, file) records a finding under the check ``masks``.
    """
    ids, files = images.get("object_id_png"), frame.get("files") or {}
    if ids is None:
        return False
    file = files.get("object_id_png")
    objects = frame.get("objects") or []
    top = len(objects) + 1
    if int(ids.max(initial=0)) > top:
        problem("masks", f"expected object ids 0 .. {top}, found {int(ids.max())}", file)
    mask, amodal = images.get("object_mask_png"), images.get("amodal_mask_png")
    if mask is not None and mask.shape == ids.shape and not np.array_equal(ids == 1, mask == 255):
        differ = int(np.count_nonzero((ids == 1) != (mask == 255)))
        problem(
            "masks", f"expected object id 1 exactly on the object mask, {differ} px differ", file
        )
    occlusion = frame.get("occlusion") or {}
    if amodal is not None and amodal.shape == ids.shape:
        on = amodal == 255
        if np.any((ids == 1) & ~on):
            problem(
                "masks",
                "expected the target's visible pixels inside its amodal mask",
                files.get("amodal_mask_png"),
            )
        expected = {
            "amodal_pixel_count": int(np.count_nonzero(on)),
            "visible_pixel_count": int(np.count_nonzero(ids == 1)),
            "occluded_pixel_count": int(np.count_nonzero(on & (ids > 1))),
        }
        for key, value in expected.items():
            if occlusion.get(key) != value:
                problem(
                    "masks", f"expected occlusion.{key} {value}, found {occlusion.get(key)}", file
                )
        if occlusion.get("amodal_bbox_xyxy_px") != mask_bbox_xyxy_px(on):
            problem("masks", "expected occlusion.amodal_bbox_xyxy_px from the amodal mask", file)
    for k, record in enumerate(objects):
        oid = k + 2
        where = ids == oid
        if record.get("object_id") != oid or record.get("pixel_count") != int(where.sum()):
            problem(
                "masks",
                f"expected object {record.get('name')!r} with id {oid} and "
                f"{int(where.sum())} px, found id {record.get('object_id')} and "
                f"{record.get('pixel_count')} px",
                file,
            )
        if record.get("bbox_xyxy_px") != mask_bbox_xyxy_px(where):
            problem("masks", f"expected object {record.get('name')!r}'s box from its ids", file)
    return True
