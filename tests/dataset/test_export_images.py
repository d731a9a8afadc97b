"""Exported images are the detector's DN, linearly scaled (``--image``), in every format.

The DN of the fixture's frames span the bias to 31 600 DN; on the pixels the scaling does
not clip, the exported value must be an exact linear function of the DN (a least-squares
line with R^2 = 1 and residuals within the rounding), and the export record must give the
line that turns values back into DN.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from export_datasets import DETECTOR, write_box_dataset
from satsight.dataset.export import export_dataset
from satsight.dataset.export.images import ExportImages
from satsight.dataset.export.splits import SplitRule
from satsight.dataset.image_files import read_png
from satsight.errors import SatsightError

RULE = SplitRule((0.5, 0.25, 0.25), seed=3)
BIAS_DN = DETECTOR["bias_dn"]
SATURATION_DN = BIAS_DN + DETECTOR["full_well_e"] / DETECTOR["conversion_gain_e_per_dn"]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return write_box_dataset(tmp_path_factory.mktemp("images") / "dataset")


def exported_pairs(export: Path, fmt: str, dataset: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """(frame DN, exported image) of every exported frame."""
    if fmt == "bop":
        files = {int(p.stem): p for p in export.glob("*/000000/gray/*.png")}
    else:
        files = {int(p.stem[3:]) - 1: p for p in export.glob("synthetic/images/*.png")}
    assert len(files) == 4
    return [
        (read_png(dataset / f"images/frame_{index:06d}.png"), read_png(path))
        for index, path in sorted(files.items())
    ]


def line_fit(dn: np.ndarray, value: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares value = a * DN + b: (a, b, R^2, largest residual)."""
    x, y = dn.astype(np.float64), value.astype(np.float64)
    a, b = np.polyfit(x, y, 1)
    residual = y - (a * x + b)
    r2 = 1.0 - residual.var() / y.var()
    return float(a), float(b), float(r2), float(np.abs(residual).max())


@pytest.mark.parametrize("fmt", ["bop", "speedplus"])
@pytest.mark.parametrize("mode", ["dn16", "raw16", "linear8"])
def test_exported_images_are_linear_in_dn(dataset: Path, tmp_path: Path, fmt: str, mode: str):
    out = tmp_path / "export"
    export_dataset(dataset, out, fmt, RULE, image=mode)
    record = json.loads((out / "satsight_export.json").read_text())["image"]
    camera = record["cameras"]["primary"]
    assert record["mode"] == mode and camera["bias_dn"] == BIAS_DN
    assert camera["saturation_dn"] == pytest.approx(SATURATION_DN, rel=1e-12)
    dn = np.concatenate([pair[0].ravel() for pair in exported_pairs(out, fmt, dataset)])
    value = np.concatenate([pair[1].ravel() for pair in exported_pairs(out, fmt, dataset)])
    assert np.ptp(dn) > 30000  # sky at the bias and the target far above it
    if mode == "linear8":
        assert value.dtype == np.uint8 and record["bits"] == 8
        white = camera["white_dn"]
        assert white == pytest.approx(SATURATION_DN - BIAS_DN, rel=1e-12)
        assert camera["dn_per_level"] == pytest.approx(white / 255, rel=1e-12)
        expected = np.clip(np.rint((dn - BIAS_DN) * 255.0 / white), 0, 255)
        assert np.array_equal(value, expected)
        # Off the exact line by the rounding to whole levels only: at most half a level,
        # and R^2 short of 1 by at most the rounding's variance (1/12 level^2) over y's.
        exact = (dn - BIAS_DN) * 255.0 / white
        assert np.abs(value - exact).max() <= 0.5 + 1e-9
        a, _, r2, _ = line_fit(dn, value)
        assert a == pytest.approx(255.0 / white, rel=1e-3)
        assert r2 >= 1 - (1 / 12) / value.astype(np.float64).var()
        back = value * camera["dn_per_level"] + camera["bias_dn"]  # the record's inverse
        assert np.abs(back - dn).max() <= camera["dn_per_level"] / 2 + 1e-9
    else:
        assert value.dtype == np.uint16 and record["bits"] == 16
        offset = 0.0 if mode == "raw16" else BIAS_DN
        assert np.array_equal(value.astype(np.float64), dn - offset)
        a, b, r2, worst = line_fit(dn, value)
        assert (a, b, r2, worst) == pytest.approx((1.0, -offset, 1.0, 0.0), abs=1e-6)


def test_linear8_white_level_and_clipping(dataset: Path, tmp_path: Path) -> None:
    """--white-dn 20000: the target (30 000 DN above the bias) clips at 255, the sky at 0,
    and the unclipped pixels stay on the line."""
    out = tmp_path / "export"
    export_dataset(dataset, out, "bop", RULE, image="linear8", white_dn=20000.0)
    pairs = exported_pairs(out, "bop", dataset)
    dn = np.concatenate([p[0].ravel() for p in pairs]).astype(np.float64)
    value = np.concatenate([p[1].ravel() for p in pairs])
    assert value.max() == 255 and np.all(value[dn - BIAS_DN >= 20000.0 * 254.5 / 255] == 255)
    linear = (dn > BIAS_DN) & (dn - BIAS_DN < 20000.0 * 254.5 / 255)
    assert np.array_equal(value[linear], np.rint((dn[linear] - BIAS_DN) * 255 / 20000.0))
    record = json.loads((out / "satsight_export.json").read_text())["image"]
    assert record["cameras"]["primary"]["white_dn"] == 20000.0


@pytest.mark.parametrize(
    ("mode", "white_dn", "says"),
    [("gamma", None, "unknown --image"), ("dn16", 100.0, "only to --image linear8"),
     ("linear8", -3.0, "positive number")],
)  # fmt: skip
def test_bad_image_options_are_refused(
    dataset: Path, tmp_path: Path, mode: str, white_dn: float | None, says: str
) -> None:
    with pytest.raises(SatsightError, match=says):
        export_dataset(dataset, tmp_path / "out", "bop", RULE, image=mode, white_dn=white_dn)
    assert not (tmp_path / "out").exists()


def test_far_camera_frames_use_their_own_detector_levels() -> None:
    header = {
        "sensor": {"detector": DETECTOR},
        "far_camera": {"sensor": {"detector": {**DETECTOR, "bias_dn": 200.0}}},
    }
    images = ExportImages.of_dataset(header, "dn16")
    dn = np.array([[1000, 1500]], dtype=np.uint16)
    assert images.pixels(dn, "primary").tolist() == [[0, 500]]
    assert images.pixels(dn, "far").tolist() == [[800, 1300]]
    with pytest.raises(SatsightError, match="camera_mode 'near'"):
        images.pixels(dn, "near")


def test_manifest_without_detector_is_refused_with_the_remedy() -> None:
    with pytest.raises(SatsightError, match=r"lacks sensor\.detector"):
        ExportImages.of_dataset({"sensor": {}}, "dn16")
