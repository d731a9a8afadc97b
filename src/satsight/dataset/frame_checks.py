"""The checks of one frame: its pose labels, its files, and the labels against the images.

Tolerances, and why (the pose checks and their constants live in
``satsight.dataset.pose_checks``):

- Quaternion norm within ``QUATERNION_NORM_TOLERANCE`` of 1: labels are written normalised
  in float64 and JSON keeps every bit, so any larger error is an edit.
- Keypoints within ``KEYPOINT_RTOL`` times max(1, |(u, v)|) pixels of the projection of
  ``header["target"]["keypoints_body_m"]`` (and the box's, ``box_keypoints_body_m``)
  through K and the pose; ``keypoints_visible`` as the depth image decides it
  (``satsight.dataset.labels.keypoints_visible``). Relative, because a
  corner near the camera plane projects thousands of pixels off the image, where rounding
  grows with the coordinate; 1e-6 is ten orders above float64 rounding, and a pose error it
  would miss moves a keypoint by less than a millionth of its pixel coordinates (0.004 px
  at the far corner of a 4096-pixel image).
- Depth inside the depth range of the target's bounding box under the pose, to
  ``DEPTH_RTOL`` of the range (float32 depth) plus ``DEPTH_ATOL_M``; mask box inside the
  box of the projected corners, to ``BBOX_MARGIN_PX`` (a pixel is in the mask when its
  footprint, not its centre, meets the target).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.file_checks import read_frame_file
from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.dataset.object_checks import check_object_masks
from satsight.dataset.pose_checks import (
    FLOAT64_RTOL,
    PoseChecks,
    close_to,
    number_text,
)
from satsight.dataset.problems import Findings

DEPTH_RTOL = 1e-5
DEPTH_ATOL_M = 1e-3
BBOX_MARGIN_PX = 1.0
# Images compared with the labels after decoding; the others are checked and dropped.
KEPT_IMAGES = (
    "object_mask_png", "part_mask_png16", "depth_exr", "background_mask_png",
    "object_id_png", "amodal_mask_png",
)  # fmt: skip


@dataclass(frozen=True)
class TargetPoints:
    """The manifest's body-frame points (metres) that frames label: the keypoints (N, 3)
    and the box's corners and centre (9, 3); None where the manifest lacks them. Datasets
    written before ``box_keypoints_body_m`` existed labelled the box as their keypoints."""

    keypoints_body_m: np.ndarray | None
    box_keypoints_body_m: np.ndarray | None
    box_is_keypoints: bool = False


class FrameCheck(PoseChecks):
    """Checks of one frame record and its files; problems go to ``self.findings``.

    root: the dataset folder. frame: the frame's record. points: the target's keypoints and
    box corners in the body frame (``TargetPoints``).
    record_file: where the record is read from (``labels.json``, or ``journal.jsonl`` for
    an incomplete dataset).
    hashes: compare SHA-256 sums.
    """

    def __init__(
        self,
        root: Path,
        frame: dict,
        points: TargetPoints,
        record_file: str,
        hashes: bool,
    ):
        self.root = Path(root)
        self.frame = frame
        self.index = frame.get("frame_index")
        self.points = points
        self.record_file = record_file
        self.hashes = hashes
        self.findings = Findings()

    def problem(self, check: str, message: str, file: str | None = None) -> None:
        self.findings.add(check, message, self.index, file or self.record_file)

    # --- the whole frame ------------------------------------------------------------------
    def run(self) -> Findings:
        """Every check of the frame; returns the findings."""
        points_cam, keypoints_cam = self.check_pose()
        size = self.frame.get("image_size_px")
        shape = (int(size[1]), int(size[0])) if _is_size(size) else None
        if shape is None:
            self.problem("files", f"expected image_size_px [W, H], found {size!r}")
        images = self.read_files(self.frame.get("files") or {}, shape)
        self.check_images(images, self.frame, self.frame.get("files") or {}, "masks")
        if images.get("object_mask_png") is not None:
            self.findings.ran("masks")
            mask_file = self.frame["files"]["object_mask_png"]
            self.check_mask_counts(images["object_mask_png"] == 255, self.frame, mask_file, "masks")
        check_object_masks(self.frame, images, self.problem)
        if points_cam is not None:
            self.check_pose_against_images(images, points_cam)
        if keypoints_cam is not None:
            self.check_keypoints_visible(images, keypoints_cam)
        crop = self.frame.get("crop")
        if crop is not None:
            self.check_crop(crop, images, points_cam, keypoints_cam)
        self.check_checksum_entries()
        return self.findings

    def read_files(self, files: dict, shape: tuple[int, int] | None) -> dict:
        """Output name -> decoded image of ``files`` (None where missing or broken).

        Only the images the later checks compare (masks, depth) are kept in memory.
        """
        checksums = self.frame.get("checksums") or {}
        images = {}
        for key, relative in files.items():
            image = read_frame_file(
                self.root,
                relative,
                key,
                shape,
                checksums.get(relative),
                self.hashes,
                self.findings,
                self.index,
            )
            images[key] = image if key in KEPT_IMAGES else None
        return images

    def check_checksum_entries(self) -> None:
        """Every checksum entry names one of the frame's files."""
        listed = set((self.frame.get("files") or {}).values())
        listed |= set(((self.frame.get("crop") or {}).get("files") or {}).values())
        for path in sorted(set(self.frame.get("checksums") or {}) - listed):
            self.problem(
                "checksums",
                "expected only the frame's files in its checksums, found this "
                "one, which is not among them",
                path,
            )

    # --- pose -----------------------------------------------------------------------------
    # --- labels against the images --------------------------------------------------------
    def check_images(self, images: dict, labels: dict, files: dict, check: str) -> None:
        """Box from the object mask; part mask and depth nonzero exactly where the mask is;
        the background mask zero on the target, and its Earth and Moon pixel counts those of
        the frame's exposure labels (``sensor.regions``, when recorded)."""
        mask = images.get("object_mask_png")
        if mask is None:
            return
        on = mask == 255
        box = mask_bbox_xyxy_px(on)
        if "bbox_xyxy_px" in labels and labels["bbox_xyxy_px"] != box:
            self.problem(
                check,
                f"expected bbox_xyxy_px {box} (the object mask's box), found "
                f"{labels['bbox_xyxy_px']}",
                files["object_mask_png"],
            )
        ids = images.get("object_id_png")  # with other objects: any object's pixels
        scene = on if ids is None or ids.shape != on.shape else ids > 0
        for key, what in (("part_mask_png16", "part id"), ("depth_exr", "depth")):
            image = images.get(key)
            if image is None or image.shape != on.shape:
                continue
            differ = (image > 0) != scene
            if differ.any():
                y, x = np.argwhere(differ)[0]
                self.problem(
                    check,
                    f"expected {what} > 0 exactly where the object mask (or object ids) is, "
                    f"found {int(differ.sum())} pixel(s) where they differ, the first "
                    f"at (x={x}, y={y})",
                    files[key],
                )
        self.check_background(images.get("background_mask_png"), on, labels, files, check)

    def check_background(
        self, background: np.ndarray | None, on: np.ndarray, labels: dict, files: dict, check: str
    ) -> None:
        """The background mask (0 space, 1 Earth, 2 Moon) is 0 where the target is, and
        counts the pixels the exposure labels give for the Earth and the Moon."""
        if background is None or background.shape != on.shape:
            return
        file = files["background_mask_png"]
        both = on & (background > 0)
        if both.any():
            y, x = np.argwhere(both)[0]
            self.problem(
                check,
                f"expected background 0 where the object mask is, found {int(both.sum())} "
                f"pixel(s) with a body, the first at (x={x}, y={y})",
                file,
            )
        regions = (labels.get("sensor") or {}).get("regions")
        if not isinstance(regions, dict):
            return
        for value, name in ((1, "earth"), (2, "moon")):
            found = (regions.get(name) or {}).get("pixel_count")
            count = int(np.count_nonzero(background == value))
            if found is not None and found != count:
                self.problem(
                    check,
                    f"expected sensor.regions.{name}.pixel_count {count} (the background "
                    f"mask's pixels of value {value}), found {found}",
                    file,
                )

    def check_mask_counts(self, on: np.ndarray, labels: dict, file: str, check: str) -> None:
        """object_pixel_count, visible_pixel_fraction and truncated (those ``labels`` has)
        from the object mask ``on`` (boolean (H, W))."""
        count = int(on.sum())
        expected = {
            "object_pixel_count": count,
            "visible_pixel_fraction": count / on.size,
            "truncated": bool(on[0].any() or on[-1].any() or on[:, 0].any() or on[:, -1].any()),
        }
        for key, value in expected.items():
            if key not in labels:
                continue
            found = labels[key]
            same = (
                found == value if isinstance(value, bool | int) else close_to(found, value, 1e-12)
            )
            if not same:
                self.problem(
                    check, f"expected {key} {value} (from the object mask), found {found}", file
                )

    def check_pose_against_images(self, images: dict, points_cam: np.ndarray) -> None:
        """The target seen in the images lies inside its bounding box placed by the pose."""
        corners = points_cam[:8]
        if (corners[:, 2] <= 0).any():
            return
        files = self.frame.get("files") or {}
        z_near, z_far = float(corners[:, 2].min()), float(corners[:, 2].max())
        slack = DEPTH_RTOL * z_far + DEPTH_ATOL_M
        mask, depth = images.get("object_mask_png"), images.get("depth_exr")
        if mask is not None and depth is not None and mask.shape == depth.shape:
            depth = np.where(mask == 255, depth, 0)  # the target's pixels only
        if depth is not None and (depth > 0).any():
            seen = depth[depth > 0]
            low, high = float(seen.min()), float(seen.max())
            if low < z_near - slack or high > z_far + slack:
                self.problem(
                    "pose",
                    f"expected depths within {z_near:.6g} .. {z_far:.6g} m (the "
                    f"target's box under the pose), found {low:.6g} .. {high:.6g} m",
                    files["depth_exr"],
                )
        if mask is not None and (mask == 255).any():
            K = np.array(self.frame["K"], dtype=np.float64)
            uv = corners @ K.T
            uv = uv[:, :2] / uv[:, 2:]
            lo, hi = uv.min(axis=0) - BBOX_MARGIN_PX, uv.max(axis=0) + BBOX_MARGIN_PX
            x0, y0, x1, y1 = mask_bbox_xyxy_px(mask == 255)
            if x0 < lo[0] or y0 < lo[1] or x1 > hi[0] or y1 > hi[1]:
                self.problem(
                    "pose",
                    f"expected the object mask inside the projected box of the "
                    f"target, {number_text([*lo, *hi])} px, found its box at "
                    f"{[x0, y0, x1, y1]}",
                    files["object_mask_png"],
                )

    # --- crop -----------------------------------------------------------------------------
    def check_crop(
        self,
        crop: dict,
        images: dict,
        points_cam: np.ndarray | None,
        keypoints_cam: np.ndarray | None = None,
    ) -> None:
        """Crop K, size and keypoints from the full frame's; crop images against its labels."""
        self.findings.ran("crop")
        try:
            x0, y0, x1, y1 = (int(v) for v in crop["box_xyxy_px"])
            K = np.array(self.frame["K"], dtype=np.float64)
            K_crop = np.array(crop["K"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as error:
            self.problem("crop", f"expected crop box_xyxy_px and K, found {error!r}")
            return
        size, box = crop.get("size_px"), [x0, y0, x1, y1]
        if not (size == x1 - x0 == y1 - y0):
            self.problem(
                "crop", f"expected crop size_px the side of its square box {box}, found {size!r}"
            )
        width, height = self.frame.get("image_size_px") or (None, None)
        if not (0 <= x0 < x1 <= (width or x1) and 0 <= y0 < y1 <= (height or y1)):
            self.problem(
                "crop", f"expected the crop box inside the {width} x {height} image, found {box}"
            )
        shifted = K.copy()
        shifted[0, 2] -= x0
        shifted[1, 2] -= y0
        if K_crop.shape != (3, 3) or not np.allclose(K_crop, shifted, rtol=FLOAT64_RTOL, atol=0):
            self.problem(
                "crop",
                f"expected crop K = K shifted by the box origin ({x0}, {y0}), "
                f"{shifted.tolist()}, found {crop['K']}",
            )
        for name, points in (("keypoints_px", keypoints_cam), ("box_keypoints_px", points_cam)):
            if points is not None and (name in crop or not self.points.box_is_keypoints):
                self.check_keypoints(crop.get(name), points, shifted, "crop", f"crop {name}")
        files = crop.get("files") or {}
        crop_images = self.read_files(files, (y1 - y0, x1 - x0))
        self.check_images(crop_images, crop, files, "crop")
        part = crop_images.get("object_mask_png")
        if part is None:
            return
        self.check_mask_counts(part == 255, crop, files["object_mask_png"], "crop")
        full = images.get("object_mask_png")
        window = None if full is None else full[y0:y1, x0:x1]
        if window is not None and window.shape == part.shape and not np.array_equal(window, part):
            self.problem(
                "crop",
                f"expected the crop's object mask equal to the full frame's "
                f"in {box}, found {int((window != part).sum())} pixel(s) that differ",
                files["object_mask_png"],
            )


def _is_size(size) -> bool:
    return (
        isinstance(size, list)
        and len(size) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)
    )
