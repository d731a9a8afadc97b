"""The frame plan as text: a printable table and a CSV of a ``PoseTrack``.

``plan_table_rows`` gives one display row per frame and ``write_plan_csv`` every value of
every frame, in SI units and degrees, with the unit in each column name.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from satsight.poses.track import FLAG_FIELDS, PoseTrack

# Rows of plan.csv formatted together.
CSV_CHUNK_ROWS = 8192

# Short names of the failing flags in the table's "visible" column.
FLAG_SHORT_NAMES = {
    "earth_occulted": "occulted",
    "eclipsed": "eclipse",
    "sun_excluded": "sun",
    "phase_rejected": "phase",
}


def plan_table_rows(
    track: PoseTrack, with_epoch: bool = True, frames: Sequence[int] | None = None
) -> list[dict]:
    """One dict per frame for a printed table, numbers rounded for display.

    ``frames``: the frame indices to give rows for, in that order (default: every frame; a
    printed table of a long plan asks for its first and last few only).

    Keys, in order: frame, time_s (0.1 s), epoch_utc (only when the track has epochs and
    ``with_epoch``), range_km (to the metre), phase_deg (0.1 deg), sunlit (fraction 0..1,
    3 decimals), visible ("yes", or the short names of the failing flags: occulted,
    eclipse, sun, phase) and interval.
    """
    with_epoch = with_epoch and any(track.epoch_utc)
    visible = track.visible
    rows = []
    for i in range(len(track)) if frames is None else (int(k) for k in frames):
        row: dict = {"frame": i, "time_s": round(float(track.time_s[i]), 1)}
        if with_epoch:
            row["epoch_utc"] = track.epoch_utc[i]
        row["range_km"] = round(float(track.range_m[i]) / 1000.0, 3)
        row["phase_deg"] = round(float(np.degrees(track.phase_angle_rad[i])), 1)
        row["sunlit"] = round(float(track.sunlit_fraction[i]), 3)
        if visible[i]:
            row["visible"] = "yes"
        else:
            failing = [FLAG_SHORT_NAMES[f] for f in FLAG_FIELDS if getattr(track, f)[i]]
            row["visible"] = ",".join(failing)
        row["interval"] = track.interval[i]
        rows.append(row)
    return rows


def plan_csv_columns() -> list[str]:
    """The header of ``write_plan_csv``."""
    columns = [
        "frame",
        "time_s",
        "epoch_utc",
        "interval",
        "range_m",
        "phase_angle_deg",
        "sunlit_fraction",
        "los_clearance_m",
        "sun_boresight_angle_deg",
        *FLAG_FIELDS,
        "visible",
    ]
    columns += [f"q_cam_from_body_{c}" for c in "wxyz"]
    columns += [f"t_cam_from_body_{c}_m" for c in "xyz"]
    columns += [f"rho_rtn_{c}_m" for c in "rtn"]
    for body in ("sun", "earth", "moon"):
        columns += [f"{body}_from_target_cam_{c}" for c in "xyz"]
        columns.append(f"{body}_distance_m")
    return columns


def write_plan_csv(track: PoseTrack, path: Path) -> Path:
    """Write every frame's values to ``path`` as CSV (parent folders created).

    Lengths in m, angles in deg, directions as unit vectors in camera axes, the quaternion
    scalar first; each column name carries its unit (see ``plan_csv_columns``). Floats are
    written with full precision ("nan" and "inf" where not defined); flags as true/false.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    visible = track.visible
    n = len(track)
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(plan_csv_columns())
        # Column by column, a chunk of rows at a time: the same text as one float at a time
        # (repr of each float64), several times faster for long plans.
        for start in range(0, n, CSV_CHUNK_ROWS):
            rows = slice(start, min(n, start + CSV_CHUNK_ROWS))
            columns = [
                map(str, range(rows.start, rows.stop)),
                _texts(track.time_s[rows]),
                track.epoch_utc[rows],
                track.interval[rows],
                _texts(track.range_m[rows]),
                _texts(np.degrees(track.phase_angle_rad[rows])),
                _texts(track.sunlit_fraction[rows]),
                _texts(track.los_clearance_m[rows]),
                _texts(np.degrees(track.sun_boresight_angle_rad[rows])),
                *(_flag_texts(getattr(track, name)[rows]) for name in FLAG_FIELDS),
                _flag_texts(visible[rows]),
                *(_texts(track.q_cam_from_body[rows, k]) for k in range(4)),
                *(_texts(track.t_cam_from_body_m[rows, k]) for k in range(3)),
                *(_texts(track.rho_rtn_m[rows, k]) for k in range(3)),
            ]
            for body in ("sun", "earth", "moon"):
                columns += [_texts(getattr(track, f"{body}_from_target_cam")[rows, k])
                            for k in range(3)]  # fmt: skip
                columns.append(_texts(getattr(track, f"{body}_distance_m")[rows]))
            writer.writerows(zip(*columns, strict=True))
    return path


def _texts(values: np.ndarray) -> list[str]:
    """Each float at full precision, as ``repr`` writes it ("nan", "inf" where not defined)."""
    return [repr(x) for x in values.tolist()]


def _flag_texts(values: np.ndarray) -> list[str]:
    return ["true" if x else "false" for x in values.tolist()]
