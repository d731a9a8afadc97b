"""Keypoints on the target: the body-frame points a pose network learns to find.

Three ways to choose them (``KeypointRule.method``):

``surface``
    Farthest-point sampling on the mesh: the candidates are the mesh's vertices and
    ``SURFACE_SAMPLES`` points drawn on its triangles (area-weighted, seeded, so the same
    mesh always gives the same keypoints); the first keypoint is the candidate farthest
    from the bounding-box centre, and each next one the candidate farthest from those
    chosen. The points spread over the spacecraft's extremities (panel corners, antenna
    tips, bus corners), as the hand-picked 11 points of the SPEED+ target do, and every
    one lies on the surface.
``corners``
    The 8 corners of the bounding box and its centre (``TargetMesh.box_keypoints_body_m``);
    they are not on the spacecraft.
``file``
    The user's own points, body frame, metres, read by ``read_keypoints_file``.

Every dataset also labels the box corners and centre under ``box_keypoints_*``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.errors import SatsightError
from satsight.scene.mesh import TargetMesh

KEYPOINT_METHODS = ("surface", "corners", "file")
DEFAULT_KEYPOINT_COUNT = 11
#: Points drawn on the triangles as farthest-point candidates, besides the vertices.
SURFACE_SAMPLES = 20000
#: Seed of the surface draw (fixed: keypoints depend on the mesh alone).
SURFACE_SEED = 0
#: What each method's points are, as the dataset manifest says it.
KEYPOINT_DESCRIPTIONS = {
    "surface": "farthest-point sampling over the mesh's vertices and 20000 seeded "
    "area-weighted surface points, starting from the point farthest from the box centre",
    "corners": "the bounding box's 8 corners (bit 0: x, bit 1: y, bit 2: z; 0 min, 1 max), "
    "then its centre",
    "file": "the points of the scenario's target.keypoints.path (body frame, metres)",
}


@dataclass(frozen=True)
class KeypointRule:
    """Which keypoints a dataset labels: method, count (``surface``) and the points
    (``file``: (N, 3) body frame, metres)."""

    method: str = "surface"
    count: int = DEFAULT_KEYPOINT_COUNT
    points_body_m: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        if self.method not in KEYPOINT_METHODS:
            raise SatsightError(
                f"unknown keypoint method {self.method!r}; choose one of "
                f"{', '.join(KEYPOINT_METHODS)}"
            )
        if self.method == "surface" and self.count < 1:
            raise SatsightError(f"keypoint count must be >= 1, got {self.count}")
        if self.method == "file" and not self.points_body_m:
            raise SatsightError("keypoints from a file need the file's points")


def surface_candidates(mesh: TargetMesh, samples: int = SURFACE_SAMPLES) -> np.ndarray:
    """(V + samples, 3) points on the mesh: its vertices used by a face, then area-weighted
    uniform points on its triangles (a fixed seed)."""
    vertices = mesh.vertices_m[np.unique(mesh.faces)]
    corners = mesh.vertices_m[mesh.faces]  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    if not np.any(area > 0):
        return vertices
    rng = np.random.default_rng(np.random.SeedSequence([SURFACE_SEED]))
    faces = rng.choice(len(area), size=samples, p=area / area.sum())
    r1, r2 = rng.random(samples), rng.random(samples)
    # uniform on a triangle: (1 - sqrt(r1)) a + sqrt(r1) (1 - r2) b + sqrt(r1) r2 c
    s = np.sqrt(r1)
    weights = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
    points = np.einsum("nk,nkj->nj", weights, corners[faces])
    return np.vstack([vertices, points])


def farthest_points(candidates: np.ndarray, count: int, start: np.ndarray) -> np.ndarray:
    """``count`` of the candidates by farthest-point sampling: first the one farthest from
    ``start`` (3,), then each time the one farthest from all chosen. (count, 3)."""
    candidates = np.asarray(candidates, dtype=np.float64)
    if count > len(candidates):
        raise SatsightError(
            f"{count} keypoints asked of a mesh with {len(candidates)} candidate points"
        )
    chosen = [int(np.argmax(np.linalg.norm(candidates - start, axis=1)))]
    distance = np.linalg.norm(candidates - candidates[chosen[0]], axis=1)
    for _ in range(count - 1):
        k = int(np.argmax(distance))
        chosen.append(k)
        distance = np.minimum(distance, np.linalg.norm(candidates - candidates[k], axis=1))
    return candidates[chosen]


def target_keypoints_body_m(mesh: TargetMesh, rule: KeypointRule) -> np.ndarray:
    """The keypoints a rule chooses on a mesh, (N, 3), body frame, metres."""
    if rule.method == "corners":
        return mesh.box_keypoints_body_m
    if rule.method == "file":
        return np.array(rule.points_body_m, dtype=np.float64)
    return farthest_points(surface_candidates(mesh), rule.count, mesh.center_m)


def read_keypoints_file(path: Path) -> tuple[tuple[float, float, float], ...]:
    """Body-frame keypoints (metres) from a file: JSON (a list of [x, y, z], or an object
    with ``keypoints_body_m``), or text/CSV with three numbers per line (``#`` comments)."""
    path = Path(path)
    if not path.is_file():
        raise SatsightError(f"keypoints file not found: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise SatsightError(f"{path}: cannot read keypoints ({error})") from None
    if path.suffix.lower() == ".json":
        try:
            document = json.loads(text)
        except json.JSONDecodeError as error:
            raise SatsightError(f"{path}: not JSON ({error})") from None
        if isinstance(document, dict):
            document = document.get("keypoints_body_m")
        rows = document
    else:
        rows = []
        for number, line in enumerate(text.splitlines(), start=1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            fields = [f for f in line.replace(",", " ").split() if f]
            try:
                rows.append([float(f) for f in fields])
            except ValueError:
                raise SatsightError(
                    f"{path}, line {number}: expected three numbers x y z (metres), found {line!r}"
                ) from None
    try:
        points = np.array(rows, dtype=np.float64)
    except (TypeError, ValueError):
        points = np.zeros((0,))
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise SatsightError(
            f"{path}: expected N rows of three numbers x y z (metres, body frame), found "
            f"{'shape ' + str(points.shape) if points.size else 'no points'}"
        )
    if not np.all(np.isfinite(points)):
        raise SatsightError(f"{path}: keypoints must be finite numbers")
    return tuple(tuple(float(v) for v in row) for row in points)
