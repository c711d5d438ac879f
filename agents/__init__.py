"""Heuristic observation-control rules with SB3's ``predict`` interface."""
