"""The frame journal and the closing of a dataset: torn lines, lazy records, streaming."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from satsight.dataset.journal import (
    JOURNAL_NAME,
    JournalWriter,
    iter_journal,
    journal_frames,
    read_journal,
    record_line,
    sorted_journal_frames,
    truncate_torn_tail,
)
from satsight.dataset.manifest import finalize_dataset, json_bytes, labels_lines
from satsight.errors import SatsightError
from synthetic_datasets import (
    MemoryPeak,
    assert_peak_does_not_grow,
    held_records_bytes,
    traced_peak,
)

MANIFEST = {
    "format": "satsight-dataset",
    "version": 3,
    "scenario": "journal-test",
    "frame_count": 3,
    "outputs": {"contact_sheet": False},
    "nested": {"a": [1, 2.5, None], "b": "x"},
}


def record(index: int, payload_chars: int = 20) -> dict:
    return {
        "frame_index": index,
        "plan_index": 2 * index,
        "pose": [0.5, -1.25e-7, 3.0],
        "labels": {"box": [1, 2, 3, 4], "none": None, "text": "é" + "x" * payload_chars},
        "files": {},
    }


def write_journal(root: Path, records: list[dict]) -> None:
    (root / JOURNAL_NAME).write_bytes(b"".join(record_line(r) for r in records))


@pytest.mark.parametrize("count", [0, 1, 3])
def test_labels_are_the_manifest_with_one_journal_line_per_frame(count: int) -> None:
    records = [record(i) for i in range(count)]
    text = b"".join(labels_lines(MANIFEST, map(record_line, records))).decode("utf-8")
    assert json.loads(text) == {**MANIFEST, "frames": records}
    assert text.startswith(json_bytes(MANIFEST).decode("utf-8")[:-3])  # the header, indented
    lines = text.splitlines()
    assert len(lines[-2 - count : -2]) == count
    for i, line in enumerate(lines[-2 - count : -2]):
        assert json.loads(line.strip().rstrip(",")) == records[i]


def test_a_torn_last_line_is_not_a_commit_and_is_cut_before_appending(tmp_path: Path) -> None:
    write_journal(tmp_path, [record(0), record(1)])
    with open(tmp_path / JOURNAL_NAME, "ab") as stream:
        stream.write(record_line(record(2))[:-1])  # all but the newline
    assert [r["frame_index"] for r in read_journal(tmp_path)] == [0, 1]
    with JournalWriter(tmp_path) as journal:
        offset, length = journal.append(record(3))
    assert [r["frame_index"] for r in read_journal(tmp_path)] == [0, 1, 3]
    data = (tmp_path / JOURNAL_NAME).read_bytes()
    assert json.loads(data[offset : offset + length]) == record(3)


def test_a_torn_line_longer_than_the_read_block_is_cut_whole(tmp_path: Path) -> None:
    write_journal(tmp_path, [record(0)])
    kept = (tmp_path / JOURNAL_NAME).stat().st_size
    with open(tmp_path / JOURNAL_NAME, "ab") as stream:
        stream.write(record_line(record(1, payload_chars=300_000))[:200_000])
    truncate_torn_tail(tmp_path)
    assert (tmp_path / JOURNAL_NAME).stat().st_size == kept
    (tmp_path / JOURNAL_NAME).write_bytes(b'{"frame_index": 0')  # no newline at all
    truncate_torn_tail(tmp_path)
    assert (tmp_path / JOURNAL_NAME).read_bytes() == b""


def test_a_corrupt_line_before_the_end_is_an_error_naming_it(tmp_path: Path) -> None:
    lines = [record_line(record(0)), b"not json\n", record_line(record(2))]
    (tmp_path / JOURNAL_NAME).write_bytes(b"".join(lines))
    with pytest.raises(SatsightError, match="line 2: not a frame record"):
        read_journal(tmp_path)


def test_journal_frames_keep_the_last_line_of_a_frame_and_sort(tmp_path: Path) -> None:
    second = {**record(1), "plan_index": 99}
    write_journal(tmp_path, [record(2), record(1), record(0), second, record(3)])
    frames = journal_frames(tmp_path, keep=lambda r: r["frame_index"] != 3)
    assert list(frames.indices) == [0, 1, 2]
    assert [f["frame_index"] for f in frames] == [0, 1, 2]
    assert frames[1] == second and frames[-1] == record(2)
    assert frames[0:2] == [record(0), second]
    with pytest.raises(IndexError):
        frames[3]
    offsets = [offset for _, offset, _ in iter_journal(tmp_path)]
    assert list(frames.offsets) == [offsets[2], offsets[3], offsets[0]]


def test_closing_streams_records_without_holding_them(tmp_path: Path) -> None:
    """Journals of N and 4N records of 5 kB (written out of order) close into a sorted
    journal and labels.json with the same memory peak, within a few bytes per frame: far
    below the records' size."""
    peaks = []
    for count in (1000, 4000):
        root = tmp_path / f"records_{count}"
        root.mkdir()
        order = list(range(1, count, 2)) + list(range(0, count, 2))
        with open(root / JOURNAL_NAME, "wb") as stream:  # as JournalWriter appends them
            for i in order:
                stream.write(record_line(record(i, payload_chars=5_000)))
        lines = journal_frames(root)
        manifest = {**MANIFEST, "frame_count": count}
        _, peak = traced_peak(
            lambda root=root, m=manifest, lines=lines: finalize_dataset(root, m, lines.raw_lines())
        )
        journal_bytes = (root / JOURNAL_NAME).stat().st_size
        assert journal_bytes > count * 5_000
        closed = sorted_journal_frames(root)
        assert len(closed) == count
        assert [closed[i]["frame_index"] for i in (0, 1, count // 2, count - 1)] == [
            0, 1, count // 2, count - 1,
        ]  # fmt: skip
        complete = json.loads((root / "complete.json").read_text(encoding="utf-8"))
        labels = (root / "labels.json").read_bytes()
        assert complete["labels_sha256"] == hashlib.sha256(labels).hexdigest()
        assert complete["frame_count"] == count
        document = json.loads(labels)
        assert [f["frame_index"] for f in document["frames"]] == list(range(count))
        peaks.append(MemoryPeak(count, peak, held_records_bytes(root)))
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 20, peaks[-1]
