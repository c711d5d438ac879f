"""Throughput of sensorgym/GimbalTracking-v0: env steps per second, single and vectorised.

Run: ``.venv/bin/python benchmarks/gimbal_tracking.py [--steps 300] [--repeat 3]``; the rows
are described in ``benchmarks/env_throughput.py``; writes
``benchmarks/results/gimbal_tracking.json``.
"""

from env_throughput import main

if __name__ == "__main__":
    main("sensorgym/GimbalTracking-v0", "gimbal_tracking", __doc__.splitlines()[0])
