"""Labels of a frame whose scene holds other objects beside the target.

Object ids: 0 background, 1 the target, 2.. the scenario's ``objects`` in order. Three
per-pixel images, all from pixel-centre rays:

* ``object_id``: the id of what each pixel sees in the rendered scene (visible pixels);
* ``target_amodal``: the target's whole silhouette, from a labels-only render of the target
  alone (the amodal mask: also behind an occluder);
* ``objects_amodal_id``: the ids from a labels-only render of the objects without the
  target, so each object's amodal pixels are its silhouette with the target removed (one
  object hiding another still counts as hidden there: objects' mutual occlusion is not
  undone).

Visible fraction of an object (the target included) = its visible pixels / its amodal
pixels, as BOP's ``visib_fract`` (Hodan et al., "BOP: Benchmark for 6D object pose
estimation", ECCV 2018, sec. 2.3), within the image.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.frames.rigid import RigidTransform


def target_occlusion(object_id: np.ndarray, target_amodal: np.ndarray) -> dict:
    """The target's occlusion record: amodal and visible pixel counts, the occluded pixels
    (amodal target pixels where an object is seen), ``visib_fract`` and the amodal box."""
    visible = object_id == 1
    amodal = np.asarray(target_amodal, dtype=bool)
    amodal_count = int(np.count_nonzero(amodal))
    visible_count = int(np.count_nonzero(visible))
    return {
        "amodal_pixel_count": amodal_count,
        "visible_pixel_count": visible_count,
        "occluded_pixel_count": int(np.count_nonzero(amodal & (object_id > 1))),
        "visib_fract": visible_count / amodal_count if amodal_count else 0.0,
        "amodal_bbox_xyxy_px": mask_bbox_xyxy_px(amodal),
    }


def object_records(
    names: Sequence[str],
    cam_from_objects: Sequence[RigidTransform],
    object_id: np.ndarray,
    objects_amodal_id: np.ndarray,
) -> list[dict]:
    """One record per object: name, id, pose in the camera frame (scalar-first), visible
    pixel count and box, amodal pixel count and visible fraction (module docstring)."""
    records = []
    for k, (name, pose) in enumerate(zip(names, cam_from_objects, strict=True)):
        oid = k + 2
        visible = object_id == oid
        count = int(np.count_nonzero(visible))
        amodal = int(np.count_nonzero(objects_amodal_id == oid))
        records.append(
            {
                "name": name,
                "object_id": oid,
                "q_cam_from_object": pose.q_a_from_b.tolist(),
                "t_cam_from_object_m": pose.t_a_from_b_m.tolist(),
                "pixel_count": count,
                "bbox_xyxy_px": mask_bbox_xyxy_px(visible),
                "amodal_pixel_count": amodal,
                "visib_fract": count / amodal if amodal else 0.0,
            }
        )
    return records
