"""The outputs block: which preview stretch and EXR compression it chooses, and the values
it refuses."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from satsight.config.outputs import OutputsConfig
from satsight.dataset.preview import DEFAULT_ASINH_SOFTENING_DN, PreviewStretch


def test_outputs_choose_the_stretch() -> None:
    default = OutputsConfig()
    assert default.preview_stretch == "asinh"
    assert default.preview_softening_dn == DEFAULT_ASINH_SOFTENING_DN
    assert default.build_preview() == PreviewStretch()
    assert OutputsConfig(preview_softening_dn=8.0).build_preview() == PreviewStretch("asinh", 8.0)
    assert OutputsConfig(preview_stretch="gamma").build_preview().name == "gamma"


def test_outputs_choose_the_exr_compression() -> None:
    assert OutputsConfig().exr_compression == "rle"
    assert OutputsConfig(exr_compression="zstd").exr_compression == "zstd"


@pytest.mark.parametrize(
    "bad",
    [{"preview_stretch": "log"}, {"preview_softening_dn": 0}, {"exr_compression": "piz"}],
)
def test_outputs_refuse_an_unknown_stretch_or_softening(bad: dict) -> None:
    with pytest.raises(ValidationError, match=next(iter(bad))):
        OutputsConfig(**bad)
