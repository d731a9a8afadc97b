"""Light curves: the target's in-band irradiance at the observer and its magnitude over time.

For every frame of a scenario's plan the target is rendered small by a camera of its own:
at the observer's position, looking at the target's box centre, its focal length chosen so
that the target's bounding sphere spans ``FILL_FRACTION`` of a ``size_px`` square image
whatever the range. The target is then always resolved (the light curve does not depend on
how many pixels the scenario's camera would give it at long range), and the irradiance is
the photometric label of the frames, E = sum L_pixel Omega_pixel over the target's pixels
(``satsight.sensor.photometry``), with the scenario's light: the Sun (dimmed in the
Earth's shadow), earthshine and moonshine, inter-reflections. Its V-equivalent magnitude is
-26.76 - 2.5 log10(E / E_sun) + 5 log10(d_sun / 1 AU).

Useful for unresolved far frames (what a wide-field camera sees as a point) and for checking
attitude laws (a tumbling or Sun-pointing target has a recognisable curve).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.config.scenario import Scenario
from satsight.dataset.labels import frame_labels
from satsight.errors import SatsightError
from satsight.frame_light import frame_light
from satsight.frames.rigid import look_at_cam_from_body
from satsight.pipeline import FrameEngine, frame_seed
from satsight.render.renderer import Renderer
from satsight.sensor.photometry import frame_photometry

#: Fraction of the image side that the target's bounding sphere spans.
FILL_FRACTION = 0.8

#: Columns of the light curve's CSV, in order.
CSV_COLUMNS = (
    "frame_index",
    "plan_index",
    "time_s",
    "epoch_utc",
    "range_m",
    "phase_angle_deg",
    "sunlit_fraction",
    "target_irradiance_w_m2",
    "v_magnitude_equivalent",
)


@dataclass(frozen=True)
class LightCurve:
    """One row per frame (``CSV_COLUMNS``), and the scenario's name."""

    name: str
    rows: tuple[dict, ...]

    def column(self, key: str) -> np.ndarray:
        """A column as float64 (None becomes NaN)."""
        return np.array([np.nan if r[key] is None else r[key] for r in self.rows], dtype=float)


def lightcurve_camera(
    range_m: float, bounding_radius_m: float, pixel_pitch_m: float, size_px: int
) -> PinholeCamera:
    """A square camera of ``size_px`` whose field of view holds a sphere of radius
    ``bounding_radius_m`` at ``range_m`` (centre distance) within ``FILL_FRACTION`` of its
    side: the sphere's angular radius asin(R / d) maps to FILL_FRACTION * size / 2 px."""
    if not range_m > bounding_radius_m:
        raise SatsightError(
            f"the observer is {range_m:.3g} m from the target's centre, inside its bounding "
            f"sphere ({bounding_radius_m:.3g} m): no light curve there"
        )
    tan_radius = math.tan(math.asin(bounding_radius_m / range_m))
    focal_px = 0.5 * FILL_FRACTION * size_px / tan_radius
    return PinholeCamera(focal_px * pixel_pitch_m, pixel_pitch_m, size_px, size_px)


def run_lightcurve(
    scenario: Scenario,
    size_px: int = 96,
    samples_per_pixel: int | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> LightCurve:
    """The light curve of the scenario's frames (those a dataset would render).

    size_px: side of the small renders. samples_per_pixel: overrides the scenario's render
    setting (more samples make a smoother curve where bounces or the environment are
    sampled). on_frame(done, total): progress callback.
    """
    if not (isinstance(size_px, int) and size_px >= 16):
        raise SatsightError(f"size_px must be a whole number >= 16, got {size_px!r}")
    engine = FrameEngine(scenario)
    settings = scenario.render.settings()
    if samples_per_pixel is not None:
        settings = dataclasses.replace(settings, samples_per_pixel=int(samples_per_pixel))
    renderer = Renderer(engine.mesh, settings, scenario.render.variant)
    mesh, track, pitch = engine.mesh, engine.track, engine.camera.pixel_pitch_m
    rows = []
    total = engine.frame_count
    for frame_index in range(total):
        plan_index = int(engine.plan_indices[frame_index])
        pose = track.cam_from_body(plan_index)
        eye_body = -pose.R_a_from_b.T @ pose.t_a_from_b_m
        center = np.asarray(mesh.center_m, dtype=float)
        range_m = float(np.linalg.norm(eye_body - center))
        camera = lightcurve_camera(range_m, mesh.bounding_radius_m, pitch, size_px)
        look = look_at_cam_from_body(eye_body, center, up_hint_body=_up_hint(eye_body - center))
        light = frame_light(scenario, track, plan_index)
        image = renderer.render(camera, look, light, seed=frame_seed(scenario.seed, plan_index))
        labels = frame_labels(mesh, camera, look, light.sun, image)
        sun_irradiance, sun_distance_m = engine.sun_irradiance_at_camera(plan_index)
        photometry = frame_photometry(
            image,
            camera,
            engine.sensor.channel_weights,
            labels["box_keypoints_px"][:8],
            sun_irradiance,
            sun_distance_m,
        )
        rows.append(
            {
                "frame_index": frame_index,
                "plan_index": plan_index,
                "time_s": float(track.time_s[plan_index]),
                "epoch_utc": track.epoch_utc[plan_index] or "",
                "range_m": range_m,
                "phase_angle_deg": math.degrees(float(track.phase_angle_rad[plan_index])),
                "sunlit_fraction": float(track.sunlit_fraction[plan_index]),
                "target_irradiance_w_m2": photometry["target_irradiance_w_m2"],
                "v_magnitude_equivalent": photometry["target_v_magnitude_equivalent"],
            }
        )
        if on_frame is not None:
            on_frame(frame_index + 1, total)
    return LightCurve(scenario.name, tuple(rows))


def _up_hint(view_body: np.ndarray) -> np.ndarray:
    """Any axis not parallel to the line of sight (the light curve ignores the roll)."""
    axis = np.eye(3)[int(np.argmin(np.abs(view_body)))]
    return axis


def write_csv(curve: LightCurve, path: Path) -> Path:
    """The light curve as CSV (``CSV_COLUMNS``; an empty magnitude where the target sends no
    light)."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for row in curve.rows:
            writer.writerow({k: ("" if row[k] is None else row[k]) for k in CSV_COLUMNS})
    return path


def plot_lightcurve(curve: LightCurve, path: Path) -> Path:
    """Magnitude (inverted axis) and phase angle over time, one figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = curve.column("time_s")
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    top.plot(t, curve.column("v_magnitude_equivalent"), "o-", ms=3)
    top.invert_yaxis()
    top.set_ylabel("V-equivalent magnitude")
    top.grid(alpha=0.3)
    top.set_title(f"{curve.name}: light curve")
    bottom.plot(t, curve.column("phase_angle_deg"), "o-", ms=3, color="tab:orange")
    bottom.set_ylabel("phase angle (deg)")
    bottom.set_xlabel("time (s)")
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
