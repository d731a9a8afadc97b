"""Joining shards: complete shard folders of one scenario become one dataset.

The merged folder holds the same bytes as a dataset rendered by one process: the shards'
files are linked (or copied, or moved), their journal records joined, and the dataset is
closed exactly as ``generate`` closes it.

Nothing of a shard is touched until the merged dataset is whole: every shard file is
checked first (there, with its journal size), the merged folder is staged beside ``--out``
and renamed into place, and only then does ``--move`` delete the shards' frame files
(they were linked, or copied where links are impossible). A missing file, a full disk or
any other error leaves every shard as it was.
"""

from __future__ import annotations

import errno
import os
import shutil
from contextlib import ExitStack, suppress
from pathlib import Path

from satsight.dataset.lock import WriterLock
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


def _place(source: Path, target: Path) -> None:
    """Link ``source`` at ``target`` (no data written), or copy it where links fail."""
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError as error:
        if error.errno in (errno.ENOSPC, errno.EDQUOT):
            raise
        shutil.copyfile(source, target)


def _shard_frames(shards: dict, shard_count: int):
    """(shard folder, record) of every shard frame, checking each shard's frame order."""
    for k, (dataset, folder) in sorted(shards.items()):
        for position, record in enumerate(dataset.frames):
            if record["frame_index"] != k + position * shard_count:
                raise SatsightError(
                    f"{folder}: frame {record['frame_index']} where frame "
                    f"{k + position * shard_count} was expected; validate the shard"
                )
            yield folder, record


def _check_shard_files(shards: dict, shard_count: int, out_dir: Path, move: bool) -> None:
    """Every shard file is there with its journal size, and the merged folder's disk can
    hold the copies a merge across file systems makes; refused before anything is done."""
    out_parent = next(p for p in (out_dir, *out_dir.parents) if p.exists())
    copy_bytes = 0
    for folder, record in _shard_frames(shards, shard_count):
        linkable = os.stat(folder).st_dev == os.stat(out_parent).st_dev
        for relative, checksum in record["checksums"].items():
            try:
                size = (folder / relative).stat().st_size
            except OSError as error:
                found = error.strerror or "cannot be read"
                problem = f"is missing ({found})" if isinstance(error, FileNotFoundError) else (
                    f"cannot be read ({found})")  # fmt: skip
            else:
                if size == checksum["size_bytes"]:
                    copy_bytes += 0 if linkable else size
                    continue
                problem = f"has {size} bytes where its journal says {checksum['size_bytes']}"
            shard = read_json(folder / MANIFEST_NAME)["shard"]
            raise SatsightError(
                f"{folder}: frame {record['frame_index']}'s file {relative} {problem}; nothing "
                f"was {'moved' if move else 'merged'}: repair the shard with satsight generate "
                f"SCENARIO --out {folder} --shard {shard} --resume, then merge again"
            )
    free = shutil.disk_usage(out_parent).free
    if copy_bytes > free:
        raise SatsightError(
            f"merging into {out_dir} copies {copy_bytes / 1e9:.2f} GB of shard files (another "
            f"file system than the shards') and {out_parent} has {free / 1e9:.2f} GB free; "
            "nothing was merged: free space, or merge on the shards' file system"
        )


def _delete_moved(shards: dict, shard_count: int) -> None:
    """--move, once the merged dataset is in place: the shards' frame files go."""
    for folder, record in _shard_frames(shards, shard_count):
        for relative in record["checksums"]:
            with suppress(FileNotFoundError):
                (folder / relative).unlink()


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
    out_dir = Path(out_dir)
    with ExitStack() as locks:
        locks.enter_context(WriterLock(out_dir))  # one writer per folder
        for folder in folders if move else ():  # --move changes the shards too
            locks.enter_context(WriterLock(folder))
        _check_shard_files(shards, shard_count, out_dir.resolve(), move)
        try:
            with staged_folder(out_dir) as root:
                write_manifest(root, manifest)
                shutil.copyfile(first / "scenario.yaml", root / "scenario.yaml")
                shutil.copytree(first / "model", root / "model")
                for folder, record in _shard_frames(shards, shard_count):
                    for relative in record["checksums"]:
                        _place(folder / relative, root / relative)

                def merged_lines():
                    streams = [shards[k][0].frames.raw_lines() for k in range(shard_count)]
                    for index in range(count):
                        yield next(streams[index % shard_count])

                finalize_dataset(root, manifest, merged_lines())
        except OSError as error:
            raise SatsightError(
                f"could not write {error.filename or out_dir}: {error.strerror or error}; "
                "nothing was merged and the shards are as they were: free space or fix the "
                "folder, then merge again"
            ) from None
        if move:
            _delete_moved(shards, shard_count)
    return count
