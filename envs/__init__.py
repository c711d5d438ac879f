"""Simulated worlds and the Gymnasium / PettingZoo environments built on them."""
