"""Host (NumPy) values handed to the kernels in memory Dr.Jit allocates.

Dr.Jit maps a NumPy array's memory instead of copying it, and a kernel that reads a mapped
array element by element is compiled for its alignment: 64 bytes or not, which for arrays
made afresh each frame changes from frame to frame (NumPy's allocations are 16-byte
aligned). Each alignment then compiles kernels of its own (0.1-0.5 s each on the CPU, and
as many again cached on disk). An array copied once into memory of Dr.Jit's own is
always aligned, so the frame's kernels are the same every frame.
"""

from __future__ import annotations

import numpy as np


def kernel_array(array_type, values: np.ndarray):
    """``values`` (1-D NumPy) as an evaluated ``array_type`` (a Dr.Jit 1-D array type of
    the active variant, e.g. ``mi.Float``) in memory Dr.Jit allocated (64-byte aligned)."""
    import drjit as dr

    mapped = array_type(np.ascontiguousarray(values))
    n = dr.width(mapped)
    owned = dr.empty(array_type, n)  # (a gather from an arange would be the mapped array)
    dr.scatter(owned, mapped, dr.arange(dr.uint32_array_t(array_type), n))
    dr.eval(owned)
    return owned
