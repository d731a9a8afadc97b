"""Time, Sun and Moon, orbits and visibility: where everything is at each frame."""
