"""The system MTF plot: a 7 x 4.5 inch figure at 100 dpi with one curve per MTF factor."""

from __future__ import annotations

from matplotlib import colormaps

from figure_checks import figure_pixels, has_colour
from satsight.sensor.mtf_plot import plot_system_mtf
from satsight.sensor.optics import Optics

DEFOCUS_D_M = 90e-6  # blur-circle diameter: 6 pixels of 15 um
SIZE_PX = (700, 450)
# matplotlib's default colour cycle (tab10): diffraction, pixel, jitter, defocus in order.
CYCLE = [colormaps["tab10"](k) for k in range(4)]


def test_plot_system_mtf_draws_each_factor(tmp_path):
    optics = Optics.for_preset("high_resolution", jitter_rms_rad=1e-6)
    path = plot_system_mtf(optics, 15e-6, (450.0, 900.0), tmp_path / "mtf" / "system.png")
    pixels = figure_pixels(path, SIZE_PX)
    # Diffraction, pixel and jitter curves; no defocus curve without defocus.
    assert all(has_colour(pixels, colour) for colour in CYCLE[:3])
    assert not has_colour(pixels, CYCLE[3])


def test_plot_system_mtf_adds_the_defocus_curve(tmp_path):
    defocused = Optics.for_preset("high_resolution", defocus_blur_diameter_m=DEFOCUS_D_M)
    path = plot_system_mtf(defocused, 15e-6, (450.0, 900.0), tmp_path / "defocus.png")
    pixels = figure_pixels(path, SIZE_PX)
    assert all(has_colour(pixels, colour) for colour in CYCLE)
