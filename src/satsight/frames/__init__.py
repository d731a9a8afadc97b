"""Pure rotation and rigid-transform math (no rendering, no I/O)."""
