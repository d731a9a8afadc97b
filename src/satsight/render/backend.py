"""Choose and start the Mitsuba 3 / Dr.Jit variant.

``llvm_ad_rgb`` runs on the CPU through a shared libLLVM; ``cuda_ad_rgb`` runs on an NVIDIA
GPU and is chosen automatically when one answers. Dr.Jit needs LLVM >= 16 here: Debian 12's
LLVM 15 crashes at the first kernel, so when ``DRJIT_LIBLLVM_PATH`` is unset we point it at
the newest libLLVM found on the system before Dr.Jit is imported.

Mitsuba's variant is process-wide state; this module is the only place that sets it.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache

from satsight.errors import SatsightError

CPU_VARIANT = "llvm_ad_rgb"
GPU_VARIANT = "cuda_ad_rgb"
_MIN_LLVM_MAJOR = 16
_LIB_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
)


def find_libllvm() -> str | None:
    """Path of the newest shared libLLVM with major version >= 16, or None."""
    best: tuple[int, str] | None = None
    for directory in _LIB_DIRS:
        for path in glob.glob(os.path.join(directory, "libLLVM*.so*")):
            match = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
            if match and int(match.group(1)) >= _MIN_LLVM_MAJOR:
                major = int(match.group(1))
                if best is None or major > best[0]:
                    best = (major, path)
    return None if best is None else best[1]


def _prepare_llvm_environment() -> None:
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    path = find_libllvm()
    if path is not None:
        os.environ["DRJIT_LIBLLVM_PATH"] = path


@cache
def _cuda_works() -> bool:
    """Whether Mitsuba's CUDA variant exists and a kernel runs on an NVIDIA GPU."""
    import mitsuba as mi

    if GPU_VARIANT not in mi.variants():
        return False
    previous = mi.variant()
    try:
        mi.set_variant(GPU_VARIANT)
        import drjit as dr

        value = dr.cuda.Float(1.0, 2.0) + 1.0
        dr.eval(value)
        return True
    except Exception:
        return False
    finally:
        if previous is not None:
            mi.set_variant(previous)


def gpu_available() -> bool:
    """True when the ``cuda_ad_rgb`` variant can run here."""
    _prepare_llvm_environment()
    return _cuda_works()


def use_variant(requested: str = "auto") -> str:
    """Start Mitsuba with a variant and return its name.

    requested: ``"auto"`` (CUDA when an NVIDIA GPU works, else LLVM on the CPU),
    ``"llvm_ad_rgb"`` or ``"cuda_ad_rgb"``. The environment variable ``SATSIGHT_VARIANT``
    overrides ``"auto"``; ``SATSIGHT_RENDER_THREADS`` (a whole number >= 1) sets the CPU
    backend's thread count (default: one per core), for several satsight processes sharing
    a machine, where threads beyond the cores wait on each other. Renders do not depend on
    the thread count.
    """
    if requested == "auto":
        requested = os.environ.get("SATSIGHT_VARIANT", "auto")
    if requested not in ("auto", CPU_VARIANT, GPU_VARIANT):
        raise SatsightError(
            f"unknown render variant '{requested}'; use 'auto', '{CPU_VARIANT}' or '{GPU_VARIANT}'"
        )
    _prepare_llvm_environment()
    import mitsuba as mi

    if requested in ("auto", GPU_VARIANT) and _cuda_works():
        mi.set_variant(GPU_VARIANT)
        return GPU_VARIANT
    if requested == GPU_VARIANT:
        raise SatsightError(
            "the CUDA variant was requested but no working NVIDIA GPU/driver was found; "
            f"use '{CPU_VARIANT}' or 'auto'"
        )
    try:
        mi.set_variant(CPU_VARIANT)
        _llvm_works()
        _limit_cpu_threads()
    except SatsightError:
        raise
    except Exception as exc:  # pragma: no cover - depends on the system's LLVM
        raise SatsightError(
            "Dr.Jit's CPU backend could not start (it needs a shared libLLVM >= 16). "
            "On Debian/Ubuntu run: sudo apt-get install libllvm19 "
            "(or set DRJIT_LIBLLVM_PATH to a libLLVM.so). Cause: " + str(exc)
        ) from exc
    return CPU_VARIANT


def machine_cores() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    return cores or os.cpu_count() or 1


@contextmanager
def render_threads_beside_other_work(variant: str) -> Iterator[None]:
    """Within the block, the CPU backend renders on one thread fewer than the cores (at
    least one, and never more than it had), for a run whose other stages (the sensor, the
    file encoders) work beside the renderer; then its thread count is put back. Nothing
    changes with the CUDA variant or with ``SATSIGHT_RENDER_THREADS`` set.

    Dr.Jit's workers wait for the next kernel by spinning, for tens of milliseconds, and
    the thread that launches a kernel computes with them until it ends: with one worker
    per core, the spinning takes the cores from the other stages. Measured on 2 cores, 20
    frames of the RSSF example at 4096 x 4112 with lean outputs: one worker thread, 0.62 s
    a frame end to end, against 0.97 s with two; rendered alone, the frames took 7 % longer
    on one worker than on two."""
    if variant != CPU_VARIANT or os.environ.get("SATSIGHT_RENDER_THREADS", "").strip():
        yield
        return
    import drjit as dr

    previous = dr.thread_count()
    dr.set_thread_count(min(previous, max(1, machine_cores() - 1)))
    try:
        yield
    finally:
        dr.set_thread_count(previous)


def release_render_memory(variant: str) -> None:
    """Hand the buffers the renderer has freed, which Dr.Jit keeps for its next kernels,
    back to the system (CPU variant; nothing with CUDA, whose memory is the GPU's). A
    4096 x 4112 frame's render leaves about 0.3 GB of them behind its images."""
    if variant != CPU_VARIANT:
        return
    import drjit as dr

    dr.flush_malloc_cache()


def _limit_cpu_threads() -> None:
    """Dr.Jit's CPU threads from ``SATSIGHT_RENDER_THREADS``, when it is set."""
    text = os.environ.get("SATSIGHT_RENDER_THREADS", "").strip()
    if not text:
        return
    if not text.isdigit() or int(text) < 1:
        raise SatsightError(
            f"SATSIGHT_RENDER_THREADS must be a whole number >= 1, got {text!r}; "
            "unset it for one thread per core"
        )
    import drjit as dr

    dr.set_thread_count(int(text))


@cache
def _llvm_works() -> None:
    import drjit as dr

    dr.eval(dr.llvm.Float(1.0, 2.0) + 1.0)
