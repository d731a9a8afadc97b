"""The images an export writes: the detector's DN, linearly scaled, or the preview.

A pose network trained on exported images should see what a camera gives: a linear
function of the light. The modes (``--image``):

``dn16`` (default)
    16-bit PNG of the DN above the bias: ``value = clip(DN - bias_dn, 0, 65535)``. Space
    reads about 0 (read noise below the bias clips to 0), a pixel at full well reads
    ``full_well_dn - bias_dn``. Exactly linear in DN wherever DN >= bias_dn.
``raw16``
    16-bit PNG of the DN as read out (bias included): the dataset's own ``images/`` file.
``linear8``
    8-bit PNG with one fixed gain per camera, like a camera's 8-bit readout:
    ``value = clip(round((DN - bias_dn) * 255 / white_dn), 0, 255)``, ``white_dn`` the DN
    above the bias that reads 255 (default: the detector's saturation level, full well
    or ADC maximum, whichever is lower, minus the bias). Linear up to white, rounded to
    the nearest level (half to even).
``preview``
    The 8-bit display previews (asinh or gamma stretch): for looking, not for training.

The mode, its formula and each camera's ``bias_dn`` and ``white_dn`` go into the export's
``satsight_export.json`` (``image``), so a user can turn exported values back into DN.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.export.source import ExportFrame, read_png, require_file
from satsight.dataset.image_files import encode_png
from satsight.dataset.preview import PreviewStretch
from satsight.errors import SatsightError

IMAGE_MODES = ("dn16", "raw16", "linear8", "preview")
DEFAULT_IMAGE_MODE = "dn16"
UINT16_MAX = 65535
UINT8_MAX = 255

FORMULAS = {
    "dn16": "value = clip(DN - bias_dn, 0, 65535), uint16",
    "raw16": "value = DN (as read out, bias included), uint16",
    "linear8": "value = clip(round_half_even((DN - bias_dn) * 255 / white_dn), 0, 255), uint8",
    "preview": "the dataset's 8-bit display preview (non-linear stretch, see labels.json preview)",
}


@dataclass(frozen=True)
class DetectorLevels:
    """One camera's DN levels: bias (black) and saturation (the lower of full well in DN
    and the ADC's largest value), both as read out."""

    bias_dn: float
    saturation_dn: float

    @classmethod
    def from_sensor(cls, sensor: dict | None, where: str) -> DetectorLevels:
        detector = (sensor or {}).get("detector") or {}
        try:
            bias = float(detector["bias_dn"])
            full_well = bias + float(detector["full_well_e"]) / float(
                detector["conversion_gain_e_per_dn"]
            )
            adc_max = float((1 << int(detector["adc_bits"])) - 1)
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            raise SatsightError(
                f"the dataset's manifest lacks {where}.detector (bias_dn, full_well_e, "
                "conversion_gain_e_per_dn, adc_bits), which the exported images need; "
                "regenerate the dataset"
            ) from None
        return cls(bias, min(full_well, adc_max))


def camera_levels(header: dict) -> dict[str, DetectorLevels]:
    """Camera mode (``primary``, and ``far`` when the dataset has one) -> its levels."""
    levels = {"primary": DetectorLevels.from_sensor(header.get("sensor"), "sensor")}
    far = header.get("far_camera")
    if far:
        levels["far"] = DetectorLevels.from_sensor(far.get("sensor"), "far_camera.sensor")
    return levels


@dataclass(frozen=True)
class ExportImages:
    """How an export turns a frame's DN into the image it writes (module docstring).

    mode: one of ``IMAGE_MODES``. levels: camera mode -> bias and saturation.
    white_dn: for ``linear8``, the DN above the bias that reads 255 (None: each camera's
    saturation level minus its bias). stretch: the previews' stretch (``preview`` mode,
    for datasets without preview files).
    """

    mode: str
    levels: dict[str, DetectorLevels]
    white_dn: float | None = None
    stretch: PreviewStretch | None = None

    def __post_init__(self) -> None:
        if self.mode not in IMAGE_MODES:
            raise SatsightError(
                f"unknown --image {self.mode!r}; choose one of {', '.join(IMAGE_MODES)}"
            )
        if self.white_dn is not None:
            if self.mode != "linear8":
                raise SatsightError("--white-dn applies only to --image linear8")
            if not (np.isfinite(self.white_dn) and self.white_dn > 0):
                raise SatsightError(f"--white-dn must be a positive number, got {self.white_dn}")

    @classmethod
    def of_dataset(cls, header: dict, mode: str, white_dn: float | None = None) -> ExportImages:
        """The image rule for a dataset's manifest (``header``)."""
        stretch = PreviewStretch.from_header(header.get("preview")) if mode == "preview" else None
        return cls(mode, camera_levels(header), white_dn, stretch)

    @property
    def bits(self) -> int:
        return 16 if self.mode in ("dn16", "raw16") else 8

    def white_of(self, camera_mode: str) -> float:
        """DN above the bias that reads 255 in ``linear8``."""
        levels = self._levels(camera_mode)
        if self.white_dn is not None:
            return float(self.white_dn)
        return levels.saturation_dn - levels.bias_dn

    def _levels(self, camera_mode: str) -> DetectorLevels:
        try:
            return self.levels[camera_mode]
        except KeyError:
            raise SatsightError(
                f"a frame has camera_mode {camera_mode!r}, which the manifest does not "
                "describe; the dataset is damaged: regenerate it"
            ) from None

    def source_key(self, frame: ExportFrame) -> str:
        """The file key the frame's image is made from."""
        if self.mode == "preview" and "preview_png8" in frame.files:
            return "preview_png8"
        return "dn_png16"

    def require(self, frame: ExportFrame, purpose: str) -> Path:
        """The path of the file the frame's image is made from, or a SatsightError."""
        if self.mode == "preview" and "preview_png8" not in frame.files:
            if "dn_png16" not in frame.files:
                raise SatsightError(
                    f"{purpose} needs an image, and {'crop' if frame.crop else 'frame'} "
                    f"{frame.frame_index} has neither preview_png8 nor dn_png16; regenerate "
                    "the dataset with 'preview' or 'dn' in outputs.files"
                )
        key = self.source_key(frame)
        if key == "dn_png16" and key not in frame.files and "preview_png8" in frame.files:
            raise SatsightError(
                f"{purpose} needs the DN images (dn_png16, output 'dn'), which "
                f"{'crop' if frame.crop else 'frame'} {frame.frame_index} lacks; regenerate "
                "the dataset with 'dn' in outputs.files, or export its display previews with "
                "--image preview (not linear in the light)"
            )
        return require_file(frame, key, purpose)

    def pixels(self, dn: np.ndarray, camera_mode: str) -> np.ndarray:
        """The exported image of a raw DN image ``dn`` ((H, W) uint16) of a camera."""
        levels = self._levels(camera_mode)
        bias = levels.bias_dn
        if self.mode == "raw16":
            return np.asarray(dn, dtype=np.uint16)
        if self.mode == "dn16":
            above = np.asarray(dn, dtype=np.float64) - bias
            return np.clip(np.rint(above), 0, UINT16_MAX).astype(np.uint16)
        if self.mode == "linear8":
            gain = UINT8_MAX / self.white_of(camera_mode)
            lut = np.clip(np.rint((np.arange(65536.0) - bias) * gain), 0, UINT8_MAX)
            return lut.astype(np.uint8)[np.asarray(dn, dtype=np.uint16)]
        stretch = self.stretch or PreviewStretch()
        return stretch.apply(dn, bias, levels.saturation_dn)

    def write(self, frame: ExportFrame, camera_mode: str, target: Path, purpose: str) -> str:
        """Write the frame's exported image to ``target`` (PNG); returns its source key."""
        source = self.require(frame, purpose)
        key = self.source_key(frame)
        if key == "preview_png8" or self.mode == "raw16":  # already the image: copied
            shutil.copyfile(source, target)
            return key
        width, height = frame.size_px
        dn = read_png(source)
        if dn.shape != (height, width) or dn.dtype != np.uint16:
            raise SatsightError(
                f"{source}: expected a {width} x {height} uint16 DN image, found shape "
                f"{dn.shape} {dn.dtype}; the dataset is damaged: regenerate it"
            )
        target.write_bytes(encode_png(self.pixels(dn, camera_mode), noisy=True))
        return key

    def record(self) -> dict:
        """The rule as ``satsight_export.json`` holds it (``image``)."""
        entry: dict = {"mode": self.mode, "bits": self.bits, "formula": FORMULAS[self.mode]}
        entry["cameras"] = {}
        for name, levels in self.levels.items():
            camera = {"bias_dn": levels.bias_dn, "saturation_dn": levels.saturation_dn}
            if self.mode == "linear8":
                camera["white_dn"] = self.white_of(name)
                camera["dn_per_level"] = self.white_of(name) / UINT8_MAX
            entry["cameras"][name] = camera
        if self.mode == "preview" and self.stretch is not None:
            entry["stretch"] = self.stretch.header()
        return entry

    def note(self) -> str:
        """One phrase for the export's summary line."""
        return {
            "dn16": "images: 16-bit DN above the bias",
            "raw16": "images: 16-bit DN as read out",
            "linear8": "images: 8-bit, linear in DN",
            "preview": "images: 8-bit previews (display stretch, not linear)",
        }[self.mode]
