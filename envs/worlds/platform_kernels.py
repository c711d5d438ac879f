"""Compiled primitives of the bearings-only world, one platform or target per call.

:func:`sensorgym.envs.worlds.platform.fly`, :func:`~sensorgym.envs.worlds.platform.
propagate_target` and :func:`~sensorgym.envs.worlds.platform.noisy_bearings` loop
:func:`fly_platform`, :func:`propagate_target` and :func:`noisy_bearing` over their batches, and
the BearingsManeuver kernels and rules call them per row: each formula is written here once.
"""

from __future__ import annotations

import math

from numba import njit

from sensorgym.trackers.bearings.models import bearing_scalar
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


# x' = F x + w: position += T · velocity; w = G ε (G Gᵀ = Q, ε standard normal) when q̃ > 0
@njit(**_JIT)
def propagate_target(x, eps, G, T, q_tilde, out):
    """Writes the target state ``out (4,)`` one step of ``T`` seconds on from ``x (4,)``;
    ``eps (4,)`` and ``G (4, 4)`` are read only when ``q̃ > 0``."""
    for i in range(2):
        out[i] = x[i] + T * x[i + 2]
        out[i + 2] = x[i + 2]
    if q_tilde > 0.0:
        for i in range(4):
            w = 0.0
            for j in range(4):
                w += eps[j] * G[i, j]
            out[i] += w


# z = wrap(β + σ ε),  β = atan2(x_t − x_p, y_t − y_p)  (from North clockwise)
@njit(**_JIT)
def noisy_bearing(tx, ty, px, py, sigma, eps):
    return wrap(bearing_scalar(tx, ty, px, py) + sigma * eps)


@njit(**_JIT)
def propagate_batch(x, eps, G, T, q_tilde, out):
    for m in range(x.shape[0]):
        propagate_target(x[m], eps[m] if q_tilde > 0.0 else x[m], G, T, q_tilde, out[m])


@njit(**_JIT)
def noisy_bearing_batch(target, platform, sigma, eps, out):
    for m in range(out.shape[0]):
        out[m] = noisy_bearing(
            target[m, 0], target[m, 1], platform[m, 0], platform[m, 1], sigma, eps[m]
        )
