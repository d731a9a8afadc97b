"""Benchmark ``satsight generate`` end to end; prints JSON (seconds per frame, CPU, memory).

Usage: python benchmarks/dataset_bench.py [--frames 21]
Same as ``satsight bench --dataset N``; see ``satsight.tools.dataset_benchmark`` for what is timed.
"""

from satsight.tools.dataset_benchmark import main

if __name__ == "__main__":
    main()
