"""The figure of ``satsight stats``: the histograms and the frames per distance interval."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Panels per row; more histograms (a randomised dataset's) add rows.
MAX_COLUMNS = 4


def plot_stats(stats: dict, path: Path) -> Path:
    """Draw ``stats`` (from ``dataset_stats``) as a grid of panels, four to a row (two rows
    for a dataset without randomised values), saved as PNG.

    Panels: one per histogram (range on a log axis, m; phase angle, deg; visible pixel
    fraction; exposure time, s; saturated pixel count; target V-equivalent magnitude; the
    Earth's level behind the target; then each randomised value), then frames per distance
    interval. Returns ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    panels = len(stats["histograms"]) + 1
    cols = min(MAX_COLUMNS, -(-panels // 2))
    rows = -(-panels // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 4.25 * rows), layout="constrained")
    for ax in axes.ravel()[len(stats["histograms"]) : -1]:
        ax.axis("off")
    for ax, hist in zip(axes.ravel(), stats["histograms"].values(), strict=False):
        ax.set_xlabel(hist["label"])
        ax.set_ylabel("frames x materials" if "(every material)" in hist["label"] else "frames")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        if hist["scale"] == "log":
            ax.set_xscale("log")
        if not hist["counts"]:
            ax.text(0.5, 0.5, "no values", ha="center", va="center", transform=ax.transAxes)
            continue
        edges = np.asarray(hist["edges"])
        ax.stairs(hist["counts"], edges, fill=True, alpha=0.8)
        unit = "" if hist["unit"] == "1" else f" {hist['unit']}"
        without = f" ({hist['missing']} frames without)" if hist["missing"] else ""
        summary = f"min {hist['min']:.4g}, median {hist['median']:.4g}, max {hist['max']:.4g}"
        ax.set_title(summary + unit + without, fontsize=9)
    ax = axes.ravel()[-1]
    intervals = stats["counts"]["distance_interval"]
    positions = np.arange(len(intervals))
    ax.barh(positions, list(intervals.values()))
    ax.set_yticks(positions, list(intervals))
    ax.invert_yaxis()
    ax.set_xlabel("frames")
    ax.set_ylabel("distance interval")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("frames per distance interval", fontsize=9)
    visibility = ", ".join(f"{k} {v}" for k, v in stats["counts"]["visibility"].items())
    classes = ", ".join(f"{k} ({v})" for k, v in stats["counts"]["target_class"].items())
    fig.suptitle(
        f"{stats.get('scenario') or stats['dataset']}: {stats['frame_count']} frames; "
        f"target class {classes or 'none'}\nvisibility flags (frames): {visibility}"
    )
    fig.savefig(path, dpi=90, facecolor="white")
    plt.close(fig)
    return Path(path)
