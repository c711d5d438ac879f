"""Angle prediction while a gimbal loses its target (paper 001).

| module | role |
|--------|------|
| :mod:`.prediction` | the paper's azimuth/elevation predictor through a short loss |
| :mod:`.baselines` | line-fit and Kalman angle predictors to compare it with |
"""
