"""Stable-baselines3 training on vectorised sensorgym environments."""
