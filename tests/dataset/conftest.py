"""Datasets shared by the dataset tests: a large labels-only dataset for the memory tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from export_datasets import tiny_scenario_dict
from synthetic_datasets import LARGE_FRAME_COUNT, write_synthetic_dataset


@pytest.fixture(scope="session")
def labels_only_template(tmp_path_factory) -> Path:
    """A real one-frame dataset without files (``outputs.files: []``), with a crop."""
    from satsight.config.scenario import parse_scenario
    from satsight.run.generation import generate_dataset

    scenario = tiny_scenario_dict()
    scenario.update(name="labels-only", frames=scenario["frames"][:1])
    scenario["outputs"] = {"files": [], "crop": {"size_px": 48}}
    root = tmp_path_factory.mktemp("labels_only") / "template"
    generate_dataset(parse_scenario(scenario, "test"), root)
    return root


@pytest.fixture(scope="session")
def large_labels_only(tmp_path_factory, labels_only_template: Path) -> Path:
    """``LARGE_FRAME_COUNT`` frames made from the template's one (see synthetic_datasets)."""
    root = tmp_path_factory.mktemp("large") / "dataset"
    return write_synthetic_dataset(root, labels_only_template, LARGE_FRAME_COUNT)
