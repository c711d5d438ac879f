"""Compiled platform flight of the bearings-only world, one platform per call.

:func:`sensorgym.envs.worlds.platform.fly` loops :func:`fly_platform` over its batch and the
BearingsManeuver step kernel calls it per platform: the flight is written here once.
"""

from __future__ import annotations

import math

from numba import njit

from sensorgym.trackers.geometry import wrap_angle_scalar as wrap

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}


# sinc(x) = sin(πx) / (πx), sinc(0) = 1            (numpy's normalised sinc)
@njit(**_JIT)
def sinc(x):
    if x == 0.0:
        return 1.0
    y = math.pi * x
    return math.sin(y) / y


# ω = clip(ω_cmd, ±ω_max), Δv = clip(speed + clip(Δv_cmd, ±Δv_max), v_min, v_max) − speed,
# v = speed + Δv; exact arc: Δp = v T sinc(ωT/2π·π) (sin ψ_m, cos ψ_m), ψ_m = ψ₀ + ωT/2,
# ψ' = wrap(ψ₀ + ωT)
@njit(**_JIT)
def fly_platform(
    px, py, heading, speed, omega_cmd, dv_cmd, T, max_turn, max_dv, min_speed, max_speed
):
    """Returns the platform's ``(x, y, heading, speed)`` one step of ``T`` seconds on."""
    omega = min(max(omega_cmd, -max_turn), max_turn)
    dv = min(max(dv_cmd, -max_dv), max_dv)
    new_speed = min(max(speed + dv, min_speed), max_speed)
    v = speed + (new_speed - speed)
    half = 0.5 * omega * T
    psi_mid = heading + half
    chord = v * T * sinc(half / math.pi)
    return (
        px + chord * math.sin(psi_mid),
        py + chord * math.cos(psi_mid),
        wrap(heading + omega * T),
        v,
    )


@njit(**_JIT)
def fly_batch(pos, heading, speed, command, T, max_turn, max_dv, min_speed, max_speed):
    """In place on ``pos (M, 2)``, ``heading (M,)``, ``speed (M,)`` under ``command (M, 2)``."""
    for m in range(pos.shape[0]):
        pos[m, 0], pos[m, 1], heading[m], speed[m] = fly_platform(
            pos[m, 0],
            pos[m, 1],
            heading[m],
            speed[m],
            command[m, 0],
            command[m, 1],
            T,
            max_turn,
            max_dv,
            min_speed,
            max_speed,
        )
