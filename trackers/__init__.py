"""Trackers: pure, batched estimators for passive location, grouped by domain.

| subpackage | holds |
|------------|-------|
| :mod:`.stereo` | conjugation least squares, its accuracy and the position information, multi-object association and tracking over scan periods (papers 000, 003) |
| :mod:`.bearings` | bearings-only motion analysis: models, bounds, filters, batch estimators (paper 002) |
| :mod:`.angles` | angle prediction through target loss (paper 001) |
| :mod:`.fusion` | multi-channel fusion weighted by detection probability (paper 004) |

Shared by all: :mod:`.geometry` (frames, rotations, angles) and :mod:`.validation` (input
checks). Trackers are deterministic functions of their inputs; noise is drawn only in the
simulated worlds under :mod:`sensorgym.envs`.
"""
