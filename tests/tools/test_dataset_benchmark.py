"""The dataset benchmark's kernel cache: each case compiles its kernels (an empty Dr.Jit
cache of its own) unless the user's cache is asked for."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from satsight.errors import SatsightError
from satsight.tools.dataset_benchmark import _kernel_cache_env


def test_a_cold_case_compiles_into_an_empty_cache_of_its_own(tmp_path: Path) -> None:
    env = _kernel_cache_env("cold", tmp_path / "kernels")
    assert env["DRJIT_CACHE_DIR"] == str(tmp_path / "kernels")
    assert list((tmp_path / "kernels").iterdir()) == []
    # Dr.Jit writes the kernels it compiles there.
    code = (
        "import drjit as dr, mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
        "x = dr.arange(mi.Float, 64) * 2.71828 + 1; dr.eval(x)"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, check=False)
    assert done.returncode == 0, done.stderr
    assert any(p.suffix == ".bin" for p in (tmp_path / "kernels").iterdir())
    with pytest.raises(FileExistsError):  # never a cache left by another case
        _kernel_cache_env("cold", tmp_path / "kernels")


def test_a_warm_case_keeps_the_users_cache_and_other_names_are_refused(tmp_path) -> None:
    env = _kernel_cache_env("warm", tmp_path / "unused")
    assert env.get("DRJIT_CACHE_DIR") == os.environ.get("DRJIT_CACHE_DIR")
    assert not (tmp_path / "unused").exists()
    with pytest.raises(SatsightError, match="'cold' or 'warm'"):
        _kernel_cache_env("lukewarm", tmp_path / "k")
