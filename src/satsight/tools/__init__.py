"""Tools that use the pipeline: the radiative-model ablation, light curves, and the render
and dataset benchmarks (``satsight ablate``, ``lightcurve``, ``bench``)."""
