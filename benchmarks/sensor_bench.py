"""Benchmark the sensor chain at full frame; prints JSON (median and all repeats, seconds).

Usage: python benchmarks/sensor_bench.py [--size 4096x4112] [--repeats 5] [--threads N]

The image is (height, width) float32 focal-plane irradiance: the left half is a sunlit target
at about 0.4 W m^-2 with a deterministic texture (smooth panels times a +-20 % pixel-scale
pattern), the right half is empty space (0). Timed cases:

* ``apply_optics``: the default high-resolution kernel for rendered frames (``frame_kernel``
  of the ``high_resolution`` optics, 16 sub-band wavelengths of 450-900 nm, 15 um pixels,
  one centre sample per pixel, 41 x 41), supersampling 1;
* ``simulate_detector_first_frame``: a new camera seed each repeat, so the fixed-pattern maps
  (PRNU, DSNU) are drawn inside the timing;
* ``simulate_detector_cached``: the same camera seed, its maps already cached;
* ``chain``: ``apply_optics`` then ``simulate_detector`` with cached maps;
* ``frame_with_stars``: the whole per-frame sensor stage of ``satsight generate``
  (``pipeline`` order) for each camera preset: a rendered frame (the same target as (H, W, 3)
  radiance, 64 W m^-2 sr^-1 on average, a grey Lambertian plate in sunlight, with the
  margin ring the renderer adds for the blur: the target continues beyond the frame's left,
  top and bottom edges) through ``SensorChain`` (band radiance, camera equation, blur
  kernel, the auto exposure rule), the
  catalogue stars of a rich Milky Way field (RA 280 deg, Dec -5 deg) at 2026-03-20 seen
  from low Earth orbit, hidden behind the target's half, their photons, and the readout.

The exposure is ``exposure_for_fill`` of the brightest pixel (fill 0.7 of the full well).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np
import scipy

from satsight.camera.pinhole import PinholeCamera
from satsight.render.buffers import RadianceImage, margin_pixels_xy
from satsight.sensor.chain import PSF_SIZE_PX, SensorChain
from satsight.sensor.convolution import apply_optics
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.exposure import exposure_for_fill, simulate_detector
from satsight.sensor.mtf import band_wavelengths_m
from satsight.sensor.optics import Optics
from satsight.sensor.psf import frame_kernel

BAND_NM = (450.0, 900.0)
STAR_FIELD_RA_DEC_DEG = (280.0, -5.0)
STAR_EPOCH_UTC = "2026-03-20T12:00:00Z"
LEO_VELOCITY_GCRS_M_S = np.array([0.0, 7500.0, 0.0])


def half_covered_irradiance(height: int, width: int) -> np.ndarray:
    """(height, width) float32 W m^-2: textured target (~0.4 W m^-2) on the left, 0 right."""
    y = np.linspace(0.0, 1.0, height, dtype=np.float32)[:, None]
    x = np.linspace(0.0, 1.0, width // 2, dtype=np.float32)[None, :]
    panels = 1.0 + 0.25 * np.sin(2 * np.pi * 6 * x) * np.cos(2 * np.pi * 4 * y)
    texture = np.random.default_rng(0).uniform(0.8, 1.2, (height, width // 2)).astype(np.float32)
    image = np.zeros((height, width), dtype=np.float32)
    image[:, : width // 2] = np.float32(0.4) * panels * texture
    return image


def _pointing(ra_deg: float, dec_deg: float) -> np.ndarray:
    """R_cam_from_gcrs with the boresight at (ra, dec) and image y towards the south."""
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    z = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def _frame_with_stars(
    preset: str, irradiance: np.ndarray, repeats: int, threads: dict
) -> dict[str, object]:
    from satsight.sensor.star_catalog import load_star_catalog
    from satsight.sensor.star_field import stars_in_view
    from satsight.sensor.star_stamps import star_photons_image

    height, width = irradiance.shape
    camera = (
        PinholeCamera.high_resolution()
        if preset == "high_resolution"
        else (PinholeCamera.wide_field())
    )
    camera = camera.with_size(width, height)
    optics = Optics.for_preset(preset)
    sensor = SensorChain(camera, optics, DetectorParameters(), BAND_NM, camera_seed=1)
    radiance = irradiance * np.float32(160.0)  # 0.4 W m^-2 at f/10 is ~64 W m^-2 sr^-1
    hit = radiance > 0
    ring_x, _ = margin_pixels_xy(width, height, sensor.margin_px)
    ring = np.where(ring_x[:, None] < width // 2, np.float32(64.0), np.float32(0.0))
    image = RadianceImage(
        radiance_w_m2_sr=np.repeat(radiance[..., None], 3, axis=2),
        depth_m=np.where(hit, np.float32(1000.0), np.float32(0.0)),
        part_id=hit.astype(np.uint16),
        normals_cam=np.zeros((height, width, 3), np.float32),
        margin_px=sensor.margin_px,
        margin_radiance_w_m2_sr=np.repeat(ring, 3, axis=1),
    )
    R = _pointing(*STAR_FIELD_RA_DEC_DEG)
    catalog = load_star_catalog(9.5)
    counts = []

    def frame(i: int) -> np.ndarray:
        focal = sensor.focal_plane_irradiance_w_m2(image)
        t = sensor.exposure_time_s(focal, image.object_mask)
        stars = stars_in_view(
            catalog, R, camera, STAR_EPOCH_UTC, LEO_VELOCITY_GCRS_M_S,
            object_mask=image.object_mask, band_nm=BAND_NM,
        )  # fmt: skip
        star_photons_image(
            stars, (height, width), optics, 15e-6, t, BAND_NM,
            out=focal, scale=sensor.photons_to_irradiance_factor(t),
        )  # fmt: skip
        counts.append(len(stars))
        return sensor.read_out(focal, t, np.random.default_rng(i)).dn

    frame(0)  # warm-up: catalogue load, fixed-pattern maps, PSF cache
    timing = _time(frame, repeats)
    timing["stars_drawn"] = counts[-1]
    return timing


def _time(fn: Callable[[int], object], repeats: int) -> dict[str, object]:
    seconds = []
    for i in range(repeats):
        t0 = time.perf_counter()
        fn(i)
        seconds.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(seconds), "repeats_s": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="4096x4112", help="frame WIDTHxHEIGHT in pixels")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per case (>= 1)")
    parser.add_argument(
        "--threads", type=int, default=None, help="worker threads (default: all cores)"
    )
    args = parser.parse_args()
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(f"--size must look like 4096x4112; got {args.size!r}")
    if width < 2 or height < 1 or args.repeats < 1:
        parser.error("need a frame of at least 2 x 1 pixels and --repeats >= 1")
    threads = {} if args.threads is None else {"threads": args.threads}

    irradiance = half_covered_irradiance(height, width)
    psf = frame_kernel(
        Optics.for_preset("high_resolution"), band_wavelengths_m(), None, 15e-6, PSF_SIZE_PX
    )
    params = DetectorParameters()
    exposure_s = exposure_for_fill(float(irradiance.max()), params, BAND_NM, 0.7)

    def optics(_: int) -> np.ndarray:
        return apply_optics(irradiance, psf, 1, **threads)

    def detector(camera_seed: int, i: int) -> np.ndarray:
        rng = np.random.default_rng(i)
        return simulate_detector(
            irradiance, exposure_s, params, BAND_NM, rng, camera_seed, **threads
        )

    def chain(i: int) -> np.ndarray:
        blurred = apply_optics(irradiance, psf, 1, **threads)
        rng = np.random.default_rng(i)
        return simulate_detector(blurred, exposure_s, params, BAND_NM, rng, 1, **threads)

    optics(0)  # warm-up: FFT plans, page faults
    results = {"apply_optics": _time(optics, args.repeats)}
    results["simulate_detector_first_frame"] = _time(lambda i: detector(1000 + i, i), args.repeats)
    detector(1, 0)  # draws and caches camera 1's fixed pattern
    results["simulate_detector_cached"] = _time(lambda i: detector(1, i), args.repeats)
    results["chain"] = _time(chain, args.repeats)
    for preset in ("high_resolution", "wide_field"):
        results[f"frame_with_stars_{preset}"] = _frame_with_stars(
            preset, irradiance, args.repeats, threads
        )
    report = {
        "benchmark": "sensor",
        "width_px": width,
        "height_px": height,
        "covered_fraction": float(np.count_nonzero(irradiance)) / irradiance.size,
        "exposure_s": exposure_s,
        "psf_shape": list(psf.shape),
        "repeats": args.repeats,
        "threads": args.threads,
        "machine": {
            "cpu_count": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
        },
        "results": results,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
