"""Helpers for tests that compare whole dataset folders."""

from __future__ import annotations

import hashlib
from pathlib import Path

import yaml


def file_hashes(root: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under ``root`` (hidden files included)."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def write_scenario_yaml(folder: Path, scenario: dict) -> Path:
    """``scenario`` written as ``folder/scenario.yaml``; returns its path."""
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario), encoding="utf-8")
    return path
