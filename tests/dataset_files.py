"""Helpers for tests that compare whole dataset folders."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import yaml


def file_hashes(root: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under ``root`` (hidden files included)."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def views_scenario(
    name: str,
    seed: int,
    frame_count: int,
    size_px: tuple[int, int],
    distance_step_km: float,
    turn_deg: tuple[float, int, int, float],
    target_seed: int,
) -> dict:
    """A small scenario of hand-placed views of the two-wing satellite at about 30 m
    (one bounce). Frame i: distance 0.03 km + i * distance_step_km; turn_deg = (azimuth
    step, elevation step, elevation span, roll step): azimuth step * i, elevation
    (i * elevation step) % span - span / 2, roll step * i."""
    azimuth, elevation, span, roll = turn_deg
    frames = [
        {"distance_km": 0.03 + distance_step_km * i, "azimuth_deg": azimuth * i,
         "elevation_deg": (i * elevation) % span - span // 2, "roll_deg": roll * i}
        for i in range(frame_count)
    ]  # fmt: skip
    return {
        "name": name,
        "seed": seed,
        "camera": {"preset": "wide_field", "width_px": size_px[0], "height_px": size_px[1]},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": target_seed}},
        "frames": frames,
        "render": {"bounces": 1},
    }


def write_scenario_yaml(folder: Path, scenario: dict) -> Path:
    """``scenario`` written as ``folder/scenario.yaml``; returns its path."""
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario), encoding="utf-8")
    return path


def generated_dataset(out: Path, scenario: dict) -> Path:
    """The dataset of an uninterrupted local run of ``scenario`` in ``out`` (checked to be
    complete); returns ``out``."""
    from satsight.config.scenario import parse_scenario
    from satsight.run.generation import generate_dataset

    assert generate_dataset(parse_scenario(scenario), out).complete
    return out


def footprint_box_mask(shape: tuple[int, int], footprint: dict) -> np.ndarray:
    """(H, W) bool: the pixels under a frame's integrated footprint box (its
    ``target_footprint`` label), where a small target's light may lie off the pixel-centre
    mask; all False when the frame's pixels were not integrated."""
    box = np.zeros(shape, dtype=bool)
    if footprint["integrated"]:
        x0, y0, x1, y1 = footprint["projected_box_xyxy_px"]
        box[
            max(math.floor(y0 + 0.5), 0) : math.floor(y1 + 0.5) + 1,
            max(math.floor(x0 + 0.5), 0) : math.floor(x1 + 0.5) + 1,
        ] = True
    return box
