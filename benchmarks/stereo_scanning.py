"""Throughput of sensorgym/StereoScanning-v0: env steps per second, single and vectorised.

Run: ``.venv/bin/python benchmarks/stereo_scanning.py [--steps 300] [--repeat 3]``; the rows
are described in ``benchmarks/env_throughput.py`` (interleaved with CartPole-v1); writes
``benchmarks/results/stereo_scanning.json`` (not committed: the coordinator reruns it).
"""

from env_throughput import main

if __name__ == "__main__":
    main("sensorgym/StereoScanning-v0", "stereo_scanning", __doc__.splitlines()[0])
