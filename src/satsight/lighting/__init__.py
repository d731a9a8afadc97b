"""Light at the target: the Sun, earthshine and other bodies as spherical harmonics."""
