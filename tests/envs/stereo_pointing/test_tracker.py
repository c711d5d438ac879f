"""The pointing env's Kalman tracker on singular innovation covariances (issue 10, defect 3):
exact fixes (R = 0) with an exact track, the pseudo-inverse gain, and the regular path kept
(to round-off: since issue 11 the compiled update solves ``S`` by its own LU, not LAPACK's)."""

from __future__ import annotations

import numpy as np

from sensorgym.trackers.stereo.kalman import (
    RCOND,
    CVTrack,
    cv_predict,
    cv_prior,
    cv_update,
    singular_innovation,
)


def _reference_update(track: CVTrack, z, R, mask) -> CVTrack:
    """The update as it was before singular S was handled (np.linalg.solve throughout)."""
    m = np.asarray(mask, dtype=bool)
    S = np.where(m[..., None, None], track.P[..., :3, :3] + R, np.eye(3))
    K = np.swapaxes(np.linalg.solve(S, track.P[..., :3, :]), -1, -2)
    x = track.x + np.einsum("...ij,...j->...i", K, z - track.position)
    P = track.P - K @ S @ np.swapaxes(K, -1, -2)
    P = 0.5 * (P + np.swapaxes(P, -1, -2))
    return CVTrack(np.where(m[..., None], x, track.x), np.where(m[..., None, None], P, track.P))


def _random_spd(rng: np.random.Generator, shape: tuple[int, ...], n: int) -> np.ndarray:
    A = rng.normal(size=(*shape, n, n))
    return A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(n)


def test_regular_updates_equal_the_plain_solve():
    rng = np.random.default_rng(0)
    track = CVTrack(rng.normal(size=(64, 3, 6)) * 20.0, _random_spd(rng, (64, 3), 6))
    z = rng.normal(size=(64, 3, 3)) * 20.0
    R = _random_spd(rng, (64, 3), 3) * 1e-3
    mask = rng.random((64, 3)) < 0.7
    got, want = cv_update(track, z, R, mask), _reference_update(track, z, R, mask)
    np.testing.assert_array_equal(got.x[~mask], want.x[~mask])  # no fix: untouched
    np.testing.assert_array_equal(got.P[~mask], want.P[~mask])
    np.testing.assert_allclose(got.x, want.x, rtol=1e-12, atol=1e-12 * np.abs(want.x).max())
    np.testing.assert_allclose(got.P, want.P, rtol=1e-12, atol=1e-12 * np.abs(want.P).max())
    # one singular element in the batch leaves every other one untouched, bit for bit
    got = cv_update(track, z, R, np.ones((64, 3), bool))
    P = track.P.copy()
    P[5, 1] = 0.0
    R0 = R.copy()
    R0[5, 1] = 0.0
    mixed = cv_update(CVTrack(track.x, P), z, R0, np.ones((64, 3), bool))
    keep = np.ones((64, 3), bool)
    keep[5, 1] = False
    np.testing.assert_array_equal(mixed.x[keep], got.x[keep])
    np.testing.assert_array_equal(mixed.P[keep], got.P[keep])
    np.testing.assert_allclose(mixed.x[5, 1, :3], z[5, 1], rtol=1e-15)


def test_a_certain_track_and_an_exact_fix_take_the_fix():
    """S = 0: both claim to be exact; the position becomes the fix, velocity and P stay."""
    P = np.zeros((6, 6))
    P[3:, 3:] = np.diag([4.0, 1.0, 9.0])
    track = CVTrack(np.array([1.0, 2.0, 3.0, 0.5, -0.5, 1.0]), P)
    z = np.array([1.5, 2.0, 2.0])
    new = cv_update(track, z, np.zeros((3, 3)), True)
    np.testing.assert_allclose(new.position, z, rtol=1e-15)
    np.testing.assert_array_equal(new.velocity, track.velocity)
    np.testing.assert_array_equal(new.P, P)


def test_an_exact_fix_on_a_partly_certain_track():
    """P_pp of rank 1 (only z uncertain, correlated with v_z), R = 0: the fix is taken in every
    direction, and the velocity along z is corrected through the correlation."""
    track = cv_prior(np.zeros(3), np.zeros(3), 1.0, 1.0)
    P = np.zeros((6, 6))
    P[2, 2], P[2, 5], P[5, 2], P[5, 5] = 4.0, 2.0, 2.0, 2.0
    P[3, 3] = P[4, 4] = 1.0
    track = CVTrack(track.x, P)
    z = np.array([0.1, -0.2, 1.0])
    assert singular_innovation(P[:3, :3])
    new = cv_update(track, z, np.zeros((3, 3)), True)
    np.testing.assert_allclose(new.position, z, rtol=0, atol=1e-15)
    np.testing.assert_allclose(new.velocity, [0.0, 0.0, 0.5], rtol=0, atol=1e-15)
    # posterior: z and v_z conditioned on the exact z
    want = P.copy()
    want[2, :] = want[:, 2] = 0.0
    want[5, 5] = 2.0 - 2.0 * 2.0 / 4.0
    np.testing.assert_allclose(new.P, want, rtol=0, atol=1e-15)


def test_exact_fixes_without_process_noise_stay_finite_and_exact():
    """The defect's filter alone: σ = 0 (R = 0), q = 0, fixes of a straight track for 150
    steps: no LinAlgError, the position is the fix and the velocity the truth."""
    rng = np.random.default_rng(1)
    p, v = rng.normal(size=(8, 2, 3)) * 50.0, rng.normal(size=(8, 2, 3)) * 8.0
    track = cv_prior(p + 5.0 * rng.normal(size=p.shape), v + 2.0 * rng.normal(size=v.shape),
                     5.0, 2.0)  # fmt: skip
    R = np.zeros((8, 2, 3, 3))
    for k in range(150):
        p = p + 0.2 * v
        track = cv_predict(track, 0.2, 0.0)
        track = cv_update(track, p, R, rng.random((8, 2)) < 0.8 if k > 1 else np.ones((8, 2)))
        assert np.all(np.isfinite(track.x)) and np.all(np.isfinite(track.P))
    np.testing.assert_allclose(track.velocity, v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(track.position_sigma, 0.0, atol=1e-6)


def test_singular_innovation_flags_exactly_the_numerically_singular_matrices():
    rng = np.random.default_rng(2)
    regular = _random_spd(rng, (500,), 3)
    assert not singular_innovation(regular).any()
    # ill-conditioned but regular (κ = 1e10): solved as before
    Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    assert not singular_innovation(Q @ np.diag([1.0, 1e-5, 1e-10]) @ Q.T)
    for lam in ([1.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, -1e-3],
                [5.0, -1.0, -1.0], [1.0, 1.0, 0.1 * RCOND]):  # fmt: skip
        assert singular_innovation(Q @ np.diag(lam) @ Q.T), lam
    # the cheap screen never hides a singular matrix: compare with the eigenvalue test
    S = _random_spd(rng, (2000,), 3)
    lam, V = np.linalg.eigh(S)
    lam[:, 0] *= 10.0 ** rng.uniform(-18, 0, 2000)
    lam[::7, 0] = -lam[::7, 0]
    S = np.einsum("nik,nk,njk->nij", V, lam, V)
    exact = np.linalg.eigvalsh(S)
    want = exact[:, 0] <= RCOND * np.abs(exact).max(axis=-1)
    np.testing.assert_array_equal(singular_innovation(S), want)
    assert 0 < want.sum() < len(want)
