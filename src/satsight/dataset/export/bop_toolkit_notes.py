"""``BOP_TOOLKIT.md``: how to register one BOP export in bop_toolkit, with its own numbers.

bop_toolkit knows its datasets by name: a new one needs entries in
``bop_toolkit_lib/dataset_params.py`` (object ids, scene ids, image size, modalities) and
a VSD tolerance in the evaluation scripts. The numbers depend on the export (image size,
splits, range of distances, depth quantum), so the export writes them out, ready to paste.

Depth tolerance: bop_toolkit decides visibility by ``d_model - d_image <= delta`` (mm,
bop_toolkit_lib/visibility.py), the default delta being 15 mm. The exported depth is
quantised to ``depth_scale`` (half a step of error at most; 1 m steps at 50 km) and
bop_toolkit's renderer computes depth in float32 (a relative error of order 1e-6 after a
few operations), so a kilometre-range export needs
``delta >= 2 * max depth_scale + 1e-6 * max distance``; the notes give the smallest value
of the 1-2-5 series at or above that and 15 mm.

Dataset name: bop_toolkit splits result file names (``METHOD_DATASET-SPLIT.csv``,
bop_toolkit_lib/inout.py ``parse_result_filename``) at ``_`` and ``-``, so the name it
knows the export by keeps only the folder name's letters and digits (``toolkit_name``),
and the notes link the folder under that name.
"""

from __future__ import annotations

import math
import re
from typing import Protocol

TOOLKIT_NOTES = "BOP_TOOLKIT.md"
#: bop_toolkit's default visibility tolerance (mm).
DEFAULT_DELTA_MM = 15.0
#: Relative depth error allowed for float32 rendering and the depth-to-distance step.
FLOAT32_DEPTH_RTOL = 1e-6


class ExportedImages(Protocol):
    images: int
    max_depth_scale_mm: float
    min_distance_mm: float
    max_distance_mm: float


def nice_ceil(value: float) -> float:
    """The smallest value of the 1-2-5 series (…, 10, 20, 50, 100, …) >= value (> 0)."""
    exponent = math.floor(math.log10(value))
    for step in (1, 2, 5, 10):
        candidate = step * 10.0**exponent
        if candidate >= value * (1 - 1e-12):
            return float(f"{candidate:.12g}")
    raise AssertionError("unreachable")  # pragma: no cover


def toolkit_name(folder_name: str) -> str:
    """The dataset name for bop_toolkit: the export folder's final name, its letters and
    digits only, lower case."""
    return re.sub(r"[^a-z0-9]", "", folder_name.lower()) or "satsight"


def visibility_delta_mm(max_depth_scale_mm: float, max_distance_mm: float) -> float:
    """The visibility tolerance (mm) that fits an export's depth quantum and range."""
    needed = 2.0 * max_depth_scale_mm + FLOAT32_DEPTH_RTOL * max_distance_mm
    return nice_ceil(max(DEFAULT_DELTA_MM, needed))


def toolkit_notes(
    name: str,
    camera: dict,
    model_info: dict,
    written: ExportedImages,
    splits: list[str],
    with_depth: bool,
    with_targets: bool,
) -> str:
    """The Markdown of ``BOP_TOOLKIT.md`` for one export.

    name: the export folder's name; bop_toolkit knows the export by ``toolkit_name(name)``.
    camera: the export's camera.json. model_info: object 1's models_info.json entry.
    written: the images written (count, largest depth_scale, distance range in mm).
    splits: the split folders written. with_depth: whether depth/ was written.
    with_targets: whether test_targets_bop19.json / bop24.json were written.
    """
    delta = visibility_delta_mm(written.max_depth_scale_mm, written.max_distance_mm)
    folder = name
    name = toolkit_name(folder)
    scene_ids = ", ".join(
        f'"{split}": {[0] if split in splits else []}' for split in ("train", "val", "test")
    )
    modalities = '["gray", "depth"]' if with_depth else '["gray"]'
    near = written.min_distance_mm if math.isfinite(written.min_distance_mm) else 0.0
    place = (
        f"1. Put (or link) this folder at `$BOP_PATH/{name}`; the folder name is the"
        if folder == name
        else f"1. Link this folder (`{folder}`) as `$BOP_PATH/{name}`, from inside it:\n"
        f'   `ln -s "$PWD" "$BOP_PATH/{name}"`. The folder name is the'
    )
    lines = [
        f"# Using this export with bop_toolkit ({name})",
        "",
        "bop_toolkit (github.com/thodan/bop_toolkit) finds datasets by name under its",
        "`BOP_PATH`. Steps, with this export's numbers:",
        "",
        place,
        "   dataset name; it must hold letters and digits only (result files are named",
        "   `METHOD_DATASET-SPLIT.csv` and split at `_` and `-`) and must not be one of",
        "   bop_toolkit's own datasets.",
        "2. In `bop_toolkit_lib/dataset_params.py`, `get_model_params`: add",
        f'   `"{name}": [1],` as the first entry of `obj_ids` and `"{name}": [],` as the',
        "   first entry of `symmetric_obj_ids` (their last entries have no trailing comma).",
        "3. In the same file, `get_split_params`: add a branch before the final `else`:",
        "",
        "   ```python",
        f'       elif dataset_name == "{name}":',
        f'           p["scene_ids"] = {{{scene_ids}}}[split]',
        f'           p["im_size"] = ({camera["width"]}, {camera["height"]})',
        f'           p["im_modalities"] = {modalities}',
        f'           p["depth_range"] = ({near:.1f}, {written.max_distance_mm:.1f})',
        "   ```",
        "",
        "4. In `scripts/eval_bop19_pose.py` (`vsd_deltas`: the one it passes on) and",
        "   `scripts/eval_calc_errors.py` (`vsd_deltas`, for running it alone), add",
        f'   `"{name}": {delta:g},`. To recompute scene_gt_info.json (it is rewritten in',
        f'   place) with `scripts/calc_gt_info.py`, set its `p["dataset"] = "{name}"`,',
        f'   `p["delta"] = {delta:g}`, `p["modality"] = None` and `p["sensor"] = None` (its',
        '   defaults "rgb" and "realsense" are for multi-sensor datasets: KeyError here).',
        "5. Run the toolkit's scripts from its folder with its Python environment first on",
        "   `PATH` (the evaluation scripts start `python` subprocesses), `BOP_PATH`,",
        f"   `BOP_RESULTS_PATH` and `BOP_EVAL_PATH` set, `--dataset {name}` (or `--datasets`)",
        "   and `--renderer_type vispy`; without a screen, with Mesa's EGL:",
        "   `PYOPENGL_PLATFORM=egl EGL_PLATFORM=surfaceless`.",
    ]
    if with_targets:
        lines += [
            "   The ground truth as a result file, and its evaluation (recall 1.0):",
            "",
            "   ```sh",
            f"   python scripts/create_pose_results_file_from_gt.py --dataset {name} \\",
            "       --targets_filename test_targets_bop19.json",
            "   python scripts/eval_bop19_pose.py --renderer_type vispy --num_workers 2 \\",
            f"       --result_filenames gt-results_{name}-test_pose.csv",
            "   ```",
        ]
    lines += [
        "",
        "## The numbers",
        "",
        f"- Images: {written.images} in splits {', '.join(splits) or '(none)'}; image size "
        f"{camera['width']} x {camera['height']} px; object 1, diameter "
        f"{model_info['diameter']:.1f} mm (models_info.json).",
        f"- Camera-object distance: {near:.1f} to {written.max_distance_mm:.1f} mm.",
        f"- Visibility tolerance (delta, VSD and calc_gt_info.py): {delta:g} mm. bop_toolkit's "
        "default of 15 mm is too small at these ranges: the depth PNGs are quantised to "
        f"depth_scale, up to {written.max_depth_scale_mm:g} mm here, and a pixel whose "
        "stored depth rounds a few mm past the rendered one would read as hidden. Rule: the "
        "smallest 1-2-5 value >= max(15 mm, 2 x max depth_scale + 1e-6 x max distance).",
        "- `cam_K` and camera.json follow bop_toolkit's pixel convention (pixel corners at "
        "integers): satsight's principal point + 0.5 px.",
        "- `models_eval/` is a copy of `models/` (the model's vertices hold the maxima MSSD "
        "and MSPD search for).",
    ]
    if with_targets:
        lines.append(
            "- `test_targets_bop19.json` (pose estimation) and `test_targets_bop24.json` "
            "(detection) list the test images in which the target shows."
        )
    else:
        lines.append("- No test image shows the target: no test targets files were written.")
    if not with_depth:
        lines.append("- No depth was exported: VSD cannot be computed, use MSSD and MSPD.")
    return "\n".join(lines) + "\n"
