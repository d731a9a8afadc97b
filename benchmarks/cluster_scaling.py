"""Benchmark a Dask LocalCluster's scaling; prints JSON (seconds per frame, speed-up).

Usage: python benchmarks/cluster_scaling.py [--frames 40]
One worker held to one core against one worker per core (``satsight.tools.dataset_benchmark
.run_cluster_scaling``), each on the first N frames of the RSSF example at 1024 x 1024.
"""

import sys

from satsight.tools.dataset_benchmark import main

if __name__ == "__main__":
    main(["--cluster-scaling", *sys.argv[1:]])
