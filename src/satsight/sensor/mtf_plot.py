"""Plots of the camera's MTF (PNG, matplotlib's Agg backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from satsight.sensor.mtf import (
    DEFAULT_N_WAVELENGTHS,
    band_wavelengths_m,
    defocus_mtf,
    diffraction_mtf,
    jitter_mtf,
    pixel_mtf,
)
from satsight.sensor.optics import Optics, _check_positive


def plot_system_mtf(
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float] | None,
    path: str | Path,
    n_wavelengths: int = DEFAULT_N_WAVELENGTHS,
) -> Path:
    """Write a PNG of the diffraction, pixel, jitter and system MTF vs frequency (cycles/mm).

    The axis runs to 1.1 x the pixel Nyquist frequency 1 / (2 p), which is marked; the
    shortest-wavelength diffraction cut-off 1 / (lambda_min N) is marked when it is in range.
    With defocus (optics.defocus_blur_diameter_m > 0) its signed geometric OTF is drawn too,
    the system curve includes it (and is then the signed OTF) and the axis shows the negative
    lobes. Returns the path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    lam = band_wavelengths_m(band_nm, n_wavelengths)
    nyquist = 1.0 / (2.0 * p)
    lo_nm, hi_nm = lam[0] * 1e9, lam[-1] * 1e9
    cutoff = 1.0 / (float(lam.min()) * optics.f_number)
    f = np.linspace(0.0, 1.1 * nyquist, 512)
    diff = np.mean(
        [diffraction_mtf(f, lk, optics.f_number, optics.obscuration_ratio) for lk in lam], axis=0
    )
    pix = pixel_mtf(f, p)
    jit = jitter_mtf(f, optics.jitter_rms_rad, optics.focal_length_m)
    d = optics.defocus_blur_diameter_m
    system = diff * pix * jit
    if d > 0.0:
        dfc = defocus_mtf(f, d)
        system = system * dfc
    f_mm = f * 1e-3
    fig, ax = plt.subplots(figsize=(7, 4.5))
    try:
        ax.plot(f_mm, diff, label=f"diffraction (f/{optics.f_number:.3g}, band-averaged)")
        ax.plot(f_mm, pix, label=f"pixel ({p * 1e6:.3g} um, 100 % fill)")
        ax.plot(f_mm, jit, label=f"jitter ({optics.jitter_rms_rad * 1e6:.3g} urad RMS)")
        if d > 0.0:
            ax.plot(f_mm, dfc, label=f"defocus ({d * 1e6:.3g} um blur disc, geometric OTF)")
        ax.plot(f_mm, system, "k", lw=2, label="system")
        ax.axvline(nyquist * 1e-3, color="gray", ls="--", label="Nyquist 1/(2p)")
        if cutoff < 1.1 * nyquist:
            ax.axvline(cutoff * 1e-3, color="red", ls=":", label="diffraction cut-off")
        ax.set_xlim(0.0, 1.1 * nyquist * 1e-3)
        if d > 0.0:  # the defocus OTF is signed: show its negative lobes
            ax.axhline(0.0, color="black", lw=0.5)
            ax.set_ylim(min(0.0, float(dfc.min()), float(system.min())) - 0.02, 1.02)
        else:
            ax.set_ylim(0.0, 1.02)
        ax.set_xlabel("spatial frequency in the focal plane (cycles/mm)")
        ax.set_ylabel("MTF" if d == 0.0 else "MTF (signed OTF where negative)")
        ax.set_title(f"System MTF, {lo_nm:.0f}-{hi_nm:.0f} nm sub-band centres")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=100)
    finally:
        plt.close(fig)
    return out
