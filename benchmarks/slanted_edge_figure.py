"""Slanted-edge MTF of rendered frames against the system MTF; prints JSON, writes a PNG.

Usage: python benchmarks/slanted_edge_figure.py [--out docs/images/slanted_edge_mtf.png]

For each camera preset (``wide_field`` f = 0.7 m, D = 0.1 m; ``high_resolution`` f = 3 m,
D = 0.3 m; 15 um pixels, 450-900 nm), a large grey Lambertian plate whose straight edge runs
at a slope of 1/11 (5.19 deg) to the pixel columns is rendered (Sun only, no environment,
no bounces; one sample at each pixel centre, the default render settings) with the margin
ring the sensor chain asks for. Its focal-plane irradiance is measured with the ISO 12233
slanted-edge method (``satsight.sensor.slanted_edge``, per-phase bins) after

* ``SensorChain.focal_plane_irradiance_w_m2``: the kernel designed so that the frame's
  response is the system OTF (``frame_kernel``), and
* the spatially sampled PSF that rendered frames were blurred with before (``psf_kernel``,
  15 x 15, pixel-integrated Airy pattern),

and compared with ``system_mtf``. A second plate, its edge at 5.00 deg, is measured with
ISO 4x bins, to show what the standard binning reads on a point-sampled frame. The
irradiance is linear in the DN the detector makes (which adds only noise, fixed pattern
and quantisation), so the MTF is measured on it directly.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts
from satsight.sensor.chain import SensorChain
from satsight.sensor.convolution import apply_optics
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.mtf import band_wavelengths_m, system_mtf
from satsight.sensor.optics import Optics
from satsight.sensor.psf import psf_kernel
from satsight.sensor.slanted_edge import slanted_edge_mtf

BAND_NM = (450.0, 900.0)
PITCH_M = 15e-6
PHASES = 11
WIDTH_PX, HEIGHT_PX = 176, 220
DISTANCE_OVER_FOCAL = 1000.0
SUN = LightField.sun_only(np.array([0.3, 0.2, 1.0]), 1000.0)
PRESETS = {"wide_field": "wide field, f/7", "high_resolution": "high resolution, f/10"}
REPORT_CYC_PER_PX = (0.1, 0.2, 0.3, 0.4, 0.45, 0.5)


def edge_view(camera: PinholeCamera, slope: float):
    """Pose of a camera above the plane z = 0 (body frame) and a triangle whose left side
    draws the edge u = u0 + slope (v - cy) in the image, the other sides far outside."""
    distance_m = camera.focal_length_m * DISTANCE_OVER_FOCAL
    pose = look_at_cam_from_body(
        np.array([0.0, 0.0, distance_m]), np.zeros(3), up_hint_body=(0.0, 1.0, 0.0)
    )
    cx, cy = camera.cx_px, camera.cy_px
    u0 = (round(WIDTH_PX / 2 * PHASES - cy) + 0.5 + cy) / PHASES
    corners_px = [
        (u0 + slope * (-3 * HEIGHT_PX - cy), -3 * HEIGHT_PX),
        (u0 + slope * (4 * HEIGHT_PX - cy), 4 * HEIGHT_PX),
        (u0 + 50 * WIDTH_PX, cy),
    ]
    metres_per_px = camera.pixel_pitch_m * DISTANCE_OVER_FOCAL
    body_from_cam = pose.inverse()
    corners = [
        body_from_cam.apply(np.array([u - cx, v - cy, 0.0]) * metres_per_px + [0, 0, distance_m])
        for u, v in corners_px
    ]
    return pose, np.array(corners)


def edge_renderer(slope: float) -> Renderer:
    corners = edge_view(PinholeCamera.wide_field().with_size(WIDTH_PX, HEIGHT_PX), slope)[1]
    grey = Material("grey_lambert", (0.5, 0.5, 0.5), metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", grey.name, corners, np.array([[0, 1, 2]]))], {grey.name: grey})
    return Renderer(mesh, RenderSettings(environment="off", bounces=0))


def measure(preset: str, renderers: dict[str, Renderer]) -> dict:
    camera = getattr(PinholeCamera, preset)().with_size(WIDTH_PX, HEIGHT_PX)
    optics = Optics.for_preset(preset)
    chain = SensorChain(camera, optics, DetectorParameters(), BAND_NM)
    old_kernel = psf_kernel(optics, band_wavelengths_m(BAND_NM), None, PITCH_M, 15)
    curves = {}
    for name, renderer in renderers.items():
        slope = 1 / PHASES if name == "lattice" else math.tan(math.radians(5.0))
        pose = edge_view(camera, slope)[0]
        image = renderer.render(camera, pose, SUN, seed=1, margin_px=chain.margin_px)
        new = chain.focal_plane_irradiance_w_m2(image)
        if name == "lattice":
            curves["new"] = slanted_edge_mtf(new, phases_per_px=PHASES)
            band = chain.band_radiance_w_m2_sr(image.radiance_w_m2_sr)
            curves["old"] = slanted_edge_mtf(apply_optics(band, old_kernel), phases_per_px=PHASES)
        else:
            curves["new_iso_4x_5deg"] = slanted_edge_mtf(new, oversampling=4)
    table = {}
    for key, result in curves.items():
        f = result.frequency_cyc_per_px
        table[key] = {
            "angle_deg": math.degrees(result.angle_rad),
            "at_cyc_per_px": {
                str(q): float(np.interp(q, f, result.mtf)) for q in REPORT_CYC_PER_PX
            },
        }
        band = f <= 0.5
        reference = system_mtf(f[band] / PITCH_M, optics, PITCH_M, band_wavelengths_m(BAND_NM))
        table[key]["max_relative_error_to_nyquist"] = float(
            np.abs(result.mtf[band] / reference - 1).max()
        )
    table["system_mtf"] = {
        str(q): float(system_mtf(q / PITCH_M, optics, PITCH_M)) for q in REPORT_CYC_PER_PX
    }
    return {"table": table, "curves": curves, "optics": optics}


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6), sharey=True)
    try:
        for ax, (preset, result) in zip(axes, results.items(), strict=True):
            f = np.linspace(0.0, 0.5, 201)
            ax.plot(f, system_mtf(f / PITCH_M, result["optics"], PITCH_M), "k", lw=2,
                    label="system MTF (optics x pixel)")  # fmt: skip
            styles = {
                "new": ("C0", "o", "rendered, designed kernel"),
                "old": ("C3", "s", "rendered, sampled PSF (before)"),
            }
            for key, (colour, marker, label) in styles.items():
                curve = result["curves"][key]
                band = curve.frequency_cyc_per_px <= 0.5
                ax.plot(curve.frequency_cyc_per_px[band], curve.mtf[band], marker, color=colour,
                        ms=3.5, mfc="none", label=label)  # fmt: skip
            iso = result["curves"]["new_iso_4x_5deg"]
            band = iso.frequency_cyc_per_px <= 0.5
            ax.plot(iso.frequency_cyc_per_px[band], iso.mtf[band], "--", color="C0", lw=1,
                    label="designed kernel, ISO 4x bins, 5 deg")  # fmt: skip
            ax.set_title(PRESETS[preset])
            ax.set_xlim(0.0, 0.5)
            ax.set_ylim(0.0, 1.02)
            ax.set_xlabel("spatial frequency (cycles / pixel; Nyquist = 0.5)")
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("MTF (slanted edge)")
        axes[0].legend(loc="lower left", fontsize=7.5)
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=90)
    finally:
        plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images/slanted_edge_mtf.png"))
    args = parser.parse_args()
    renderers = {
        "lattice": edge_renderer(1 / PHASES),
        "iso": edge_renderer(math.tan(math.radians(5.0))),
    }
    results = {preset: measure(preset, renderers) for preset in PRESETS}
    plot(results, args.out)
    report = {
        "figure": "slanted-edge MTF of rendered frames",
        "png": str(args.out),
        "presets": {preset: result["table"] for preset, result in results.items()},
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
