"""Fixed-pattern noise of one camera: PRNU and DSNU maps, drawn once per camera seed.

Photo-response non-uniformity (PRNU, a per-pixel relative gain) and dark-signal
non-uniformity (DSNU, the per-pixel spread of the dark current) are spatial: the same in
every frame of one camera (Janesick, *Photon Transfer*, SPIE Press, 2007, ch. 6-7). They
are drawn from ``np.random.SeedSequence(camera_seed)`` alone, never from the per-frame
generator, in the same fixed row bands as the temporal noise (``satsight.sensor.noise``),
and the maps of the most recent cameras are cached.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import numpy as np

from satsight.errors import SatsightError
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.noise import _row_bands, _standard_normal_f32
from satsight.sensor.threads import check_threads, run_jobs


def fixed_pattern_maps(
    shape: tuple[int, int], params: DetectorParameters, camera_seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel fixed-pattern maps of one camera: (prnu_gain_map, dsnu_e_per_s_map).

    prnu_gain_map: (H, W) float32, dimensionless relative response, 1 + prnu_fraction z with
        z standard normal, clipped at 0 (a 5-sigma event at the largest allowed 20 %).
        Mean 1, rms spread prnu_fraction.
    dsnu_e_per_s_map: (H, W) float32, e-/s, the per-pixel dark current minus its mean. The
        per-pixel dark current D_ij is lognormal with mean dark_current_e_per_s and rms
        dsnu_e_per_s (a positive, right-skewed distribution, as measured dark currents are;
        Janesick 2007, ch. 7), so the map has mean 0 and D + map >= 0 everywhere.
    Both are drawn from ``np.random.SeedSequence(camera_seed)`` (one child stream each, split
    into fixed row bands), so they depend only on the camera seed, the shape and the two
    spreads, never on the temporal-noise generator or the thread count; switching one off
    leaves the other unchanged. float32 holds them to 6e-8 relative, far below their 1 %
    spread. The maps of the two most recent cameras are cached (PRNU and the per-pixel dark
    current, 2 x 67 MB for a 4096 x 4112 frame; drawing them costs ~0.08 s on 2 cores); the arrays
    returned are read-only.
    """
    prnu, dark_e_per_s = _camera_maps(shape, params, camera_seed)
    h, w = int(shape[0]), int(shape[1])
    if prnu is None:
        prnu = np.ones((h, w), dtype=np.float32)
    if dark_e_per_s is None:
        dsnu = np.zeros((h, w), dtype=np.float32)
    else:
        dsnu = dark_e_per_s - np.float32(params.dark_current_e_per_s)
    prnu.setflags(write=False)
    dsnu.setflags(write=False)
    return prnu, dsnu


_CAMERA_MAPS: OrderedDict[tuple, tuple[np.ndarray | None, np.ndarray | None]] = OrderedDict()
_CAMERA_MAPS_LOCK = threading.Lock()
_CAMERA_MAPS_KEPT = 2


def _camera_maps(
    shape: tuple[int, int],
    params: DetectorParameters,
    camera_seed: int,
    threads: int | None = None,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Cached (prnu_gain_map, dark_current_e_per_s_map) of one camera, float32 (H, W).

    None stands for a switched-off map (PRNU 1 everywhere; dark current D everywhere).
    The dark-current map is D_ij = D + DSNU_ij >= 0. Thread count does not change values.
    """
    if len(shape) != 2 or not all(isinstance(n, int | np.integer) and n > 0 for n in shape):
        raise SatsightError(f"shape must be (H, W) with positive whole numbers, got {shape!r}")
    if not isinstance(camera_seed, int | np.integer) or camera_seed < 0:
        raise SatsightError(f"camera_seed must be a non-negative whole number, got {camera_seed!r}")
    key = (
        (int(shape[0]), int(shape[1])),
        params.prnu_fraction,
        params.dark_current_e_per_s,
        params.dsnu_e_per_s,
        int(camera_seed),
    )
    with _CAMERA_MAPS_LOCK:
        if key in _CAMERA_MAPS:
            _CAMERA_MAPS.move_to_end(key)
            return _CAMERA_MAPS[key]
        maps = _draw_camera_maps(*key, check_threads(threads))
        _CAMERA_MAPS[key] = maps
        while len(_CAMERA_MAPS) > _CAMERA_MAPS_KEPT:
            _CAMERA_MAPS.popitem(last=False)
        return maps


def _draw_camera_maps(
    shape: tuple[int, int],
    prnu_fraction: float,
    dark_current_e_per_s: float,
    dsnu_e_per_s: float,
    camera_seed: int,
    threads: int,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    prnu_seq, dsnu_seq = np.random.SeedSequence(int(camera_seed)).spawn(2)
    bands = _row_bands(*shape)
    prnu = dark = None
    if prnu_fraction > 0:
        prnu = np.empty(shape, dtype=np.float32)
        prnu_seeds = prnu_seq.spawn(len(bands))

        def draw_prnu(i: int) -> None:
            band = prnu[bands[i][0] : bands[i][1]]
            _standard_normal_f32(np.random.default_rng(prnu_seeds[i]), band.reshape(-1))
            band *= np.float32(prnu_fraction)
            band += np.float32(1.0)
            np.maximum(band, np.float32(0.0), out=band)

        run_jobs(draw_prnu, len(bands), threads)
        prnu.setflags(write=False)
    if dsnu_e_per_s > 0:
        # Lognormal with mean D and rms s: sigma_ln^2 = ln(1 + (s / D)^2), mu_ln = ln D -
        # sigma_ln^2 / 2.
        mean = dark_current_e_per_s
        sigma_ln = math.sqrt(math.log1p((dsnu_e_per_s / mean) ** 2))
        dark = np.empty(shape, dtype=np.float32)
        dsnu_seeds = dsnu_seq.spawn(len(bands))

        def draw_dark(i: int) -> None:
            band = dark[bands[i][0] : bands[i][1]]
            _standard_normal_f32(np.random.default_rng(dsnu_seeds[i]), band.reshape(-1))
            band *= np.float32(sigma_ln)
            band += np.float32(math.log(mean) - 0.5 * sigma_ln**2)
            np.exp(band, out=band)

        run_jobs(draw_dark, len(bands), threads)
        dark.setflags(write=False)
    return prnu, dark
