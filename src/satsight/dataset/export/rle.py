"""COCO run-length encoding (RLE) of a binary mask, compressed to COCO's counts string.

The format (COCO "Data format" page, "segmentation" with RLE; pycocotools
``common/maskApi.c``: ``rleEncode``, ``rleToString``, ``rleFrString``):

- The mask's pixels are read in column-major order (down the first column, then the
  next), and ``counts`` holds the lengths of the alternating runs, the first one of
  zeros (0 when the first pixel is set). The runs sum to H x W.
- The compressed form writes ``counts`` as one ASCII string: each value is replaced by
  its difference from the value two places before it (from the fourth value on, i.e.
  index i > 2), and that signed integer is written in groups of 5 bits, least significant
  first, one character per group: ``chr(48 + group + 0x20 * more)``, characters 48-111,
  ``more`` telling that another group follows. The last group's 0x10 bit is the sign:
  the writer stops when what is left of the value (shifted arithmetically) is 0 with
  that bit clear, or -1 with it set.

A mask is then written ``{"size": [H, W], "counts": "<string>"}``, which
``pycocotools.mask.decode`` reads back.
"""

from __future__ import annotations

import numpy as np

#: The offset that makes each 6-bit group a printable character (``'0'``).
_CHAR_OFFSET = 48
_GROUP_BITS = 5
_GROUP_MASK = 0x1F
_SIGN_BIT = 0x10
_MORE_BIT = 0x20


def rle_counts(mask: np.ndarray) -> list[int]:
    """Run lengths of a (H, W) mask read column by column, zeros first (module docstring)."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"a mask is (H, W), got shape {mask.shape}")
    flat = np.ascontiguousarray(mask.T != 0).reshape(-1)
    if flat.size == 0:
        return [0]
    changes = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    bounds = np.concatenate(([0], changes, [flat.size]))
    runs = np.diff(bounds).tolist()
    return [0, *runs] if flat[0] else runs


def counts_string(counts: list[int]) -> str:
    """COCO's compressed counts string of run lengths ``counts`` (module docstring)."""
    chars = []
    for index, count in enumerate(counts):
        value = int(count) - (int(counts[index - 2]) if index > 2 else 0)
        while True:
            group = value & _GROUP_MASK
            value >>= _GROUP_BITS  # arithmetic shift: a negative value tends to -1
            done = value == (-1 if group & _SIGN_BIT else 0)
            chars.append(chr(_CHAR_OFFSET + group + (0 if done else _MORE_BIT)))
            if done:
                break
    return "".join(chars)


def encode_rle(mask: np.ndarray) -> dict:
    """COCO compressed RLE of a (H, W) mask (nonzero = set): ``{"size": [H, W],
    "counts": str}``."""
    height, width = np.shape(mask)
    return {"size": [int(height), int(width)], "counts": counts_string(rle_counts(mask))}
