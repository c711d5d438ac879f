"""Throughput of sensorgym/StereoPlacement-v0: env steps per second, single and vectorised.

Run: ``.venv/bin/python benchmarks/stereo_placement.py [--steps 300] [--repeat 3]``; the rows
are described in ``benchmarks/env_throughput.py``; writes
``benchmarks/results/stereo_placement.json``.
"""

from env_throughput import main

if __name__ == "__main__":
    main("sensorgym/StereoPlacement-v0", "stereo_placement", __doc__.splitlines()[0])
