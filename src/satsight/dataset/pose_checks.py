"""The pose checks of one frame: the quaternion, the keypoints and box corners labelled
under the pose, their depths and visibility (``PoseChecks``, a part of
``satsight.dataset.frame_checks.FrameCheck``), and the number comparisons both use.

Tolerances (why: ``satsight.dataset.frame_checks``): ``QUATERNION_NORM_TOLERANCE`` on the
quaternion's norm, ``KEYPOINT_RTOL`` x max(1, |(u, v)|) pixels on keypoints,
``FLOAT64_RTOL`` on numbers recomputed in float64.
"""

from __future__ import annotations

import numpy as np

from satsight.dataset.labels import keypoints_visible
from satsight.frames.quaternion import matrix_from_quaternion

QUATERNION_NORM_TOLERANCE = 1e-9
KEYPOINT_RTOL = 1e-6
FLOAT64_RTOL = 1e-9  # depths, ranges, K entries and fractions recomputed in float64


class PoseChecks:
    """The pose checks of ``FrameCheck`` (it provides ``frame``, ``points``, ``findings``
    and ``problem``)."""

    def check_pose(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Unit quaternion, qw >= 0, keypoints, their depths and the range from the pose.

        Returns the box's corners and centre and the keypoints in the camera frame ((9, 3),
        (N, 3), metres), each None when the pose or the points cannot be read.
        """
        self.findings.ran("pose")
        try:
            q = np.array(self.frame["q_cam_from_body"], dtype=np.float64)
            t = np.array(self.frame["t_cam_from_body_m"], dtype=np.float64)
            K = np.array(self.frame["K"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as error:
            self.problem(
                "pose",
                f"expected q_cam_from_body, t_cam_from_body_m and K, found "
                f"an unreadable pose ({error!r})",
            )
            return None, None
        if (
            q.shape != (4,)
            or t.shape != (3,)
            or K.shape != (3, 3)
            or not (np.isfinite(q).all() and np.isfinite(t).all() and np.isfinite(K).all())
        ):
            self.problem(
                "pose",
                f"expected a finite quaternion (4), translation (3) and K "
                f"(3x3), found shapes {q.shape}, {t.shape}, {K.shape}",
            )
            return None, None
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            self.problem("pose", f"expected a unit q_cam_from_body, found norm {norm:.12g}")
        if q[0] < 0:
            self.problem("pose", f"expected q_cam_from_body with qw >= 0, found qw = {q[0]:g}")
        if norm == 0:
            return None, None
        range_m = self.frame.get("range_m")
        if range_m is not None and not close_to(range_m, float(np.linalg.norm(t)), FLOAT64_RTOL):
            self.problem(
                "pose",
                f"expected range_m = |t_cam_from_body_m| = "
                f"{np.linalg.norm(t):.9g}, found {range_m}",
            )
        R = matrix_from_quaternion(q)
        keypoints_cam = self.check_point_labels(self.points.keypoints_body_m, R, t, K, "keypoints")
        if self.points.box_is_keypoints:
            return keypoints_cam, keypoints_cam
        box_cam = self.check_point_labels(
            self.points.box_keypoints_body_m, R, t, K, "box_keypoints"
        )
        return box_cam, keypoints_cam

    def check_point_labels(
        self,
        points_body_m: np.ndarray | None,
        R: np.ndarray,
        t: np.ndarray,
        K: np.ndarray,
        name: str,
    ) -> np.ndarray | None:
        """``{name}_px`` and ``{name}_depth_m`` against the points under the pose; returns
        the points in the camera frame (None without points)."""
        if points_body_m is None:
            return None
        points_cam = points_body_m @ R.T + t
        self.check_keypoints(self.frame.get(f"{name}_px"), points_cam, K, "pose", f"{name}_px")
        depths = self.frame.get(f"{name}_depth_m")
        if depths is not None and not listsclose_to(depths, points_cam[:, 2], FLOAT64_RTOL):
            self.problem(
                "pose",
                f"expected {name}_depth_m equal to the points' z under "
                f"the pose, {number_text(points_cam[:, 2])}, found {number_text(depths)}",
            )
        return points_cam

    def check_keypoints_visible(self, images: dict, keypoints_cam: np.ndarray) -> None:
        """keypoints_visible as the depth image decides it (when both are there)."""
        labelled, depth = self.frame.get("keypoints_visible"), images.get("depth_exr")
        if labelled is None or depth is None:
            return
        K = np.array(self.frame["K"], dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            uvw = keypoints_cam @ K.T
            uv = np.where(uvw[:, 2:] > 0, uvw[:, :2] / uvw[:, 2:], np.nan)
        expected = keypoints_visible(uv, keypoints_cam[:, 2], depth).tolist()
        if labelled != expected:
            wrong = [i for i, (a, b) in enumerate(zip(labelled, expected, strict=False)) if a != b]
            self.problem(
                "pose",
                f"expected keypoints_visible {expected} (the keypoints against the depth "
                f"image), found {labelled} (differs at {wrong})",
                (self.frame.get("files") or {}).get("depth_exr"),
            )

    def check_keypoints(
        self, labelled, points_cam: np.ndarray, K: np.ndarray, check: str, name: str
    ) -> None:
        """Labelled keypoints (pixels, None behind the camera) against their projection."""
        if not isinstance(labelled, list) or len(labelled) != len(points_cam):
            count = len(labelled) if isinstance(labelled, list) else labelled
            self.problem(check, f"expected {len(points_cam)} {name}, found {count}")
            return
        projected = points_cam @ K.T
        if _keypoints_clearly_right(labelled, projected):
            return
        worst: tuple[float, int, str, str] | None = None
        for i, (label, point) in enumerate(zip(labelled, projected, strict=True)):
            if point[2] <= 0:
                if label is not None:
                    self.problem(
                        check,
                        f"expected {name}[{i}] null (behind the camera under "
                        f"the pose), found {label}",
                    )
                continue
            uv = point[:2] / point[2]
            try:
                found = np.array(label, dtype=np.float64)
                error = float(np.linalg.norm(found - uv))
            except (TypeError, ValueError):
                error, found = np.inf, label
            if not np.isfinite(error):
                error = np.inf
            tolerance = KEYPOINT_RTOL * max(1.0, float(np.linalg.norm(uv)))
            if not error <= tolerance and (worst is None or error > worst[0]):
                worst = (error, i, number_text(uv), number_text(found))
        if worst is not None:
            error, i, expected, found = worst
            self.problem(
                check,
                f"expected {name}[{i}] = {expected} (K and the pose applied to "
                f"keypoints_body_m), found {found}: {error:.3g} px off",
            )


def _keypoints_clearly_right(labelled: list, projected: np.ndarray) -> bool:
    """Whether every labelled keypoint is a pixel within (a hair under) its tolerance of
    its projection (N, 3 homogeneous), checked for all at once; False sends the keypoints
    to the point-by-point check, which words the problems (and decides the borderline)."""
    if not (projected[:, 2] > 0).all():
        return False
    try:
        found = np.array(labelled, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    if found.shape != (len(projected), 2):
        return False
    uv = projected[:, :2] / projected[:, 2:]
    error = np.sqrt(((found - uv) ** 2).sum(axis=1))
    tolerance = KEYPOINT_RTOL * np.maximum(1.0, np.sqrt((uv**2).sum(axis=1)))
    return bool((error <= (1.0 - 1e-6) * tolerance).all())


def close_to(found, expected: float, rtol: float) -> bool:
    """Whether a labelled number is within rtol x max(1, |expected|) of ``expected``."""
    try:
        return abs(float(found) - expected) <= rtol * max(1.0, abs(expected))
    except (TypeError, ValueError):
        return False


def listsclose_to(found, expected: np.ndarray, rtol: float) -> bool:
    if not isinstance(found, list) or len(found) != len(expected):
        return False
    return all(close_to(f, float(e), rtol) for f, e in zip(found, expected, strict=True))


def number_text(values) -> str:
    """A short text of a number list (6 significant digits)."""
    try:
        return "[" + ", ".join(f"{float(v):.6g}" for v in values) + "]"
    except (TypeError, ValueError):
        return repr(values)
