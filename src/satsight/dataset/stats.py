"""``satsight stats``: what a dataset holds, counted and binned from its labels.

Counts per distance interval, per target class and per visibility flag; histograms of the
range (log bins), phase angle, visible pixel fraction, exposure time, saturated pixel count,
the target's V-equivalent magnitude and the Earth's level behind the target (fraction of
full well); in a randomised dataset, one histogram per randomised value
(``randomized.GROUP.KEY``, each material's draws pooled over the materials). Everything
comes from the frame records (no image is read); ``stats.json`` holds the numbers and
``stats.png`` draws them. Frames without a value (a target that sends no light has no
magnitude; datasets written before a label existed lack it) are counted as ``missing``.

The records are read once, one at a time: counts are kept per group, and the histograms'
inputs as a few floats per frame (``array('d')``), so that a dataset of 10^6 frames is
summarised in tens of MB.
"""

from __future__ import annotations

import json
import re
from array import array
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError

#: The plan's visibility flags (see ``PoseTrack.record``), in the order they are shown.
VISIBILITY_FLAGS = ("visible", "earth_occulted", "eclipsed", "sun_excluded", "phase_rejected")

#: Histogram name -> (unit, bin scale, axis label) of each distribution.
DISTRIBUTIONS = {
    "range_m": ("m", "log", "range, camera to body origin (m)"),
    "phase_angle_deg": ("deg", "linear", "phase angle (deg)"),
    "visible_pixel_fraction": ("1", "linear", "visible pixel fraction (of the image)"),
    "exposure_time_s": ("s", "linear", "exposure time (s)"),
    "saturated_pixel_count": ("pixels", "linear", "saturated pixels (count)"),
    "target_v_magnitude_equivalent": ("mag", "linear", "target V-equivalent magnitude"),
    "earth_fill_fraction_p99": ("1", "linear", "Earth behind the target: p99 level / full well"),
}
#: Where a distribution's value sits in a frame record, when not at its top level.
_PATHS = {
    "exposure_time_s": ("sensor", "exposure_time_s"),
    "saturated_pixel_count": ("sensor", "saturated_pixel_count"),
    "earth_fill_fraction_p99": ("sensor", "regions", "earth", "fill_fraction_p99"),
}
MAX_BINS = 30
PHASE_BIN_DEG = 10.0
STATS_JSON, STATS_PNG = "stats.json", "stats.png"


def target_class(header: dict, frame: dict) -> str:
    """The target class of a frame: its own, else the dataset's target's.

    A procedural target is named ``CLASS-seedN``; the class is the name without the seed.
    """
    target = frame.get("target") if isinstance(frame.get("target"), dict) else None
    for source in (target, header.get("target") or {}):
        if source and source.get("satellite_class"):
            return str(source["satellite_class"])
    name = str((header.get("target") or {}).get("name", "unknown"))
    return re.sub(r"-seed\d+$", "", name)


def distance_interval(frame: dict) -> str:
    """The frame's distance interval name from its plan (``unknown`` when it has none)."""
    plan = frame.get("plan") or {}
    name = plan.get("distance_interval", plan.get("interval"))
    return "unknown" if name is None else str(name)


def _value(frame: dict, name: str) -> float | None:
    """A frame's value of distribution ``name`` (None when absent or not finite)."""
    value = frame
    for key in _PATHS.get(name, (name,)):
        value = value.get(key) if isinstance(value, dict) else None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if np.isfinite(value) else None


#: A randomised value's unit, from the end of its name.
_RANDOMIZED_UNITS = (("_e_per_dn", "e-/DN"), ("_rad", "rad"), ("_m", "m"), ("_e", "e-"))
#: The draws of each material that are pooled over the materials (one value per material).
_MATERIAL_DRAWS = ("roughness_scale", "base_color_scale", "ior_shift")


def randomized_spec(name: str) -> tuple[str, str, str]:
    """(unit, bin scale, axis label) of a randomised value ``randomized.GROUP.KEY``."""
    key = name.rsplit(".", 1)[-1]
    unit = next((u for suffix, u in _RANDOMIZED_UNITS if key.endswith(suffix)), "1")
    pooled = " (every material)" if ".materials." in name else ""
    return unit, "linear", f"{name.removeprefix('randomized.')}{pooled}"


def randomized_values(frame: dict) -> dict[str, list[float]]:
    """A frame's randomised numbers (its ``randomized`` label) by ``randomized.GROUP.KEY``:
    each group's numeric values, and each material's draws pooled over the materials."""
    record = frame.get("randomized")
    out: dict[str, list[float]] = {}
    if not isinstance(record, dict):
        return out

    def number(value) -> float | None:
        if isinstance(value, bool) or not isinstance(value, int | float):
            return None
        return float(value) if np.isfinite(value) else None

    for group, values in record.items():
        if not isinstance(values, dict):
            continue
        if group == "materials":
            for material in values.values():
                for key in _MATERIAL_DRAWS:
                    value = number(material.get(key)) if isinstance(material, dict) else None
                    if value is not None:
                        out.setdefault(f"randomized.materials.{key}", []).append(value)
            continue
        for key, value in values.items():
            if (value := number(value)) is not None:
                out[f"randomized.{group}.{key}"] = [value]
    return out


def _spec(name: str) -> tuple[str, str, str]:
    return DISTRIBUTIONS[name] if name in DISTRIBUTIONS else randomized_spec(name)


def bin_edges(values: np.ndarray, name: str) -> np.ndarray:
    """Histogram bin edges of distribution ``name`` over ``values`` (not empty)."""
    low, high = float(values.min()), float(values.max())
    bins = int(min(MAX_BINS, max(5, np.ceil(np.sqrt(values.size)))))
    scale = _spec(name)[1]
    if name == "phase_angle_deg":
        return np.arange(0.0, 180.0 + PHASE_BIN_DEG, PHASE_BIN_DEG)
    if name == "saturated_pixel_count" and high - low < bins:
        return np.arange(np.floor(low), np.floor(high) + 2.0) - 0.5  # one bin per count
    if scale == "log" and low > 0:
        if high <= low:
            low, high = low / 1.1, high * 1.1
        return np.geomspace(low, high, bins + 1)
    if high <= low:
        low, high = low - 0.5 * max(abs(low), 1e-12), high + 0.5 * max(abs(high), 1e-12)
    return np.linspace(low, high, bins + 1)


def histogram(values: Sequence[float], name: str, missing: int) -> dict:
    """JSON-ready histogram of one distribution (``values``: a list, an ``array('d')`` or
    a numpy array): unit, scale, edges, counts, summary."""
    unit, scale, label = _spec(name)
    result = {"unit": unit, "scale": scale, "label": label, "missing": missing}
    if not len(values):
        return {**result, "edges": [], "counts": [], "min": None, "median": None, "max": None}
    array = np.asarray(values, dtype=np.float64)
    edges = bin_edges(array, name)
    counts, _ = np.histogram(np.clip(array, edges[0], edges[-1]), bins=edges)
    return {
        **result,
        "edges": edges.tolist(),
        "counts": counts.tolist(),
        "min": float(array.min()),
        "median": float(np.median(array)),
        "max": float(array.max()),
    }


def dataset_stats(dataset: Dataset) -> dict:
    """Counts and histograms of a dataset's frames, JSON-ready (see the module docstring).

    Distance intervals are listed by increasing median range of their frames. One pass
    over the records; memory holds a few numbers per frame, not the records.
    """
    intervals: Counter = Counter()
    interval_ids: dict[str, int] = {}
    frame_interval = array("l")  # per frame: its interval's id
    frame_range = array("d")  # per frame: its range (inf when it has none), for the order
    classes: Counter = Counter()
    visibility = dict.fromkeys(VISIBILITY_FLAGS, 0)
    values = {name: array("d") for name in DISTRIBUTIONS}
    missing = dict.fromkeys(DISTRIBUTIONS, 0)
    randomized: dict[str, array] = {}
    randomized_frames: Counter = Counter()  # frames holding each randomised value
    count = 0
    for frame in dataset.frames:
        count += 1
        interval = distance_interval(frame)
        intervals[interval] += 1
        frame_interval.append(interval_ids.setdefault(interval, len(interval_ids)))
        range_m = _value(frame, "range_m")
        frame_range.append(np.inf if range_m is None else range_m)
        classes[target_class(dataset.header, frame)] += 1
        plan = frame.get("plan") or {}
        for flag in VISIBILITY_FLAGS:
            visibility[flag] += plan.get(flag) is True
        for name in DISTRIBUTIONS:
            value = _value(frame, name)
            if value is None:
                missing[name] += 1
            else:
                values[name].append(value)
        for name, drawn in randomized_values(frame).items():
            randomized.setdefault(name, array("d")).extend(drawn)
            randomized_frames[name] += 1
    for name in sorted(randomized):
        values[name] = randomized[name]
        missing[name] = count - randomized_frames[name]
    ids = np.asarray(frame_interval, dtype=np.int64)
    ranges = np.asarray(frame_range, dtype=np.float64)
    median = {name: float(np.median(ranges[ids == k])) for name, k in interval_ids.items()}
    order = sorted(intervals, key=lambda name: (median[name], name))
    return {
        "dataset": str(dataset.root),
        "scenario": dataset.header.get("scenario"),
        "frame_count": count,
        "complete": dataset.complete,
        "counts": {
            "distance_interval": {name: intervals[name] for name in order},
            "target_class": dict(classes),
            "visibility": visibility,
        },
        "histograms": {name: histogram(values[name], name, missing[name]) for name in values},
    }


def output_folder(dataset_root: Path, out_dir: Path) -> Path:
    """``out_dir``, checked not to lie inside the dataset (which must stay unchanged)."""
    root, out = Path(dataset_root).resolve(), Path(out_dir).resolve()
    if out == root or root in out.parents:
        raise SatsightError(
            f"--out {out_dir} lies inside the dataset {dataset_root}, which stats never "
            "changes; choose a folder outside it"
        )
    return Path(out_dir)


def write_stats(stats: dict, out_dir: Path) -> tuple[Path, Path]:
    """Write ``stats.json`` and ``stats.png`` into ``out_dir`` (created); their paths."""
    from satsight.dataset.stats_plot import plot_stats

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / STATS_JSON
    json_path.write_text(json.dumps(stats, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    png_path = plot_stats(stats, out_dir / STATS_PNG)
    return json_path, png_path


def stats_tables(stats: dict) -> list:
    """Rich tables of ``stats``: the counts, then the distributions' summaries."""
    from rich.table import Table

    counts = Table(title=f"{stats['frame_count']} frames of {stats['dataset']}")
    for column, justify in (("group", "left"), ("value", "left"), ("frames", "right")):
        counts.add_column(column, justify=justify)
    for group, values in stats["counts"].items():
        for value, count in values.items():
            counts.add_row(group.replace("_", " "), value, str(count))
    spread = Table(title="distributions")
    for column in ("quantity", "unit", "min", "median", "max", "without"):
        spread.add_column(column, justify="left" if column == "quantity" else "right")
    for name, hist in stats["histograms"].items():
        numbers = [
            "-" if hist[key] is None else f"{hist[key]:.4g}" for key in ("min", "median", "max")
        ]
        spread.add_row(name, hist["unit"], *numbers, str(hist["missing"]))
    return [counts, spread]
