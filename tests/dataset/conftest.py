"""Datasets shared by the dataset tests: the synthetic datasets of the memory tests, two
sizes of each kind, built once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from export_datasets import box_mesh, tiny_scenario_dict
from synthetic_datasets import (
    LABELS_ONLY_FRAME_COUNTS,
    WITH_FILES_FRAME_COUNTS,
    write_synthetic_dataset,
)


def _one_frame_template(root: Path, name: str, outputs: dict) -> Path:
    """A real one-frame dataset of the tiny scenario with these outputs, in ``root``."""
    from satsight.config.scenario import parse_scenario
    from satsight.run.generation import generate_dataset

    scenario = tiny_scenario_dict()
    scenario.update(name=name, frames=scenario["frames"][:1], outputs=outputs)
    generate_dataset(parse_scenario(scenario, "test"), root)
    return root


@pytest.fixture(scope="session")
def labels_only_template(tmp_path_factory) -> Path:
    """A real one-frame dataset without files (``outputs.files: []``), with a crop."""
    root = tmp_path_factory.mktemp("labels_only") / "template"
    return _one_frame_template(root, "labels-only", {"files": [], "crop": {"size_px": 48}})


@pytest.fixture(scope="session")
def labels_only_datasets(tmp_path_factory, labels_only_template: Path) -> tuple[Path, ...]:
    """Labels-only datasets of ``LABELS_ONLY_FRAME_COUNTS`` frames made from the template's
    one (see synthetic_datasets). Read them; copy one to change it."""
    parent = tmp_path_factory.mktemp("labels_only_sizes")
    return tuple(
        write_synthetic_dataset(parent / f"frames_{count}", labels_only_template, count)
        for count in LABELS_ONLY_FRAME_COUNTS
    )


@pytest.fixture(scope="session")
def datasets_with_files(tmp_path_factory) -> tuple[Path, ...]:
    """Datasets of ``WITH_FILES_FRAME_COUNTS`` frames, every frame sharing the preview and
    the object mask of a real one-frame dataset; their model is a 12-triangle box, so that
    an export's model files (written once) take little time and memory, and its peak is
    that of the frames."""
    parent = tmp_path_factory.mktemp("with_files")
    template = _one_frame_template(parent / "template", "with-files", {"crop": {"size_px": 48}})
    files = ("preview_png8", "object_mask_png")
    return tuple(
        write_synthetic_dataset(
            parent / f"frames_{count}", template, count, files=files, model=box_mesh()
        )
        for count in WITH_FILES_FRAME_COUNTS
    )
