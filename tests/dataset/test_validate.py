"""``satsight validate`` on a freshly generated tiny dataset, clean and with corruptions.

Each corruption is made in a copy of one module-scoped dataset and must be reported with
its frame and its file named. Edits of frame records are made either plainly (so the
SHA-256 sums in complete.json give them away) or "forged": labels.json, the journal and
complete.json rewritten consistently, so that only the checks of the labels against the
pose and the images can find them.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from satsight.cli import main
from satsight.config.scenario import parse_scenario
from satsight.dataset.journal import record_line, sorted_journal_frames
from satsight.dataset.manifest import json_bytes, labels_lines
from satsight.dataset.problems import MAX_KEPT_PROBLEMS
from satsight.dataset.validate import validate_dataset
from satsight.dataset.validation_report import ValidationReport
from satsight.errors import SatsightError
from satsight.run.generation import generate_dataset
from synthetic_datasets import (
    MemoryPeak,
    assert_peak_does_not_grow,
    held_records_bytes,
    traced_peak,
    write_synthetic_dataset,
)

FRAME_COUNT = 4
CROP_PX = 32

SCENARIO = {
    "name": "validate-test",
    "seed": 3,
    "camera": {"preset": "wide_field", "width_px": 96, "height_px": 80},
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    # 5-8 km: the 8 m target spans 45-75 px, inside the 96 x 80 frame
    "frames": [
        {"distance_km": 5.0, "azimuth_deg": 20, "elevation_deg": 25, "roll_deg": 0},
        {"distance_km": 6.5, "azimuth_deg": 80, "elevation_deg": 10, "roll_deg": 30},
        {"distance_km": 8.0, "azimuth_deg": 150, "elevation_deg": -20, "roll_deg": 0},
        {"distance_km": 6.0, "azimuth_deg": 260, "elevation_deg": 40, "roll_deg": 60},
    ],
    "render": {"bounces": 0},
    "outputs": {"crop": {"size_px": CROP_PX}},
}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("validate") / "dataset"
    generate_dataset(parse_scenario(SCENARIO, "test"), out)
    assert (out / "complete.json").is_file()
    return out


@pytest.fixture
def copy(dataset: Path, tmp_path: Path) -> Path:
    """A copy of the dataset to corrupt."""
    return Path(shutil.copytree(dataset, tmp_path / "dataset"))


def labels_of(root: Path) -> dict:
    return json.loads((root / "labels.json").read_text(encoding="utf-8"))


def forge_records(root: Path, edit: Callable[[list[dict]], None]) -> None:
    """Edit the frame records in labels.json and the journal alike, and re-sum complete.json."""
    labels = labels_of(root)
    frames = labels.pop("frames")
    edit(frames)
    journal_lines = [record_line(r) for r in frames]
    labels_data = b"".join(labels_lines(labels, journal_lines))
    journal_data = b"".join(journal_lines)
    (root / "labels.json").write_bytes(labels_data)
    (root / "journal.jsonl").write_bytes(journal_data)
    summary = json.loads((root / "complete.json").read_text(encoding="utf-8"))
    summary["labels_sha256"] = hashlib.sha256(labels_data).hexdigest()
    summary["journal_sha256"] = hashlib.sha256(journal_data).hexdigest()
    summary["frame_count"] = len(frames)
    (root / "complete.json").write_bytes(json_bytes(summary))


def frame_file(root: Path, index: int, key: str, crop: bool = False) -> str:
    """The relative path of one of a frame's files, from labels.json."""
    frame = labels_of(root)["frames"][index]
    return (frame["crop"] if crop else frame)["files"][key]


def problems_at(report: ValidationReport, frame: int | None, file: str | None) -> list[str]:
    """The problems reported for that frame and file, as text."""
    return [p.message for p in report.findings.problems if p.frame == frame and p.file == file]


def only_problems_at(report: ValidationReport, places: set[tuple[int | None, str]]) -> None:
    """Every problem reported lies at one of ``places`` (frame, file), and each place has one."""
    found = {(p.frame, p.file) for p in report.findings.problems}
    assert found == places, [str(p) for p in report.findings.problems]


# --- a clean dataset ----------------------------------------------------------------------
def test_clean_dataset_passes_every_check(dataset: Path) -> None:
    report = validate_dataset(dataset)
    assert report.ok, [str(p) for p in report.findings.problems]
    assert report.complete and report.frames_checked == FRAME_COUNT
    counts = report.findings.counts()
    # 8 files of the full frame and 8 of its crop, every frame
    assert counts["files"] == (2 * 8 * FRAME_COUNT, 0)
    assert counts["checksums"] == (2 * 8 * FRAME_COUNT, 0)
    for check in ("pose", "masks", "journal"):
        assert counts[check] == (FRAME_COUNT, 0)
    assert counts["crop"][1] == 0 and counts["crop"][0] >= FRAME_COUNT


def test_forging_nothing_keeps_the_dataset_byte_identical(dataset: Path, copy: Path) -> None:
    forge_records(copy, lambda frames: None)
    for name in ("labels.json", "journal.jsonl", "complete.json"):
        assert (copy / name).read_bytes() == (dataset / name).read_bytes(), name


def test_cli_exits_0_on_a_clean_dataset_and_leaves_it_unchanged(dataset: Path, capsys) -> None:
    before = {p: p.read_bytes() for p in dataset.rglob("*") if p.is_file()}
    main(["validate", str(dataset)])  # returns: exit status 0
    out = capsys.readouterr().out
    assert "0 problem(s)" in out and "checksums" in out
    assert {p: p.read_bytes() for p in dataset.rglob("*") if p.is_file()} == before


# --- corrupted files ----------------------------------------------------------------------
def test_truncated_png_is_reported(copy: Path) -> None:
    name = frame_file(copy, 1, "dn_png16")
    data = (copy / name).read_bytes()
    (copy / name).write_bytes(data[: len(data) // 2])
    report = validate_dataset(copy)
    messages = problems_at(report, 1, name)
    assert any("does not decode" in m for m in messages), messages
    assert any(f"expected {len(data)} bytes, found {len(data) // 2}" in m for m in messages)
    only_problems_at(report, {(1, name)})


def test_deleted_depth_file_is_reported(copy: Path) -> None:
    name = frame_file(copy, 2, "depth_exr")
    (copy / name).unlink()
    report = validate_dataset(copy)
    assert problems_at(report, 2, name) == ["expected the depth_exr file, found none (missing)"]
    only_problems_at(report, {(2, name)})


def test_changed_byte_in_an_exr_is_a_hash_mismatch(copy: Path) -> None:
    name = frame_file(copy, 0, "radiance_exr")
    data = bytearray((copy / name).read_bytes())
    data[len(data) // 2] ^= 0x01
    (copy / name).write_bytes(bytes(data))
    report = validate_dataset(copy)
    assert any(m.startswith("expected SHA-256") for m in problems_at(report, 0, name))
    assert {p.file for p in report.findings.problems} == {name}
    # without hashes the size still matches: the change goes unseen unless it breaks decoding
    quick = validate_dataset(copy, hashes=False)
    assert not any("SHA-256" in p.message for p in quick.findings.problems)


def test_object_mask_values_and_shapes_are_checked(copy: Path) -> None:
    from satsight.dataset.image_files import read_png, write_png

    name = frame_file(copy, 3, "object_mask_png")
    mask = read_png(copy / name)
    mask[0, 0] = 7
    write_png(copy / name, mask)
    crop_name = frame_file(copy, 3, "part_mask_png16", crop=True)
    write_png(copy / crop_name, read_png(copy / crop_name)[:-1])
    report = validate_dataset(copy, hashes=False)
    assert any(
        "values 0 and 255 only" in m and "(x=0, y=0)" in m for m in problems_at(report, 3, name)
    )
    assert any(
        f"expected uint16 {CROP_PX}x{CROP_PX}, found uint16 {CROP_PX - 1}x{CROP_PX}" in m
        for m in problems_at(report, 3, crop_name)
    )


def test_background_mask_values_and_agreement_are_checked(copy: Path) -> None:
    """Values other than 0, 1, 2; a body on the target; Earth pixels the labels do not count."""
    from satsight.dataset.image_files import read_png, write_png

    name = frame_file(copy, 1, "background_mask_png")
    background = read_png(copy / name)
    on = read_png(copy / frame_file(copy, 1, "object_mask_png")) == 255
    y, x = np.argwhere(on)[0]
    background[y, x] = 1  # the Earth on the target
    write_png(copy / name, background)
    report = validate_dataset(copy, hashes=False)
    messages = problems_at(report, 1, name)
    assert any(
        "expected background 0 where the object mask is" in m and f"(x={x}, y={y})" in m
        for m in messages
    ), messages
    assert any("expected sensor.regions.earth.pixel_count 1" in m for m in messages), messages
    background[0, 0] = 3
    write_png(copy / name, background)
    report = validate_dataset(copy, hashes=False)
    assert any(
        "values 0 (space), 1 (Earth) and 2 (Moon) only" in m and "(x=0, y=0)" in m
        for m in problems_at(report, 1, name)
    )


# --- edited labels ------------------------------------------------------------------------
def test_swapped_poses_are_reported_for_both_frames(copy: Path) -> None:
    def swap(frames: list[dict]) -> None:
        for key in ("q_cam_from_body", "t_cam_from_body_m"):
            frames[0][key], frames[1][key] = frames[1][key], frames[0][key]

    forge_records(copy, swap)
    report = validate_dataset(copy)
    for index in (0, 1):
        messages = problems_at(report, index, "labels.json")
        assert any("keypoints_px" in m and "px off" in m for m in messages), messages
        assert any("range_m" in m for m in messages), messages
    # the depth images disagree with the swapped poses as well
    assert problems_at(report, 0, frame_file(copy, 0, "depth_exr"))
    assert {p.frame for p in report.findings.problems} == {0, 1}


def test_edited_quaternion_is_reported(copy: Path) -> None:
    def edit(frames: list[dict]) -> None:
        frames[1]["q_cam_from_body"][1] += 0.01

    forge_records(copy, edit)
    messages = problems_at(validate_dataset(copy), 1, "labels.json")
    assert any(m.startswith("expected a unit q_cam_from_body, found norm") for m in messages)
    assert any("keypoints_px" in m for m in messages)


def test_negated_quaternion_breaks_only_the_sign_rule(copy: Path) -> None:
    def negate(frames: list[dict]) -> None:
        frames[2]["q_cam_from_body"] = [-c for c in frames[2]["q_cam_from_body"]]

    forge_records(copy, negate)
    report = validate_dataset(copy)
    (message,) = problems_at(report, 2, "labels.json")
    assert message.startswith("expected q_cam_from_body with qw >= 0")
    assert len(report.findings.problems) == 1


def test_edited_bbox_is_reported_with_the_mask_file(copy: Path) -> None:
    truth = labels_of(copy)["frames"][2]["bbox_xyxy_px"]

    def edit(frames: list[dict]) -> None:
        frames[2]["bbox_xyxy_px"][0] += 1

    forge_records(copy, edit)
    report = validate_dataset(copy)
    mask = frame_file(copy, 2, "object_mask_png")
    (message,) = problems_at(report, 2, mask)
    assert message.startswith(f"expected bbox_xyxy_px {truth} (the object mask's box), found")
    only_problems_at(report, {(2, mask)})


def test_edited_pixel_count_and_crop_labels_are_reported(copy: Path) -> None:
    def edit(frames: list[dict]) -> None:
        frames[0]["object_pixel_count"] += 1
        frames[3]["crop"]["K"][0][2] += 1.0
        frames[3]["crop"]["keypoints_px"][8][1] += 0.01

    forge_records(copy, edit)
    report = validate_dataset(copy)
    assert any(
        m.startswith("expected object_pixel_count")
        for m in problems_at(report, 0, frame_file(copy, 0, "object_mask_png"))
    )
    messages = problems_at(report, 3, "labels.json")
    assert any(m.startswith("expected crop K = K shifted by the box origin") for m in messages)
    assert any(m.startswith("expected crop keypoints_px[8]") for m in messages)


def test_labels_edited_after_completion_are_reported(copy: Path) -> None:
    text = (copy / "labels.json").read_text(encoding="utf-8")
    labels = json.loads(text)
    value = labels["frames"][3]["sun_irradiance_w_m2"]
    labels["frames"][3]["sun_irradiance_w_m2"] = value * 2
    (copy / "labels.json").write_bytes(json_bytes(labels))
    report = validate_dataset(copy)
    (summary,) = problems_at(report, None, "labels.json")
    assert "changed after the dataset was completed" in summary
    (journal,) = problems_at(report, 3, "labels.json")
    assert journal == "expected the journal.jsonl record, found other values of sun_irradiance_w_m2"
    assert len(report.findings.problems) == 2


def test_missing_frame_is_reported(copy: Path) -> None:
    forge_records(copy, lambda frames: frames.pop(2))
    report = validate_dataset(copy)
    messages = problems_at(report, None, "labels.json")
    assert any("expected 4 frames" in m and "missing 2" in m for m in messages), messages
    assert problems_at(report, None, "complete.json") == [
        "expected frame_count 4 (from manifest.json), found 3"
    ]


def test_unsorted_repeated_frames_and_wrong_plan_index_are_reported(copy: Path) -> None:
    def edit(frames: list[dict]) -> None:
        frames[:] = [frames[0], frames[2], frames[1], json.loads(json.dumps(frames[1]))]
        frames[0]["plan_index"] = 3

    forge_records(copy, edit)
    report = validate_dataset(copy)
    messages = problems_at(report, 1, "labels.json")
    assert "expected frames sorted by frame_index, found 1 after 2" in messages
    assert "expected each frame once, found this one again" in messages
    assert problems_at(report, 0, "labels.json") == [
        "expected plan_index 0 (manifest plan_indices), found 3"
    ]
    assert any("missing 3" in m for m in problems_at(report, None, "labels.json"))


# --- completeness -------------------------------------------------------------------------
def test_missing_complete_json_is_refused_with_how_to_resume(copy: Path) -> None:
    (copy / "complete.json").unlink()
    report = validate_dataset(copy)
    (message,) = problems_at(report, None, "complete.json")
    assert "incomplete dataset (4 of 4 frames committed)" in message
    assert f"satsight generate SCENARIO --out {copy} --resume" in message
    assert "--allow-incomplete" in message
    assert report.frames_checked == 0 and not report.ok


def test_allow_incomplete_checks_the_committed_frames(dataset: Path, copy: Path) -> None:
    (copy / "complete.json").unlink()
    (copy / "labels.json").unlink()
    lines = (copy / "journal.jsonl").read_bytes().splitlines(keepends=True)
    (copy / "journal.jsonl").write_bytes(b"".join(lines[:2]) + lines[2][:40])  # torn last
    report = validate_dataset(copy, allow_incomplete=True)
    assert report.ok, [str(p) for p in report.findings.problems]
    assert not report.complete and report.frames_checked == 2
    name = frame_file(dataset, 1, "depth_exr")
    (copy / name).unlink()
    assert problems_at(validate_dataset(copy, allow_incomplete=True), 1, name)


# --- the command line ---------------------------------------------------------------------
def test_cli_names_each_problem_and_exits_1(copy: Path, capsys) -> None:
    name = frame_file(copy, 2, "depth_exr")
    (copy / name).unlink()
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(copy), "--no-hashes"])
    assert exit_info.value.code == 1
    out = capsys.readouterr().out
    assert f"frame 2, {name}: expected the depth_exr file, found none (missing) [files]" in out
    assert "1 problem(s)" in out


def test_cli_exits_1_on_an_incomplete_dataset(copy: Path, capsys) -> None:
    (copy / "complete.json").unlink()
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(copy)])
    assert exit_info.value.code == 1
    assert "--resume" in capsys.readouterr().out


def test_missing_folder_is_a_usage_error(tmp_path: Path, capsys) -> None:
    with pytest.raises(SatsightError, match="dataset folder not found"):
        validate_dataset(tmp_path / "nowhere")
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(tmp_path / "nowhere")])
    assert exit_info.value.code == 2
    assert "dataset folder not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(tmp_path)])  # a folder, but no dataset
    assert exit_info.value.code == 2


# --- labels.json read as a stream ---------------------------------------------------------
def test_labels_in_another_layout_differ_only_in_their_hash(copy: Path) -> None:
    (copy / "labels.json").write_text(json.dumps(labels_of(copy)), encoding="utf-8")
    report = validate_dataset(copy, hashes=False)
    (message,) = [str(p) for p in report.findings.problems]
    assert message.startswith("labels.json: expected SHA-256") and "changed after" in message


def test_unreadable_labels_are_reported_and_the_journal_checked(copy: Path) -> None:
    data = (copy / "labels.json").read_bytes()
    (copy / "labels.json").write_bytes(data[: len(data) // 2])
    report = validate_dataset(copy, hashes=False)
    (message,) = problems_at(report, None, "labels.json")[1:]
    assert "labels.json is not readable JSON: " in message and " line " in message
    assert report.frames_checked == FRAME_COUNT
    assert report.findings.counts()["journal"] == (0, 0)


# --- large datasets: memory bounded, problems capped -----------------------------------------
def test_validation_memory_does_not_grow_with_the_frame_count(
    labels_only_datasets: tuple[Path, ...],
) -> None:
    """Datasets of N and 2N frames (records of 21 kB each as Python objects) are found
    clean with the same memory peak, within a few bytes per frame: far below the records'
    size."""
    peaks = []
    for root in labels_only_datasets:
        count = len(sorted_journal_frames(root))
        records_bytes = held_records_bytes(root)
        assert (root / "labels.json").stat().st_size > (root / "journal.jsonl").stat().st_size
        report, peak = traced_peak(lambda root=root: validate_dataset(root))
        assert report.ok, [str(p) for p in report.findings.problems[:10]]
        assert report.frames_checked == count
        assert report.findings.counts()["journal"] == (count, 0)
        peaks.append(MemoryPeak(count, peak, records_bytes))
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 2, peaks[-1]


def test_a_labels_edit_is_found_in_a_large_dataset_with_bounded_memory(
    labels_only_datasets: tuple[Path, ...], tmp_path: Path
) -> None:
    """labels.json differs from the journal in one frame: read again, as a stream, to name
    that frame, with a memory peak that does not grow with the frame count."""
    peaks = []
    for source in labels_only_datasets:
        root = tmp_path / source.name
        shutil.copytree(source, root)
        count = len(sorted_journal_frames(root))
        edited = 3 * count // 5
        manifest = json.loads((root / "manifest.json").read_text(encoding="utf-8"))

        def records(root=root, edited=edited):
            for frame in sorted_journal_frames(root):
                if frame["frame_index"] == edited:
                    frame["sun_irradiance_w_m2"] *= 2
                yield frame

        labels = root / "labels.json.new"
        with open(labels, "wb") as stream:
            for piece in labels_lines(manifest, map(record_line, records())):
                stream.write(piece)
        labels.replace(root / "labels.json")
        records_bytes = held_records_bytes(root)
        report, peak = traced_peak(lambda root=root: validate_dataset(root))
        assert problems_at(report, edited, "labels.json") == [
            "expected the journal.jsonl record, found other values of sun_irradiance_w_m2"
        ]
        changed = problems_at(report, None, "labels.json")[0]
        assert "changed after the dataset was completed" in changed
        assert report.findings.total == 2 and report.frames_checked == count
        peaks.append(MemoryPeak(count, peak, records_bytes))
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 2, peaks[-1]


def test_problems_beyond_the_cap_are_counted_not_kept(
    labels_only_template: Path, tmp_path: Path, capsys
) -> None:
    count = MAX_KEPT_PROBLEMS + 1500

    def negate(record: dict) -> None:  # the same rotation: only the sign rule breaks
        record["q_cam_from_body"] = [-c for c in record["q_cam_from_body"]]

    root = write_synthetic_dataset(tmp_path / "d", labels_only_template, count, edit=negate)
    report = validate_dataset(root)
    assert len(report.findings.problems) == MAX_KEPT_PROBLEMS
    assert report.findings.total == count and report.findings.omitted == 1500
    assert report.findings.counts()["pose"] == (count, count)
    assert [p.frame for p in report.findings.problems] == list(range(MAX_KEPT_PROBLEMS))
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(root)])
    assert exit_info.value.code == 1
    out = capsys.readouterr().out
    assert f"... and 1500 more problem(s), not listed: the first {MAX_KEPT_PROBLEMS}" in out
    assert f"{count} problem(s)" in out
