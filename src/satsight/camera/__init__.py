"""Camera geometry: the pinhole model, its intrinsics and the paper's presets."""
