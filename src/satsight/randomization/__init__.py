"""Seeded domain randomisation: what may vary from frame to frame, and each frame's draws.

``ranges`` holds the ranges of each group (materials, sun, earth, sensor, pose) as frozen
dataclasses; ``draws`` draws one frame's values from its own seed streams; ``apply`` turns
the draws into the stages' inputs (materials, sensor chain, rotations). The scenario's
``randomize`` section (``satsight.config.randomize``) builds the ranges, and
``satsight.frame_variation`` applies a frame's draws in the pipeline.
"""
