"""Stereo / multi-receiver passive location (papers 000 and 003).

| module | role |
|--------|------|
| :mod:`.conjugation` | least-squares conjugation of direction vectors: ranges, velocity, acceleration and ``σ²(AᵀA)⁻¹``; the exact angle-noise covariance of the n = 3 velocity fix |
| :mod:`.conjugation_kernels` | compiled closed forms of the two- and three-receiver systems |
| :mod:`.information` | position Fisher information, observability test, bound and log-ratio reward (unchecked, batched: what envs and rules call) |
| :mod:`.accuracy` | closed-form range accuracies and the checked Fisher-information API |
| :mod:`.association` | grouping, gating and selection shared by the multi-object trackers |
| :mod:`.period_tracking` | paper 000: tracking several objects over scan periods |
| :mod:`.algebraic_detection` | paper 003, algebraic approach: motion from one scan period |
| :mod:`.algorithmic_detection` | paper 003, algorithmic approach: velocity-aware track initiation |
| :mod:`.kalman` | masked multi-receiver position fixes and a constant-velocity Kalman filter |
"""
