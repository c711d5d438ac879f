"""Paired differences of the crowded-env ARS runs to ``plan-search-exhaustive`` on the tuning
seeds, from the committed per-episode returns (``scores/``: 64 scenarios per batch,
``scores_32/``: 32, each with the rule rescored on the same batch).

    python research/crowded_ars/paired.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
RULE = "plan-search-exhaustive"


def main() -> None:
    for folder in ("scores", "scores_32"):
        for run in sorted((HERE / folder).glob("ars_seed0_*.json")):
            doc = json.loads(run.read_text())
            seed, episodes = doc["seed"], len(doc["returns"])
            rule = json.loads((HERE / folder / f"{RULE}_{seed}_{episodes}.json").read_text())
            d = np.asarray(doc["returns"]) - np.asarray(rule["returns"])
            ci = 1.96 * d.std(ddof=1) / np.sqrt(d.size)
            print(
                f"{folder}/{run.name}: seed {seed}, {episodes} episodes, "
                f"paired {d.mean():+.2f} ± {ci:.2f}, better/worse {(d > 0).sum()}/{(d < 0).sum()}"
            )


if __name__ == "__main__":
    main()
