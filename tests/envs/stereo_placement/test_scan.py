"""The scan period of moving receivers and its conjugation fix (envs/stereo_placement/scan.py): the
documented covariance mapping, its Monte Carlo check, and OC-3's clustered-versus-circle case."""

from __future__ import annotations

import numpy as np

from sensorgym.envs.stereo_placement import simulation as core
from sensorgym.envs.stereo_placement.scan import boresight_rotations, scan
from sensorgym.envs.stereo_placement.simulation import PlacementParams
from sensorgym.envs.worlds.scanning import ReceiverLayout
from sensorgym.envs.worlds.stereo_scene import perturb_directions
from sensorgym.trackers.stereo.conjugation import solve_conjugation


def test_reported_covariance_is_the_papers_model_at_sigma_e_equal_sigma_ang_mean_range():
    """The documented mapping, recomputed independently from the same noise draw: frames
    looking at the aim point, ``solve_conjugation(order=1, sigma_e=σ_ang·mean r̂)``, and the
    solution taken from frame 1 to the world at the period end."""
    d, tau, sigma = np.array([0.0, 0.25, 0.6]), 1.0, 2e-3
    start = np.array([[[0.0, 0.0, 0.0], [70.0, 0.0, -10.0], [-20.0, 0.0, 80.0]]])
    end = start + np.array([[[4.0, 0.0, 0.0], [0.0, 0.0, 3.0], [-3.0, 0.0, -3.0]]])
    drone, velocity = np.array([[30.0, 45.0, 60.0]]), np.array([[9.0, 0.0, -4.0]])
    aim = drone + np.array([[5.0, -3.0, 2.0]])
    fix, geometry = scan(
        d, tau, sigma, 1.2, start, end, drone, velocity, aim, np.random.default_rng(3)
    )
    z = perturb_directions(geometry.los, sigma, np.random.default_rng(3))
    R = boresight_rotations(geometry.origins, aim, 1.2)
    layout = ReceiverLayout(R[0], geometry.origins[0])
    P, b = layout.relative
    a = np.einsum("kji,kj->ki", R[0], z[0])
    first = solve_conjugation(a[0], a[1:], P, b, d[1:], order=1)
    sol = solve_conjugation(a[0], a[1:], P, b, d[1:], order=1, sigma_e=sigma * first.ranges.mean())
    np.testing.assert_allclose(fix.range_sigma[0], sol.range_sigma, rtol=1e-9)
    q_vv = np.trace(sol.covariance[3:, 3:])
    np.testing.assert_allclose(fix.velocity_sigma[0], np.sqrt(q_vv), rtol=1e-9)
    np.testing.assert_allclose(fix.velocity[0], R[0, 0] @ sol.velocity, rtol=1e-9)
    at_end = (
        geometry.origins[0, 0] + R[0, 0] @ sol.position + (tau - d[0]) * (R[0, 0] @ sol.velocity)
    )
    np.testing.assert_allclose(fix.position[0], at_end, rtol=1e-9)
    assert np.linalg.norm(fix.position[0] - drone[0]) < 5.0  # and it is a real fix


def test_reported_velocity_sigma_is_close_to_the_monte_carlo_scatter():
    """The papers' i.i.d. model is only an approximation of angular noise (module docstring of
    scan.py): on the √2·h circle the reported velocity σ is within 30 % of the scatter."""
    N, h = 4000, 50.0
    ang = np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
    ring = np.stack([np.sqrt(2.0) * h * np.sin(ang), 0.0 * ang, np.sqrt(2.0) * h * np.cos(ang)], -1)
    o = np.broadcast_to(ring, (N, 3, 3))
    p = np.broadcast_to([0.0, h, 0.0], (N, 3))
    v = np.broadcast_to([8.0, 0.0, 3.0], (N, 3))
    rng = np.random.default_rng(13)
    fix, _ = scan(np.array([0.0, 0.25, 0.6]), 1.0, 1e-3, 1.2, o, o, p, v, p, rng)
    scatter = np.sqrt(np.mean(np.sum((fix.velocity - v) ** 2, axis=-1)))
    assert 0.7 < np.median(fix.velocity_sigma) / scatter < 1.3


def test_scan_of_any_layout_uses_the_kernels_the_env_compiled():
    """Broadcast (strided) inputs to :func:`scan` reach the kernels C-ordered, as the env's own
    arrays do: no second compile (15 s on a fresh install) for another layout."""
    from sensorgym.envs.stereo_placement import kernels

    params = PlacementParams(delays=(0.3, 0.3, 0.3))  # every period degenerate: the slow rows
    state = core.reset(params, np.random.default_rng(0), 2)
    core.step(params, state, np.zeros((2, 6)), np.random.default_rng(0))
    env_layouts = set(kernels.period_systems.signatures) | set(kernels.period_finish.signatures)
    assert env_layouts
    o = np.broadcast_to([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [0.0, 0.0, 40.0]], (4, 3, 3))
    p = np.broadcast_to([10.0, 50.0, 20.0], (4, 3))
    v = np.broadcast_to([8.0, 0.0, 3.0], (4, 3))
    scan(np.array([0.0, 0.25, 0.6]), 1.0, 1e-3, 1.2, o, o, p, v, p, np.random.default_rng(1))
    assert set(kernels.period_systems.signatures) | set(kernels.period_finish.signatures) == (
        env_layouts
    )


def test_noisy_fixes_on_a_circle_are_accurate_and_clustered_ones_are_not():
    """OC-3: the same drones fixed from a 15 m cluster and from the √2·h circle."""
    params = PlacementParams()
    rng = np.random.default_rng(12)
    state = core.reset(params, rng, 400)
    clustered = np.linalg.norm(state.fix.position - state.drone_position, axis=-1)
    p = state.drone_position
    ang = np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
    rho = np.sqrt(2.0) * p[:, 1:2]
    ring = np.stack(
        [p[:, :1] + rho * np.sin(ang), 0.0 * rho * ang, p[:, 2:] + rho * np.cos(ang)], -1
    )
    circle = core.start(params, ring, p, state.drone_velocity, rng)
    on_circle = np.linalg.norm(circle.fix.position - p, axis=-1)
    assert np.median(on_circle) < 1.0 < 5.0 < np.median(clustered)
    assert np.median(circle.bound) < 0.2 * np.median(state.bound)
    assert np.median(circle.fix.condition) < np.median(state.fix.condition)
