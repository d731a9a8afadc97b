"""The system MTF plot."""

from __future__ import annotations

from satsight.sensor.mtf_plot import plot_system_mtf
from satsight.sensor.optics import Optics

DEFOCUS_D_M = 90e-6  # blur-circle diameter: 6 pixels of 15 um


def test_plot_system_mtf_writes_png(tmp_path):
    optics = Optics.for_preset("high_resolution", jitter_rms_rad=1e-6)
    path = plot_system_mtf(optics, 15e-6, (450.0, 900.0), tmp_path / "mtf" / "system.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 10_000
    defocused = Optics.for_preset("high_resolution", defocus_blur_diameter_m=DEFOCUS_D_M)
    path = plot_system_mtf(defocused, 15e-6, (450.0, 900.0), tmp_path / "defocus.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
