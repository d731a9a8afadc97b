"""The memory a run needs for its frame size, checked against the machine's before anything
heavy is loaded.

A frame's buffers grow with its pixel count: the renderer's radiance, depth, normal,
part-id and mask images, the sensor chain's float64 copies (optics, photons, electrons,
noise), the DN image, the encoded files, and up to 2 frames in flight at once (one
rendering while the one before is sensed and written; 3 when these figures were measured,
so they now overestimate by about a frame's buffers, ~0.5 GB at 4096^2, which errs on the
safe side). Measured with ``benchmarks/frame_memory.py``
(peak resident set size of ``satsight generate``, 6 frames of the example scenario at
1024^2, 2048^2 and 4096^2 px, 2-core CPU, ``llvm_ad_rgb``): about 0.7 GB fixed
(interpreter, Mitsuba, Dr.Jit's kernels, the mesh) plus 164 bytes a pixel with the lean
outputs and 175 with all of them; neither samples per pixel nor supersampling changes it
(passes accumulate into the same buffers). ``FIXED_BYTES`` and ``BYTES_PER_PIXEL`` round
these up.

The machine's memory is ``MemAvailable`` of ``/proc/meminfo`` (memory the kernel can hand
out without swapping), or less where a cgroup (container) limit leaves less. The
environment variable ``SATSIGHT_MEMORY_LIMIT_GB`` replaces it: a number of gigabytes to
count on (a machine with swap, a figure known better), or ``off`` for no check.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from satsight.errors import SatsightError

#: Memory of a run whatever its frame size, bytes (measured 0.67-0.71 GB).
FIXED_BYTES = 0.75e9
#: Memory per pixel of the frame, bytes (measured 164-175).
BYTES_PER_PIXEL = 180.0
#: The variable that replaces the machine's available memory (GB, or "off").
MEMORY_LIMIT_VARIABLE = "SATSIGHT_MEMORY_LIMIT_GB"
_GB = 1e9


def frame_memory_bytes(width_px: int, height_px: int) -> float:
    """Estimated peak memory (bytes) of a run that renders width x height px frames."""
    return FIXED_BYTES + BYTES_PER_PIXEL * float(width_px) * float(height_px)


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


def largest_frame_px(width_px: int, height_px: int, limit_bytes: float) -> tuple[int, int]:
    """The largest frame of the same shape (aspect ratio) whose estimate fits in
    ``limit_bytes``; (0, 0) where not even the fixed cost fits."""
    pixels = (limit_bytes - FIXED_BYTES) / BYTES_PER_PIXEL
    if pixels < 1:
        return 0, 0
    scale = math.sqrt(pixels / (float(width_px) * float(height_px)))
    width, height = int(width_px * scale), int(height_px * scale)
    while width > 0 and height > 0 and frame_memory_bytes(width, height) > limit_bytes:
        width, height = width - 1, height - 1  # rounding at the edge
    return max(width, 0), max(height, 0)


def check_frame_memory(
    width_px: int, height_px: int, limit_bytes: float | None = None, environ: dict | None = None
) -> None:
    """Refuse a frame size whose estimated run memory is more than the machine has.

    limit_bytes: the memory to count on (default: ``memory_limit_bytes``, which reads
    ``SATSIGHT_MEMORY_LIMIT_GB`` from ``environ``, default ``os.environ``).
    """
    if limit_bytes is None:
        limit_bytes = memory_limit_bytes(environ)
        if limit_bytes is None:  # "off", or nothing readable: no check
            return
    need = frame_memory_bytes(width_px, height_px)
    if need <= limit_bytes:
        return
    width, height = largest_frame_px(width_px, height_px, limit_bytes)
    fits = (
        f"the largest frame of this shape that fits is {width} x {height} px"
        if width and height
        else "no frame fits"
    )
    raise SatsightError(
        f"camera.width_px x camera.height_px = {width_px} x {height_px} px needs about "
        f"{need / _GB:.1f} GB of memory ({FIXED_BYTES / _GB:.2f} GB + "
        f"{BYTES_PER_PIXEL:.0f} bytes a pixel, measured), but {limit_bytes / _GB:.1f} GB is "
        f"available; {fits}: lower camera.width_px and camera.height_px (or render on a "
        f"machine with more memory; {MEMORY_LIMIT_VARIABLE}=<GB> sets the memory to count "
        "on, 'off' skips this check)"
    )
