"""Which flying objects a frame keeps (``FrameView``), against the rules written out: a
1 m-radius object 1 km from a 2 m-radius target is kept when it is near (inside
100 r + r + R), sunward within the shadow's reach, or inside the widened field of view, and
left out otherwise; a sphere just past a side of the field of view by more than its
radius is left out, just inside it is kept.
"""

from __future__ import annotations

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frame_scene import SUN_ANGULAR_RADIUS_RAD, FrameView
from satsight.frames.rigid import RigidTransform
from satsight.scene.mesh import TargetMesh


def _sphere_like(radius_m: float, name: str) -> TargetMesh:
    """An octahedron of circumradius ``radius_m`` about the origin."""
    v = radius_m * np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
    )
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])  # fmt: skip
    return TargetMesh(v, f, np.zeros(8, dtype=int), ("body",), ("lambert_white",), name=name)


TARGET = _sphere_like(2.0, "target")
OBJECT = _sphere_like(1.0, "object")
CAMERA = PinholeCamera(focal_length_m=0.1, pixel_pitch_m=1e-5, width_px=200, height_px=100)
# The camera 100 m from the target along body -z, looking along +z (x_cam = x_body + t).
CAM_FROM_BODY = RigidTransform(np.eye(3), np.array([0.0, 0.0, 100.0]))
SUN = np.array([1.0, 0.0, 0.0])


def _shows(position_body_m, sun=SUN, margin_px: int = 0) -> bool:
    view = FrameView(CAMERA, CAM_FROM_BODY, sun, margin_px)
    pose = RigidTransform(np.eye(3), np.asarray(position_body_m, dtype=float))
    return view.shows(TARGET, ("o", OBJECT, pose))


def test_near_objects_are_kept_and_far_ones_out_of_view_left_out() -> None:
    near = 100 * 1.0 + 1.0 + 2.0
    assert _shows([0.0, near - 1.0, 0.0])  # 60 m past the edge of the field, but near
    # Beside the camera (y / z = 104 in the camera frame: the field spans |y / z| <= 0.05).
    assert not _shows([0.0, near + 1.0, -99.0])


def test_sunward_objects_are_kept_within_the_shadows_reach() -> None:
    d = 1000.0  # x_cam / z_cam = 10 there: out of view
    reach = 2.0 + 1.0 + d * SUN_ANGULAR_RADIUS_RAD
    assert _shows(SUN * d + np.array([0.0, reach - 0.1, 0.0]))
    assert not _shows(SUN * d + np.array([0.0, reach + 0.1, 0.0]))
    assert not _shows(-SUN * d)  # on the night side: no shadow


def test_the_field_of_view_keeps_a_sphere_that_touches_it() -> None:
    z_body = 900.0  # 1000 m from the camera, far from the target and not sunward
    sun = np.array([0.0, 0.0, -1.0])  # towards the camera: the object is anti-sunward
    # The image's right edge, 100 px right of the principal point (pixel centres 0..199,
    # edges at -0.5 and 199.5), is 100 px x 10 um / 0.1 m x 1000 m = 10 m off the axis.
    edge = 10.0
    assert _shows([edge + 0.9, 0.0, z_body], sun)
    assert not _shows([edge + 1.1, 0.0, z_body], sun)
    # A margin ring of 10 px widens it by 1 m at 1000 m.
    assert _shows([edge + 1.9, 0.0, z_body], sun, margin_px=10)
    assert not _shows([edge + 2.1, 0.0, z_body], sun, margin_px=10)
    assert not _shows([0.0, 0.0, -1000.0])  # behind the camera (and not sunward)


def test_a_principal_point_off_the_image_keeps_the_view_the_image_sees() -> None:
    """With the principal point far right of the image (a cropped sensor), the field of view
    lies to the left of the boresight: a sphere on the image centre's ray is kept, one on
    the boresight (outside the image) is left out."""
    camera = PinholeCamera(
        focal_length_m=0.1, pixel_pitch_m=1e-5, width_px=200, height_px=100, cx_px=400.0
    )
    view = FrameView(camera, CAM_FROM_BODY, np.array([0.0, 0.0, -1.0]))
    z_cam = 1000.0  # far from the target, anti-sunward
    centre_x = (99.5 - 400.0) / camera.focal_length_px * z_cam  # the image centre's ray

    def shows(x_cam: float) -> bool:
        pose = RigidTransform(np.eye(3), np.array([x_cam, 0.0, z_cam - 100.0]))
        return view.shows(TARGET, ("o", OBJECT, pose))

    assert shows(centre_x)
    assert not shows(0.0)
