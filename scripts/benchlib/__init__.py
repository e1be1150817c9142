"""Benchmark modules driven by scripts/bench.

- common.py: machine information, running the `render` command and parsing its output,
  reading and writing EXR images, image error metrics. Shared by every benchmark.
- convergence.py: the speed-against-error benchmark (docs/results/speed-vs-error.md) and the
  reference images it measures against (docs/references/).
- performance.py (optional, written separately): throughput benchmarks.
"""
