"""Per-frame labels: pose, intrinsics, sun, range, box, keypoints, visible fraction.

Every label is computed from the exact pose and intrinsics used to render the frame, not
from the images, except the 2D box and pixel counts which come from the object mask.
"""

from __future__ import annotations

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import RigidTransform
from satsight.render.buffers import RadianceImage, SunLight
from satsight.scene.mesh import TargetMesh


def mask_bbox_xyxy_px(mask: np.ndarray) -> list[int] | None:
    """Tight box [x_min, y_min, x_max, y_max] (inclusive pixel indices) of a mask, or None."""
    ys = np.flatnonzero(mask.any(axis=1))
    if ys.size == 0:
        return None
    xs = np.flatnonzero(mask.any(axis=0))
    return [int(xs[0]), int(ys[0]), int(xs[-1]), int(ys[-1])]


def frame_labels(
    mesh: TargetMesh,
    camera: PinholeCamera,
    cam_from_body: RigidTransform,
    sun: SunLight,
    image: RadianceImage,
) -> dict:
    """The label record of one rendered frame (JSON-ready).

    Keys: q_cam_from_body (scalar-first), t_cam_from_body_m, K, image_size_px [W, H],
    sun_direction_cam (unit, towards the Sun), sun_irradiance_w_m2, range_m (camera to
    body origin), range_to_center_m (to the bounding-box centre), phase_angle_deg
    (Sun-target-camera angle at the box centre), bbox_xyxy_px (from the object mask),
    keypoints_px (projected bounding-box corners then centre, see
    ``TargetMesh.keypoints_body_m``; null for one at or behind the camera),
    keypoints_depth_m, object_pixel_count, visible_pixel_fraction (object pixels / image
    pixels), truncated (mask touches the image border).
    """
    mask = image.object_mask
    keypoints_cam = cam_from_body.apply(mesh.keypoints_body_m)
    keypoints_px = camera.project(keypoints_cam)
    center_cam = cam_from_body.apply(mesh.center_m)
    to_camera = -center_cam / np.linalg.norm(center_cam)
    sun_cam = cam_from_body.rotate(sun.direction_body)
    phase = np.degrees(np.arccos(np.clip(np.dot(to_camera, sun_cam), -1.0, 1.0)))
    count = int(mask.sum())
    border = mask[0, :].any() or mask[-1, :].any() or mask[:, 0].any() or mask[:, -1].any()
    return {
        "q_cam_from_body": cam_from_body.q_a_from_b.tolist(),
        "t_cam_from_body_m": cam_from_body.t_a_from_b_m.tolist(),
        "K": camera.K.tolist(),
        "image_size_px": [camera.width_px, camera.height_px],
        "sun_direction_cam": sun_cam.tolist(),
        "sun_irradiance_w_m2": float(sun.irradiance_w_m2),
        "range_m": float(np.linalg.norm(cam_from_body.t_a_from_b_m)),
        "range_to_center_m": float(np.linalg.norm(center_cam)),
        "phase_angle_deg": float(phase),
        "bbox_xyxy_px": mask_bbox_xyxy_px(mask),
        # a keypoint at or behind the camera plane has no projection: null
        "keypoints_px": [None if np.isnan(p).any() else p.tolist() for p in keypoints_px],
        "keypoints_depth_m": keypoints_cam[:, 2].tolist(),
        "object_pixel_count": count,
        "visible_pixel_fraction": count / mask.size,
        "truncated": bool(border),
    }


def crop_window_xyxy_px(
    center_px: list[float] | None, size_px: int, shape: tuple[int, int]
) -> tuple[int, int, int, int]:
    """The crop window of side ``size_px`` centred on a pixel position, inside the image.

    center_px: [x, y] of the target's projected box centre (pixel (0, 0) is the centre of
    the top-left pixel), or None (behind the camera: the image centre is used). The window
    is centred on the pixel holding that point and shifted inward at the borders, so its
    size never changes. Returns (x0, y0, x1, y1) with exclusive ends.
    """
    height, width = shape
    if size_px > min(height, width):
        raise ValueError(f"crop of {size_px} px does not fit a {width} x {height} image")
    if center_px is None:
        center_px = [(width - 1) / 2.0, (height - 1) / 2.0]
    origin = []
    for value, extent in zip(center_px, (width, height), strict=True):
        pixel = int(np.floor(np.clip(value, -1e9, 1e9) + 0.5))
        origin.append(int(np.clip(pixel - size_px // 2, 0, extent - size_px)))
    x0, y0 = origin
    return x0, y0, x0 + size_px, y0 + size_px


def crop_labels(labels: dict, mask: np.ndarray, box: tuple[int, int, int, int]) -> dict:
    """The labels of a crop window: its intrinsics (K with the principal point moved by
    the window's origin), the mask's box and pixel count inside it, and the keypoints in
    its pixels. ``labels``: the full frame's record; ``mask``: its (H, W) object mask."""
    x0, y0, x1, y1 = box
    K = np.array(labels["K"], dtype=np.float64)
    K[0, 2] -= x0
    K[1, 2] -= y0
    window = mask[y0:y1, x0:x1]
    count = int(window.sum())
    border = window[0, :].any() or window[-1, :].any() or window[:, 0].any()
    border = bool(border or window[:, -1].any())
    return {
        "size_px": x1 - x0,
        "box_xyxy_px": [x0, y0, x1, y1],
        "K": K.tolist(),
        "bbox_xyxy_px": mask_bbox_xyxy_px(window),
        "keypoints_px": [
            None if p is None else [p[0] - x0, p[1] - y0] for p in labels["keypoints_px"]
        ],
        "object_pixel_count": count,
        "truncated": border,
    }
