"""The ring of pixels around the frame that the renderer adds for the optics' blur.

Its radiance must be the radiance of the same pixels in a frame rendered larger by the
margin on every side (a camera with the principal point shifted by the margin): with one
pixel-centre sample and the Sun only the two renders are deterministic and must agree.
"""

from __future__ import annotations

import numpy as np

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.buffers import margin_pixels_xy
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts


def test_margin_pixels_cover_the_ring_once_in_row_major_order():
    x, y = margin_pixels_xy(5, 3, 2)
    assert len(x) == (5 + 4) * (3 + 4) - 5 * 3
    inside = (x >= 0) & (x < 5) & (y >= 0) & (y < 3)
    assert not inside.any()
    order = (y + 2) * 9 + (x + 2)
    assert np.all(np.diff(order) > 0)


def test_margin_radiance_equals_a_larger_render():
    v, f = plate_parts(size_m=2.0)
    material = Material("plate_lambert", (0.6, 0.5, 0.4), metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")
    renderer = Renderer(mesh, RenderSettings(environment="off", bounces=0))
    # The plate (2 m at 400 m, f = 3 m: 1000 px) overfills a 40 x 30 frame.
    camera = PinholeCamera(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=40, height_px=30)
    m = 4
    larger = PinholeCamera(
        focal_length_m=3.0,
        pixel_pitch_m=15e-6,
        width_px=40 + 2 * m,
        height_px=30 + 2 * m,
        cx_px=camera.cx_px + m,
        cy_px=camera.cy_px + m,
    )
    pose = look_at_cam_from_body(
        np.array([0.1, 0.05, 400.0]), np.zeros(3), up_hint_body=(0.0, 1.0, 0.0)
    )
    light = LightField.sun_only(np.array([0.3, 0.2, 1.0]), 1000.0)
    image = renderer.render(camera, pose, light, seed=3, margin_px=m)
    reference = renderer.render(larger, pose, light, seed=3).radiance_w_m2_sr
    assert image.margin_radiance_w_m2_sr.shape == (len(margin_pixels_xy(40, 30, m)[0]), 3)
    assert image.margin_radiance_w_m2_sr.min() > 0.0  # the plate fills the ring too
    np.testing.assert_allclose(image.padded_radiance_w_m2_sr(), reference, rtol=1e-5)
    # Without a margin the image is the same frame.
    plain = renderer.render(camera, pose, light, seed=3)
    assert plain.margin_radiance_w_m2_sr is None
    np.testing.assert_array_equal(plain.radiance_w_m2_sr, image.radiance_w_m2_sr)
