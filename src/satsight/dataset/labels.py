"""Per-frame labels: pose, intrinsics, sun, range, box, keypoints, visible fraction.

Every label is computed from the exact pose and intrinsics used to render the frame, not
from the images, except the 2D box and pixel counts, which come from the object mask, and
each keypoint's visibility, which comes from the depth buffer:

A keypoint is visible when it projects inside the image (within the outer edges of the
border pixels) and, of the 3 x 3 pixels around the pixel it falls on (those inside the
image), at least one shows no surface of the target nearer to the camera than the
keypoint's depth minus ``KEYPOINT_DEPTH_TOLERANCE`` (``keypoint_depth_tolerance_m``): a
point on a surface turned towards the camera has a neighbour pixel at or behind its depth
(the surface through it, or the sky past its edge), and a point behind another part has
that part in front of it at every neighbour. The tolerance covers the float32 depth
buffer (relative 1e-5) and 1 cm.
"""

from __future__ import annotations

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import SunLight
from satsight.render.buffers import RadianceImage, mask_box
from satsight.scene.mesh import TargetMesh
from satsight.vectors import angle_between_rad

#: Keypoint depth tolerance: KEYPOINT_DEPTH_ATOL_M + KEYPOINT_DEPTH_RTOL * depth.
KEYPOINT_DEPTH_ATOL_M = 0.01
KEYPOINT_DEPTH_RTOL = 1e-5
KEYPOINT_DEPTH_TOLERANCE = "0.01 m + 1e-5 x depth"


def keypoint_depth_tolerance_m(depth_m: np.ndarray) -> np.ndarray:
    """How much nearer than a keypoint a surface must be to hide it (metres)."""
    return KEYPOINT_DEPTH_ATOL_M + KEYPOINT_DEPTH_RTOL * np.abs(depth_m)


def keypoints_visible(
    keypoints_px: np.ndarray, keypoints_depth_m: np.ndarray, depth_m: np.ndarray
) -> np.ndarray:
    """(N,) bool: which keypoints the camera sees (module docstring).

    keypoints_px: (N, 2) pixel positions (NaN behind the camera). keypoints_depth_m: (N,)
    depths along +z_cam. depth_m: (H, W) depth buffer, 0 where no surface.
    """
    height, width = depth_m.shape
    points = np.asarray(keypoints_px, dtype=np.float64)
    z = np.asarray(keypoints_depth_m, dtype=np.float64)
    visible = np.zeros(len(points), dtype=bool)
    finite = np.all(np.isfinite(points), axis=1) & (z > 0)
    inside = finite.copy()
    inside[finite] = (
        (points[finite, 0] >= -0.5)
        & (points[finite, 0] < width - 0.5)
        & (points[finite, 1] >= -0.5)
        & (points[finite, 1] < height - 0.5)
    )
    for k in np.flatnonzero(inside):
        col, row = (int(np.floor(v + 0.5)) for v in points[k])
        window = depth_m[max(row - 1, 0) : row + 2, max(col - 1, 0) : col + 2]
        nearest_allowed = z[k] - keypoint_depth_tolerance_m(z[k])
        visible[k] = bool(np.any((window <= 0) | (window >= nearest_allowed)))
    return visible


def mask_bbox_xyxy_px(mask: np.ndarray) -> list[int] | None:
    """Tight box [x_min, y_min, x_max, y_max] (inclusive pixel indices) of a mask, or None."""
    box = mask_box(mask)
    if box is None:
        return None
    rows, columns = box
    return [columns.start, rows.start, columns.stop - 1, rows.stop - 1]


def _projected(points_px: np.ndarray) -> list:
    """Pixel positions as JSON: null for a point at or behind the camera plane."""
    return [None if np.isnan(p).any() else p.tolist() for p in points_px]


def frame_labels(
    mesh: TargetMesh,
    camera: PinholeCamera,
    cam_from_body: RigidTransform,
    sun: SunLight,
    image: RadianceImage,
    keypoints_body_m: np.ndarray | None = None,
) -> dict:
    """The label record of one rendered frame (JSON-ready).

    Keys: q_cam_from_body (scalar-first), t_cam_from_body_m, K, image_size_px [W, H],
    sun_direction_cam (unit, towards the Sun), sun_irradiance_w_m2, range_m (camera to
    body origin), range_to_center_m (to the bounding-box centre), phase_angle_deg
    (Sun-target-camera angle at the box centre), bbox_xyxy_px (from the object mask),
    keypoints_px (the projected ``keypoints_body_m`` (N, 3), default the box's; null for
    one at or behind the camera), keypoints_depth_m, keypoints_visible (module
    docstring), box_keypoints_px and box_keypoints_depth_m (the bounding box's corners then
    centre, ``TargetMesh.box_keypoints_body_m``), object_pixel_count,
    visible_pixel_fraction (object pixels / image pixels), truncated (mask touches the
    image border), target_footprint (whether the radiance of a small target's pixels was
    integrated over their area, ``satsight.render.footprint``: its projected box, whether
    it is sub-pixel, the grid's spacing and size; ``{"integrated": false}`` otherwise).
    """
    mask = image.object_mask
    box_cam = cam_from_body.apply(mesh.box_keypoints_body_m)
    if keypoints_body_m is None:
        keypoints_body_m = mesh.box_keypoints_body_m
    keypoints_cam = cam_from_body.apply(np.asarray(keypoints_body_m, dtype=np.float64))
    keypoints_px = camera.project(keypoints_cam)
    visible = keypoints_visible(keypoints_px, keypoints_cam[:, 2], image.depth_m)
    center_cam = cam_from_body.apply(mesh.center_m)
    to_camera = -center_cam / np.linalg.norm(center_cam)
    sun_cam = cam_from_body.rotate(sun.direction_body)
    phase = np.degrees(angle_between_rad(to_camera, sun_cam))
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
        "keypoints_px": _projected(keypoints_px),
        "keypoints_depth_m": keypoints_cam[:, 2].tolist(),
        "keypoints_visible": visible.tolist(),
        "box_keypoints_px": _projected(camera.project(box_cam)),
        "box_keypoints_depth_m": box_cam[:, 2].tolist(),
        "object_pixel_count": count,
        "visible_pixel_fraction": count / mask.size,
        "truncated": bool(border),
        "target_footprint": image.footprint or {"integrated": False},
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


def _in_window(point_px: list | None, x0: int, y0: int, x1: int, y1: int) -> bool:
    """Whether a pixel position lies in the window's pixels (exclusive ends x1, y1)."""
    if point_px is None:
        return False
    u, v = point_px
    return x0 - 0.5 <= u < x1 - 0.5 and y0 - 0.5 <= v < y1 - 0.5


def _shifted(points_px: list, x0: int, y0: int) -> list:
    return [None if p is None else [p[0] - x0, p[1] - y0] for p in points_px]


def crop_labels(labels: dict, mask: np.ndarray, box: tuple[int, int, int, int]) -> dict:
    """The labels of a crop window: its intrinsics (K with the principal point moved by
    the window's origin), the mask's box and pixel count inside it, and the keypoints in
    its pixels (visible: visible in the frame and inside the window). ``labels``: the full
    frame's record; ``mask``: its (H, W) object mask."""
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
        "keypoints_px": _shifted(labels["keypoints_px"], x0, y0),
        "keypoints_visible": [
            bool(seen) and _in_window(p, x0, y0, x1, y1)
            for p, seen in zip(labels["keypoints_px"], labels["keypoints_visible"], strict=True)
        ],
        "box_keypoints_px": _shifted(labels["box_keypoints_px"], x0, y0),
        "object_pixel_count": count,
        "truncated": border,
    }
