"""Variant selection: libLLVM discovery, variant names, and CUDA against LLVM on a GPU."""

from __future__ import annotations

import ctypes
import math
import os
from pathlib import Path

import numpy as np
import pytest

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.lighting.light_field import SunLight
from satsight.poses.views import View
from satsight.render import backend
from satsight.render.backend import (
    CPU_VARIANT,
    GPU_VARIANT,
    find_libllvm,
    gpu_available,
    use_variant,
)
from satsight.render.direct import DirectRenderer
from satsight.scene.mesh import merge_parts
from satsight.scene.procedural import generate_satellite

MIN_LLVM_MAJOR = 16
AGREEMENT_FRACTION = 0.999
RADIANCE_RTOL = 1e-4
DEPTH_RTOL = 1e-5  # float32 depth of ~1 km, different rounding on CPU and GPU


# --- libLLVM ---------------------------------------------------------------------------------
def _llvm_version(path: str) -> tuple[int, int, int]:
    """The version the library itself reports (LLVMGetVersion exists from LLVM 16 on)."""
    lib = ctypes.CDLL(path)
    try:
        get_version = lib.LLVMGetVersion
    except AttributeError:
        return (0, 0, 0)  # older than 16
    major, minor, patch = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
    get_version(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch))
    return major.value, minor.value, patch.value


def test_find_libllvm_returns_a_library_of_version_16_or_newer() -> None:
    path = find_libllvm()
    if path is None:
        pytest.skip(
            f"no shared libLLVM >= {MIN_LLVM_MAJOR} in {', '.join(backend._LIB_DIRS)} "
            "(install e.g. libllvm19)"
        )
    assert os.path.isabs(path)
    assert Path(path).is_file()
    assert Path(path).name.startswith("libLLVM")
    assert _llvm_version(path)[0] >= MIN_LLVM_MAJOR


def test_find_libllvm_picks_the_newest_supported_major(tmp_path: Path, monkeypatch) -> None:
    lib_a, lib_b = tmp_path / "a", tmp_path / "b"
    lib_a.mkdir()
    lib_b.mkdir()
    for name in ("libLLVM-14.so", "libLLVM-15.so.1", "libLLVM-17.so", "libLLVMSupport.a"):
        (lib_a / name).write_bytes(b"")
    for name in ("libLLVM.so.18.1", "libLLVM-16.so.1", "libLLVM-9.so"):
        (lib_b / name).write_bytes(b"")
    monkeypatch.setattr(backend, "_LIB_DIRS", (str(lib_a), str(lib_b)))
    assert find_libllvm() == str(lib_b / "libLLVM.so.18.1")
    (lib_a / "libLLVM-20.so.1").write_bytes(b"")
    assert find_libllvm() == str(lib_a / "libLLVM-20.so.1")


def test_find_libllvm_ignores_versions_below_16(tmp_path: Path, monkeypatch) -> None:
    for name in ("libLLVM-14.so", "libLLVM-15.so", "libLLVM.so.15.0"):
        (tmp_path / name).write_bytes(b"")
    monkeypatch.setattr(backend, "_LIB_DIRS", (str(tmp_path), str(tmp_path / "missing")))
    assert find_libllvm() is None


def test_llvm_path_is_set_only_when_unset(monkeypatch, tmp_path: Path) -> None:
    (tmp_path / "libLLVM-18.so").write_bytes(b"")
    monkeypatch.setattr(backend, "_LIB_DIRS", (str(tmp_path),))
    # setenv first so that monkeypatch records (and restores) the original state even when
    # the variable was unset: _prepare_llvm_environment writes os.environ directly.
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "placeholder")
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH")
    backend._prepare_llvm_environment()
    assert os.environ["DRJIT_LIBLLVM_PATH"] == str(tmp_path / "libLLVM-18.so")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "/opt/my/libLLVM.so")
    backend._prepare_llvm_environment()
    assert os.environ["DRJIT_LIBLLVM_PATH"] == "/opt/my/libLLVM.so"


# --- variant names ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bogus", "scalar_rgb", "llvm_ad_spectral", ""])
def test_unknown_variant_is_refused(name: str) -> None:
    with pytest.raises(SatsightError, match="unknown render variant") as info:
        use_variant(name)
    assert CPU_VARIANT in str(info.value) and GPU_VARIANT in str(info.value)


def test_environment_variable_overrides_auto(monkeypatch, llvm_variant) -> None:
    monkeypatch.setenv("SATSIGHT_VARIANT", "bogus")
    with pytest.raises(SatsightError, match="'bogus'"):
        use_variant("auto")
    monkeypatch.setenv("SATSIGHT_VARIANT", CPU_VARIANT)
    assert use_variant("auto") == CPU_VARIANT


def test_llvm_variant_starts(llvm_variant) -> None:
    import mitsuba as mi

    assert llvm_variant == CPU_VARIANT
    assert use_variant(CPU_VARIANT) == CPU_VARIANT
    assert mi.variant() == CPU_VARIANT


def test_cuda_request_without_gpu_is_a_satsight_error(llvm_variant) -> None:
    if gpu_available():
        pytest.skip("a working NVIDIA GPU is present")
    with pytest.raises(SatsightError, match="no working NVIDIA GPU"):
        use_variant(GPU_VARIANT)
    use_variant(CPU_VARIANT)


# --- CUDA against LLVM -----------------------------------------------------------------------
def _plate_scene():
    v, f = plate_parts(size_m=2.0)
    mesh = merge_parts([("plate", "white_paint", v, f)], name="plate")
    camera = PinholeCamera(focal_length_m=0.5, pixel_pitch_m=15e-6, width_px=128, height_px=96)
    pose = View(1000.0, math.radians(30.0), math.radians(60.0)).cam_from_body(mesh.center_m)
    return mesh, camera, pose, SunLight(np.array([0.2, -0.1, 1.0]), 671.5)


def _satellite_scene():
    mesh = generate_satellite("two_wings_dish", seed=5)
    pitch, side = 15e-6, 256
    focal = 0.8 * side * pitch * 1500.0 / (2.0 * mesh.bounding_radius_m)
    camera = PinholeCamera(focal, pitch, side, side)
    pose = View(1500.0, math.radians(35.0), math.radians(25.0)).cam_from_body(mesh.center_m)
    return mesh, camera, pose, SunLight(np.array([0.5, -0.4, 0.75]), 671.5)


def _agreement(cuda, llvm) -> dict[str, float]:
    """Fractions of pixels on which the two renders agree, per output."""
    both = (cuda.part_id > 0) & (llvm.part_id > 0)
    depth_ok = np.where(
        both,
        np.abs(cuda.depth_m - llvm.depth_m) <= DEPTH_RTOL * np.maximum(llvm.depth_m, 1.0),
        cuda.depth_m == llvm.depth_m,
    )
    scale = float(llvm.radiance_w_m2_sr.max())
    close = np.abs(cuda.radiance_w_m2_sr - llvm.radiance_w_m2_sr) <= RADIANCE_RTOL * np.maximum(
        np.abs(llvm.radiance_w_m2_sr), 1e-6 * scale
    )
    return {
        "part_id": float(np.mean(cuda.part_id == llvm.part_id)),
        "depth": float(np.mean(depth_ok)),
        "radiance": float(np.mean(close.all(axis=-1))),
        "hits": int(both.sum()),
    }


def _render_both(scene, variants=(GPU_VARIANT, CPU_VARIANT)):
    mesh, camera, pose, sun = scene
    images = []
    for variant in variants:  # one renderer after the other: Mitsuba's variant is global
        renderer = DirectRenderer(mesh, variant)
        assert renderer.variant == variant
        images.append(renderer.render(camera, pose, sun))
    return images


@pytest.mark.gpu
@pytest.mark.parametrize("scene", [_plate_scene, _satellite_scene], ids=["plate", "satellite"])
def test_cuda_and_llvm_agree(scene) -> None:
    if not gpu_available():
        pytest.skip("no working NVIDIA GPU / cuda_ad_rgb variant on this machine")
    try:
        cuda, llvm = _render_both(scene())
    finally:
        use_variant(CPU_VARIANT)
    _check_agreement(cuda, llvm)


def _check_agreement(cuda, llvm) -> None:
    agreement = _agreement(cuda, llvm)
    assert agreement["hits"] > 500, agreement
    assert agreement["part_id"] >= AGREEMENT_FRACTION, agreement
    assert agreement["depth"] >= AGREEMENT_FRACTION, agreement
    assert agreement["radiance"] >= AGREEMENT_FRACTION, agreement
    assert np.mean(cuda.object_mask == llvm.object_mask) >= AGREEMENT_FRACTION


@pytest.mark.gpu
def test_cuda_and_llvm_plate_radiance_agree_everywhere_on_the_plate() -> None:
    """A flat plate has no shadows: every pixel both backends see matches to 1e-4."""
    if not gpu_available():
        pytest.skip("no working NVIDIA GPU / cuda_ad_rgb variant on this machine")
    try:
        cuda, llvm = _render_both(_plate_scene())
    finally:
        use_variant(CPU_VARIANT)
    both = cuda.object_mask & llvm.object_mask
    assert both.sum() > 500
    lit = llvm.radiance_w_m2_sr[both]
    assert lit.min() > 0
    np.testing.assert_allclose(cuda.radiance_w_m2_sr[both], lit, rtol=RADIANCE_RTOL, atol=0)
    np.testing.assert_allclose(cuda.depth_m[both], llvm.depth_m[both], rtol=DEPTH_RTOL, atol=0)


def test_agreement_check_passes_for_identical_llvm_renders(llvm_variant) -> None:
    """The comparison used on GPUs, run LLVM against LLVM: it must accept equal renders
    and reject a render with a different pose."""
    scene = _satellite_scene()
    first, second = _render_both(scene, (CPU_VARIANT, CPU_VARIANT))
    _check_agreement(first, second)
    mesh, camera, _, sun = scene
    moved = View(1500.0, math.radians(36.0), math.radians(25.0)).cam_from_body(mesh.center_m)
    other = DirectRenderer(mesh, CPU_VARIANT).render(camera, moved, sun)
    with pytest.raises(AssertionError):
        _check_agreement(other, first)


def test_render_threads_come_from_the_environment(llvm_variant, monkeypatch) -> None:
    """SATSIGHT_RENDER_THREADS sets the CPU backend's thread count; a bad value is one
    clear error."""
    import drjit as dr

    before = dr.thread_count()
    try:
        monkeypatch.setenv("SATSIGHT_RENDER_THREADS", "3")
        backend._limit_cpu_threads()
        assert dr.thread_count() == 3
        for bad in ("0", "two", "-1"):
            monkeypatch.setenv("SATSIGHT_RENDER_THREADS", bad)
            with pytest.raises(SatsightError, match="SATSIGHT_RENDER_THREADS must be a whole"):
                backend._limit_cpu_threads()
        monkeypatch.delenv("SATSIGHT_RENDER_THREADS")
        backend._limit_cpu_threads()
        assert dr.thread_count() == 3  # unset: left as it is
    finally:
        dr.set_thread_count(before)


def test_render_threads_leave_a_core_to_the_other_stages(llvm_variant, monkeypatch) -> None:
    """Beside the sensor and file stages, the CPU backend renders on one thread fewer than
    the cores (never none, never more than it had), and its count is put back after the
    block, error or not; the CUDA variant and an explicit SATSIGHT_RENDER_THREADS leave it
    alone."""
    import drjit as dr

    before = dr.thread_count()
    try:
        dr.set_thread_count(9)
        monkeypatch.delenv("SATSIGHT_RENDER_THREADS", raising=False)
        for cores, inside in ((8, 7), (2, 1), (1, 1)):
            monkeypatch.setattr(backend, "machine_cores", lambda cores=cores: cores)
            with backend.render_threads_beside_other_work(CPU_VARIANT):
                assert dr.thread_count() == inside
            assert dr.thread_count() == 9
        monkeypatch.setattr(backend, "machine_cores", lambda: 8)
        dr.set_thread_count(3)  # fewer than the rule's 7: kept
        with backend.render_threads_beside_other_work(CPU_VARIANT):
            assert dr.thread_count() == 3
        dr.set_thread_count(9)
        with pytest.raises(RuntimeError), backend.render_threads_beside_other_work(CPU_VARIANT):
            raise RuntimeError("a frame failed")
        assert dr.thread_count() == 9
        with backend.render_threads_beside_other_work(GPU_VARIANT):
            assert dr.thread_count() == 9
        monkeypatch.setenv("SATSIGHT_RENDER_THREADS", "3")
        with backend.render_threads_beside_other_work(CPU_VARIANT):
            assert dr.thread_count() == 9
    finally:
        dr.set_thread_count(before)
