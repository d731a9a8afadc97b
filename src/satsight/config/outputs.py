"""Which files a dataset holds for each frame: the output profile and the target crop.

Each output costs disk and encoding time (measured on a 4096 x 4112 frame, 2-core CPU;
see docs/dataset_format.md); a user who needs only DN images, labels and masks should not
pay for 3 float32 EXRs per frame.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from satsight.dataset.output_files import OUTPUT_FILE_KEYS
from satsight.dataset.preview import (
    DEFAULT_ASINH_SOFTENING_DN,
    DEFAULT_PREVIEW_STRETCH,
    PreviewStretch,
    PreviewStretchName,
)
from satsight.errors import SatsightError

OutputName = Literal["dn", "preview", "radiance", "depth", "normals", "masks"]
ALL_OUTPUTS: tuple[str, ...] = tuple(OUTPUT_FILE_KEYS)
#: Named profiles accepted by ``--outputs``.
OUTPUT_PROFILES: dict[str, tuple[str, ...]] = {
    "all": ALL_OUTPUTS,
    "lean": ("dn", "masks"),
}


class CropConfig(BaseModel):
    """A fixed-size square crop centred on the target's projected box centre.

    size_px: side of the crop (pixels). full_frame: also write the full frame's files
    (False: only the crops, which is what pose networks train on at long range).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    size_px: int = Field(ge=16, le=8192)
    full_frame: bool = True


class OutputsConfig(BaseModel):
    """The files written per frame (labels are always written).

    preview_stretch: how raw DN become the 8-bit previews (``asinh`` or ``gamma``, see
    ``satsight.dataset.preview``). preview_softening_dn: the asinh stretch's softening,
    DN above the bias (unused by ``gamma``). exr_compression: the lossless compression of
    the radiance, depth and normals EXRs (``satsight.dataset.image_files.EXR_COMPRESSIONS``):
    ``rle`` (default, every OpenEXR reader), ``zip`` (every reader, files with the Earth in
    view about 9x smaller, 2.5x slower to write), ``htj2k`` (OpenEXR 3.4 or newer) or
    ``zstd`` (OpenEXR 3.5 or newer; about 19x smaller and 1.5x faster than RLE).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    files: tuple[OutputName, ...] = ALL_OUTPUTS
    crop: CropConfig | None = None
    contact_sheet: bool = True
    preview_stretch: PreviewStretchName = DEFAULT_PREVIEW_STRETCH
    preview_softening_dn: float = Field(default=DEFAULT_ASINH_SOFTENING_DN, gt=0, le=65535)
    exr_compression: Literal["rle", "zip", "htj2k", "zstd"] = "rle"

    @field_validator("files")
    @classmethod
    def _canonical(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(value)) != len(value):
            raise ValueError(f"outputs.files lists a name twice: {list(value)}")
        # Canonical order, so that equal choices hash equal.
        return tuple(name for name in ALL_OUTPUTS if name in value)

    def file_keys(self) -> tuple[str, ...]:
        """The file keys (``dn_png16``, ...) of the chosen outputs."""
        return tuple(key for name in self.files for key in OUTPUT_FILE_KEYS[name])

    def build_preview(self) -> PreviewStretch:
        """The stretch of the 8-bit previews this block chooses."""
        return PreviewStretch(self.preview_stretch, self.preview_softening_dn)


def parse_outputs_option(text: str) -> tuple[str, ...]:
    """The output names of a ``--outputs`` value: a profile (all, lean) or a comma list."""
    text = text.strip()
    if text in OUTPUT_PROFILES:
        return OUTPUT_PROFILES[text]
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    unknown = [name for name in names if name not in OUTPUT_FILE_KEYS]
    if unknown or not names:
        raise SatsightError(
            f"--outputs {text!r}: unknown output {', '.join(unknown) or '(none given)'}; give "
            f"'all', 'lean' or a comma list of {', '.join(ALL_OUTPUTS)}"
        )
    return names
