"""``satsight stats`` on a tiny RSSF dataset: counts against hand counts from labels.json,
the JSON's keys, the figure, and the dataset left untouched."""

from __future__ import annotations

import json
from collections import Counter
from importlib import resources
from pathlib import Path

import imagecodecs
import numpy as np
import pytest
import yaml

from satsight.cli import main
from satsight.config.scenario import parse_scenario
from satsight.dataset.journal import sorted_journal_frames
from satsight.dataset.reader import open_dataset
from satsight.dataset.stats import (
    DISTRIBUTIONS,
    VISIBILITY_FLAGS,
    dataset_stats,
    histogram,
    write_stats,
)
from satsight.run.generation import generate_dataset
from synthetic_datasets import (
    MemoryPeak,
    assert_peak_does_not_grow,
    held_records_bytes,
    traced_peak,
)

FRAME_COUNT = 14  # two per distance interval: six approach intervals and the hover


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    path = Path(str(resources.files("satsight") / "examples" / "rssf_dataset.yaml"))
    config = yaml.safe_load(path.read_text(encoding="utf-8"))
    config["camera"].update(width_px=96, height_px=80)
    config["sampler"]["frame_count"] = FRAME_COUNT
    config["outputs"] = {**(config.get("outputs") or {}), "contact_sheet": False}  # not read
    out = tmp_path_factory.mktemp("stats") / "rssf"
    generate_dataset(parse_scenario(config, "test"), out)
    return out


@pytest.fixture(scope="module")
def frames(dataset: Path) -> list[dict]:
    return json.loads((dataset / "labels.json").read_text(encoding="utf-8"))["frames"]


@pytest.fixture(scope="module")
def stats(dataset: Path) -> dict:
    return dataset_stats(open_dataset(dataset))


def test_counts_equal_hand_counts_from_the_labels(stats: dict, frames: list[dict]) -> None:
    assert stats["frame_count"] == len(frames) == FRAME_COUNT
    intervals = Counter(f["plan"]["interval"] for f in frames)
    assert stats["counts"]["distance_interval"] == dict(intervals)
    assert len(intervals) == 7 and set(intervals.values()) == {2}
    for flag in VISIBILITY_FLAGS:
        assert stats["counts"]["visibility"][flag] == sum(f["plan"][flag] for f in frames), flag
    assert stats["counts"]["target_class"] == {"two_wings_dish": FRAME_COUNT}


def test_intervals_are_listed_from_near_to_far(stats: dict, frames: list[dict]) -> None:
    order = list(stats["counts"]["distance_interval"])
    median = {
        name: np.median([f["range_m"] for f in frames if f["plan"]["interval"] == name])
        for name in order
    }
    assert [median[name] for name in order] == sorted(median.values())
    assert order[-1].startswith("hover")


def test_histograms_hold_every_frame_in_their_bins(stats: dict, frames: list[dict]) -> None:
    assert set(stats["histograms"]) == set(DISTRIBUTIONS)
    values = {
        "range_m": [f["range_m"] for f in frames],
        "phase_angle_deg": [f["phase_angle_deg"] for f in frames],
        "visible_pixel_fraction": [f["visible_pixel_fraction"] for f in frames],
        "exposure_time_s": [f["sensor"]["exposure_time_s"] for f in frames],
        "saturated_pixel_count": [f["sensor"]["saturated_pixel_count"] for f in frames],
        "target_v_magnitude_equivalent": [
            f["target_v_magnitude_equivalent"]
            for f in frames
            if f["target_v_magnitude_equivalent"] is not None
        ],
        "earth_fill_fraction_p99": [
            f["sensor"]["regions"]["earth"]["fill_fraction_p99"]
            for f in frames
            if f["sensor"]["regions"]["earth"]["fill_fraction_p99"] is not None
        ],
    }
    for name, hist in stats["histograms"].items():
        assert hist["missing"] == FRAME_COUNT - len(values[name]), name
        assert sum(hist["counts"]) == len(values[name]), name
        if not values[name]:  # no frame has it (e.g. no Earth behind the target)
            continue
        assert len(hist["edges"]) == len(hist["counts"]) + 1
        assert hist["min"] == min(values[name]) and hist["max"] == max(values[name])
        assert hist["median"] == pytest.approx(np.median(values[name]), rel=1e-12)
        counts, _ = np.histogram(values[name], bins=hist["edges"])
        assert counts.tolist() == hist["counts"], name
    edges = np.asarray(stats["histograms"]["range_m"]["edges"])
    ratios = edges[1:] / edges[:-1]
    assert stats["histograms"]["range_m"]["scale"] == "log"
    assert np.allclose(ratios, ratios[0])  # log bins: equal ratios
    assert stats["histograms"]["phase_angle_deg"]["edges"] == list(np.arange(0.0, 190.0, 10.0))


def test_histogram_of_nothing_and_of_one_value() -> None:
    empty = histogram([], "range_m", missing=3)
    assert empty["counts"] == [] and empty["missing"] == 3 and empty["median"] is None
    one = histogram([5.0], "saturated_pixel_count", missing=0)
    assert one["counts"] == [1] and one["edges"] == [4.5, 5.5]
    same = histogram([2e4, 2e4], "range_m", missing=0)
    assert sum(same["counts"]) == 2 and same["edges"][0] < 2e4 < same["edges"][-1]


def test_written_json_and_png(stats: dict, tmp_path: Path) -> None:
    json_path, png_path = write_stats(stats, tmp_path / "out")
    written = json.loads(json_path.read_text(encoding="utf-8"))
    assert written == json.loads(json.dumps(stats))
    assert set(written) == {
        "dataset",
        "scenario",
        "frame_count",
        "complete",
        "counts",
        "histograms",
    }
    assert set(written["counts"]) == {"distance_interval", "target_class", "visibility"}
    for hist in written["histograms"].values():
        assert {"unit", "scale", "label", "edges", "counts", "min", "median", "max", "missing"} == (
            set(hist)
        )
    image = imagecodecs.png_decode(png_path.read_bytes())
    assert image.ndim == 3 and image.shape[0] > 400 and image.shape[1] > 800
    assert image.std() > 0  # something is drawn


def test_cli_prints_tables_writes_outside_and_leaves_the_dataset_unchanged(
    dataset: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    before = {p: p.read_bytes() for p in dataset.rglob("*") if p.is_file()}
    monkeypatch.chdir(tmp_path)
    main(["stats", str(dataset)])
    out = capsys.readouterr().out
    assert "hover 100 km" in out and "phase_angle_deg" in out and "two_wings_dish" in out
    default = tmp_path / "out" / "stats" / dataset.name
    assert (default / "stats.json").is_file() and (default / "stats.png").is_file()
    main(["stats", str(dataset), "--out", str(tmp_path / "elsewhere")])
    assert (tmp_path / "elsewhere" / "stats.json").is_file()
    assert {p: p.read_bytes() for p in dataset.rglob("*") if p.is_file()} == before


def test_cli_refuses_an_output_folder_inside_the_dataset(dataset: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["stats", str(dataset), "--out", str(dataset / "stats")])
    assert exit_info.value.code == 2
    assert "lies inside the dataset" in capsys.readouterr().err
    assert not (dataset / "stats").exists()


def test_cli_refuses_an_incomplete_dataset(dataset: Path, tmp_path: Path, capsys) -> None:
    import shutil

    copy = Path(shutil.copytree(dataset, tmp_path / "copy"))
    (copy / "complete.json").unlink()
    with pytest.raises(SystemExit) as exit_info:
        main(["stats", str(copy), "--out", str(tmp_path / "out")])
    assert exit_info.value.code == 2
    assert "--resume" in capsys.readouterr().err


def test_stats_memory_does_not_grow_with_the_frame_count(
    labels_only_datasets: tuple[Path, ...],
) -> None:
    """Datasets of N and 2N frames (records of 21 kB each as Python objects) are counted
    and binned in one pass holding a few numbers per frame: the memory peak grows by those
    numbers alone, and stays far below the records' size."""
    peaks = []
    for root in labels_only_datasets:
        count = len(sorted_journal_frames(root))
        records_bytes = held_records_bytes(root)
        stats, peak = traced_peak(lambda root=root: dataset_stats(open_dataset(root)))
        assert stats["frame_count"] == count
        assert sum(stats["counts"]["distance_interval"].values()) == count
        assert sum(stats["counts"]["target_class"].values()) == count
        for name, hist in stats["histograms"].items():
            assert sum(hist["counts"]) + hist["missing"] == count, name
        assert stats["histograms"]["phase_angle_deg"]["max"] > 170.0  # varies frame to frame
        peaks.append(MemoryPeak(count, peak, records_bytes))
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 20, peaks[-1]


def test_piped_tables_keep_every_name_and_number_whole(
    dataset: Path, tmp_path: Path, monkeypatch
) -> None:
    """Not on a terminal (CliRunner's output is a buffer, 80 columns by default): both tables
    come out whole, tab-separated, with the numbers of stats.json."""
    from click.testing import CliRunner

    from satsight.cli import cli

    monkeypatch.delenv("COLUMNS", raising=False)
    result = CliRunner().invoke(cli, ["stats", str(dataset), "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    assert "…" not in result.stdout
    counts_text, spread_text = result.stdout.strip().split("\n\n")
    numbers = json.loads((tmp_path / "s" / "stats.json").read_text(encoding="utf-8"))
    counts = counts_text.splitlines()
    assert counts[0] == f"# {FRAME_COUNT} frames of {numbers['dataset']}"
    assert counts[1].split("\t") == ["group", "value", "frames"]
    assert {tuple(line.split("\t")) for line in counts[2:]} == {
        (group.replace("_", " "), value, str(count))
        for group, values in numbers["counts"].items()
        for value, count in values.items()
    }
    spread = spread_text.splitlines()
    assert spread[:2] == ["# distributions", "quantity\tunit\tmin\tmedian\tmax\twithout"]
    rows = {line.split("\t")[0]: line.split("\t")[1:] for line in spread[2:]}
    assert set(rows) == set(DISTRIBUTIONS)
    for name, hist in numbers["histograms"].items():
        whole = ["-" if hist[k] is None else f"{hist[k]:.4g}" for k in ("min", "median", "max")]
        assert rows[name] == [hist["unit"], *whole, str(hist["missing"])], name
