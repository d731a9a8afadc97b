"""The memory a run needs for its frame size, checked against the machine's before anything
heavy is loaded, and the frames a local run keeps in flight within it.

A frame's buffers grow with its pixel count: the renderer's radiance, depth, normal,
part-id and mask images and its per-ray arrays, the sensor chain's float64 copies
(optics, photons, electrons, noise), the DN image and the encoded files. A local run
keeps two frames in flight when the memory allows (one rendering while the one before is
sensed and written, ``PIPELINED_FRAMES``), else makes them one at a time and hands the
renderer's freed buffers back to the system before each frame's sensor stage. Measured
with ``benchmarks/frame_memory.py`` (peak resident set size of ``satsight generate``,
frames of the example scenario at 1024^2, 2048^2 and 4096^2 px, 2-core CPU,
``llvm_ad_rgb``; see ``BYTES_PER_PIXEL`` and ``BYTES_PER_PIXEL_IN_FLIGHT``): a fixed
cost (interpreter, Mitsuba, Dr.Jit's kernels, the mesh) plus bytes per pixel for one frame
and for each further frame in flight; neither samples per pixel nor supersampling changes
it (passes accumulate into the same buffers). The constants round these up.

The machine's memory is ``MemAvailable`` of ``/proc/meminfo`` (memory the kernel can hand
out without swapping), or less where a cgroup (container) limit leaves less. The
environment variable ``SATSIGHT_MEMORY_LIMIT_GB`` replaces it: a number of gigabytes to
count on (a machine with swap, a figure known better, or a budget to keep a run within),
or ``off`` for no check.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
from functools import cache
from pathlib import Path

from satsight.errors import SatsightError

# A local run that makes one frame at a time (each stage in turn on one thread, the
# render's freed buffers and the freed heap handed back, ``satsight.run.local``): fits of
# 6 frames of the example at 1024^2 to 4096^2, 0.37 GB + 45.9 (lean) to 51.5 (all outputs)
# bytes a pixel. The constants round these up.
#: Memory of a run whatever its frame size, one frame at a time, bytes.
FIXED_BYTES = 0.4e9
#: Memory per pixel of a run that makes one frame at a time, bytes.
BYTES_PER_PIXEL = 60.0
# Each further frame in flight (two in flight, all outputs, after the grey Earth map and
# the half-float normals: 0.48 GB + 94.3-96.2 bytes a pixel, two runs; the RSSF example's
# 20 frames at 4096 x 4112 with all outputs, the Earth behind some, peaked at 2.13-2.19 GB).
#: Memory of each further frame in flight whatever its size (threads' heaps), bytes.
IN_FLIGHT_FIXED_BYTES = 0.1e9
#: Memory per pixel of each further frame in flight, bytes.
BYTES_PER_PIXEL_IN_FLIGHT = 50.0
# A process that makes one frame at a time and keeps Dr.Jit's buffers between frames: the
# Python interface (float32 normals) and a Dask worker (a 1-worker LocalCluster peaked at
# 0.64 GB at 128^2 px, 0.92 GB at 2048^2, 1.87 GB at 4096^2, 69-73 bytes a pixel over 0.75).
#: Memory of such a process whatever its frame size, bytes.
KEPT_FIXED_BYTES = 0.75e9
#: Memory per pixel of such a process, bytes.
KEPT_BYTES_PER_PIXEL = 80.0
#: Frames a local run keeps in flight when the memory allows: one renders while the one
#: before is sensed and written.
PIPELINED_FRAMES = 2
#: The variable that replaces the machine's available memory (GB, or "off").
MEMORY_LIMIT_VARIABLE = "SATSIGHT_MEMORY_LIMIT_GB"
_GB = 1e9


def frame_memory_bytes(
    width_px: int, height_px: int, frames_in_flight: int = 1, kept: bool = False
) -> float:
    """Estimated peak memory (bytes) of a local run that renders width x height px frames
    with ``frames_in_flight`` frames in flight at once; with ``kept``, of a process that
    makes one frame at a time and keeps Dr.Jit's buffers (the Python interface, a Dask
    worker)."""
    pixels = float(width_px) * float(height_px)
    if kept:
        return KEPT_FIXED_BYTES + KEPT_BYTES_PER_PIXEL * pixels
    more = frames_in_flight - 1
    fixed = FIXED_BYTES + IN_FLIGHT_FIXED_BYTES * more
    return fixed + (BYTES_PER_PIXEL + BYTES_PER_PIXEL_IN_FLIGHT * more) * pixels


def frames_in_flight(
    width_px: int, height_px: int, limit_bytes: float | None = None, environ: dict | None = None
) -> tuple[int, str | None]:
    """The frames a local run keeps in flight for width x height px frames:
    ``PIPELINED_FRAMES`` when their estimate fits in ``limit_bytes`` (default:
    ``memory_limit_bytes``, from ``environ``), else 1; and why, when 1 (else None)."""
    if limit_bytes is None:
        limit_bytes = memory_limit_bytes(environ)
    need = frame_memory_bytes(width_px, height_px, PIPELINED_FRAMES)
    if limit_bytes is None or need <= limit_bytes:
        return PIPELINED_FRAMES, None
    return 1, (
        f"frames are made one at a time: {PIPELINED_FRAMES} in flight at {width_px} x "
        f"{height_px} px would need about {need / _GB:.1f} GB, {limit_bytes / _GB:.1f} GB is "
        f"available (one at a time needs about "
        f"{frame_memory_bytes(width_px, height_px) / _GB:.1f} GB and is slower; "
        f"{MEMORY_LIMIT_VARIABLE}=<GB> sets the memory to count on)"
    )


def available_memory_bytes(
    meminfo: str | None = None, cgroup: Path | None = Path("/sys/fs/cgroup")
) -> float | None:
    """Memory the run may use (bytes): ``MemAvailable`` of ``/proc/meminfo`` (``meminfo``:
    its text), lowered to what a cgroup v2 limit in ``cgroup`` leaves (memory.max -
    memory.current); else ``os.sysconf``'s free pages; None where none can be read."""
    if meminfo is None:
        try:
            meminfo = Path("/proc/meminfo").read_text()
        except OSError:
            meminfo = ""
    available = None
    for line in meminfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "MemAvailable" and value.split():
            available = float(value.split()[0]) * 1024.0  # kB
    if available is None:
        try:
            available = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    if cgroup is not None:
        try:
            limit = (cgroup / "memory.max").read_text().strip()
            used = (cgroup / "memory.current").read_text().strip()
            if limit != "max":
                available = min(available, max(float(limit) - float(used), 0.0))
        except (OSError, ValueError):
            pass
    return available


def memory_limit_bytes(environ: dict | None = None) -> float | None:
    """The memory to compare with: ``SATSIGHT_MEMORY_LIMIT_GB`` when set (None for
    ``off``), else ``available_memory_bytes()``."""
    value = (os.environ if environ is None else environ).get(MEMORY_LIMIT_VARIABLE)
    if value is None or not value.strip():
        return available_memory_bytes()
    if value.strip().lower() == "off":
        return None
    try:
        gigabytes = float(value)
    except ValueError:
        gigabytes = math.nan
    if not (math.isfinite(gigabytes) and gigabytes > 0):
        raise SatsightError(
            f"{MEMORY_LIMIT_VARIABLE}={value!r}: expected a positive number of gigabytes "
            "(the memory a run may use) or 'off' (no frame-size check)"
        )
    return gigabytes * _GB


def largest_frame_px(
    width_px: int, height_px: int, limit_bytes: float, kept: bool = False
) -> tuple[int, int]:
    """The largest frame of the same shape (aspect ratio) whose estimate, one frame at a
    time (``kept``: see ``frame_memory_bytes``), fits in ``limit_bytes``; (0, 0) where not
    even the fixed cost fits."""
    fixed = KEPT_FIXED_BYTES if kept else FIXED_BYTES
    pixels = (limit_bytes - fixed) / (KEPT_BYTES_PER_PIXEL if kept else BYTES_PER_PIXEL)
    if pixels < 1:
        return 0, 0
    scale = math.sqrt(pixels / (float(width_px) * float(height_px)))
    width, height = int(width_px * scale), int(height_px * scale)
    while width > 0 and height > 0 and frame_memory_bytes(width, height, kept=kept) > limit_bytes:
        width, height = width - 1, height - 1  # rounding at the edge
    return max(width, 0), max(height, 0)


def check_frame_memory(
    width_px: int,
    height_px: int,
    limit_bytes: float | None = None,
    environ: dict | None = None,
    kept: bool = False,
) -> None:
    """Refuse a frame size whose estimated memory, one frame at a time, is more than the
    machine has.

    limit_bytes: the memory to count on (default: ``memory_limit_bytes``, which reads
    ``SATSIGHT_MEMORY_LIMIT_GB`` from ``environ``, default ``os.environ``). kept: the
    estimate of a process that keeps Dr.Jit's buffers between frames (``frame_memory_bytes``).
    """
    if limit_bytes is None:
        limit_bytes = memory_limit_bytes(environ)
        if limit_bytes is None:  # "off", or nothing readable: no check
            return
    need = frame_memory_bytes(width_px, height_px, kept=kept)
    if need <= limit_bytes:
        return
    width, height = largest_frame_px(width_px, height_px, limit_bytes, kept)
    fits = (
        f"the largest frame of this shape that fits is {width} x {height} px"
        if width and height
        else "no frame fits"
    )
    fixed, per_pixel = (
        (KEPT_FIXED_BYTES, KEPT_BYTES_PER_PIXEL) if kept else (FIXED_BYTES, BYTES_PER_PIXEL)
    )
    raise SatsightError(
        f"camera.width_px x camera.height_px = {width_px} x {height_px} px needs about "
        f"{need / _GB:.1f} GB of memory ({fixed / _GB:.2f} GB + "
        f"{per_pixel:.0f} bytes a pixel, measured), but {limit_bytes / _GB:.1f} GB is "
        f"available; {fits}: lower camera.width_px and camera.height_px (or render on a "
        f"machine with more memory; {MEMORY_LIMIT_VARIABLE}=<GB> sets the memory to count "
        "on, 'off' skips this check)"
    )


def return_freed_heap() -> None:
    """Hand the heap memory this process has freed back to the system (glibc's
    ``malloc_trim``; nothing where the C library has none). numpy's freed arrays below
    glibc's mmap threshold (up to 32 MB) stay in the heap otherwise; measured on the RSSF
    example at 4096 x 4112, one frame in flight: 0.1 GB less before each render."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@cache
def _malloc_trim():
    name = ctypes.util.find_library("c")
    try:
        return getattr(ctypes.CDLL(name), "malloc_trim", None) if name else None
    except OSError:
        return None
