"""Applying a blur kernel to a focal-plane image: windowed, banded FFT convolution.

The kernels come from ``satsight.sensor.psf``. The convolution is linear (zero outside the
image given), so the light just outside a frame reaches its edge pixels only when the image
carries a margin ring around the frame (``apply_optics(margin_px=...)``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.fft

from satsight.errors import SatsightError
from satsight.sensor.threads import check_threads, run_jobs

_FFT_BAND_ELEMENTS = 1 << 18
"""Elements per band of the banded FFT convolution (about 256 rows of a 1000-wide window)."""

NEGATIVE_LOBE_RADIUS_PX = 20
"""Default half-width (px) of the square neighbourhood from which a pixel of a blurred frame
that dips below 0 takes back its deficit (``fill_negative_lobes``); ``apply_optics`` uses
the kernel's own radius, so every dip of a bright pixel's blur has that pixel within reach.
Smaller squares leave dips with only dips around them (the frame kernel's outer taps
alternate in sign): a lone bright pixel then keeps 0.50 / 0.22 / 0.08 % of its power too much
for half-widths of 2 / 4 / 6 px (f/7). The running box sums cost the same for any size."""

_LOBE_BAND_ROWS = 256
"""Rows per band of ``fill_negative_lobes`` (bounds its float64 temporaries)."""

_ROUND_OFF_DIP = 1e-6
"""Dips shallower than this fraction of a blurred image's peak are the FFT's round-off
(float32: ~1e-7 of the values it sums): ``fill_negative_lobes`` clips them instead."""


def _box_sum(a: np.ndarray, r: int) -> np.ndarray:
    """Sums of ``a`` (2-D) over the (2 r + 1)^2 squares centred on each element, zero
    outside; float64 running sums along each axis."""
    k = 2 * r + 1
    c = np.cumsum(np.pad(a, ((r + 1, r), (0, 0))), axis=0, dtype=np.float64)
    rows = c[k:] - c[: c.shape[0] - k]
    c = np.cumsum(np.pad(rows, ((0, 0), (r + 1, r))), axis=1)
    return c[:, k:] - c[:, : c.shape[1] - k]


def _runs(flags: np.ndarray, grow: int) -> list[tuple[int, int]]:
    """[start, end) of the runs of True in the 1-D ``flags`` grown by ``grow`` each way."""
    n = flags.size
    counts = np.cumsum(np.concatenate([[0], flags.astype(np.int64)]))
    index = np.arange(n)
    grown = counts[np.minimum(index + grow + 1, n)] - counts[np.maximum(index - grow, 0)] > 0
    edges = np.flatnonzero(np.diff(np.concatenate([[False], grown, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def fill_negative_lobes(image: np.ndarray, radius_px: int = NEGATIVE_LOBE_RADIUS_PX) -> None:
    """Make a blurred image non-negative in place, keeping its sum where it can.

    A kernel with negative taps (``satsight.sensor.psf.frame_kernel``) makes dips below 0
    beside bright, isolated pixels. Clipping them at 0 would add their deficit to the
    image (+9 % for a lone bright pixel). Instead each negative pixel j takes its deficit
    d_j back from the positive values P around it, in proportion to them: with W(j) the
    (2 r + 1)^2 square around j and Q_j = sum_{i in W(j)} P_i, pixel i keeps
    P_i (1 - sum_{j: i in W(j)} d_j / Q_j). The total taken is sum_j d_j exactly (each d_j is
    shared out over its Q_j); a pixel asked for more than it holds stops at 0, and a dip
    with no positive value within reach (far, faint wings) is dropped, the only two ways
    the sum can change. Dips shallower than ``_ROUND_OFF_DIP`` of the image's peak are
    the FFT's round-off and are clipped (at most that fraction of the peak per pixel).
    Rows are done in bands with a 2 r halo, and in each band only the runs of columns
    within 2 r of a dip, so the work follows the dips (a target's edges, or a whole
    textured Earth), not the frame.
    """
    r = int(radius_px)
    h = image.shape[0]
    peak = float(image.max()) if image.size else 0.0
    threshold = -_ROUND_OFF_DIP * peak
    dips = image < threshold if peak > 0.0 else np.zeros(image.shape, dtype=bool)
    dip_rows = np.flatnonzero(dips.any(axis=1))
    updates = []
    if dip_rows.size:
        lo, hi = max(int(dip_rows[0]) - r, 0), min(int(dip_rows[-1]) + r + 1, h)
        for a in range(lo, hi, _LOBE_BAND_ROWS):
            b = min(a + _LOBE_BAND_ROWS, hi)
            a0, b0 = max(a - 2 * r, 0), min(b + 2 * r, h)
            # The dips that can reach rows [a, b), and the columns that give to them.
            reaching = dips[max(a - r, 0) : min(b + r, h)].any(axis=0)
            for c0, c1 in _runs(reaching, 2 * r):
                block = image[a0:b0, c0:c1].astype(np.float64)
                positive = np.maximum(block, 0.0)
                deficit = np.where(block < threshold, -block, 0.0)
                share = _box_sum(positive, r)
                ratio = np.divide(deficit, share, out=np.zeros_like(share), where=share > 0)
                taken = _box_sum(ratio, r)
                kept = positive * np.maximum(1.0 - taken, 0.0)
                updates.append((a, b, c0, c1, kept[a - a0 : b - a0]))
    for a, b, c0, c1, rows in updates:
        image[a:b, c0:c1] = rows
    np.maximum(image, 0, out=image)  # round-off dips, and rows out of every dip's reach


def _window(lo: int, hi: int, radius: int, size: int, margin: int, s: int) -> tuple:
    """Along one axis (samples): the output span [o0, o1) to compute (within reach of the
    signal [lo, hi), inside the frame [margin, size - margin)) and the span [a, b) to
    convolve (it holds that output span and all the signal within reach of it), both on
    whole s-blocks."""
    o0 = max(lo - radius, margin) // s * s
    o1 = -(-min(hi + radius, size - margin) // s) * s
    a = min(o0, max(lo, o0 - radius)) // s * s
    b = min(-(-max(o1, min(hi, o1 + radius)) // s) * s, size)
    return o0, o1, a, b


def apply_optics(
    irradiance_w_m2: np.ndarray,
    psf: np.ndarray,
    supersampling: int = 1,
    *,
    threads: int | None = None,
    signal_box: tuple[int, int, int, int] | None = None,
    margin_px: int = 0,
) -> np.ndarray:
    """Blur a supersampled focal-plane irradiance image by a kernel and bin it into pixels.

    irradiance_w_m2: (H * s, W * s) focal-plane irradiance (W m^-2) on the supersampled grid
    (s = supersampling), or, with ``margin_px`` = m > 0, ((H + 2 m) s, (W + 2 m) s): the frame
    with a ring m pixels wide around it (the light just outside the frame, which the kernel
    spreads into its edge pixels). psf: 2-D kernel on the same grid, odd size, normally
    summing to 1 (``satsight.sensor.psf``), so that power is conserved away from the
    borders. The convolution is the linear, "same"-size convolution of
    ``scipy.signal.fftconvolve(mode="same")`` (zero outside the image given: without a ring
    at least the kernel's radius wide, edge pixels miss the light from beyond the frame and
    read low), computed by FFT in the image's precision (see ``fft_convolve_same``); then
    each s x s block is averaged, so each output pixel holds the pixel-averaged irradiance
    (W m^-2) and pixel power = value x pixel area. Only the bounding box of the non-zero
    input, padded by the kernel radius, is convolved (the rest of the frame is empty space
    and stays exactly 0); an all-zero frame returns zeros without convolving. Values below
    zero (the dips of a kernel with negative taps beside bright, isolated pixels, and FFT
    round-off) are taken back from the positive pixels within the kernel's radius of them,
    keeping the frame's sum (``fill_negative_lobes``), after the binning.
    ``threads`` (default: all cores) does not change the result. ``signal_box`` = (row0, row1,
    col0, col1), end exclusive, on the supersampled grid of the whole input: a box known to
    hold every non-zero sample, which saves the scan for it (a box too small loses light).
    Returns the frame, (H, W), in the input's float dtype.
    """
    img = np.asarray(irradiance_w_m2)
    kern = np.asarray(psf, dtype=np.float64)
    if img.ndim != 2 or not np.issubdtype(img.dtype, np.floating):
        raise SatsightError(
            "irradiance_w_m2 must be a 2-D float image (H*s, W*s); "
            f"got shape {img.shape}, dtype {img.dtype}"
        )
    if kern.ndim != 2 or kern.shape[0] % 2 == 0 or kern.shape[1] % 2 == 0:
        raise SatsightError(
            f"psf must be a 2-D kernel with odd sizes (centred); got shape {kern.shape}. "
            "Build it with psf_kernel or frame_kernel (size_px odd)."
        )
    if isinstance(supersampling, bool) or int(supersampling) != supersampling or supersampling < 1:
        raise SatsightError(f"supersampling must be a positive integer; got {supersampling!r}")
    n_threads = check_threads(threads)
    s = int(supersampling)
    hs, ws = img.shape
    if hs % s or ws % s:
        raise SatsightError(
            f"the supersampled image {img.shape} is not a whole number of {s} x {s} blocks; "
            "render at (H * s, W * s)."
        )
    if isinstance(margin_px, bool) or int(margin_px) != margin_px or margin_px < 0:
        raise SatsightError(f"margin_px must be a whole number >= 0; got {margin_px!r}")
    m = int(margin_px)
    if hs // s <= 2 * m or ws // s <= 2 * m:
        raise SatsightError(
            f"an image of {hs // s} x {ws // s} pixels cannot hold a frame inside a ring "
            f"{m} pixels wide; pass the frame plus its ring, or margin_px=0"
        )
    out = np.zeros((hs // s - 2 * m, ws // s - 2 * m), dtype=img.dtype)
    if signal_box is None:
        rows = np.flatnonzero(np.any(img != 0, axis=1))
        if rows.size == 0:
            return out
        cols = np.flatnonzero(np.any(img[rows[0] : rows[-1] + 1] != 0, axis=0))
    else:
        b0, b1, b2, b3 = (int(v) for v in signal_box)
        if not (0 <= b0 < b1 <= hs and 0 <= b2 < b3 <= ws):
            raise SatsightError(
                f"signal_box must be (row0, row1, col0, col1) inside the {hs} x {ws} image "
                f"with row0 < row1 and col0 < col1; got {signal_box!r}"
            )
        rows, cols = np.array([b0, b1 - 1]), np.array([b2, b3 - 1])
    ms = m * s
    ry, rx = kern.shape[0] // 2, kern.shape[1] // 2
    row_lo, row_hi = int(rows[0]), int(rows[-1]) + 1
    col_lo, col_hi = int(cols[0]), int(cols[-1]) + 1
    o0, o1, _, _ = _window(row_lo, row_hi, ry, hs, ms, s)
    q0, q1, _, _ = _window(col_lo, col_hi, rx, ws, ms, s)
    if o0 >= o1 or q0 >= q1:  # all the light is too far outside the frame to reach it
        return out
    # The blur over the frame and its ring (within reach of the light), so that a dip in the
    # frame can take its deficit back from light in the ring; then the frame is cut out.
    o0, o1, r0, r1 = _window(row_lo, row_hi, ry, hs, 0, s)
    q0, q1, c0, c1 = _window(col_lo, col_hi, rx, ws, 0, s)
    whole = out if m == 0 else np.zeros((hs // s, ws // s), dtype=img.dtype)
    target = whole[o0 // s : o1 // s, q0 // s : q1 // s]

    def finish(band_r0: int, blurred: np.ndarray) -> None:
        """Bin a band of blurred rows (a multiple of s), its part in the output span, into
        ``target``."""
        top = r0 + band_r0
        lo, hi = max(top, o0), min(top + blurred.shape[0], o1)
        if lo >= hi:
            return
        block = blurred[lo - top : hi - top, q0 - c0 : q1 - c0]
        pixels = target[(lo - o0) // s : (hi - o0) // s]
        if s == 1:
            pixels[...] = block
        else:
            h, w = block.shape
            pixels[...] = block.reshape(h // s, s, w // s, s).mean(axis=(1, 3))

    fft_convolve_same(img[r0:r1, c0:c1], kern, threads=n_threads, row_multiple=s, sink=finish)
    fill_negative_lobes(target, max(ry, rx) // s)
    if m:
        out[...] = whole[m : hs // s - m, m : ws // s - m]
    return out


def fft_convolve_same(
    image: np.ndarray,
    kernel: np.ndarray,
    *,
    threads: int | None = None,
    row_multiple: int = 1,
    sink: Callable[[int, np.ndarray], None] | None = None,
) -> np.ndarray | None:
    """Linear convolution of ``image`` (H, W) with ``kernel`` (ky, kx), "same" size, by FFT.

    The same result as ``scipy.signal.fftconvolve(image, kernel, mode="same")`` up to FFT
    round-off (float32 images are transformed in single precision, as scipy does; float64 in
    double): out[i, j] = sum_ab image[i + (ky - 1) // 2 - a, j + (kx - 1) // 2 - b] k[a, b],
    zero outside the image. Both axes are zero-padded to 5-smooth lengths M >= H + ky - 1 and
    N >= W + kx - 1, so the cyclic convolution of the FFTs is the linear one. The work is
    split into fixed bands (a function of the sizes only) run on ``threads`` threads
    (default: all cores): real FFTs of row bands, then per band of columns the column FFT,
    the product with the kernel's spectrum and the inverse column FFT, then inverse real FFTs
    of row bands. The kernel's spectrum is made per column band from the real FFT of its ky
    rows, as scipy makes it (no BLAS call: OpenBLAS's own threads would compete with these).

    With ``sink``, each band of output rows (a multiple of ``row_multiple`` rows except at
    the end) is passed to ``sink(first_row, rows)`` as it is made, the rows being a scratch
    array it may change, and None is returned; else the (H, W) result is returned.
    """
    img = np.asarray(image)
    real = np.float32 if img.dtype == np.float32 else np.float64
    img = img.astype(real, copy=False)
    kern = np.asarray(kernel, dtype=np.float64)
    if img.ndim != 2 or kern.ndim != 2 or 0 in img.shape or 0 in kern.shape:
        raise SatsightError(
            f"image and kernel must be non-empty 2-D arrays; got {img.shape} and {kern.shape}"
        )
    n_threads = check_threads(threads)
    complex_dtype = np.complex64 if real is np.float32 else np.complex128
    h, w = img.shape
    ky, kx = kern.shape
    oy, ox = (ky - 1) // 2, (kx - 1) // 2
    m = scipy.fft.next_fast_len(h + ky - 1)
    n = scipy.fft.next_fast_len(w + kx - 1, real=True)
    nf = n // 2 + 1
    kern_rows = scipy.fft.rfft(kern.astype(real), n, axis=1)  # (ky, nf), as scipy does
    spectrum = np.empty((h, nf), dtype=complex_dtype)
    result = np.empty((h, w), dtype=real) if sink is None else None
    step = max(1, _FFT_BAND_ELEMENTS // n)
    step = max(row_multiple, step // row_multiple * row_multiple)
    row_bands = [(a, min(a + step, h)) for a in range(0, h, step)]
    col_step = max(1, _FFT_BAND_ELEMENTS // m)
    col_bands = [(a, min(a + col_step, nf)) for a in range(0, nf, col_step)]

    def forward(i: int) -> None:
        a, b = row_bands[i]
        padded = np.zeros((b - a, n), dtype=real)  # faster than rfft's own zero-padding
        padded[:, :w] = img[a:b]
        spectrum[a:b] = scipy.fft.rfft(padded, axis=1)

    def columns(i: int) -> None:
        a, b = col_bands[i]
        block = scipy.fft.fft(spectrum[:, a:b], m, axis=0)
        block *= scipy.fft.fft(kern_rows[:, a:b], m, axis=0)
        spectrum[:, a:b] = scipy.fft.ifft(block, axis=0, overwrite_x=True)[oy : oy + h]

    def inverse(i: int) -> None:
        a, b = row_bands[i]
        rows = scipy.fft.irfft(spectrum[a:b], n, axis=1)[:, ox : ox + w]
        if sink is None:
            result[a:b] = rows
        else:
            sink(a, rows)

    run_jobs(forward, len(row_bands), n_threads)
    run_jobs(columns, len(col_bands), n_threads)
    run_jobs(inverse, len(row_bands), n_threads)
    return result
