"""Fixtures shared by every test folder: the Mitsuba CPU variant, started once per session.

Named tolerances (ONE_MM, ARCSEC_RAD, ...) are module constants in ``tolerances.py``; small
shared builders and helpers are modules beside this file (``builders.py``, ``cli_runner.py``,
...), imported by name.
"""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def llvm_variant() -> str:
    """Start Mitsuba on the CPU backend once per test session."""
    from satsight.render.backend import CPU_VARIANT, use_variant

    return use_variant(CPU_VARIANT)
