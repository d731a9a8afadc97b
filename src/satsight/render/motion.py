"""Motion during the exposure: the frame as the time average of sub-frames over it.

A detector integrates the image over its exposure [t - T/2, t + T/2] (the frame's plan time
t at mid-exposure). When the target turns or moves across it, the frame is the time average
of the radiance; it is estimated by the mean of ``n`` renders at the midpoints of ``n``
equal strata of the exposure,

    tau_k = ((k + 1/2) / n - 1/2) T,    k = 0 .. n - 1,

each with the pose and the light (body frame) of its instant (``satsight.poses.pose_rates``)
and its own render seed, so the Monte Carlo noise of the sub-frames averages as well. The
mean of the sub-frames conserves the signal: every sub-frame is an estimate of the same
radiance integral over 1/n of the exposure. With n odd the middle stratum's instant is the
frame's own (tau = 0), and the still render (the frame's seed) is that sub-frame.

The motion is measured on the target's bounding-box corners projected through the pinhole:
``motion_px`` is the largest displacement of a corner between the exposure's start and end,
``path_px`` the longest corner path over it (``PATH_STEPS`` chords: a turning corner's arc).
Rules: ``motion_blur: auto`` blurs when ``motion_px > MOTION_THRESHOLD_PX`` (``true``: any
motion, however small); the sample count is ``n = ceil(path_px / SAMPLE_SPACING_PX)``, at
least 2 and at most ``MAX_TIME_SAMPLES``, so consecutive sub-frames move <= 0.5 px (below
the pixel's own box and the optics blur) up to 16 px of smear; beyond it the sub-frames'
images are path_px / 32 apart.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField
from satsight.poses.pose_rates import poses_at_offsets, track_at_offset
from satsight.poses.track import PoseTrack
from satsight.render.buffers import RadianceImage

#: ``motion_blur: auto`` renders time samples above this corner displacement (px).
MOTION_THRESHOLD_PX = 0.1
#: Largest image step between consecutive time samples (px).
SAMPLE_SPACING_PX = 0.5
#: Most time samples of one frame.
MAX_TIME_SAMPLES = 32
#: Chords of a corner's path over the exposure when its length is measured.
PATH_STEPS = 16


@dataclass(frozen=True)
class ExposureMotion:
    """How frame ``index`` moves over its exposure, and the instants it is rendered at.

    exposure_s: the exposure time T (s). motion_px: the largest box-corner displacement
    between the exposure's start and end (px); path_px: the longest box-corner path over
    it (px). offsets_s: (n,) the instants of the time samples from the frame's time (s).
    """

    exposure_s: float
    motion_px: float
    path_px: float
    offsets_s: np.ndarray

    @property
    def sample_count(self) -> int:
        return len(self.offsets_s)

    def labels(self) -> dict:
        """The frame record's ``exposure_motion``: the exposure interval from the frame's
        time (s), the number of time samples and the motion (px)."""
        return {
            "start_offset_s": -0.5 * self.exposure_s,
            "end_offset_s": 0.5 * self.exposure_s,
            "time_samples": self.sample_count,
            "motion_px": self.motion_px,
            "path_px": self.path_px,
        }


Corners = np.ndarray | Callable[[float], np.ndarray]


def corner_paths_px(
    camera: PinholeCamera,
    track: PoseTrack,
    index: int,
    corners_body_m: Corners,
    offsets_s: np.ndarray,
) -> np.ndarray:
    """(K, M, 2) pixel positions of the points ``corners_body_m`` (M, 3) at the offsets
    ``offsets_s`` (K,) s from frame ``index``'s time; corners_body_m may also be a function
    of the offset giving them (points that move in the body frame: flying objects)."""
    offsets = np.asarray(offsets_s, dtype=np.float64).reshape(-1)
    R, t = poses_at_offsets(track, index, offsets)  # (K, 3, 3), (K, 3)
    if callable(corners_body_m):
        points = np.stack([np.asarray(corners_body_m(float(tau)), dtype=np.float64).reshape(-1, 3)
                           for tau in offsets])  # fmt: skip
    else:
        points = np.asarray(corners_body_m, dtype=np.float64).reshape(1, -1, 3)
    return camera.project(points @ R.transpose(0, 2, 1) + t[:, None, :])


def exposure_motion(
    camera: PinholeCamera,
    track: PoseTrack,
    index: int,
    corners_body_m: Corners,
    exposure_s: float,
    mode: str | bool,
) -> ExposureMotion:
    """The motion of frame ``index`` over an exposure of ``exposure_s`` and its time samples
    under ``mode`` (``motion_blur``: "auto", True or False; module docstring for the rules).
    Without blur the one sample is the frame's own instant."""
    if mode not in ("auto", True, False):
        raise SatsightError(f"motion_blur must be 'auto', true or false, got {mode!r}")
    if not (exposure_s >= 0 and math.isfinite(exposure_s)):
        raise SatsightError(f"the exposure must be a finite time >= 0 s, got {exposure_s!r}")
    steps = np.linspace(-0.5, 0.5, PATH_STEPS + 1) * exposure_s
    paths = corner_paths_px(camera, track, index, corners_body_m, steps)
    motion_px = float(np.max(np.linalg.norm(paths[-1] - paths[0], axis=-1)))
    path_px = float(np.max(np.linalg.norm(np.diff(paths, axis=0), axis=-1).sum(axis=0)))
    blur = (mode is True and path_px > 0) or (mode == "auto" and motion_px > MOTION_THRESHOLD_PX)
    n = 1
    if blur:
        n = min(MAX_TIME_SAMPLES, max(2, math.ceil(path_px / SAMPLE_SPACING_PX)))
    offsets = ((np.arange(n) + 0.5) / n - 0.5) * exposure_s
    return ExposureMotion(float(exposure_s), motion_px, path_px, offsets)


def subframe_seed(frame_seed: int, sample: int) -> int:
    """The render seed of time sample ``sample`` of a frame (its own stream)."""
    state = np.random.SeedSequence([int(frame_seed), 2, int(sample)]).generate_state(2, np.uint32)
    return int(state[0]) << 32 | int(state[1])


def render_over_exposure(
    render: Callable[[RigidTransform, LightField, int, float], RadianceImage],
    light_at: Callable[[PoseTrack, int], LightField],
    track: PoseTrack,
    index: int,
    still: RadianceImage,
    frame_seed: int,
    motion: ExposureMotion,
) -> RadianceImage:
    """Frame ``index`` averaged over its exposure: the mean radiance (and margin ring) of
    the time samples of ``motion``, each rendered by ``render(cam_from_body, light, seed,
    offset_s)`` with the light ``light_at(track, 0)`` of its one-frame track (offset_s: the
    sample's instant from the frame's time, for what else moves in the scene). The geometric label
    images (depth, part ids, normals, background) are the still's, at mid-exposure.
    ``still``: the frame rendered at its own time with ``frame_seed``, reused as the middle
    sample when the count is odd."""
    n = motion.sample_count
    if n == 1 and motion.offsets_s[0] == 0.0:
        return still
    total = np.zeros(still.radiance_w_m2_sr.shape, dtype=np.float64)
    margin = None
    if still.margin_radiance_w_m2_sr is not None:
        margin = np.zeros(still.margin_radiance_w_m2_sr.shape, dtype=np.float64)
    for k, tau in enumerate(motion.offsets_s):
        if tau == 0.0:
            image = still
        else:
            moved = track_at_offset(track, index, float(tau))
            seed = subframe_seed(frame_seed, k)
            image = render(moved.cam_from_body(0), light_at(moved, 0), seed, float(tau))
        total += image.radiance_w_m2_sr
        if margin is not None:
            margin += image.margin_radiance_w_m2_sr
    return dataclasses.replace(
        still,
        radiance_w_m2_sr=(total / n).astype(np.float32),
        margin_radiance_w_m2_sr=None if margin is None else (margin / n).astype(np.float32),
    )
