"""Telescope optics: the Optics description and the camera equation.

Oracles: the closed-form camera equation E = pi L tau (1 - eps^2) / (4 N^2) (Slater 1980, Ch. 7).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.sensor.mtf import defocus_mtf
from satsight.sensor.optics import (
    DEFAULT_APERTURE_DIAMETER_M,
    Optics,
    focal_plane_irradiance_w_m2,
)

REL = 1e-12  # closed forms evaluated the same way up to float64 rounding
LAM_M = 550e-9
N = 10.0
OPTICS = Optics(aperture_diameter_m=0.3, focal_length_m=3.0)  # f/10


# --- Optics -----------------------------------------------------------------------------------


def test_optics_defaults_and_f_number():
    assert OPTICS.f_number == pytest.approx(10.0, rel=REL)
    assert OPTICS.transmission == 0.8
    hr = Optics.for_preset("high_resolution")
    wf = Optics.for_preset("wide_field")
    assert hr.aperture_diameter_m == DEFAULT_APERTURE_DIAMETER_M["high_resolution"]
    assert hr.f_number == pytest.approx(10.0, rel=REL)
    assert wf.f_number == pytest.approx(7.0, rel=REL)
    assert Optics.for_preset("wide_field", jitter_rms_rad=1e-6).jitter_rms_m == pytest.approx(
        0.7e-6, rel=REL
    )


_F3 = {"aperture_diameter_m": 0.3, "focal_length_m": 3.0}  # a valid f/10 telescope
_DEFOCUS = "defocus_blur_diameter_m .* must be a finite number >= 0"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({**_F3, "aperture_diameter_m": 0.0}, "aperture_diameter_m must be a positive"),
        ({**_F3, "focal_length_m": -1.0}, "focal_length_m must be a positive"),
        ({**_F3, "transmission": 80.0}, r"transmission must be in \(0, 1\]"),
        ({**_F3, "obscuration_ratio": 1.0}, r"obscuration_ratio .* must be in \[0, 1\)"),
        ({**_F3, "jitter_rms_rad": -1e-6}, "jitter_rms_rad must be a finite number >= 0"),
        ({"aperture_diameter_m": 3.0, "focal_length_m": 0.3}, "f-number f/D = 0.1 is below 1"),
        ({**_F3, "defocus_blur_diameter_m": -1e-6}, _DEFOCUS),
        ({**_F3, "defocus_blur_diameter_m": math.nan}, _DEFOCUS),
        ({**_F3, "defocus_blur_diameter_m": math.inf}, _DEFOCUS),
        ({**_F3, "defocus_blur_diameter_m": "far"}, _DEFOCUS),
    ],
)
def test_optics_rejects_bad_values(kwargs, match):
    with pytest.raises(SatsightError, match=match):
        Optics(**kwargs)


@pytest.mark.parametrize("bad", [-1e-6, math.nan, math.inf, None])
def test_defocus_rejects_bad_blur_diameters_with_a_hint(bad):
    with pytest.raises(SatsightError, match=r"defocus_blur_diameter_m .* d = dz / N"):
        Optics(0.3, 3.0, defocus_blur_diameter_m=bad)
    with pytest.raises(SatsightError, match="blur_diameter_m"):
        defocus_mtf(1e4, bad)


# --- camera equation --------------------------------------------------------------------------


def test_irradiance_closed_form():
    radiance = np.full((4, 5), 12.5)
    e = focal_plane_irradiance_w_m2(radiance, OPTICS)
    expected = math.pi * 12.5 * 0.8 / (4 * N**2)
    np.testing.assert_allclose(e, expected, rtol=REL)
    obscured = Optics(0.3, 3.0, obscuration_ratio=0.4)
    np.testing.assert_allclose(
        focal_plane_irradiance_w_m2(radiance, obscured), expected * (1 - 0.16), rtol=REL
    )
    theta = np.full((4, 5), 0.3)
    np.testing.assert_allclose(
        focal_plane_irradiance_w_m2(radiance, OPTICS, theta),
        expected * math.cos(0.3) ** 4,
        rtol=REL,
    )
    assert focal_plane_irradiance_w_m2(radiance.astype(np.float32), OPTICS).dtype == np.float32
    with pytest.raises(SatsightError, match=r"field angles .* in \(-pi/2, pi/2\)"):
        focal_plane_irradiance_w_m2(radiance, OPTICS, np.full((4, 5), 2.0))
