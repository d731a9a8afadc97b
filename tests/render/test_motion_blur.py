"""Motion during the exposure (``satsight.render.motion``) on a 256 px frame of a flat white
square plate, 2 m wide, seen face on from 3 km with the high-resolution camera (f = 3 m,
15 um pixels: 2e5 px per radian, the plate 133 px wide) through a fixed 0.2 s exposure.

The frame plan's motion is set by hand (``PoseTrack`` rates), so each case has a closed
form: a spin about the plate's normal (the boresight) turns the image about its centre by
w t; a translation across the line of sight at v shifts it by v t / range x f / pitch.
With the Sun at 30 AU the plate fills ~45 % of full well: no pixel saturates, so the DN
above bias measures the collected signal.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from satsight.config.scenario import parse_scenario
from satsight.pipeline import FrameEngine, frame_seed
from satsight.render.motion import MAX_TIME_SAMPLES, SAMPLE_SPACING_PX, exposure_motion

SIZE_PX = 256
RANGE_M = 3000.0
F_PX = 3.0 / 15e-6
EXPOSURE_S = 0.2
SPIN_RAD_S = np.radians(20.0)
HALF_DIAGONAL_M = np.sqrt(2.0)
# 1.5 m/s across the line of sight: 1.5 x 0.2 / 3000 x 2e5 = 20 px of smear.
V_ACROSS_M_S = 1.5
SMEAR_PX = V_ACROSS_M_S * EXPOSURE_S / RANGE_M * F_PX
# The summed DN above bias: shot noise on ~2e4 lit pixels at ~1e4 DN each is ~1e-4 of the
# total; the 2 % budget holds the plate's anti-aliased edge pixels (4 samples a pixel) that
# move across the frame, far above it.
TOTAL_DN_REL = 0.02


def _plate(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("plate") / "plate.obj"
    path.write_text(
        "o plate\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\n"
        "f 1//1 2//1 3//1\nf 1//1 3//1 4//1\n"
    )
    return str(path)


@pytest.fixture(scope="module")
def plate_path(tmp_path_factory) -> str:
    return _plate(tmp_path_factory)


def _engine(plate_path: str, blur, exposure: dict | None = None, **rates) -> FrameEngine:
    scenario = parse_scenario(
        {
            "name": "motion",
            "seed": 3,
            "camera": {
                "preset": "high_resolution", "width_px": SIZE_PX, "height_px": SIZE_PX,
                "exposure": exposure or {"mode": "fixed", "time_s": EXPOSURE_S},
            },
            "target": {"mesh": {"path": plate_path, "materials": {"plate": "lambert_white"}}},
            "sun": {"azimuth_deg": 0.0, "elevation_deg": 60.0, "distance_au": 30.0},
            "frames": [{"distance_km": RANGE_M / 1e3, "azimuth_deg": 0.0, "elevation_deg": 90.0}],
            "render": {"bounces": 0, "samples_per_pixel": 16, "motion_blur": blur},
        },
        "test",
    )  # fmt: skip
    engine = FrameEngine(scenario)
    values = {name: np.asarray([value], dtype=np.float64) for name, value in rates.items()}
    engine.track = dataclasses.replace(engine.track, **values)
    return engine


def _frame(engine: FrameEngine):
    frame = engine.render(0)
    record, arrays, _ = engine.finish(frame)
    assert record["sensor"]["regions"]["target"]["saturated_pixel_count"] == 0
    return frame, record, arrays


def _luminance(image: np.ndarray) -> np.ndarray:
    return image.radiance_w_m2_sr.astype(np.float64).sum(axis=-1)


def _gradient_energy(radiance: np.ndarray, where: np.ndarray) -> float:
    """Mean squared gradient over ``where``: a step edge blurred over w px keeps its total
    variation but its squared gradient falls as 1 / w."""
    gy, gx = np.gradient(radiance)
    return float(np.mean((gx**2 + gy**2)[where]))


def _dn_above_bias(arrays) -> float:
    dn = arrays.dn_image
    return float(np.sum(dn.dn.astype(np.float64) - dn.bias_dn))


@pytest.fixture(scope="module")
def spinning(llvm_variant, plate_path):
    """The still and the blurred frame of the plate spinning about its normal."""
    spin = {"omega_body_rad_s": [0.0, 0.0, SPIN_RAD_S]}
    return _frame(_engine(plate_path, False, **spin)), _frame(_engine(plate_path, "auto", **spin))


def test_a_spinning_target_is_smeared_and_keeps_its_signal(spinning) -> None:
    (still, still_record, still_arrays), (blurred, record, arrays) = spinning
    motion = record["exposure_motion"]
    # The box corners turn on a circle of radius sqrt(2) m: arc r w t / range x f / pitch.
    arc_px = HALF_DIAGONAL_M * SPIN_RAD_S * EXPOSURE_S / RANGE_M * F_PX
    assert motion["path_px"] == pytest.approx(arc_px, rel=1e-3)  # 16 chords of a 4 deg arc
    assert motion["time_samples"] == int(np.ceil(arc_px / SAMPLE_SPACING_PX))
    assert (motion["start_offset_s"], motion["end_offset_s"]) == (-0.1, 0.1)
    assert still_record["exposure_motion"]["time_samples"] == 1
    where = ndimage.binary_dilation(still.image.object_mask, iterations=8)
    sharp = _gradient_energy(_luminance(still.image), where)
    smeared = _gradient_energy(_luminance(blurred.image), where)
    assert smeared < 0.8 * sharp
    assert _dn_above_bias(arrays) == pytest.approx(_dn_above_bias(still_arrays), rel=TOTAL_DN_REL)


def _turned(image: np.ndarray, angle_rad: float) -> np.ndarray:
    """``image`` turned by ``angle_rad`` about the principal point (the frame's centre),
    bilinear: out(u) = image(c + R(-angle) (u - c))."""
    c = (SIZE_PX - 1) / 2.0
    y, x = np.mgrid[0:SIZE_PX, 0:SIZE_PX].astype(np.float64)
    cos, sin = np.cos(angle_rad), np.sin(angle_rad)
    xs = c + cos * (x - c) + sin * (y - c)
    ys = c - sin * (x - c) + cos * (y - c)
    return ndimage.map_coordinates(image, [ys, xs], order=3)


def test_the_spin_smear_spans_the_turn_of_the_exposure(spinning) -> None:
    # The blurred frame against the still turned over +-s w t / 2 (the mean of 32 copies,
    # cubic-spline resampled): the smear's length is s w t, best fitted at s = 1 on a 10 %
    # grid (the misfit at s = 0.9 and 1.1 is 1.2x and 1.8x that at 1; the interval is
    # symmetric, so the turn's sense does not show).
    (still, _, _), (blurred, _, _) = spinning
    sharp, smeared = _luminance(still.image), _luminance(blurred.image)
    taus = ((np.arange(MAX_TIME_SAMPLES) + 0.5) / MAX_TIME_SAMPLES - 0.5) * EXPOSURE_S

    def misfit(scale: float) -> float:
        model = np.mean([_turned(sharp, scale * SPIN_RAD_S * t) for t in taus], axis=0)
        return float(np.sum((model - smeared) ** 2))

    scales = [0.0, 0.8, 0.9, 1.0, 1.1, 1.2]
    errors = [misfit(s) for s in scales]
    assert scales[int(np.argmin(errors))] == 1.0
    assert errors[3] < 0.1 * errors[0]


def _moments_x(radiance: np.ndarray) -> tuple[float, float]:
    weight = radiance.sum(axis=0)
    x = np.arange(weight.size)
    mean = float(np.sum(weight * x) / weight.sum())
    return mean, float(np.sum(weight * (x - mean) ** 2) / weight.sum())


def test_a_target_moving_across_the_line_of_sight_smears_by_v_t_over_range(
    llvm_variant, plate_path
) -> None:
    # The camera does not turn; the plate moves along image +x. The frame is the mean of n
    # copies shifted by L (k + 1/2) / n - L / 2: its centroid is the still's and its variance
    # along x grows by that of n evenly spaced points over L, L^2 (1 - 1 / n^2) / 12.
    move = {"t_dot_cam_from_body_m_s": [V_ACROSS_M_S, 0.0, 0.0]}
    still, _, still_arrays = _frame(_engine(plate_path, False, **move))
    blurred, record, arrays = _frame(_engine(plate_path, True, **move))
    n = record["exposure_motion"]["time_samples"]
    assert record["exposure_motion"]["motion_px"] == pytest.approx(SMEAR_PX, rel=1e-3)
    assert n == min(MAX_TIME_SAMPLES, int(np.ceil(SMEAR_PX / SAMPLE_SPACING_PX)))
    (m0, v0), (m1, v1) = _moments_x(_luminance(still.image)), _moments_x(_luminance(blurred.image))
    # The still's anti-aliased edges (16 samples a pixel, ~530 edge pixels 66 px from the
    # centre) move its centroid by ~0.02 px and its variance (~1480 px^2) by ~0.4 px^2 (rms
    # over seeds); the smear adds 33 px^2: 4 sigma is 0.08 px and 5 % of the variance,
    # 2.5 % of the length.
    assert m1 == pytest.approx(m0, abs=0.08)
    length_px = np.sqrt(12.0 * (v1 - v0) / (1.0 - 1.0 / n**2))
    assert length_px == pytest.approx(SMEAR_PX, rel=0.025)
    where = ndimage.binary_dilation(still.image.object_mask, iterations=8)
    sharp = _gradient_energy(_luminance(still.image), where)
    assert _gradient_energy(_luminance(blurred.image), where) < 0.6 * sharp
    assert _dn_above_bias(arrays) == pytest.approx(_dn_above_bias(still_arrays), rel=TOTAL_DN_REL)


def test_blur_off_or_a_static_scene_gives_the_still_bytes(llvm_variant, plate_path) -> None:
    spin = {"omega_body_rad_s": [0.0, 0.0, SPIN_RAD_S]}
    off = _engine(plate_path, False, **spin).render(0)
    engine = _engine(plate_path, "auto")  # no motion
    static = engine.render(0)
    still = engine.renderer.render(
        engine.camera,
        engine.track.cam_from_body(0),
        off.light,
        seed=frame_seed(engine.scenario.seed, 0),
        margin_px=engine.sensor.margin_px,
    )
    for frame in (off, static):
        assert frame.motion is None
        assert frame.image.radiance_w_m2_sr.tobytes() == still.radiance_w_m2_sr.tobytes()
    # Motion under the threshold leaves auto's still too.
    slow = exposure_motion(
        engine.camera, engine.track, 0, engine.mesh.box_keypoints_body_m[:8], EXPOSURE_S, "auto"
    )
    assert slow.sample_count == 1 and slow.motion_px == 0.0


def test_a_blurred_frame_is_the_same_bytes_twice(llvm_variant, plate_path) -> None:
    spin = {"omega_body_rad_s": [0.0, 0.0, SPIN_RAD_S]}
    first, second = (_engine(plate_path, "auto", **spin).render(0) for _ in range(2))
    assert first.motion.sample_count > 1
    assert first.image.radiance_w_m2_sr.tobytes() == second.image.radiance_w_m2_sr.tobytes()


def test_the_auto_exposure_is_decided_on_the_still(llvm_variant, plate_path) -> None:
    # The exposure rule reads the still (mid-exposure); the time samples then span it.
    auto = {"mode": "auto", "fill_fraction": 0.7}
    spin = {"omega_body_rad_s": [0.0, 0.0, SPIN_RAD_S]}
    _, still_record, _ = _frame(_engine(plate_path, False, auto, **spin))
    blurred, record, _ = _frame(_engine(plate_path, "auto", auto, **spin))
    exposure_s = still_record["sensor"]["exposure_time_s"]
    assert record["sensor"]["exposure_time_s"] == exposure_s == blurred.motion.exposure_s
    assert record["exposure_motion"]["end_offset_s"] == 0.5 * exposure_s
    arc_px = HALF_DIAGONAL_M * SPIN_RAD_S * exposure_s / RANGE_M * F_PX
    assert record["exposure_motion"]["path_px"] == pytest.approx(arc_px, rel=1e-3)


def test_a_still_under_the_auto_exposure_gives_the_same_bytes_as_blur_off(
    llvm_variant, plate_path
) -> None:
    # 2e-3 rad/s: the box corners could move 1.9 px over the longest auto exposure (10 s),
    # so the still's irradiance is computed for the exposure decision, but only ~0.06 px
    # over the exposure chosen (~0.3 s): the frame stays the still, its DN those of blur off.
    auto = {"mode": "auto", "fill_fraction": 0.7}
    slow = {"omega_body_rad_s": [0.0, 0.0, 2e-3]}
    _, off_record, off_arrays = _frame(_engine(plate_path, False, auto, **slow))
    still, record, arrays = _frame(_engine(plate_path, "auto", auto, **slow))
    assert still.still_irradiance_w_m2 is not None and still.motion.sample_count == 1
    assert record["exposure_motion"]["motion_px"] < 0.1
    assert record["sensor"]["exposure_time_s"] == off_record["sensor"]["exposure_time_s"]
    assert arrays.dn_image.dn.tobytes() == off_arrays.dn_image.dn.tobytes()
