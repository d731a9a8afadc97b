"""LightField and its Sun (satsight.lighting.light_field)."""

from __future__ import annotations

import numpy as np

from satsight.lighting.light_field import LightField, SunLight


def test_sun_light_is_the_light_fields_sun_to_the_bit():
    rng = np.random.default_rng(3)
    for _ in range(200):
        light = LightField(rng.normal(size=3), 1361.0 * rng.random(), np.zeros(25))
        sun = light.sun
        np.testing.assert_array_equal(sun.direction_body, light.sun_direction_body)
        assert sun.irradiance_w_m2 == light.sun_irradiance_w_m2


def test_sun_light_scales_any_direction_to_unit_length():
    sun = SunLight(np.array([0.0, 3.0, 4.0]), 100.0)
    np.testing.assert_allclose(sun.direction_body, [0.0, 0.6, 0.8], rtol=0, atol=1e-16)
