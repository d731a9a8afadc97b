"""Applying a kernel to a focal-plane image: power, flat field, the signal-box fast path,
the margin ring, and the banded FFT against scipy's convolutions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import convolve2d, fftconvolve

from kernel_taps import edge_and_corner_loss, frame_kernel_taps
from satsight.errors import SatsightError
from satsight.sensor.convolution import apply_optics, fft_convolve_same, fill_negative_lobes
from satsight.sensor.mtf import band_wavelengths_m
from satsight.sensor.optics import Optics
from satsight.sensor.psf import psf_kernel

OPTICS = Optics(aperture_diameter_m=0.3, focal_length_m=3.0)  # f/10


# --- apply_optics ------------------------------------------------------------------------------


def _small_psf(size: int = 9) -> np.ndarray:
    return psf_kernel(OPTICS, band_wavelengths_m(None, 4), None, 5e-6, size)


def test_apply_optics_conserves_power_and_flat_field():
    s = 2
    psf = _small_psf(9)
    img = np.zeros((64 * s, 80 * s))
    img[40:90, 50:120] = 3.0  # a uniform patch well inside the borders
    out = apply_optics(img, psf, s)
    assert out.shape == (64, 80)
    pixel_area, sample_area = 1.0, 1.0 / s**2  # relative areas
    assert out.sum() * pixel_area == pytest.approx(img.sum() * sample_area, rel=1e-6)
    # interior of the patch, farther than the kernel radius from its edges: unchanged
    interior = out[(40 + 4) // s + 1 : (90 - 4) // s - 1, (50 + 4) // s + 1 : (120 - 4) // s - 1]
    np.testing.assert_allclose(interior, 3.0, rtol=1e-12)


def test_apply_optics_fast_path_equals_full_convolution():
    rng = np.random.default_rng(7)
    s = 3
    psf = _small_psf(11)
    img = np.zeros((40 * s, 50 * s))
    y, x = np.indices(img.shape)
    blob = np.hypot(y - 50, x - 70) < 12
    img[blob] = rng.uniform(1.0, 2.0, blob.sum())
    img[2, 3] = 5.0  # near a corner: its blur is cut by the frame in both paths
    full = fftconvolve(img, psf, mode="same")
    full = np.maximum(full, 0).reshape(40, s, 50, s).mean(axis=(1, 3))
    fast = apply_optics(img, psf, s)
    np.testing.assert_allclose(fast, full, rtol=1e-6, atol=1e-6 * full.max())


def test_apply_optics_empty_frame_and_point_source():
    psf = _small_psf(9)
    out = apply_optics(np.zeros((30, 40), dtype=np.float32), psf, 1)
    assert out.dtype == np.float32
    assert not out.any()
    s = 3
    img = np.zeros((20 * s, 20 * s))
    img[10 * s + 1, 10 * s + 1] = 1.0  # centre sample of pixel (10, 10)
    out = apply_optics(img, psf, s)
    padded = np.zeros((21 * s, 21 * s))
    c = 10 * s + 1
    padded[c - 4 : c + 5, c - 4 : c + 5] = psf
    expected = padded[: 20 * s, : 20 * s].reshape(20, s, 20, s).mean(axis=(1, 3))
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-15)
    assert out.sum() == pytest.approx(1.0 / s**2, rel=1e-9)


def test_apply_optics_rejects_bad_input():
    psf = _small_psf(9)
    with pytest.raises(SatsightError, match="not a whole number of 2 x 2 blocks"):
        apply_optics(np.zeros((31, 40)), psf, 2)
    with pytest.raises(SatsightError, match="odd sizes"):
        apply_optics(np.zeros((30, 40)), np.ones((4, 4)) / 16, 1)
    with pytest.raises(SatsightError, match="must be a 2-D float image"):
        apply_optics(np.zeros((30, 40, 3)), psf, 1)


def _textured_scene(shape: tuple[int, int], dtype: type) -> np.ndarray:
    """A textured extended target, a few point sources and empty space around them."""
    rng = np.random.default_rng(11)
    img = np.zeros(shape, dtype=dtype)
    h, w = shape
    img[h // 5 : 3 * h // 4, w // 6 : w // 2] = rng.uniform(
        0.1, 1.0, (3 * h // 4 - h // 5, w // 2 - w // 6)
    )
    img[rng.integers(0, h, 20), rng.integers(0, w, 20)] = 5.0
    img[h - 1, w - 1] = 2.0  # in the corner: the blur is cut by the frame
    return img


@pytest.mark.parametrize("s", [1, 2])
def test_apply_optics_float32_matches_fftconvolve_for_any_thread_count(s):
    # 900 x 1500 samples: several row and column bands of the banded FFT. The reference is
    # scipy's fftconvolve of the whole frame in float32; the two differ by FFT round-off
    # (~1e-7 relative per term, a few e-7 of the peak after ~20 butterfly levels).
    psf = psf_kernel(OPTICS, band_wavelengths_m(None, 4), None, 5e-6 / s, 15)
    img = _textured_scene((900, 1500), np.float32)
    ref = fftconvolve(img, psf.astype(np.float32), mode="same")
    ref = np.maximum(ref, 0).reshape(900 // s, s, 1500 // s, s).mean(axis=(1, 3))
    outs = [apply_optics(img, psf, s, threads=k) for k in (1, 2, 3)]
    assert outs[0].dtype == np.float32
    np.testing.assert_allclose(outs[0], ref, rtol=0, atol=4e-6 * float(ref.max()))
    assert outs[1].tobytes() == outs[0].tobytes()
    assert outs[2].tobytes() == outs[0].tobytes()


def test_fft_convolve_same_matches_direct_convolution():
    # Float64 against scipy's direct (non-FFT) convolution: non-symmetric kernels, an image
    # split into several bands, and a kernel larger than the image.
    rng = np.random.default_rng(12)
    img = rng.uniform(0.0, 1.0, (700, 1500))
    kern = rng.uniform(0.0, 1.0, (15, 9))
    direct = convolve2d(img, kern, mode="same")
    np.testing.assert_allclose(fft_convolve_same(img, kern, threads=2), direct, rtol=1e-10)
    small = rng.uniform(0.0, 1.0, (5, 7))
    big_kernel = rng.uniform(0.0, 1.0, (15, 11))
    np.testing.assert_allclose(
        fft_convolve_same(small, big_kernel),
        fftconvolve(small, big_kernel, mode="same"),
        rtol=1e-10,
    )
    np.testing.assert_allclose(
        fft_convolve_same(small, big_kernel),
        convolve2d(small, big_kernel, mode="same"),
        rtol=1e-10,
    )


def test_apply_optics_with_a_known_signal_box_equals_the_scanned_result() -> None:
    psf = psf_kernel(Optics.for_preset("high_resolution"), band_wavelengths_m(), None, 15e-6, 15)
    image = np.zeros((60, 70), np.float32)
    image[20:31, 25:41] = np.random.default_rng(3).uniform(0.1, 1.0, (11, 16))
    scanned = apply_optics(image, psf)
    boxed = apply_optics(image, psf, signal_box=(20, 31, 25, 41))
    np.testing.assert_array_equal(boxed, scanned)
    # A larger box (still holding all the signal) gives the same image to round-off.
    np.testing.assert_allclose(
        apply_optics(image, psf, signal_box=(5, 50, 10, 60)), scanned, atol=1e-6 * scanned.max()
    )
    with pytest.raises(SatsightError, match="signal_box"):
        apply_optics(image, psf, signal_box=(30, 20, 0, 10))


# --- the margin ring ---------------------------------------------------------------------------


def _frame_kernel_f7() -> np.ndarray:
    from satsight.sensor.psf import frame_kernel

    return frame_kernel(Optics.for_preset("wide_field"), band_wavelengths_m(), None, 15e-6, 41)


@pytest.mark.parametrize("s", [1, 2])
def test_apply_optics_with_a_margin_is_the_inner_part_of_the_whole_convolution(s):
    # The frame plus a ring m pixels wide, blurred: the frame's pixels must equal the same
    # pixels of the whole padded image blurred without a margin (FFT round-off apart).
    m = 6
    psf = psf_kernel(OPTICS, band_wavelengths_m(None, 4), None, 5e-6 / s, 2 * 5 * s + 1)
    rng = np.random.default_rng(21)
    padded = np.zeros(((30 + 2 * m) * s, (40 + 2 * m) * s))
    padded[: 12 * s, : 20 * s] = rng.uniform(0.5, 1.0, (12 * s, 20 * s))  # into the ring
    padded[-3 * s :, -2 * s :] = 2.0  # in the ring's far corner
    whole = apply_optics(padded, psf, s)
    framed = apply_optics(padded, psf, s, margin_px=m)
    assert framed.shape == (30, 40)
    np.testing.assert_allclose(framed, whole[m:-m, m:-m], rtol=0, atol=1e-12 * whole.max())
    # Light only in the ring, within the kernel's reach, still reaches the frame.
    ring_only = np.zeros_like(padded)
    ring_only[m * s - 2, 10 * s : 20 * s] = 1.0
    out = apply_optics(ring_only, psf, s, margin_px=m)
    assert out[0].max() > 0
    expected = apply_optics(ring_only, psf, s)[m:-m, m:-m]
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)


def test_apply_optics_with_a_margin_reads_a_uniform_scene_uniform_to_the_corners():
    # A scene that fills the frame and the ring: every frame pixel's kernel footprint lies on
    # the uniform input, so each reads the input times the taps' sum, 1 (float32 FFT
    # round-off, ~1e-7 of the value, bounded by 1e-5). Without the ring the edges read low.
    psf = _frame_kernel_f7()
    m = psf.shape[0] // 2
    padded = np.full((64 + 2 * m, 80 + 2 * m), 0.37, dtype=np.float32)
    out = apply_optics(padded, psf, margin_px=m)
    np.testing.assert_allclose(out, 0.37, rtol=1e-5)
    bare = apply_optics(padded[m:-m, m:-m], psf)
    # The expected losses are the taps beyond the frame's edge, from the taps' defining
    # integral (kernel_taps.edge_and_corner_loss). The designed taps differ from those by
    # < 3e-6 each (test_psf), so a sum of at most 41 x 20 taps by < 2.5e-3; float32 FFT
    # round-off adds ~1e-6. Tolerance 2.5e-3.
    edge, corner = edge_and_corner_loss(
        frame_kernel_taps(Optics.for_preset("wide_field"), band_wavelengths_m(), 15e-6, 41)
    )
    assert bare[32, 0] / 0.37 == pytest.approx(1 - edge, abs=2.5e-3)  # edge row: -10.3 %
    assert bare[0, 0] / 0.37 == pytest.approx(1 - corner, abs=2.5e-3)  # corner: -18.9 %


def test_apply_optics_with_a_margin_skips_light_beyond_the_kernel_reach():
    psf = _small_psf(9)  # radius 4
    padded = np.zeros((40, 50))
    padded[:3, :] = 5.0  # 10 - 3 = 7 rows outside a frame behind a 10-pixel ring
    out = apply_optics(padded, psf, margin_px=10)
    assert out.shape == (20, 30)
    assert not out.any()
    with pytest.raises(SatsightError, match="ring"):
        apply_optics(padded, psf, margin_px=20)
    with pytest.raises(SatsightError, match="margin_px"):
        apply_optics(padded, psf, margin_px=-1)


def test_apply_optics_with_the_frame_kernel_conserves_power():
    # Taps summing to 1 conserve the power of the blur; the dips below 0 beside bright
    # pixels are taken back from the positive pixels within the kernel's radius instead of
    # being clipped away (which added the negative taps' share, 9 % at f/7, to a lone
    # bright pixel). What can still change the sum: a pixel asked for more than it holds,
    # and float32 round-off (~1e-7 per pixel summed). Bound: 1e-5 of the power for a
    # patch, a lone pixel and a 2 x 2 target (the task's budget is 0.5 %).
    psf = _frame_kernel_f7()
    for rows, cols in ((slice(40, 70), slice(50, 90)), (30, 40), (slice(30, 32), slice(40, 42))):
        for dtype in (np.float64, np.float32):
            img = np.zeros((120, 140), dtype=dtype)
            img[rows, cols] = 2.0
            out = apply_optics(img, psf)
            assert out.min() >= 0.0
            assert float(out.sum()) == pytest.approx(float(img.sum()), rel=1e-5)
    # Clipping would have added the negative taps' share: the kernel has them.
    assert -psf[psf < 0].sum() > 0.08


def test_fill_negative_lobes_takes_each_dip_from_the_positive_values_around_it():
    # A dip of -1 beside values 3 and 1 (within reach), a far value 5 out of reach (radius
    # 1): the dip is shared 3 : 1, so they keep 2.25 and 0.75; the far one is untouched.
    row = np.array([[0.0, 3.0, -1.0, 1.0, 0.0, 0.0, 5.0]])
    fill_negative_lobes(row, 1)
    np.testing.assert_allclose(row, [[0.0, 2.25, 0.0, 0.75, 0.0, 0.0, 5.0]], atol=1e-15)
    # A dip with nothing positive within reach is dropped (the sum rises by it).
    lone = np.array([[-0.5, 0.0, 0.0, 2.0]])
    fill_negative_lobes(lone, 1)
    np.testing.assert_array_equal(lone, [[0.0, 0.0, 0.0, 2.0]])
