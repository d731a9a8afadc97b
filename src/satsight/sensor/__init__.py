"""The sensor chain: optics (MTF, PSF, focal-plane irradiance) and the detector."""
