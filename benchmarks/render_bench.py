"""Benchmark the render stage; prints JSON (median seconds per frame per image size).

Usage: python benchmarks/render_bench.py [--frames 5] [--sizes 1024x1024,4096x4112]
Same as ``satsight bench``.
"""

from satsight.tools.render_benchmark import main

if __name__ == "__main__":
    main()
