"""Throughput of sensorgym/BearingsManeuver-v0: env steps per second, single and vectorised.

Run: ``.venv/bin/python benchmarks/bearings_maneuver.py [--steps 300] [--repeat 3]``; the rows
are described in ``benchmarks/env_throughput.py``; writes
``benchmarks/results/bearings_maneuver.json``.
"""

from env_throughput import main

if __name__ == "__main__":
    main("sensorgym/BearingsManeuver-v0", "bearings_maneuver", __doc__.splitlines()[0])
