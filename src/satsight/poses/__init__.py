"""Where the camera is relative to the target for each frame."""
