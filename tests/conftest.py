"""Shared test fixtures and tolerances (named in units)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def llvm_variant() -> str:
    """Start Mitsuba on the CPU backend once per test session."""
    from satsight.render.backend import CPU_VARIANT, use_variant

    return use_variant(CPU_VARIANT)
