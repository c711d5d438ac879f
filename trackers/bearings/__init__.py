"""Bearings-only target motion analysis from a moving platform (paper 002 and the modern
yardsticks).

| module | role |
|--------|------|
| :mod:`.models` | state, constant-velocity / CWNA motion model, bearing measurement model |
| :mod:`.crlb` | Fisher information and (posterior) Cramér–Rao bounds |
| :mod:`.filters` | Cartesian EKF, second-order EKF and CKF, and the range-parameterised bank |
| :mod:`.maximum_likelihood` | batch maximum-likelihood (or MAP) estimator |
| :mod:`.pseudolinear` | pseudo-linear estimator |
| :mod:`.four_bearings` | paper 002: the method of fictitious bearings, ideal and block-smoothed |
"""
