"""Conjugation least squares (theory §3.2–3.3; acceptance tests AT-1..AT-5)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgym.envs.worlds.stereo_scene import pair_scene, receivers_around
from sensorgym.trackers.stereo.accuracy import (
    los_angle,
    pair_covariance,
    range_sigma_general,
    triple_covariance,
)
from sensorgym.trackers.stereo.conjugation import (
    build_system,
    solve_conjugation,
    solve_pair,
    solve_proposed,
)
from tests.conftest import random_moving_scene


def _inputs(scene, a, dt=None):
    P, b = scene.relative_poses
    return a[..., 0, :], a[..., 1:, :], P, b, dt


def _frame1(scene, v):
    return np.einsum("...ji,...j->...i", scene.rotations[..., 0, :, :], v)


# --- noise-free recovery (AT-2, AT-3) ---------------------------------------------------------


@pytest.mark.parametrize("n", [2, 3, 4, 6])
def test_static_ranges_recovered_exactly(rng, n):
    scene, a, _, _, _ = random_moving_scene(rng, n, 50, order=0)
    sol = solve_conjugation(*_inputs(scene, a), order=0)
    np.testing.assert_allclose(sol.ranges, scene.ranges, rtol=1e-10)
    np.testing.assert_allclose(
        sol.position, _frame1(scene, scene.target - scene.origins[:, 0]), atol=1e-8
    )
    assert np.all(sol.residual < 1e-16 * scene.ranges.max() ** 2)
    assert not sol.used_pinv.any()


@pytest.mark.parametrize("n", [3, 4, 5])
def test_velocity_recovered_exactly(rng, n):
    """AT-2: the order-1 solve recovers r and V for non-coplanar LOS with distinct delays."""
    scene, a, dt, V, _ = random_moving_scene(rng, n, 50, order=1)
    sol = solve_conjugation(*_inputs(scene, a, dt), order=1)
    assert not sol.used_pinv.any()
    # ranges are slant ranges at each receiver's own fix time
    Mk = (
        scene.target[:, None, :]
        + V[:, None, :] * np.concatenate([np.zeros((50, 1)), dt], 1)[..., None]
    )
    r_true = np.linalg.norm(Mk - scene.origins, axis=-1)
    np.testing.assert_allclose(sol.ranges, r_true, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(sol.velocity, _frame1(scene, V), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("n", [5, 6])
def test_acceleration_recovered_exactly(rng, n):
    """AT-3: n = 5 order 2 is a 12×11 system of rank 11 that recovers V and V̇."""
    scene, a, dt, V, Vd = random_moving_scene(rng, n, 30, order=2)
    inputs = _inputs(scene, a, dt)
    A, _ = build_system(
        inputs[0], np.einsum("...ij,...j->...i", inputs[2], inputs[1]), inputs[3], dt, 2
    )
    assert A.shape[-2:] == (3 * (n - 1), n + 6)
    assert np.all(np.linalg.matrix_rank(A) == n + 6)
    sol = solve_conjugation(*inputs, order=2)
    np.testing.assert_allclose(sol.velocity, _frame1(scene, V), rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(sol.acceleration, _frame1(scene, Vd), rtol=1e-6, atol=1e-6)


def test_order_requires_enough_receivers(rng):
    scene, a, dt, _, _ = random_moving_scene(rng, 4, 2, order=1)
    with pytest.raises(ValueError, match="order 2 needs at least 5 receivers"):
        solve_conjugation(*_inputs(scene, a, dt), order=2)
    with pytest.raises(ValueError, match="order 1 needs at least 3"):
        solve_conjugation(a[:, 0], a[:, 1:2], None, np.ones((2, 1, 3)), dt[:, :1], order=1)
    with pytest.raises(ValueError, match="dt: delays are required"):
        solve_conjugation(*_inputs(scene, a), order=1)


# --- covariance against the closed forms (AT-1) -----------------------------------------------


def test_pair_covariance_matches_eq12(rng):
    scene, a, _, _, _ = random_moving_scene(rng, 2, 500, order=0)
    P, _b = scene.relative_poses
    sol = solve_conjugation(*_inputs(scene, a), order=0, sigma_e=0.3)
    c2 = np.einsum("...ij,...j->...i", P[:, 0], a[:, 1])
    gamma = los_angle(a[:, 0], c2)
    np.testing.assert_allclose(sol.covariance, pair_covariance(gamma, 0.3), rtol=1e-10)
    np.testing.assert_allclose(sol.range_sigma[:, 0], 0.3 / np.sin(gamma), rtol=1e-10)


def test_triple_covariance_matches_eq13_and_general_n(rng):
    for n in range(2, 8):
        scene, a, _, _, _ = random_moving_scene(rng, n, 200, order=0)
        a1, ak, P, b, _ = _inputs(scene, a)
        sol = solve_conjugation(a1, ak, P, b, order=0, sigma_e=2.0)
        c = np.einsum("...ij,...j->...i", P, ak)
        # σ[r̂_1] = σ_e / √(Σ sin²γ_k)
        np.testing.assert_allclose(
            sol.range_sigma[:, 0], range_sigma_general(a1, c, 2.0), rtol=1e-10
        )
        if n == 3:
            alpha, beta = los_angle(a1, c[:, 0]), los_angle(a1, c[:, 1])
            np.testing.assert_allclose(
                sol.covariance, triple_covariance(alpha, beta, 2.0), rtol=1e-10
            )


def test_sqrt2_gain_of_a_third_orthogonal_receiver():
    # three mutually orthogonal lines of sight meeting at the target
    T = np.array([0.0, 50.0, 0.0])
    d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    # the third receiver looks straight up: give it a tilted up vector through its boresight offset
    scene = receivers_around(
        T, d, np.array([150.0, 120.0, 100.0]), boresight_offset=(1.0, 0.0, 1.0)
    )
    a = scene.directions
    P, b = scene.relative_poses
    two = solve_conjugation(a[0], a[1:2], P[:1], b[:1])
    three = solve_conjugation(a[0], a[1:], P, b)
    assert two.range_sigma[0] / three.range_sigma[0] == pytest.approx(np.sqrt(2.0), rel=1e-12)


def test_velocity_aware_orthogonal_closed_form():
    """theory §3.5: σ[r_1] = σ_e √(Δt_2² + Δt_3²)/|Δt_3 − Δt_2| for orthogonal a_1, c_2, c_3."""
    a1 = np.array([0.0, 0.0, 1.0])
    c = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    b = np.array([[-100.0, 0.0, 100.0], [0.0, -100.0, 100.0]])
    for d2, d3, expected in [(0.1, 0.2, 2.236), (0.3, 0.4, 5.0)]:
        sol = solve_conjugation(a1, c, None, b, [d2, d3], order=1)
        sig = np.sqrt(np.diag(sol.covariance))
        assert sig[0] == pytest.approx(np.hypot(d2, d3) / abs(d3 - d2), rel=1e-12)
        assert sig[0] == pytest.approx(expected, abs=1e-3)
        assert sig[1] == pytest.approx(np.sqrt(1 + (d2 / d3) ** 2), rel=1e-12)
        assert sig[2] == pytest.approx(np.sqrt(1 + (d3 / d2) ** 2), rel=1e-12)
        # σ[v along c_2] = σ_e/Δt_3, along c_3 = σ_e/Δt_2, along a_1 = √2 σ_e/|Δt_3 − Δt_2|
        np.testing.assert_allclose(sig[3:], [1 / d3, 1 / d2, np.sqrt(2) / abs(d3 - d2)], rtol=1e-12)


def test_fast_paths_match_generic_svd_path(rng):
    """The closed forms (n = 2 order 0, n = 3 order 1) equal the generic weighted path with W = I."""
    for n, order in [(2, 0), (3, 1)]:
        scene, a, dt, _, _ = random_moving_scene(rng, n, 100, order=order)
        inputs = _inputs(scene, a, dt if order else None)
        fast = solve_conjugation(*inputs, order=order)
        generic = solve_conjugation(*inputs, order=order, weights=np.ones((100, n)))
        np.testing.assert_allclose(fast.ranges, generic.ranges, rtol=1e-9)
        np.testing.assert_allclose(fast.covariance, generic.covariance, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(fast.condition, generic.condition, rtol=1e-7)
        assert np.all(fast.condition >= 1.0)


# --- weights (AT-4, CHECK 5) ------------------------------------------------------------------


def test_weighted_least_squares(rng):
    scene, a, dt, _, _ = random_moving_scene(rng, 5, 20, order=1)
    a1, ak, P, b, _ = _inputs(scene, a)
    b = b + rng.normal(size=b.shape)  # inconsistent system so weights matter
    plain = solve_conjugation(a1, ak, P, b, dt, order=1)
    # AT-4: W = c·I equals unweighted LS (solution and residual up to the factor c²)
    scaled = solve_conjugation(a1, ak, P, b, dt, order=1, weights=np.full((20, 5), 0.7))
    np.testing.assert_allclose(scaled.ranges, plain.ranges, rtol=1e-9)
    np.testing.assert_allclose(scaled.residual, 0.49 * plain.residual, rtol=1e-9)
    # CHECK 5: equals lstsq(W^½ A, W^½ B) with W = diag(w_1 w_k)
    w = rng.uniform(0.2, 1.0, size=(20, 5))
    sol = solve_conjugation(a1, ak, P, b, dt, order=1, weights=w)
    c = np.einsum("...ij,...j->...i", P, ak)
    A, B = build_system(a1, c, b, dt, 1)
    sw = np.sqrt(np.repeat(w[:, :1] * w[:, 1:], 3, axis=-1))
    for i in range(20):
        x = np.linalg.lstsq(A[i] * sw[i][:, None], B[i] * sw[i], rcond=None)[0]
        np.testing.assert_allclose(sol.ranges[i], x[:5], rtol=1e-9)
        np.testing.assert_allclose(sol.velocity[i], x[5:], rtol=1e-8, atol=1e-9)
    assert not np.allclose(sol.ranges, plain.ranges)


def test_pair_weights_scale_covariance_only(rng):
    scene = pair_scene(np.deg2rad(70.0))
    a = scene.directions
    P, b = scene.relative_poses
    plain = solve_conjugation(a[0], a[1:], P, b)
    w = solve_conjugation(a[0], a[1:], P, b, weights=[0.5, 0.8])
    np.testing.assert_allclose(w.ranges, plain.ranges, rtol=1e-12)
    np.testing.assert_allclose(w.covariance, plain.covariance / 0.4, rtol=1e-12)


# --- paper 000 specifics (AT-5, proposed variant) ---------------------------------------------


def test_alternative_pair_bias_is_los_velocity_times_delay():
    """AT-5: target moving by VΔt before receiver 2 fixes it.

    The bias is exactly ``[(AᵀA)⁻¹Aᵀ V Δt]_1`` with the measured ``A``; for orthogonal lines of
    sight it is ``(a_1·V)Δt`` to first order in the displacement.
    """
    scene = pair_scene(np.pi / 2, boresight_offset=(0.0, 0.0, 0.0))
    V = np.array([6.0, -2.0, 9.0])
    dt = 0.25
    u2 = scene.target + V * dt - scene.origins[1]
    a2 = scene.rotations[1].T @ (u2 / np.linalg.norm(u2))
    a1 = scene.directions[0]
    P, b = scene.relative_poses
    sol = solve_pair(a1, a2, P[0], b[0])
    V1 = scene.rotations[0].T @ V
    c2 = P[0] @ a2
    A = np.stack([a1, -c2], -1)
    exact = (np.linalg.solve(A.T @ A, A.T @ (V1 * dt)))[0]
    assert sol.ranges[0] - scene.ranges[0] == pytest.approx(exact, abs=1e-9)
    assert sol.ranges[0] - scene.ranges[0] == pytest.approx(a1 @ V1 * dt, rel=0.05)
    # motion compensation with the true velocity removes the bias: B̂_2 = b_2 − V Δt
    comp = solve_pair(a1, a2, P[0], b[0], dt, V1)
    assert comp.ranges[0] == pytest.approx(scene.ranges[0], abs=1e-9)


def test_proposed_variant_equals_full_solve_when_invertible(rng):
    scene, a, dt, _V, _ = random_moving_scene(rng, 3, 40, order=1)
    inputs = _inputs(scene, a, dt)
    full = solve_conjugation(*inputs, order=1)
    prop = solve_proposed(*inputs)
    np.testing.assert_allclose(prop.ranges, full.ranges, rtol=1e-8)
    np.testing.assert_allclose(prop.velocity, full.velocity)


# --- degenerate geometry and bad input --------------------------------------------------------


def test_parallel_lines_of_sight_fall_back_to_pinv_finite():
    a = np.array([0.0, 0.0, 1.0])
    sol = solve_pair(a, a, None, [5.0, 0.0, 10.0])
    assert sol.used_pinv and np.isinf(sol.condition)
    assert np.all(np.isfinite(sol.ranges)) and np.all(np.isfinite(sol.covariance))
    # minimum-norm solution of r_1 a − r_2 a = b: r_1 = −r_2 = (a·b)/2
    np.testing.assert_allclose(sol.ranges, [5.0, -5.0])
    # broadcast: one degenerate geometry against a batch of base vectors
    many = solve_pair(a, a, None, np.array([[5.0, 0.0, 10.0], [1.0, 2.0, 4.0]]))
    assert many.used_pinv.all() and many.covariance.shape == (2, 2, 2)
    np.testing.assert_allclose(many.ranges, [[5.0, -5.0], [2.0, -2.0]])


def test_coplanar_lines_of_sight_with_velocity_are_flagged():
    """Receivers on a horizontal circle at the object's height: A of eq. (10) is singular."""
    T = np.zeros(3)
    d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    d[2] = [-np.sqrt(0.5), 0.0, np.sqrt(0.5)]
    scene = receivers_around(T, d, np.array([50.0, 50.0, 50.0]), boresight_offset=(0.0, 1.0, 0.0))
    P, b = scene.relative_poses
    sol = solve_conjugation(scene.directions[0], scene.directions[1:], P, b, [0.1, 0.2], order=1)
    assert sol.condition > 1e3 and sol.used_pinv
    assert np.all(np.isfinite(sol.ranges)) and np.all(np.isfinite(sol.velocity))
    assert np.all(np.isfinite(sol.covariance))
    # lifting the object 30° above the receivers' plane makes it well-conditioned (theory §4.5 CHECK 4)
    lifted = d.copy()
    lifted[:, 1] = np.sin(np.deg2rad(30.0))
    lifted[:, [0, 2]] *= np.cos(np.deg2rad(30.0))
    scene = receivers_around(
        T, lifted, np.array([50.0, 50.0, 50.0]), boresight_offset=(0.0, 1.0, 0.0)
    )
    P, b = scene.relative_poses
    ok = solve_conjugation(scene.directions[0], scene.directions[1:], P, b, [0.1, 0.2], order=1)
    assert not ok.used_pinv and ok.condition < 1e3


@pytest.mark.parametrize("dt", [[0.0, 0.2], [0.2, 0.2], [0.0, 0.0]])
def test_zero_or_equal_delays_give_finite_flagged_solution(rng, dt):
    scene, a, _, _, _ = random_moving_scene(rng, 3, 1, order=1)
    sol = solve_conjugation(*_inputs(scene, a, np.array([dt])), order=1)
    assert sol.used_pinv.all()
    for x in (sol.ranges, sol.velocity, sol.covariance, sol.residual):
        assert np.all(np.isfinite(x))


@pytest.mark.parametrize("n,order", [(2, 0), (3, 1), (4, 1)])  # two kernels, generic SVD
def test_bad_inputs_name_the_argument(rng, n, order):
    scene, a, dt, _, _ = random_moving_scene(rng, n, 2, order=order)
    a1, ak, P, b, _ = _inputs(scene, a)
    dt = dt if order else None

    def solve(a1=a1, ak=ak, P=P, b=b, dt=dt, **kw):
        return solve_conjugation(a1, ak, P, b, dt, order=order, **kw)

    with pytest.raises(ValueError, match="a1: contains NaN"):
        solve(a1=np.full_like(a1, np.nan))
    with pytest.raises(ValueError, match="ak: contains a zero-length"):
        solve(ak=np.zeros_like(ak))
    with pytest.raises(ValueError, match="ak: direction vectors must have unit length"):
        solve(ak=1.01 * ak)
    with pytest.raises(ValueError, match="b: expected shape"):
        solve(b=b[..., :2])
    with pytest.raises(ValueError, match="b: contains NaN"):
        solve(b=np.where(np.arange(3) == 1, np.inf, b))
    if order:
        with pytest.raises(ValueError, match="dt: contains NaN"):
            solve(dt=np.full_like(dt, np.inf))
    bad_P = P.copy()
    bad_P[1, 0, 2, 1] = np.nan
    with pytest.raises(ValueError, match="P: contains NaN"):
        solve(P=bad_P)
    with pytest.raises(ValueError, match="P: must hold rotation"):
        solve(P=2 * P)
    with pytest.raises(ValueError, match="inputs: batch shapes"):
        solve(a1=np.concatenate([a1, a1, a1]))
    with pytest.raises(ValueError, match="weights"):
        solve(weights=np.zeros((2, n)))
    with pytest.raises(ValueError, match="order"):
        solve_conjugation(a1, ak, P, b, dt, order=3)
    with pytest.raises(ValueError, match="sigma_e"):
        solve(sigma_e=-1.0)


@pytest.mark.parametrize("n,order", [(2, 0), (3, 1), (3, 0)])  # two kernels, generic SVD
def test_unit_length_tolerance_is_the_same_on_every_path(rng, n, order):
    """|‖v‖ − 1| ≤ 1e-6 passes and 2e-6 fails, for directions and for ‖P_k a_k‖ alike."""
    scene, a, dt, _, _ = random_moving_scene(rng, n, 3, order=order)
    a1, ak, P, b, _ = _inputs(scene, a)
    dt = dt if order else None
    solve_conjugation((1 + 0.9e-6) * a1, ak, (1 - 0.9e-6) * P, b, dt, order=order)
    with pytest.raises(ValueError, match="a1: direction vectors must have unit length"):
        solve_conjugation((1 + 2e-6) * a1, ak, P, b, dt, order=order)
    with pytest.raises(ValueError, match="P: must hold rotation"):
        solve_conjugation(a1, ak, (1 - 2e-6) * P, b, dt, order=order)


# --- batching -----------------------------------------------------------------------------------


@pytest.mark.parametrize("n,order", [(2, 0), (3, 0), (3, 1), (4, 1), (5, 2)])
def test_batched_equals_looped(rng, n, order):
    scene, a, dt, _, _ = random_moving_scene(rng, n, 12, order=order)
    inputs = _inputs(scene, a, dt if order else None)
    batch = solve_conjugation(*inputs, order=order)
    for i in range(12):
        one = solve_conjugation(*(None if x is None else x[i] for x in inputs), order=order)
        np.testing.assert_allclose(batch.ranges[i], one.ranges, rtol=1e-12)
        np.testing.assert_allclose(batch.covariance[i], one.covariance, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(batch.condition[i], one.condition, rtol=1e-12)
        assert batch.used_pinv[i] == one.used_pinv


def test_exactly_parallel_lines_of_sight_in_rotated_frames_are_flagged():
    """Regression: three parallel lines of sight seen from differently rotated frames make the
    n = 3 closed form's Cramer determinant and cofactors both rounding noise (~1e-18); their
    ratio gave a finite, small κ_F and a garbage solution reported as regular. The element
    must take the pseudo-inverse path like the SVD solver says (two zero singular values)."""
    from sensorgym.envs.worlds.scanning import ReceiverLayout

    o = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [20.0, 0.0, 0.0]])
    layout = ReceiverLayout.looking_at(o, [50.0, 30.0, -20.0])
    u = np.array([1.0, 0.0, 0.0])  # the object far along the receivers' line
    a = np.einsum("kji,j->ki", layout.rotations, u)
    P, b = layout.relative
    sol = solve_conjugation(a[0], a[1:], P, b, [0.25, 0.6], order=1)
    assert sol.used_pinv and sol.condition > 1e7
    assert np.all(np.isfinite(sol.ranges)) and np.all(np.isfinite(sol.covariance))


def test_batch_mixing_degenerate_and_regular_problems(rng):
    """A degenerate element in a batch takes the fallback without disturbing the others."""
    scene, a, dt, _, _ = random_moving_scene(rng, 3, 6, order=1)
    dt = dt.copy()
    dt[2] = [0.3, 0.3]
    inputs = _inputs(scene, a, dt)
    batch = solve_conjugation(*inputs, order=1)
    assert batch.used_pinv.tolist() == [False, False, True, False, False, False]
    for i in range(6):
        one = solve_conjugation(*(x[i] for x in inputs), order=1)
        np.testing.assert_allclose(batch.ranges[i], one.ranges, rtol=1e-12)


@pytest.mark.parametrize("n,order", [(2, 0), (3, 1)])
def test_large_batch_with_a_degenerate_element_equals_single_solves(n, order):
    """A large batch through a compiled closed form equals one-at-a-time solves; its one
    degenerate element (parallel lines of sight / equal delays) takes the fallback alone."""
    rng = np.random.default_rng(5 + n)
    scene, a, dt, _, _ = random_moving_scene(rng, n, 30_000, order=order)
    a, dt = a.copy(), dt.copy()
    bad = 12_345
    if order:
        dt[bad] = [0.2, 0.2]
    else:
        R = scene.rotations[bad]
        a[bad, 1] = R[1].T @ R[0] @ a[bad, 0]
    inputs = _inputs(scene, a, dt if order else None)
    big = solve_conjugation(*inputs, order=order)
    p = n + 3 * order
    assert big.ranges.shape == (30_000, n) and big.covariance.shape == (30_000, p, p)
    assert np.flatnonzero(big.used_pinv).tolist() == [bad]
    for i in [0, bad, 29_999]:
        one = solve_conjugation(*(None if x is None else x[i] for x in inputs), order=order)
        np.testing.assert_allclose(big.ranges[i], one.ranges, rtol=1e-12)
        np.testing.assert_allclose(big.position[i], one.position, rtol=1e-12)
        np.testing.assert_allclose(big.covariance[i], one.covariance, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(big.residual[i], one.residual, rtol=1e-9, atol=1e-20)


@pytest.mark.parametrize("n,order", [(2, 0), (3, 1), (3, 0)])
def test_broadcast_inputs_equal_explicitly_repeated_inputs(rng, n, order):
    """One receiver geometry shared by a (4, 5) batch of measurements, ``P = None`` included."""
    scene, a, dt, _, _ = random_moving_scene(rng, n, 1, order=order)
    a1, ak, P, b, _ = _inputs(scene, a)
    dt = dt[0] if order else None
    ak_batch = np.broadcast_to(ak[0], (4, 5, n - 1, 3))
    for P_shared in (P[0], None):
        shared = solve_conjugation(a1[0], ak_batch, P_shared, b[0], dt, order=order)
        Pb = None if P_shared is None else np.broadcast_to(P_shared, (4, 5, n - 1, 3, 3))
        full = solve_conjugation(
            np.broadcast_to(a1[0], (4, 5, 3)).copy(),
            ak_batch.copy(),
            None if Pb is None else Pb.copy(),
            np.broadcast_to(b[0], (4, 5, n - 1, 3)).copy(),
            None if dt is None else np.broadcast_to(dt, (4, 5, n - 1)).copy(),
            order=order,
        )
        assert shared.ranges.shape == (4, 5, n) and shared.position.shape == (4, 5, 3)
        for f in ("ranges", "position", "residual", "covariance", "condition", "used_pinv"):
            np.testing.assert_array_equal(getattr(shared, f), getattr(full, f))


@settings(max_examples=150, deadline=None)
@given(
    st.floats(-1.2, 1.2),
    st.floats(-1.2, 1.2),
    st.floats(0.2, 2.9),
    st.floats(5.0, 500.0),
    st.floats(5.0, 500.0),
)
def test_noise_free_pair_recovery_for_any_geometry(az, el, gamma, r1, r2):
    """Any two non-parallel lines of sight recover both ranges exactly; κ_F = 2/sin γ."""
    e = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    x = np.cross(e, [0.3, 1.0, -0.2])
    x /= np.linalg.norm(x)
    d2 = np.cos(gamma) * e + np.sin(gamma) * x
    scene = receivers_around(
        np.array([3.0, 40.0, -7.0]), np.stack([e, d2]), np.array([r1, r2]), (1.0, 2.0, 0.5)
    )
    a = scene.directions
    P, b = scene.relative_poses
    sol = solve_pair(a[0], a[1], P[0], b[0])
    assert not sol.used_pinv
    np.testing.assert_allclose(sol.ranges, [r1, r2], rtol=1e-9, atol=1e-9)
    assert sol.condition == pytest.approx(2.0 / np.sin(gamma), rel=1e-9)


@pytest.mark.parametrize("n,order", [(2, 0), (3, 1), (4, 1)])
def test_unchecked_nan_direction_is_still_named(rng, n, order):
    """``check_inputs=False`` skips the checks, but a NaN direction (which makes the element
    degenerate) is reported by name instead of failing inside the SVD."""
    scene, a, dt, _, _ = random_moving_scene(rng, n, 3, order=order)
    a1, ak, P, b, _ = _inputs(scene, a)
    a1 = a1.copy()
    a1[1] = np.nan
    with pytest.raises(ValueError, match="a1: contains NaN"):
        solve_conjugation(a1, ak, P, b, dt if order else None, order=order, check_inputs=False)
