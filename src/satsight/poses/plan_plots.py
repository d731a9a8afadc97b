"""The frame plan for people: figures of a ``PoseTrack``.

``write_plan_plots`` draws three PNG figures into a folder:

- ``trajectory_rtn.png``: the camera about the target in the target's RTN frame (R radial,
  T along-track, N orbit normal, in km), as one 3D view with equal axes and the three
  projections T-R, T-N and R-N (first letter horizontal). Frames are dots coloured by
  visibility, the target is a star at the origin, the first and last frames are marked.
  A scenario without an orbit (views given in the body frame) has no RTN frame:
  ``rho_rtn_m`` is NaN everywhere and this figure is skipped.
- ``range_phase.png``: range (km; log scale when it spans more than a factor of 10) and
  phase angle (deg) against time, with the distance-interval edges that fall within the
  plotted range drawn as horizontal lines and the frames' interval names shaded along the
  time axis.
- ``visibility.png``: one row per visibility flag (Earth occulted, eclipsed, Sun excluded,
  phase rejected, and "visible"), shaded where true, above the sunlit fraction and the
  Sun-boresight angle.

A plan of more than :data:`MAX_PLOTTED_FRAMES` frames is drawn from an even subset of its
frames (the first and the last included; :func:`plot_frame_indices`), so a 10^6-frame plan
plots in seconds; the visibility bands are then reduced bin by bin, each drawn frame standing
for the frames up to the next one, and a band is shaded where any frame of a bin has the
flag. The counts in the band labels are always those of the whole plan.

Time axes are in seconds after the scenario epoch, in minutes when the track spans more
than 600 s, and the frame index when every frame is at the same instant (frames of a
body-frame view grid are all at one epoch).

The same plan as a table and a CSV: ``satsight.poses.plan_table``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from satsight.errors import SatsightError
from satsight.poses.track import FLAG_FIELDS, PoseTrack

# Standard distance-interval edges (camera to target centre) and the hover distance.
STANDARD_INTERVAL_EDGES_M = (50_000.0, 40_000.0, 30_000.0, 20_000.0, 10_000.0, 5_000.0, 500.0)
HOVER_DISTANCE_M = 100_000.0

PLOT_DPI = 110
TRAJECTORY_FILE = "trajectory_rtn.png"
RANGE_PHASE_FILE = "range_phase.png"
VISIBILITY_FILE = "visibility.png"

# Times spanning more than this are plotted in minutes.
MINUTES_ABOVE_S = 600.0
# Range plotted on a log axis when max / min exceeds this.
LOG_RANGE_RATIO = 10.0
# In the 3D view an axis shorter than this fraction of the longest is drawn at this fraction
# (the RTN extents of an approach can differ by 100x; the 2D projections stay exactly equal).
MIN_BOX_SIDE_3D = 0.2
# Up to this many frames, curves also carry a marker per frame.
MARKERS_UP_TO = 200
# Longer plans are drawn from an even subset of this many frames (module docstring).
MAX_PLOTTED_FRAMES = 10_000
_FLAG_LABELS = {
    "earth_occulted": "Earth occulted",
    "eclipsed": "eclipsed",
    "sun_excluded": "Sun excluded",
    "phase_rejected": "phase rejected",
}

_VISIBLE_COLOR = "tab:green"
_HIDDEN_COLOR = "tab:red"
_FLAG_COLOR = "tab:red"
_PATH_COLOR = "0.6"
_RTN_NAMES = ("R", "T", "N")
_RTN_LABELS = ("R, radial [km]", "T, along-track [km]", "N, orbit normal [km]")
# Projections as (horizontal, vertical) RTN component indices.
_PROJECTIONS = ((1, 0), (1, 2), (0, 2))


def write_plan_plots(track: PoseTrack, out_dir: Path, title: str) -> list[Path]:
    """Draw the plan figures of ``track`` into ``out_dir`` (created if missing).

    Returns the paths written, in the order trajectory (only when the track has RTN
    positions), range and phase, visibility. ``title`` heads every figure.
    """
    if len(track) == 0:
        raise SatsightError("the pose track has no frames, so there is nothing to plot")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    heading = title.replace("$", r"\$")
    sample = plot_frame_indices(len(track))
    shown = track if sample.size == len(track) else track.select(sample)
    if shown is not track:
        heading += f" ({sample.size} of {len(track)} frames drawn)"
    paths = []
    drawers = [(RANGE_PHASE_FILE, _draw_range_phase), (VISIBILITY_FILE, _draw_visibility)]
    if has_rtn(track):
        drawers.insert(0, (TRAJECTORY_FILE, _draw_trajectory))
    for name, draw in drawers:
        fig = plt.figure(layout="constrained")
        try:
            draw(fig, track, shown, sample)
            fig.suptitle(heading)
            path = out_dir / name
            fig.savefig(path, dpi=PLOT_DPI, facecolor="white")
        finally:
            plt.close(fig)
        paths.append(path)
    return paths


def plot_frame_indices(count: int, limit: int = MAX_PLOTTED_FRAMES) -> np.ndarray:
    """The frames a plot draws, (M,) int64 ascending: all ``count`` of them up to ``limit``,
    else ``limit`` evenly spread ones, the first and the last included."""
    if limit < 2:
        raise SatsightError(f"a plot needs at least 2 frames to draw, got limit={limit}")
    if count <= limit:
        return np.arange(count, dtype=np.int64)
    return np.unique(np.round(np.linspace(0.0, count - 1.0, limit)).astype(np.int64))


def _plot_x(shown: PoseTrack, sample: np.ndarray) -> tuple[np.ndarray, str]:
    """`time_axis` of the drawn frames; a frame-index axis keeps the plan's indices."""
    x, label = time_axis(shown)
    if label.startswith("frame index"):
        x = sample.astype(np.float64)
    return x, label


def has_rtn(track: PoseTrack) -> bool:
    """Whether any frame has a camera position in the target's RTN frame."""
    return bool(np.isfinite(track.rho_rtn_m).all(axis=1).any())


# --- time axis ---------------------------------------------------------------------------


def time_axis(track: PoseTrack) -> tuple[np.ndarray, str]:
    """The x values of the time plots and their axis label.

    Seconds after the scenario epoch, minutes when the span exceeds 600 s, and the frame
    index when all frames are at one instant (or a time is not finite).
    """
    t = np.asarray(track.time_s, dtype=np.float64)
    if t.size < 2 or not np.all(np.isfinite(t)) or np.ptp(t) == 0.0:
        label = "frame index (all frames at one instant)" if t.size > 1 else "frame index"
        return np.arange(t.size, dtype=np.float64), label
    if np.ptp(t) > MINUTES_ABOVE_S:
        return t / 60.0, "time after scenario epoch [min]"
    return t, "time after scenario epoch [s]"


def _cell_edges(x: np.ndarray) -> np.ndarray:
    """(N+1,) edges of the cells that frames at ``x`` own: midpoints between neighbours."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([[2.0 * x[0] - mid[0]], mid, [2.0 * x[-1] - mid[-1]]])


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) frame indices of each run of true values."""
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    change = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(change[::2], change[1::2], strict=True)]


def _label_runs(labels: tuple[str, ...]) -> list[tuple[int, int, str]]:
    """(first, last, label) for each run of equal consecutive labels."""
    runs = []
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            runs.append((start, i - 1, labels[start]))
            start = i
    return runs


# --- figures -----------------------------------------------------------------------------


def _draw_trajectory(fig, _track: PoseTrack, track: PoseTrack, _sample: np.ndarray) -> None:
    from matplotlib.ticker import MaxNLocator

    fig.set_size_inches(12.0, 10.5)
    finite = np.isfinite(track.rho_rtn_m).all(axis=1)
    rho_km = track.rho_rtn_m[finite] / 1000.0
    visible = track.visible[finite]
    markersize = 14 if rho_km.shape[0] <= MARKERS_UP_TO else 5

    lo = np.minimum(rho_km.min(axis=0), 0.0)
    hi = np.maximum(rho_km.max(axis=0), 0.0)
    span = hi - lo
    floor = MIN_BOX_SIDE_3D * max(float(span.max()), 1e-6)
    center = 0.5 * (lo + hi)
    half = 0.5 * np.maximum(span, floor) * 1.08

    grid = fig.add_gridspec(2, 2)
    ax3 = fig.add_subplot(grid[0, 0], projection="3d")
    ax3.plot(*rho_km.T, color=_PATH_COLOR, linewidth=0.8)
    for mask, color, label in (
        (visible, _VISIBLE_COLOR, "visible"),
        (~visible, _HIDDEN_COLOR, "not visible"),
    ):
        if mask.any():
            ax3.scatter(*rho_km[mask].T, s=markersize, color=color, label=label, depthshade=False)
    ax3.scatter([0], [0], [0], marker="*", s=180, color="black", label="target")
    ax3.scatter(*rho_km[0], marker="^", s=70, color="tab:blue", label="start")
    ax3.scatter(*rho_km[-1], marker="s", s=60, color="tab:purple", label="end")
    ax3.set_xlim(center[0] - half[0], center[0] + half[0])
    ax3.set_ylim(center[1] - half[1], center[1] + half[1])
    ax3.set_zlim(center[2] - half[2], center[2] + half[2])
    ax3.set_box_aspect(tuple(half / half.max()), zoom=0.95)
    for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    ax3.set_xlabel(_RTN_LABELS[0], fontsize=8)
    ax3.set_ylabel(_RTN_LABELS[1], fontsize=8)
    ax3.set_zlabel(_RTN_LABELS[2], fontsize=8)
    ax3.tick_params(labelsize=7)
    ax3.view_init(elev=25.0, azim=-60.0)
    ax3.set_title("camera about the target, RTN frame")

    cells = (grid[0, 1], grid[1, 0], grid[1, 1])
    for cell, (h, v) in zip(cells, _PROJECTIONS, strict=True):
        ax = fig.add_subplot(cell)
        ax.plot(rho_km[:, h], rho_km[:, v], color=_PATH_COLOR, linewidth=0.8, zorder=1)
        for mask, color in ((visible, _VISIBLE_COLOR), (~visible, _HIDDEN_COLOR)):
            if mask.any():
                ax.scatter(rho_km[mask, h], rho_km[mask, v], s=markersize, color=color, zorder=2)
        ax.scatter([0], [0], marker="*", s=180, color="black", zorder=3)
        ax.scatter(rho_km[0, h], rho_km[0, v], marker="^", s=70, color="tab:blue", zorder=4)
        ax.scatter(rho_km[-1, h], rho_km[-1, v], marker="s", s=60, color="tab:purple", zorder=4)
        ax.margins(0.08)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(_RTN_LABELS[h])
        ax.set_ylabel(_RTN_LABELS[v])
        ax.set_title(f"{_RTN_NAMES[h]}-{_RTN_NAMES[v]} projection")
        ax.grid(True, linewidth=0.4, alpha=0.6)
    fig.legend(*ax3.get_legend_handles_labels(), loc="outside lower center", ncols=5)


def _draw_range_phase(fig, _track: PoseTrack, track: PoseTrack, sample: np.ndarray) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.ticker import LogFormatter

    fig.set_size_inches(11.0, 7.5)
    x, xlabel = _plot_x(track, sample)
    visible = track.visible
    range_km = track.range_m / 1000.0
    phase_deg = np.degrees(track.phase_angle_rad)
    marker = "." if len(track) <= MARKERS_UP_TO else None

    ax_range, ax_phase = fig.subplots(2, 1, sharex=True)
    for ax, y in ((ax_range, range_km), (ax_phase, phase_deg)):
        ax.plot(x, y, color=_PATH_COLOR, linewidth=1.0, marker=marker, zorder=1, label="frame")
        if (~visible).any():
            ax.scatter(
                x[~visible],
                y[~visible],
                marker="x",
                s=24,
                color=_HIDDEN_COLOR,
                zorder=3,
                label="not visible",
            )
        ax.grid(True, linewidth=0.4, alpha=0.6)

    positive = range_km[np.isfinite(range_km) & (range_km > 0)]
    if positive.size and positive.max() > LOG_RANGE_RATIO * positive.min():
        ax_range.set_yscale("log")
        ax_range.yaxis.set_major_formatter(LogFormatter())
        ax_range.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False))
    ax_range.set_ylabel("range [km]")
    ax_range.set_title("camera to target centre")
    has_edges = _draw_interval_edges(ax_range)
    _shade_intervals(ax_range, x, track.interval)

    ax_phase.set_ylim(0.0, 180.0)
    ax_phase.set_yticks(np.arange(0.0, 181.0, 30.0))
    ax_phase.set_ylabel("phase angle [deg]")
    ax_phase.set_title("Sun-target-camera angle")
    ax_phase.set_xlabel(xlabel)
    handles, labels = ax_range.get_legend_handles_labels()
    if has_edges:
        handles.append(Line2D([], [], color="tab:blue", linewidth=0.8, linestyle="--"))
        labels.append("distance-interval edge")
    fig.legend(handles, labels, loc="outside lower center", ncols=len(handles))


def _draw_interval_edges(ax) -> bool:
    """Horizontal lines at the standard interval edges inside the current y range.

    Returns whether any edge was drawn.
    """
    low, high = ax.get_ylim()
    edges = [(e / 1000.0, f"{e / 1000.0:g} km") for e in STANDARD_INTERVAL_EDGES_M]
    edges.append((HOVER_DISTANCE_M / 1000.0, f"hover {HOVER_DISTANCE_M / 1000.0:g} km"))
    transform = ax.get_yaxis_transform()
    drawn = False
    for value, label in edges:
        if low <= value <= high:
            drawn = True
            ax.axhline(value, color="tab:blue", linewidth=0.8, linestyle="--", alpha=0.7)
            ax.text(
                0.995,
                value,
                label,
                transform=transform,
                ha="right",
                va="bottom",
                fontsize=7,
                color="tab:blue",
            )
    ax.set_ylim(low, high)
    return drawn


def _shade_intervals(ax, x: np.ndarray, intervals: tuple[str, ...]) -> None:
    """Alternate shading along x for runs of frames in one interval, labelled when wide."""
    runs = _label_runs(intervals)
    if len(runs) == 1 and not runs[0][2]:
        return
    edges = _cell_edges(x)
    total = float(edges[-1] - edges[0]) or 1.0
    transform = ax.get_xaxis_transform()
    for k, (first, last, name) in enumerate(runs):
        left, right = float(edges[first]), float(edges[last + 1])
        if k % 2:
            ax.axvspan(left, right, color="0.9", zorder=0, linewidth=0)
        if name and abs(right - left) >= 0.04 * abs(total):
            ax.text(
                0.5 * (left + right),
                0.98,
                name,
                transform=transform,
                ha="center",
                va="top",
                fontsize=7,
                color="0.3",
                clip_on=True,
            )


def _draw_visibility(fig, track: PoseTrack, shown: PoseTrack, sample: np.ndarray) -> None:
    fig.set_size_inches(11.0, 7.0)
    x, xlabel = _plot_x(shown, sample)
    edges = _cell_edges(x)
    n = len(track)
    rows = [(_FLAG_LABELS[name], getattr(track, name), _FLAG_COLOR) for name in FLAG_FIELDS]
    rows.append(("visible", track.visible, _VISIBLE_COLOR))
    # Each drawn frame's bin: the plan's frames from it up to the next drawn one.
    rows = [
        (label, mask, color, np.logical_or.reduceat(mask, sample) if shown is not track else mask)
        for label, mask, color in rows
    ]

    ax_flags, ax_sun = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.2))
    ticks, tick_labels = [], []
    for k, (label, mask, color, binned) in enumerate(rows):
        y = len(rows) - 1 - k
        spans = [(edges[a], edges[b + 1] - edges[a]) for a, b in _runs(binned)]
        if spans:
            ax_flags.broken_barh(spans, (y - 0.4, 0.8), color=color, alpha=0.75, linewidth=0)
        ax_flags.axhline(y - 0.5, color="0.8", linewidth=0.5)
        ticks.append(y)
        tick_labels.append(f"{label} ({int(np.count_nonzero(mask))}/{n})")
    ax_flags.set_yticks(ticks, tick_labels)
    ax_flags.set_ylim(-0.5, len(rows) - 0.5)
    ax_flags.set_xlim(edges[0], edges[-1])
    ax_flags.set_title("visibility tests (shaded where true)")

    marker = "." if n <= MARKERS_UP_TO else None
    (sunlit,) = ax_sun.plot(
        x, shown.sunlit_fraction, color="tab:orange", marker=marker, label="sunlit fraction"
    )
    ax_sun.set_ylim(-0.03, 1.03)
    ax_sun.set_ylabel("sunlit fraction [0..1]")
    ax_sun.grid(True, linewidth=0.4, alpha=0.6)
    ax_angle = ax_sun.twinx()
    (angle,) = ax_angle.plot(
        x,
        np.degrees(shown.sun_boresight_angle_rad),
        color="tab:purple",
        marker=marker,
        label="Sun-boresight angle",
    )
    ax_angle.set_ylim(0.0, 180.0)
    ax_angle.set_yticks(np.arange(0.0, 181.0, 30.0))
    ax_angle.set_ylabel("Sun-boresight angle [deg]")
    ax_sun.legend(
        handles=[sunlit, angle],
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        ncols=2,
        fontsize=8,
        frameon=False,
    )
    ax_sun.set_xlabel(xlabel)
    ax_sun.set_title("illumination", loc="left")
