"""Joining shards: complete shard folders of one scenario become one dataset.

The merged folder holds the same bytes as a dataset rendered by one process: the shards'
files are linked (or copied, or moved), their journal records joined, and the dataset is
closed exactly as ``generate`` closes it.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from satsight.dataset.manifest import finalize_dataset, write_manifest
from satsight.dataset.reader import MANIFEST_NAME, Dataset, open_dataset, read_json
from satsight.dataset.staging import staged_folder
from satsight.errors import SatsightError


def _open_shard(folder: Path) -> tuple[Dataset, dict]:
    shard = open_dataset(folder)
    manifest = read_json(Path(folder) / MANIFEST_NAME)
    if not manifest.get("shard"):
        raise SatsightError(f"{folder} is a whole dataset, not a shard; nothing to merge")
    return shard, manifest


def _place(source: Path, target: Path, move: bool) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    if move:
        os.replace(source, target) if _same_device(source, target) else shutil.move(source, target)
        return
    try:
        os.link(source, target)
    except OSError:
        shutil.copyfile(source, target)


def _same_device(a: Path, b: Path) -> bool:
    return a.stat().st_dev == b.parent.stat().st_dev


def check_shards(manifests: list[dict], folders: list[Path]) -> None:
    """The shards are of one scenario and cover every shard of it exactly once."""
    first = {k: v for k, v in manifests[0].items() if k != "shard"}
    labels = []
    for manifest, folder in zip(manifests, folders, strict=True):
        if {k: v for k, v in manifest.items() if k != "shard"} != first:
            raise SatsightError(
                f"{folder} is a shard of another scenario or settings than {folders[0]}"
            )
        labels.append(manifest["shard"])
    count = int(labels[0].split("/")[1])
    expected = [f"{k}/{count}" for k in range(1, count + 1)]
    if sorted(labels, key=lambda s: int(s.split("/")[0])) != expected:
        given = ", ".join(labels)
        raise SatsightError(f"the shards given ({given}) are not each of 1/{count} … once")


def merge_shards(folders: list[Path], out_dir: Path, move: bool = False) -> int:
    """Merge complete shard folders into the dataset ``out_dir``; its frame count.

    Records stream from the shards' journals: frame i is line i // N of shard i % N.
    """
    folders = [Path(f) for f in folders]
    opened = [_open_shard(folder) for folder in folders]
    check_shards([manifest for _, manifest in opened], folders)
    manifest = {**opened[0][1], "shard": None}
    count = int(manifest["frame_count"])
    shards = {
        int(m["shard"].split("/")[0]) - 1: (d, f) for (d, m), f in zip(opened, folders, strict=True)
    }
    shard_count = len(shards)
    for k, (dataset, folder) in shards.items():
        if len(dataset.frames) != len(range(k, count, shard_count)):
            raise SatsightError(f"{folder} does not hold every frame of its shard")
    first = folders[0]
    with staged_folder(Path(out_dir)) as root:
        write_manifest(root, manifest)
        shutil.copyfile(first / "scenario.yaml", root / "scenario.yaml")
        shutil.copytree(first / "model", root / "model")
        for k, (dataset, folder) in shards.items():
            for position, record in enumerate(dataset.frames):
                if record["frame_index"] != k + position * shard_count:
                    raise SatsightError(
                        f"{folder}: frame {record['frame_index']} where frame "
                        f"{k + position * shard_count} was expected; validate the shard"
                    )
                for relative in record["checksums"]:
                    _place(folder / relative, root / relative, move)

        def merged_lines():
            streams = [shards[k][0].frames.raw_lines() for k in range(shard_count)]
            for index in range(count):
                yield next(streams[index % shard_count])

        finalize_dataset(root, manifest, merged_lines())
    return count
