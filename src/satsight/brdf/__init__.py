"""Measured BRDFs and the fitting of the reflection models to them (``satsight fit-brdf``).

A tool beside the frame pipeline, like the ablation: it evaluates the renderer's models
(``satsight.render.phong``, ``ggx``) in numpy and writes parameters in the material
library's form."""
