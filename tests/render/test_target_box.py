"""Tracing only the pixels of the target's projected box (``Renderer._target_box_px``) gives
the frame traced whole, byte for byte: radiance, depth, part ids and normals, with one
path per pixel and with four (sub-pixel positions), for a target in the middle of the
image and one cut by its edge, and with the Earth behind the target (its pixels outside
the box drawn along their pixel-centre rays, with their background label); a frame whose
box is most of the image, or reaches behind the camera, is traced whole."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField
from satsight.lighting.scene_bodies import BACKGROUND_EARTH, earth_body
from satsight.poses.views import View
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.procedural import generate_satellite

CAMERA = PinholeCamera(focal_length_m=0.05, pixel_pitch_m=15e-6, width_px=240, height_px=180)
LIGHT = LightField.sun_only(np.array([0.3, -0.5, 0.8]) / math.sqrt(0.98), 1361.0)


def _shifted_view(mesh, shift_px: float, distance_m: float = 120.0, azimuth_deg: float = 30.0):
    """The target seen from ``distance_m``, moved across the image by ``shift_px`` (at its
    distance)."""
    pose = View(distance_m, math.radians(azimuth_deg), math.radians(10.0)).cam_from_body(
        mesh.center_m
    )
    shift_m = shift_px * CAMERA.pixel_pitch_m / CAMERA.focal_length_m * distance_m
    return RigidTransform(pose.R_a_from_b, pose.t_a_from_b_m + np.array([shift_m, 0.0, 0.0]))


def _images(
    renderer: Renderer, pose: RigidTransform, box_off: bool, monkeypatch, light=LIGHT
) -> list:
    if box_off:
        monkeypatch.setattr(renderer, "_target_box_px", lambda camera, pose: None)
    image = renderer.render(CAMERA, pose, light, seed=7)
    monkeypatch.undo()
    return [image.radiance_w_m2_sr, image.depth_m, image.part_id, image.normals_cam,
            image.background_id]  # fmt: skip


@pytest.mark.parametrize("samples_per_pixel", [1, 4])
@pytest.mark.parametrize("shift_px", [0.0, 115.0])  # centred; cut by the image's right edge
def test_the_box_gives_the_whole_frames_bytes(
    llvm_variant, monkeypatch, samples_per_pixel, shift_px
) -> None:
    mesh = generate_satellite("two_wings", seed=1)
    settings = RenderSettings(bounces=1, environment="off", samples_per_pixel=samples_per_pixel)
    renderer = Renderer(mesh, settings)
    pose = _shifted_view(mesh, shift_px)
    box = renderer._target_box_px(CAMERA, pose)
    assert box is not None and (box[2] - box[0]) * (box[3] - box[1]) < 0.5 * 240 * 180
    if shift_px:
        assert box[2] == CAMERA.width_px  # clipped by the image's edge
    whole = _images(renderer, pose, True, monkeypatch)
    boxed = _images(renderer, pose, False, monkeypatch)
    assert (whole[2] > 0).sum() > 200  # the target is there
    for a, b in zip(whole, boxed, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("samples_per_pixel", [1, 4])
def test_the_box_with_the_earth_behind_gives_the_whole_frames_bytes(
    llvm_variant, monkeypatch, samples_per_pixel
) -> None:
    """500 km above a sunlit Earth that fills the frame behind a small target: with one
    pixel-centre path per pixel the box is traced and the Earth drawn outside it; with four
    paths (sub-pixel positions) the frame is traced whole. The bytes are those of the
    whole frame traced, background labels included."""
    mesh = generate_satellite("two_wings", seed=1)
    settings = RenderSettings(
        bounces=1, environment="unshadowed", samples_per_pixel=samples_per_pixel
    )
    renderer = Renderer(mesh, settings)
    pose = View(300.0, math.radians(30.0), math.radians(10.0)).cam_from_body(mesh.center_m)
    camera_body = pose.inverse().t_a_from_b_m
    down = (mesh.center_m - camera_body) / np.linalg.norm(mesh.center_m - camera_body)
    centre_m = camera_body + 6_871e3 * down  # the camera 500 km above a sphere of 6 371 km
    sun = -down + np.array([0.2, 0.1, 0.0]) - 0.2 * down[0] * down - 0.1 * down[1] * down
    sun /= np.linalg.norm(sun)
    earth = earth_body(centre_m, np.eye(3), 0.3, sun, 1361.0, shape="sphere")
    light = LightField(sun, 1361.0, np.zeros((25, 3)), bodies=(earth,))
    whole = _images(renderer, pose, True, monkeypatch, light)
    traced = []
    monkeypatch.setattr(
        renderer, "_bodies_outside_box", lambda *a: traced.append(a[1]) or original(*a)
    )
    original = Renderer._bodies_outside_box.__get__(renderer)
    boxed = _images(renderer, pose, False, monkeypatch, light)
    assert len(traced) == (1 if samples_per_pixel == 1 else 0)
    if traced:
        x0, y0, x1, y1, _ = traced[0]
        assert (x1 - x0) * (y1 - y0) < 0.2 * CAMERA.width_px * CAMERA.height_px
    assert (whole[2] > 0).sum() > 200  # the target is there
    background = whole[4]
    assert (background == BACKGROUND_EARTH).sum() + (whole[2] > 0).sum() == background.size
    assert whole[0][background == BACKGROUND_EARTH].min() > 0  # a lit Earth everywhere
    for a, b in zip(whole, boxed, strict=True):
        assert np.array_equal(a, b)


def test_a_box_of_most_of_the_frame_or_behind_the_camera_is_no_box(llvm_variant) -> None:
    mesh = generate_satellite("two_wings", seed=1)
    renderer = Renderer(mesh, RenderSettings(bounces=0, environment="off"))
    near = View(8.0, 0.0, 0.0).cam_from_body(mesh.center_m)  # fills the frame
    assert renderer._target_box_px(CAMERA, near) is None
    # The camera inside the box: corners behind it.
    inside = RigidTransform(np.eye(3), -mesh.center_m)
    assert renderer._target_box_px(CAMERA, inside) is None


@pytest.mark.parametrize("samples_per_pixel", [1, 4])
@pytest.mark.parametrize(
    ("shift_px", "ring_traced"),
    [(0.0, False), (10.0, True), (128.0, True), (300.0, False)],
)  # inside; its box just in the ring; cut by the right edge; past the ring
def test_a_ring_the_target_cannot_reach_is_not_traced_and_is_zero(
    llvm_variant, monkeypatch, samples_per_pixel, shift_px, ring_traced
) -> None:
    """The ring around the image (``margin_px``) is traced only where the target's
    projected box reaches into it, or a body is in view; otherwise it is the zeros that
    tracing gives, byte for byte, and so are the image's own pixels."""
    mesh = generate_satellite("two_wings", seed=1)
    settings = RenderSettings(bounces=1, environment="off", samples_per_pixel=samples_per_pixel)
    renderer = Renderer(mesh, settings)
    pose = _shifted_view(mesh, shift_px)
    margin = 12
    traced = []
    original = Renderer._render_margin.__get__(renderer)
    monkeypatch.setattr(renderer, "_render_margin", lambda *a: traced.append(1) or original(*a))
    skipped = renderer.render(CAMERA, pose, LIGHT, seed=7, margin_px=margin)
    assert bool(traced) == ring_traced
    monkeypatch.setattr(renderer, "_margin_sees_target", lambda *a: True)
    whole = renderer.render(CAMERA, pose, LIGHT, seed=7, margin_px=margin)
    assert np.array_equal(skipped.margin_radiance_w_m2_sr, whole.margin_radiance_w_m2_sr)
    assert np.array_equal(skipped.radiance_w_m2_sr, whole.radiance_w_m2_sr)
    assert skipped.margin_radiance_w_m2_sr.dtype == np.float32
    if not ring_traced:  # (the box is conservative: a traced ring may still be all 0)
        assert whole.margin_radiance_w_m2_sr.max() == 0
    if shift_px == 128.0:
        assert whole.margin_radiance_w_m2_sr.max() > 0 and whole.radiance_w_m2_sr.max() > 0


def test_frames_of_other_boxes_reuse_the_compiled_kernels(llvm_variant) -> None:
    """Frames whose target boxes differ run the same kernels: no per-frame number (the box,
    a NumPy array's alignment) is baked into a kernel, which would compile new kernels
    (0.1-0.5 s each) for every frame. Kernels that differ only in their numbers come in at
    most two variants (an input aligned to 64 bytes or not, for the small copy into Dr.Jit's
    own memory)."""
    import re

    import drjit as dr

    mesh = generate_satellite("two_wings", seed=1)
    renderer = Renderer(mesh, RenderSettings(bounces=1, environment="unshadowed"))
    variants: dict[str, set] = {}
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        for k, (distance_m, shift_px) in enumerate([(120, 0), (150, 40), (200, -50), (300, 70)]):
            pose = _shifted_view(mesh, shift_px, distance_m, 30 + 7 * k)
            assert renderer._target_box_px(CAMERA, pose) is not None
            renderer.render(CAMERA, pose, LIGHT, seed=k, margin_px=8)
            for kernel in dr.kernel_history():
                if kernel["type"] == dr.KernelType.JIT:
                    ir = kernel["ir"] if isinstance(kernel["ir"], str) else kernel["ir"].getvalue()
                    shape = re.sub(r"\b\d+\b", "N", re.sub(r"drjit_[0-9a-f]+", "K", ir))
                    variants.setdefault(shape, set()).add(kernel["hash"])
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert len(variants) > 5
    assert max(len(hashes) for hashes in variants.values()) <= 2, sorted(
        len(h) for h in variants.values()
    )
