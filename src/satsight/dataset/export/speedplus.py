"""Export to the layout of the SPEED+ spacecraft pose dataset (Park et al. 2022).

Layout written::

    OUT/camera.json                 cameraMatrix, distCoeffs, Nu, Nv, ppx, ppy, fx, fy, ccx, ccy
    OUT/tangoPoints.mat             tango3Dpoints: the body keypoints, (3, N) metres
    OUT/keypoints.json              the same points as JSON, with how they were chosen
    OUT/DOMAIN/images/imgNNNNNN.png grey images (``images.py``), NNNNNN = frame_index + 1
    OUT/DOMAIN/train.json, validation.json, test.json
                                    [{filename, q_vbs2tango_true, r_Vo2To_vbs_true}, ...]

Pose convention (SPEED+ tools: tpark94/speedplusbaseline src/utils/utils.py
``quat2dcm`` and ``project_keypoints``, and ESA's speedplus-utils utils.py ``project``):
``q_vbs2tango_true`` is scalar-first; ``quat2dcm(q)`` is the passive matrix of q, whose
transpose is used to map the target's body points into the camera frame,
``p_cam = quat2dcm(q).T @ p_body + r``. ``quat2dcm(q).T`` is the Hamilton active matrix of
q, so ``q_vbs2tango_true`` has the same components as satsight's ``q_cam_from_body`` and
``r_Vo2To_vbs_true`` (metres, camera frame) is ``t_cam_from_body_m``.

Pixel convention: SPEED and SPEED+ put the principal point at (Nu / 2, Nv / 2) (ESA
speed-utils utils.py class ``Camera``: K = [[fx / ppx, 0, nu / 2], [0, fy / ppy, nv / 2],
[0, 0, 1]]; SPEED+ camera.json: ccx = 960, ccy = 600 for 1920 x 1200 px), the sensor
centre when pixel coordinates are measured from the outer corner of the top-left pixel.
satsight measures them from that pixel's centre (image centre ((W - 1) / 2, (H - 1) / 2)),
so the export adds 0.5 px to the principal point: a point projected with the exported
labels lands at satsight's pixel position + (0.5, 0.5), the same spot on the sensor.

The label files are written entry by entry as the images are (``JsonEntries``): memory
does not grow with the number of images.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.io import savemat

from satsight.dataset.export.images import ExportImages
from satsight.dataset.export.json_entries import JsonEntries
from satsight.dataset.export.source import ExportFrame, ExportFrames
from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError
from satsight.frames.quaternion import canonical_quaternion

#: satsight pixel position + this = SPEED+ pixel position (see the module docstring).
PIXEL_OFFSET_PX = 0.5
#: SPEED+'s label file of each satsight split.
LABEL_FILES = {"train": "train.json", "val": "validation.json", "test": "test.json"}
DEFAULT_DOMAIN = "synthetic"
KEYPOINTS_MAT = "tangoPoints.mat"
KEYPOINTS_MAT_KEY = "tango3Dpoints"
KEYPOINTS_JSON = "keypoints.json"
_PURPOSE = "the SPEED+ export"


def json_text(content: dict | list) -> str:
    """JSON with one top-level key (or list element) per line, values compact."""
    if isinstance(content, dict):
        lines = [f"  {json.dumps(k)}: {json.dumps(v, allow_nan=False)}" for k, v in content.items()]
        return "{\n" + ",\n".join(lines) + "\n}\n"
    lines = [f"  {json.dumps(v, allow_nan=False)}" for v in content]
    return "[\n" + ",\n".join(lines) + ("\n]\n" if lines else "]\n")


def image_name(frame_index: int) -> str:
    """SPEED+-style image name: img000001.png for frame 0."""
    return f"img{frame_index + 1:06d}.png"


def speedplus_K(K: np.ndarray) -> np.ndarray:
    """satsight intrinsics (pixel-centre origin) -> SPEED+ cameraMatrix (corner origin)."""
    out = np.array(K, dtype=np.float64)
    out[0, 2] += PIXEL_OFFSET_PX
    out[1, 2] += PIXEL_OFFSET_PX
    return out


def label_entry(frame: ExportFrame) -> dict:
    """One SPEED+ label: file name, scalar-first quaternion, translation in metres."""
    return {
        "filename": image_name(frame.frame_index),
        "q_vbs2tango_true": canonical_quaternion(frame.q_cam_from_body).tolist(),
        "r_Vo2To_vbs_true": frame.t_cam_from_body_m.tolist(),
    }


def _shared_camera(splits: dict[str, ExportFrames]) -> tuple[np.ndarray, tuple[int, int]]:
    """The one K and size of every frame (those of the first), or a SatsightError (SPEED+
    has one camera)."""
    first = None
    for frame in (frame for split in splits.values() for frame in split):
        if first is None:
            first = frame
            K, size = frame.K, frame.size_px
            continue
        if frame.size_px != size or not np.allclose(frame.K, K, rtol=0, atol=1e-9):
            remedy = "export them with --format bop (per-image cam_K)"
            if frame.crop:
                remedy = (
                    "a crop window moves with the target; " + remedy + " or, if the dataset "
                    "keeps full frames, without --crop"
                )
            raise SatsightError(
                "SPEED+ describes every image with one camera.json, but frame "
                f"{frame.frame_index} has other intrinsics than frame "
                f"{first.frame_index}: {remedy}"
            )
    return K, size


def camera_json(dataset: Dataset, K: np.ndarray, size: tuple[int, int]) -> dict:
    """SPEED+ camera.json for intrinsics K (satsight convention) and size (W, H)."""
    camera = dataset.header.get("camera") or {}
    try:
        focal_m = float(camera["focal_length_m"])
    except (KeyError, TypeError, ValueError):
        raise SatsightError(
            "the dataset's manifest lacks camera.focal_length_m, which SPEED+'s camera.json "
            "needs (fx, fy in metres); regenerate the dataset"
        ) from None
    pitch_x, pitch_y = focal_m / K[0, 0], focal_m / K[1, 1]
    matrix = speedplus_K(K)
    return {
        "cameraMatrix": matrix.tolist(),
        "distCoeffs": [0.0, 0.0, 0.0, 0.0, 0.0],
        "Nu": int(size[0]),
        "Nv": int(size[1]),
        "ppx": pitch_x,
        "ppy": pitch_y,
        "fx": focal_m,
        "fy": focal_m,
        "ccx": float(matrix[0, 2]),
        "ccy": float(matrix[1, 2]),
    }


def write_speedplus(
    dataset: Dataset,
    splits: dict[str, ExportFrames],
    root: Path,
    domain: str,
    images: ExportImages,
) -> list[str]:
    """Write the SPEED+ export of ``splits`` into ``root``; returns notes for the summary.

    Three passes over the frames: the shared camera, the images each needs (checked before
    anything large is written), then the images and label files, split by split.
    """
    K, size = _shared_camera(splits)
    for split in splits.values():
        for frame in split:  # fail before writing anything large
            images.require(frame, _PURPOSE)
    (root / "camera.json").write_text(json_text(camera_json(dataset, K, size)), encoding="utf-8")
    notes = write_keypoints(dataset.header, root)
    folder = root / domain / "images"
    folder.mkdir(parents=True)
    for name, split_frames in splits.items():
        # the layout of json_text: one label per line, a final newline
        path = root / domain / LABEL_FILES[name]
        with JsonEntries(path, list, final_newline=True) as labels:
            for frame in split_frames:
                target = folder / image_name(frame.frame_index)
                images.write(frame, frame.camera_mode, target, _PURPOSE)
                labels.append(label_entry(frame))
    return [images.note(), "principal point shifted +0.5 px (SPEED+ pixel origin)", *notes]


def write_keypoints(header: dict, root: Path) -> list[str]:
    """The target's body keypoints as the SPEED+ baseline reads them: ``tangoPoints.mat``
    holding ``tango3Dpoints``, (3, N) float64, metres, body frame (tpark94/speedplusbaseline
    loads ``loadmat(...)['tango3Dpoints']`` and transposes it to (N, 3)), and
    ``keypoints.json``. Returns notes for the summary (none when the manifest has no
    keypoints)."""
    target = header.get("target") or {}
    try:
        points = np.array(target["keypoints_body_m"], dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
            raise ValueError
    except (KeyError, TypeError, ValueError):
        return ["no keypoints in the manifest: no tangoPoints.mat"]
    savemat(root / KEYPOINTS_MAT, {KEYPOINTS_MAT_KEY: points.T})
    method = target.get("keypoints") or {"method": "corners"}
    document = {
        "description": "the target's keypoints in its body frame (SPEED+'s 'tango' frame, "
        "the frame q_vbs2tango_true and r_Vo2To_vbs_true place), metres; the same points as "
        f"{KEYPOINTS_MAT} ({KEYPOINTS_MAT_KEY}, one column per point)",
        "method": method,
        "keypoints_body_m": points.tolist(),
    }
    (root / KEYPOINTS_JSON).write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return [f"{len(points)} body keypoints in {KEYPOINTS_MAT}"]
