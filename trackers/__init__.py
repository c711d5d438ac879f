"""Trackers: pure, batched estimators for passive location (stereo conjugation, bearings-only
motion analysis, angle prediction, multi-channel fusion). Deterministic functions of their
inputs; noise is drawn only in the simulated worlds under :mod:`sensorgym.envs`."""
