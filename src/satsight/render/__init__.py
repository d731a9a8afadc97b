"""Rendering on Mitsuba 3 / Dr.Jit: ray casting, shading and the per-frame image buffers."""
