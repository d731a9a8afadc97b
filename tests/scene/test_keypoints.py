"""Keypoints on the target: on its surface, spread by farthest-point sampling, read from
files, and labelled visible exactly where a camera sees them.

Oracles: trimesh's closest-point query for "on the surface"; the farthest-point property
(the chosen points are at least as far apart as any candidate is from them); and, for the
visibility flags, the closed form for a convex box: a corner is seen iff one of the three
faces meeting there faces the camera.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

import satsight
from satsight.config.scenario import load_scenario, parse_scenario
from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.scene.keypoints import (
    KeypointRule,
    farthest_points,
    read_keypoints_file,
    surface_candidates,
    target_keypoints_body_m,
)
from satsight.scene.procedural import SATELLITE_CLASSES, generate_satellite
from tolerances import ONE_MM

BOX_EXTENTS_M = (2.0, 1.2, 0.8)


def distance_to_surface(point: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> float:
    """Closed-form distance (m) from a point to a triangle mesh: the plane distance where
    the point projects inside a triangle, else the nearest edge segment."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    ok = area2 > 0
    a, b, c, n, area2 = a[ok], b[ok], c[ok], n[ok] / area2[ok, None], area2[ok]
    height = np.einsum("ij,ij->i", point - a, n)
    foot = point - height[:, None] * n
    inside = np.ones(len(a), dtype=bool)
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(q - p, foot - p), n) >= 0
    best = np.abs(height[inside]).min(initial=np.inf)
    for p, q in ((a, b), (b, c), (c, a)):
        edge = q - p
        t = np.clip(np.einsum("ij,ij->i", point - p, edge) / np.einsum("ij,ij->i", edge, edge),
                    0.0, 1.0)  # fmt: skip
        best = min(best, np.linalg.norm(p + t[:, None] * edge - point, axis=1).min())
    return float(best)


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_surface_keypoints_lie_on_the_mesh(satellite_class: str) -> None:
    mesh = generate_satellite(satellite_class, 2)
    points = target_keypoints_body_m(mesh, KeypointRule("surface", 11))
    assert points.shape == (11, 3)
    distance = [distance_to_surface(p, mesh.vertices_m, mesh.faces) for p in points]
    assert max(distance) < ONE_MM, distance
    # The same mesh gives the same keypoints (the surface draw is seeded).
    again = target_keypoints_body_m(mesh, KeypointRule("surface", 11))
    assert np.array_equal(points, again)


def test_farthest_point_sampling_spreads_the_points() -> None:
    """The defining property: after k picks, every candidate is within d_k of a chosen
    point, and the chosen points are pairwise at least d_k apart (d_k: the distance of
    the last pick from those before it)."""
    mesh = generate_satellite("two_wings_dish", 0)
    candidates = surface_candidates(mesh)
    chosen = farthest_points(candidates, 11, mesh.center_m)
    from_chosen = np.linalg.norm(candidates[:, None] - chosen[None], axis=-1).min(axis=1)
    pairwise = np.linalg.norm(chosen[:, None] - chosen[None], axis=-1)
    last = np.linalg.norm(chosen[:-1] - chosen[-1], axis=1).min()
    assert from_chosen.max() <= last + 1e-12
    assert pairwise[np.triu_indices(11, 1)].min() >= last - 1e-12
    # The first keypoint is the candidate farthest from the box centre.
    reach = np.linalg.norm(candidates - mesh.center_m, axis=1).max()
    assert np.linalg.norm(chosen[0] - mesh.center_m) == pytest.approx(reach, rel=1e-12)


def test_corner_keypoints_are_the_box_and_too_many_are_refused() -> None:
    mesh = generate_satellite("body_mounted", 1)
    corners = target_keypoints_body_m(mesh, KeypointRule("corners"))
    assert np.array_equal(corners, mesh.box_keypoints_body_m)
    with pytest.raises(SatsightError, match="candidate points"):
        farthest_points(np.zeros((5, 3)), 6, np.zeros(3))


def test_keypoint_files_read_json_and_text(tmp_path: Path) -> None:
    points = [[0.1, -0.2, 0.3], [1.0, 2.0, 3.5]]
    (tmp_path / "a.json").write_text(json.dumps(points))
    (tmp_path / "b.json").write_text(json.dumps({"keypoints_body_m": points}))
    (tmp_path / "c.txt").write_text("# x y z (m)\n0.1 -0.2 0.3\n\n1, 2, 3.5  # tip\n")
    for name in ("a.json", "b.json", "c.txt"):
        assert np.array_equal(np.array(read_keypoints_file(tmp_path / name)), points)


@pytest.mark.parametrize(
    ("name", "text", "says"),
    [("x.txt", "0 1\n", r"shape \(1, 2\)"), ("y.txt", "0 1 two\n", "line 1: expected three"),
     ("z.json", "{", "not JSON"), ("w.json", "[]", "no points"),
     ("v.txt", "0 nan 1\n", "finite"), ("missing.txt", None, "not found")],
)  # fmt: skip
def test_bad_keypoint_files_are_refused(tmp_path: Path, name: str, text, says: str) -> None:
    if text is not None:
        (tmp_path / name).write_text(text)
    with pytest.raises(SatsightError, match=says):
        read_keypoints_file(tmp_path / name)


def test_scenario_keypoints_section_and_relative_path(tmp_path: Path) -> None:
    (tmp_path / "kp.txt").write_text("0 0 0\n1 0 0\n")
    (tmp_path / "s.yaml").write_text(
        "target:\n  procedural: {satellite_class: body_mounted}\n"
        "  keypoints: {method: file, path: kp.txt}\n"
        "frames: [{distance_km: 1.0, azimuth_deg: 0, elevation_deg: 0, roll_deg: 0}]\n"
    )
    scenario = load_scenario(tmp_path / "s.yaml")
    assert scenario.target.keypoints.path == (tmp_path / "kp.txt").resolve()
    assert scenario.target.keypoints.build().points_body_m == ((0, 0, 0), (1, 0, 0))
    for keypoints, says in (
        ({"method": "file"}, "give 'path' exactly when method is 'file'"),
        ({"method": "edges"}, "surface"),
        ({"count": 0}, "greater than or equal to 1"),
    ):
        data = {"target": {"procedural": {}, "keypoints": keypoints}, "frames": [{}]}
        with pytest.raises(SatsightError, match=says):
            parse_scenario(data)


# --- visibility on rendered frames --------------------------------------------------------
VIEWS = [(30.0, 20.0, 10.0), (120.0, -35.0, 0.0), (250.0, 60.0, -40.0), (200.0, 5.0, 30.0),
         (315.0, -70.0, 0.0)]  # fmt: skip


@pytest.fixture(scope="module")
def box_frames(tmp_path_factory) -> list:
    """A 2 x 1.2 x 0.8 m box at 1.5-2.5 km in a 96 x 80 px frame, corners as keypoints."""
    path = tmp_path_factory.mktemp("mesh") / "box.glb"
    trimesh.creation.box(extents=BOX_EXTENTS_M).export(path)
    scenario = satsight.load_scenario(
        {
            "name": "keypoints-box",
            "camera": {"preset": "wide_field", "width_px": 96, "height_px": 80},
            "target": {"mesh": {"path": str(path)}, "keypoints": {"method": "corners"}},
            "frames": [
                {
                    "distance_km": 1.5 + 0.25 * k,
                    "azimuth_deg": az,
                    "elevation_deg": el,
                    "roll_deg": roll,
                }
                for k, (az, el, roll) in enumerate(VIEWS)
            ],
            "render": {"bounces": 0},
            "outputs": {"crop": {"size_px": 32}},
        }
    )
    return list(satsight.render_frames(scenario))


def test_box_corner_visibility_matches_the_convex_closed_form(box_frames) -> None:
    half = np.array(BOX_EXTENTS_M) / 2
    seen_counts = []
    for frame in box_frames:
        R = matrix_from_quaternion(np.asarray(frame.labels["q_cam_from_body"]))
        eye_body = -R.T @ frame.t_cam_from_body_m
        visible = frame.labels["keypoints_visible"]
        assert len(visible) == 9 and visible[8] is False  # the centre is inside the box
        for k in range(8):
            corner = half * np.array([1 if (k >> a) & 1 else -1 for a in range(3)])
            # the faces meeting at the corner: normals along each axis, the corner's sign
            faces_seen = [np.sign(corner[a]) * (eye_body[a] - corner[a]) > 0 for a in range(3)]
            assert visible[k] == any(faces_seen), (k, visible, faces_seen)
        seen_counts.append(sum(visible[:8]))
    assert min(seen_counts) >= 4 and max(seen_counts) <= 7  # generic views: 4 to 7 corners


def test_visible_keypoints_fall_on_the_mask(box_frames) -> None:
    """A visible corner projects onto the box's silhouette: its pixel or a neighbour is a
    target pixel (a corner of the silhouette may miss its own pixel's centre)."""
    for frame in box_frames:
        mask = frame.object_mask
        height, width = mask.shape
        for uv, seen in zip(
            frame.labels["keypoints_px"], frame.labels["keypoints_visible"], strict=True
        ):
            if not seen:
                continue
            col, row = (int(np.floor(v + 0.5)) for v in uv)
            assert 0 <= col < width and 0 <= row < height
            assert mask[max(row - 1, 0) : row + 2, max(col - 1, 0) : col + 2].any()


def test_crop_keypoints_are_visible_only_inside_the_window(box_frames) -> None:
    for frame in box_frames:
        crop = frame.labels["crop"]
        size = crop["size_px"]
        for uv, seen_frame, seen_crop in zip(
            crop["keypoints_px"],
            frame.labels["keypoints_visible"],
            crop["keypoints_visible"],
            strict=True,
        ):
            inside = -0.5 <= uv[0] < size - 0.5 and -0.5 <= uv[1] < size - 0.5
            assert seen_crop == (seen_frame and inside)
