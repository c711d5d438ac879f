"""Fisher information and CRLBs: unobservability, incremental = batch, PCRLB, batching."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgym.reproduce.experiments.bot_benchmark import BotScenario
from sensorgym.trackers.bearings.crlb import (
    add_bearing_information,
    batch_information,
    bearing_information,
    covariance_square_root,
    crlb,
    factor_position_rms_bound,
    factor_range_bound,
    observability,
    position_rms_bound,
    posterior_information,
    predict_bound_factor,
    predict_information,
    range_bound,
    relative_range_bound,
    transport_information,
    update_bound_factor,
)
from sensorgym.trackers.bearings.models import (
    bearing,
    cv_transition,
    cwna_covariance,
    cwna_covariance_factor,
)

SIGMA = np.deg2rad(1.0)


def _geometry(manoeuvre: bool, K: int = 20, dt: float = 60.0):
    t = dt * np.arange(K)
    vp = np.array([5.0, 0.0])
    p = np.outer(t, vp)
    if manoeuvre:  # second leg heading North
        half = K // 2
        p[half:] = p[half - 1] + np.outer(t[half:] - t[half - 1], [0.0, 5.0])
    x0 = np.array([3000.0, 8000.0, -2.0, -1.0])
    return t, p, x0


def test_information_singular_without_manoeuvre():
    t, p, x0 = _geometry(manoeuvre=False)
    J = batch_information(x0, 0.0, t, p, SIGMA)
    assert observability(J) < 1e-12
    # null direction: scale the relative trajectory (x₀ − p₀, v − v_p)
    null = np.concatenate([x0[:2] - p[0], x0[2:] - np.array([5.0, 0.0])])
    assert np.linalg.norm(J @ null) < 1e-9 * np.linalg.norm(J) * np.linalg.norm(null)
    assert np.all(np.isinf(position_rms_bound(crlb(J))))
    assert np.isinf(range_bound(crlb(J), x0[:2], p[0]))
    t, p, x0 = _geometry(manoeuvre=True)
    Jm = batch_information(x0, 0.0, t, p, SIGMA)
    assert observability(Jm) > 1e-8
    assert np.all(np.isfinite(crlb(Jm)))


def test_incremental_equals_batch_and_transport():
    t, p, x0 = _geometry(manoeuvre=True)
    J = np.zeros((4, 4))
    for k in range(t.size):
        J = add_bearing_information(J, x0, 0.0, t[k], p[k], SIGMA)
    J_batch = batch_information(x0, 0.0, t, p, SIGMA)
    np.testing.assert_allclose(J, J_batch, rtol=1e-12, atol=1e-20)
    # information about the state at t_end from the batch equals transported information
    t_end = t[-1]
    x_end = cv_transition(t_end) @ x0
    J_end = batch_information(x_end, t_end, t, p, SIGMA)
    np.testing.assert_allclose(transport_information(J_batch, t_end), J_end, rtol=1e-9, atol=1e-18)


def test_single_bearing_information_matches_finite_difference():
    x = np.array([1200.0, -700.0, 3.0, 1.0])
    p = np.array([100.0, 50.0])
    eps = 1e-3
    g = np.array([
        (bearing(x[:2] + eps * e[:2], p) - bearing(x[:2] - eps * e[:2], p)) / (2 * eps)
        for e in np.eye(4)
    ])  # fmt: skip
    np.testing.assert_allclose(
        bearing_information(x, p, SIGMA), np.outer(g, g) / SIGMA**2, rtol=1e-7
    )


def test_pcrlb_without_process_noise_equals_batch_bound():
    t, p, x0 = _geometry(manoeuvre=True)
    J0 = np.diag([1e-6, 1e-6, 1e-2, 1e-2])
    traj = np.einsum("kij,j->ki", cv_transition(t), x0)
    Im = bearing_information(traj, p, SIGMA)
    Jk = posterior_information(J0, t, Im, q_tilde=0.0)
    for k in (3, 10, 19):
        xk = traj[k]
        Jb = batch_information(xk, t[k], t[: k + 1], p[: k + 1], SIGMA)
        Jb += transport_information(J0, t[k])
        np.testing.assert_allclose(Jk[k], Jb, rtol=1e-8, atol=1e-16)


def test_predicted_information_matches_covariance_prediction():
    t, p, x0 = _geometry(manoeuvre=True)
    J = batch_information(x0, 0.0, t, p, SIGMA)
    P = np.linalg.inv(J)
    F = cv_transition(45.0)
    P_pred = F @ P @ F.T + cwna_covariance(45.0, 1e-4)
    np.testing.assert_allclose(crlb(predict_information(J, 45.0, 1e-4)), P_pred, rtol=1e-6)
    # no information at all stays no information (finite arithmetic, infinite bound)
    assert np.all(np.isinf(crlb(predict_information(np.zeros((4, 4)), 60.0, 1e-4))))
    with pytest.raises(ValueError, match="dt"):
        predict_information(J, -1.0, 0.0)


def test_process_noise_loosens_the_bound():
    t, p, x0 = _geometry(manoeuvre=True)
    J0 = np.diag([1e-6, 1e-6, 1e-2, 1e-2])
    traj = np.einsum("kij,j->ki", cv_transition(t), x0)
    Im = bearing_information(traj, p, SIGMA)
    b0 = position_rms_bound(crlb(posterior_information(J0, t, Im, 0.0)))
    b1 = position_rms_bound(crlb(posterior_information(J0, t, Im, 1e-3)))
    assert np.all(b1[1:] >= b0[1:] - 1e-9) and b1[-1] > 1.1 * b0[-1]


def test_bounds_are_batched_over_candidates():
    # leading axis over candidate platform positions for the next bearing (greedy policies)
    t, p, x0 = _geometry(manoeuvre=False, K=10)
    J = batch_information(x0, 0.0, t, p, SIGMA) + np.diag([1e-8, 1e-8, 1e-4, 1e-4])
    angles = np.linspace(0, 2 * np.pi, 7, endpoint=False)
    cands = p[-1] + 300.0 * np.stack([np.sin(angles), np.cos(angles)], -1)
    Jc = add_bearing_information(J, x0, 0.0, t[-1] + 60.0, cands, SIGMA)
    assert Jc.shape == (7, 4, 4)
    for i in range(7):
        np.testing.assert_allclose(
            Jc[i], add_bearing_information(J, x0, 0.0, t[-1] + 60.0, cands[i], SIGMA)
        )
    P = crlb(Jc)
    x_next = cv_transition(t[-1] + 60.0) @ x0
    r = np.linalg.norm(x0[:2] - p[0])
    np.testing.assert_allclose(
        relative_range_bound(P, x0[:2], p[0]), range_bound(P, x0[:2], p[0]) / r
    )
    assert position_rms_bound(P).shape == (7,)
    assert np.all(np.isfinite(x_next))


def test_pcrlb_batched_over_candidate_trajectories_equals_looped():
    J0 = np.diag([1e-6, 1e-6, 1e-2, 1e-2])
    Ims, ts = [], None
    for man in (False, True, True):
        t, p, x0 = _geometry(manoeuvre=man)
        p = p + (0.0 if not Ims else 200.0 * len(Ims))
        traj = np.einsum("kij,j->ki", cv_transition(t), x0)
        Ims.append(bearing_information(traj, p, SIGMA))
        ts = t
    batched = posterior_information(J0, ts, np.stack(Ims), 1e-4)
    for i, Im in enumerate(Ims):
        np.testing.assert_allclose(batched[i], posterior_information(J0, ts, Im, 1e-4), rtol=1e-12)


def test_textbook_pcrlb_shape():
    # Ristic ch. 6 geometry: the bound stays near the 2 km prior until the manoeuvre, then drops
    from sensorgym.reproduce.experiments.bot_benchmark import pcrlb_position, simulate

    scn = BotScenario()
    sim = simulate(scn, 50, np.random.default_rng(0))
    b = pcrlb_position(scn, sim)
    assert b[0] == pytest.approx(2000.0, rel=0.01)
    assert b[12] > 1000.0 and b[-1] < 200.0 and b[-1] < b[12] / 10.0


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="sigma"):
        bearing_information(np.zeros(4) + 1.0, np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="platform_positions"):
        batch_information(np.ones(4), 0.0, np.arange(3.0), np.zeros((4, 2)), SIGMA)
    with pytest.raises(ValueError, match="J"):
        crlb(np.full((4, 4), np.nan))


# --- square-root (covariance) form of the recursion (issue 10, defect 2) -------------------------


def _outer(L):
    return L @ np.swapaxes(L, -1, -2)


def test_cwna_factor_is_a_square_root_and_negative_steps_raise():
    for T in (0.0, 1e-3, 60.0, 1e5):
        G = cwna_covariance_factor(T, 2e-3)
        np.testing.assert_allclose(_outer(G), cwna_covariance(T, 2e-3), rtol=1e-12, atol=1e-300)
        assert np.allclose(G, np.tril(G))
    with pytest.raises(ValueError, match="T"):
        cwna_covariance(-1.0, 1e-3)
    with pytest.raises(ValueError, match="T"):
        cwna_covariance_factor(np.nan, 1e-3)


@pytest.mark.parametrize("q_tilde", [0.0, 1e-4])
def test_square_root_recursion_equals_the_information_recursion(q_tilde):
    """P̄ = F P Fᵀ + Q and P⁺ = (P̄⁻¹ + Hᵀ H/σ²)⁻¹ on a square root are the information
    recursion ``(I + J̄ Q)⁻¹ J̄ + Hᵀ H/σ²`` inverted, step after step (well-conditioned case)."""
    t, p, x0 = _geometry(manoeuvre=True)
    traj = np.einsum("kij,j->ki", cv_transition(t), x0)
    P0 = np.diag([4e6, 9e4, 4.0, 9.0])
    J = np.linalg.inv(P0)
    L = covariance_square_root(P0)
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        J = predict_information(J, dt, q_tilde) + bearing_information(traj[k], p[k], SIGMA)
        L = update_bound_factor(predict_bound_factor(L, dt, q_tilde), traj[k], p[k], SIGMA)
        np.testing.assert_allclose(
            _outer(L), crlb(J), rtol=1e-8, atol=1e-10 * np.abs(crlb(J)).max()
        )
    P = _outer(L)
    assert factor_position_rms_bound(L) == pytest.approx(position_rms_bound(P), rel=1e-12)
    assert factor_range_bound(L, traj[-1, :2], p[-1]) == pytest.approx(
        range_bound(P, traj[-1, :2], p[-1]), rel=1e-10
    )


@pytest.mark.parametrize("singular_prior, sigma", [(False, SIGMA), (True, SIGMA), (False, 1e-8)])
def test_late_bearings_equal_the_step_by_step_recursion(singular_prior, sigma):
    """Without process noise, bearings fused at the end as rows on the final state
    (``late_bearing_information``, ``late_update_root``: what the planners use) give the bound
    of fusing each at its own step; also from a singular prior (a known velocity), where the
    information form has no inverse; and with 1e-8-rad bearings, where ``N`` spans 1e20."""
    from sensorgym.trackers.bearings.kernels import late_bearing_information, late_update_root

    t, p, x0 = _geometry(manoeuvre=True)
    traj = np.einsum("kij,j->ki", cv_transition(t), x0)
    P0 = np.diag([4e6, 9e4, 0.0 if singular_prior else 4.0, 0.0 if singular_prior else 9.0])
    P0[0, 1] = P0[1, 0] = 1e5
    L0 = covariance_square_root(P0)
    L = L0
    for k in range(1, t.size):
        L = update_bound_factor(predict_bound_factor(L, t[k] - t[k - 1], 0.0), traj[k], p[k], sigma)
    Lo = predict_bound_factor(L0, t[-1] - t[0], 0.0)  # the bound at the end with no bearings
    C, u, out = np.eye(4), np.empty(4), np.empty((4, 4))
    for k in range(1, t.size):
        late_bearing_information(Lo, *traj[k, :2], *p[k], sigma, t[-1] - t[k], C, u)
    late_update_root(Lo, C, out)
    P = _outer(L)
    np.testing.assert_allclose(_outer(out), P, rtol=1e-9, atol=1e-12 * np.abs(P).max())
    assert np.all(np.isfinite(out))


def test_square_root_bound_is_finite_where_the_information_form_loses_it():
    """A full-rank prior makes the bound finite; with 1e-8 rad bearings against a 10-km range
    spread the information's eigenvalues span more than the float range, and ``crlb`` of the
    information declares directions unobservable (inf, then NaN rewards). The square root keeps
    every bound finite, positive and monotone under bearings (information only grows)."""
    sigma = 1e-8
    x = np.array([6000.0, 8000.0, -3.0, 1.0])
    u = x[:2] / np.hypot(*x[:2])
    t_ = np.array([u[1], -u[0]])
    Ppos = 1e8 * np.outer(u, u) + (1e4 * sigma) ** 2 * np.outer(t_, t_)
    P0 = np.zeros((4, 4))
    P0[:2, :2], P0[2:, 2:] = Ppos, 14.0 * np.eye(2)
    L = covariance_square_root(P0)
    m = [factor_position_rms_bound(L)]
    platform = np.zeros(2)
    for k in range(30):
        platform = platform + 300.0 * np.array([np.sin(0.3 * k), np.cos(0.3 * k)])
        x = cv_transition(60.0) @ x
        Lbar = predict_bound_factor(L, 60.0, 0.0)
        L = update_bound_factor(Lbar, x, platform, sigma)
        assert np.all(np.isfinite(L))
        # a bearing never loosens the bound
        assert factor_position_rms_bound(L) <= factor_position_rms_bound(Lbar) * (1 + 1e-12)
        m.append(factor_position_rms_bound(L))
    m = np.array(m)
    assert np.all(np.isfinite(m)) and np.all(m > 0.0)
    assert m[-1] < 1e-2 * m[0]  # the manoeuvring platform pins it down


def test_square_root_of_a_rounded_covariance_is_positive_semidefinite():
    # a covariance whose spread spans the float range can come out slightly indefinite
    u = np.array([0.6, 0.8])
    P = np.zeros((4, 4))
    P[:2, :2] = 1e12 * np.outer(u, u) - 1e-6 * np.eye(2)
    P[2:, 2:] = np.eye(2)
    L = covariance_square_root(P)
    assert np.all(np.isfinite(L))
    np.testing.assert_allclose(_outer(L), P, atol=1e-3)
    assert np.linalg.eigvalsh(_outer(L)).min() > -1e-3


def test_square_root_functions_check_their_inputs():
    L = np.eye(4)
    with pytest.raises(ValueError, match="dt"):
        predict_bound_factor(L, -1.0, 0.0)
    with pytest.raises(ValueError, match="L"):
        predict_bound_factor(np.full((4, 4), np.nan), 1.0, 0.0)
    with pytest.raises(ValueError, match="target_state"):
        update_bound_factor(L, np.zeros(4), np.zeros(2), SIGMA)
    with pytest.raises(ValueError, match="sigma"):
        update_bound_factor(L, np.ones(4), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="P"):
        covariance_square_root(np.full((4, 4), np.inf))
