"""Export a satsight dataset to other pose-estimation formats: BOP, SPEED+ and COCO.

``export_dataset`` opens a complete dataset, splits its frames into train / val / test
(``splits.py``), writes the chosen format into a hidden folder beside ``out_dir`` and moves
it into place at the end, so that a failed export leaves nothing behind. Every export also
holds ``satsight_export.json``: the source dataset, the split rule and which frames went
where. The layouts and conventions are in docs/dataset_format.md, "Exports".

Memory does not grow with the frame count beyond a few integers per frame: the split is
made of frame indices, and each split's records are read from the journal as they are
written out (``ExportFrames``).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

from satsight.dataset.export.bop import write_bop
from satsight.dataset.export.coco import write_coco
from satsight.dataset.export.images import DEFAULT_IMAGE_MODE, ExportImages
from satsight.dataset.export.source import ExportFrames, scan_frames
from satsight.dataset.export.speedplus import DEFAULT_DOMAIN, write_speedplus
from satsight.dataset.export.splits import SPLIT_NAMES, SplitRule, assign_splits
from satsight.dataset.reader import open_dataset
from satsight.dataset.staging import check_output_folder, staged_folder
from satsight.errors import SatsightError

FORMATS = ("bop", "speedplus", "coco")
EXPORT_RECORD = "satsight_export.json"
_FORMAT_TITLES = {"bop": "BOP", "speedplus": "SPEED+", "coco": "COCO"}
_DOMAIN = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


@dataclass(frozen=True)
class ExportSummary:
    """What an export wrote: where, in which format, how many frames per split."""

    out_dir: Path
    format: str
    split_sizes: dict[str, int]
    crop: bool
    notes: list[str] = field(default_factory=list)

    def line(self) -> str:
        """One-line description for the command line."""
        sizes = ", ".join(f"{name} {count}" for name, count in self.split_sizes.items())
        total = sum(self.split_sizes.values())
        what = "crops" if self.crop else "frames"
        notes = "; ".join(self.notes)
        return (
            f"exported {total} {what} ({sizes}) as {_FORMAT_TITLES[self.format]} to "
            f"{self.out_dir} ({notes})"
        )


def _check_out_dir(source: Path, out_dir: Path, overwrite: bool) -> None:
    """Refuse an output folder that is, holds or lies in the dataset, or is not ours."""
    src, out = source.resolve(), out_dir.resolve()
    if out == src or out.is_relative_to(src) or src.is_relative_to(out):
        raise SatsightError(
            f"--out {out_dir} overlaps the dataset {source}; write the export to a folder "
            "outside it"
        )
    check_output_folder(out, overwrite)
    if out.is_dir() and any(out.iterdir()) and not (out / EXPORT_RECORD).is_file():
        raise SatsightError(
            f"--overwrite replaces only earlier exports, and {out_dir} holds no "
            f"{EXPORT_RECORD}; choose an empty or new folder"
        )


def export_dataset(
    source: Path,
    out_dir: Path,
    fmt: str,
    rule: SplitRule,
    crop: bool = False,
    overwrite: bool = False,
    domain: str = DEFAULT_DOMAIN,
    image: str = DEFAULT_IMAGE_MODE,
    white_dn: float | None = None,
) -> ExportSummary:
    """Export the complete dataset in ``source`` to ``out_dir`` in format ``fmt``.

    rule: the train / val / test split. crop: export the crops (automatic when the dataset
    keeps only crops). domain: the SPEED+ image domain folder (``synthetic``). image: how
    the images are made from the DN (``images.IMAGE_MODES``: ``dn16``, ``raw16``,
    ``linear8``, ``preview``); white_dn: for ``linear8``, the DN above the bias that reads
    255 (default: the detector's saturation level).
    """
    if fmt not in FORMATS:
        raise SatsightError(f"unknown export format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if not _DOMAIN.match(domain):
        raise SatsightError(
            f"--domain {domain!r} must be a plain folder name (letters, digits, _ . -)"
        )
    source, out_dir = Path(source), Path(out_dir)
    dataset = open_dataset(source)
    images = ExportImages.of_dataset(dataset.header, image, white_dn)
    _check_out_dir(source, out_dir, overwrite)
    table = scan_frames(dataset, crop)
    use_crops = table.crop
    assignment = assign_splits(table.frame_indices.tolist(), rule)
    splits = {
        name: ExportFrames(dataset, table.positions_of(assignment[name]), use_crops)
        for name in SPLIT_NAMES
    }
    with staged_folder(out_dir, overwrite) as root:
        if fmt == "bop":
            notes = write_bop(dataset, splits, root, images, out_dir.name)
        elif fmt == "coco":
            notes = write_coco(dataset, splits, root, images)
        else:
            notes = write_speedplus(dataset, splits, root, domain, images)
        record = {
            "format": fmt,
            "source_dataset": str(source.resolve()),
            "scenario": dataset.header.get("scenario"),
            "crop": use_crops,
            "image": images.record(),
            "split": {
                "fractions": dict(zip(SPLIT_NAMES, rule.fractions, strict=True)),
                "seed": rule.seed,
                "rule": "largest-remainder sizes; frames sorted by frame_index, permuted by "
                "numpy default_rng(SeedSequence([seed])).permutation; train, val, test "
                "take consecutive runs",
                "frames": assignment,
            },
            "notes": notes,
        }
        with open(root / EXPORT_RECORD, "w", encoding="utf-8") as stream:
            json.dump(record, stream, indent=1)  # written piece by piece
            stream.write("\n")
    return ExportSummary(
        out_dir=out_dir,
        format=fmt,
        split_sizes={name: len(assignment[name]) for name in SPLIT_NAMES},
        crop=use_crops,
        notes=notes,
    )
