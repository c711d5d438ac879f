"""Simulated worlds: the objects, platforms and sensor measurements the trackers work on.

The passive stereo world of papers 000 and 003 (:mod:`.stereo`, with its receivers
:mod:`.scanning`, objects :mod:`.drones` and static scenes :mod:`.stereo_scene`), the gimbal
angles of paper 001 (:mod:`.gimbal`), the platform/target bearings world of paper 002 and the
bearings-only benchmark (:mod:`.platform`) and the imaging channels of paper 004
(:mod:`.imaging`). Environments and reproductions build on them; a world imports no tracker
(trackers run on a world's output, in the envs or in :mod:`sensorgym.reproduce.experiments`).
"""
