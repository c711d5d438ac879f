"""Azimuth and elevation prediction through a short loss of the target image (paper 001, theory §8).

Frame (theory §2.2, §8.2): carrier frame ``OXYZ``, ``OXY`` horizontal, ``OZ`` up; azimuth θ from
``OY`` towards ``OX`` (``X = Y tan θ``), elevation ϕ from the horizontal plane.

The target is assumed to move uniformly along a straight line relative to the carrier over the
last ``N + 1`` frames. Range is not measured, so the predictor works on one member of the family
of parallel *conditional* trajectories with the same angles, fixed by an arbitrary ``Y_C > 0``
(theory §8.1, §8.3). Of the window it uses three samples: A (oldest, ``i = N``), B (middle,
``i = N/2``) and C (latest, ``i = 0``)::

    (6)  Δ_Y/Δ_X = (tA − 2 tB + tC) / (2 tA tC − tA tB − tB tC) ,   t = tan θ
    (4)  X_C = Y_C tan θ_C
         A = the point of the line through C with slope Δ_Y/Δ_X seen at azimuth θ_A
         δ_X = (X_C − X_A)/N ,  δ_Y = (Y_C − Y_A)/N
    §8.5 θ_P = −atan(Δ_Y/Δ_X) ,  R = OC′ cos(θ_P − θ_C) ,  OA′ = R / cos(θ_P − θ_A)
         Z_A = OA′ tan ϕ_A ,  Z_C = OC′ tan ϕ_C ,  δ_Z = (Z_C − Z_A)/N
    §8.6 θ_пр = atan2(X_C + δ_X k, Y_C + δ_Y k) ,  ϕ_пр = atan2(Z_C + δ_Z k, OS′)

and smooths the time-constant parameters with an exponential filter ``x̂ ← x̂ + γ(x − x̂)``
(theory §8.4). The predictions are invariant to ``Y_C`` and exact for noise-free uniform
rectilinear motion (theory §12.6 AT-6).

Documented choices for the gaps (theory §13.16–13.21):

* 16 — ``tan ϕ`` in the δ_Z formula, ``R = OC′ cos(θ_P − θ_C)`` (theory §8.5 reconstruction).
* 17 — gain ``γ = 1/memory`` (``gain_rule="inverse"``, default) or ``2/(memory + 1)``
  (``"equivalent"``); the filters start at the first raw value; δ_Z is smoothed too
  (``smooth_delta_z=True``): the paper's list of filtered "time-constant parameters" omits
  it, but filtering it halves the elevation error at k = 100 in the paper's example (0.020° vs
  0.040° RMS); set False for the literal reading.
* The slope Δ_Y/Δ_X is smoothed as its direction angle ``α = atan(Δ_Y/Δ_X)`` with π-periodic
  wrapping (through :func:`~sensorgym.trackers.geometry.wrap_angle`). For the slopes of the
  paper's example this is the paper's filter to first order, and it stays finite for motion
  parallel to ``OY`` where Δ_Y/Δ_X → ∞ (item 20). Eq. (6) and the point A are evaluated in the
  equivalent homogeneous form (numerator and denominator of (6) multiplied by
  ``cos θ_A cos θ_B cos θ_C``; ``A = OA′ (sin θ_A, cos θ_A)``) so no ``tan θ`` of A or B appears.
* 18 — scale rule ``Y_C^{n+1} = Y_C^n + δ̂_Y^n``. The first ``Y_C = ρ₀ cos θ_C`` (default
  ``ρ₀ = 1000``), which is the paper's arbitrary positive ``Y_C`` whenever ``|θ_C| < 90°`` and
  keeps C on the measured ray when the target is behind ``OX``.
* 20 — singular geometry: azimuth of C at ±90° (``X_C = Y_C tan θ_C``) and a line of sight to
  A parallel to the trajectory (``cos(θ_P − θ_A) = 0``). A frame whose intermediate values are
  not finite keeps the previous estimates (zero velocity at the first estimate) — a finite
  documented fallback, never NaN.
* Before the first estimate (fewer than ``N + 1`` samples) :meth:`ABCPredictor.predict` holds
  the latest measurement.
* 20 — azimuths near ±90° of ``OY`` stay singular in the paper's frame. The construction is the
  same in any frame turned about ``OZ`` (three rays and a uniformly travelled line do not know
  where azimuth is counted from), so a tracker that runs long keeps its target near ``OY``:
  :func:`recentre` expresses a state in a frame turned by ψ, and the predictions, plus ψ, are
  the same (theory §13.20).

Time: every :meth:`ABCPredictor.update` call is one frame for every track of the batch. A track
whose image is lost (``mask`` False) coasts along its conditional trajectory, so
``predict(state, 0)`` is the commanded direction for the current frame and
``predict(state, k)`` the direction k frames later, whether the track is seen or not.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.trackers.geometry import unit_from_zup_angles, wrap_angle, zup_angles_from_unit
from sensorgym.trackers.validation import check_fields, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def wrap_half_turn(angle: ArrayLike) -> FloatArray:
    """Wrap a line direction (defined modulo π) into ``[-π/2, π/2)``."""
    return 0.5 * wrap_angle(2.0 * np.asarray(angle, dtype=np.float64))


def measurement_arrays(
    azimuth: ArrayLike, elevation: ArrayLike, batch: int, mask: ArrayLike | None
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Validate one frame of batched angles ``(B,)`` and the optional update mask ``(B,)``."""
    az = np.broadcast_to(finite_array(azimuth, "azimuth"), (batch,))
    el = np.broadcast_to(finite_array(elevation, "elevation"), (batch,))
    if mask is None:
        m = np.ones(batch, dtype=bool)
    else:
        m = np.broadcast_to(np.asarray(mask, dtype=bool), (batch,))
    return wrap_angle(az), el, m


def push_window(window: FloatArray, value: FloatArray, mask: BoolArray) -> FloatArray:
    """Append ``value (B,)`` to the sliding windows ``(B, W)`` (oldest first) where ``mask``."""
    shifted = np.concatenate([window[:, 1:], value[:, None]], axis=1)
    return np.where(mask[:, None], shifted, window)


def trajectory_direction(theta_A: ArrayLike, theta_B: ArrayLike, theta_C: ArrayLike) -> FloatArray:
    """Direction ``α = atan(Δ_Y/Δ_X)`` in ``[-π/2, π/2)`` of the horizontal trajectory, eq. (6).

    ``(6)  Δ_Y/Δ_X = T₃ / (2 T₁ T₂ + tan θ_B T₃)``, ``T₁ = tA − tB``, ``T₂ = tC − tB``,
    ``T₃ = tA − 2tB + tC`` (``t = tan θ``), evaluated with numerator and denominator multiplied
    by ``cos θ_A cos θ_B cos θ_C`` so that it stays finite at azimuths of ±90° and for motion
    parallel to ``OY``. Three equal azimuths (radial motion) give ``α = 0`` with a zero
    increment downstream, i.e. a constant predicted azimuth.
    """
    tA, tB, tC = (
        finite_array(t, n)
        for t, n in ((theta_A, "theta_A"), (theta_B, "theta_B"), (theta_C, "theta_C"))
    )
    sA, cA, sB, cB, sC, cC = np.sin(tA), np.cos(tA), np.sin(tB), np.cos(tB), np.sin(tC), np.cos(tC)
    # T₃·cAcBcC = sA cB cC − 2 cA sB cC + cA cB sC
    T3 = sA * cB * cC - 2.0 * cA * sB * cC + cA * cB * sC
    # (2T₁T₂ + tB T₃)·cAcBcC = 2 sA cB sC − sA sB cC − cA sB sC
    den = 2.0 * sA * cB * sC - sA * sB * cC - cA * sB * sC
    return wrap_half_turn(np.arctan2(T3, den))


@dataclass(frozen=True)
class ABCState:
    """Batched state of the A-B-C predictor; every array has a leading batch axis ``B``."""

    azimuth_window: FloatArray
    """Last ``N + 1`` azimuths θ (measured, or predicted while coasting), oldest first,
    ``(B, N + 1)`` (rad)."""
    elevation_window: FloatArray
    """Last ``N + 1`` elevations ϕ (measured, or predicted while coasting), oldest first,
    ``(B, N + 1)`` (rad)."""
    count: NDArray[np.int64]
    """Frames in the window since the last (re)start of the warm-up, ``(B,)``."""
    slope_angle: FloatArray
    """Smoothed direction ``α̂ = atan(Δ_Y/Δ_X)`` of the horizontal projection, ``(B,)`` (rad)."""
    delta: FloatArray
    """Smoothed per-frame increments ``(δ̂_X, δ̂_Y, δ̂_Z)`` of the conditional trajectory, ``(B, 3)``
    (conditional metres per frame)."""
    anchor: FloatArray
    """Point C ``(X_C, Y_C, Z_C)`` of the conditional trajectory at the last frame, ``(B, 3)``."""

    def __post_init__(self) -> None:
        B = self.count.shape[0]
        for name, tail in (
            ("azimuth_window", None),
            ("elevation_window", None),
            ("slope_angle", ()),
            ("delta", (3,)),
            ("anchor", (3,)),
        ):
            arr = getattr(self, name)
            if arr.shape[0] != B or (tail is not None and arr.shape[1:] != tail):
                raise ValueError(f"{name}: shape {arr.shape} does not match batch size {B}")

    @property
    def batch_size(self) -> int:
        return int(self.count.shape[0])

    @property
    def window(self) -> int:
        """N + 1, the number of samples the window holds."""
        return int(self.azimuth_window.shape[1])

    @property
    def ready(self) -> BoolArray:
        """True where the first estimate exists (at least ``N + 1`` samples), ``(B,)``."""
        return self.count >= self.window


@dataclass(frozen=True)
class ABCPredictor:
    """Three-point (A, B, C) straight-line predictor of azimuth and elevation (paper 001).

    Pure: :meth:`update` and :meth:`predict` return new values and never mutate ``state``.
    Defaults are the paper's example (``N = 50``, effective memory 10).
    """

    window: int = 50
    """N: frames between A and C (even, ≥ 2); the window holds N + 1 samples."""
    memory: float = 10.0
    """Effective memory of the exponential filter (frames)."""
    gain_rule: Literal["inverse", "equivalent"] = "inverse"
    """How ``memory`` sets the filter gain γ: ``1/memory`` or ``2/(memory + 1)`` (theory §8.4)."""
    initial_scale: float = 1000.0
    """Horizontal range ``OC′ = ρ₀`` of C at the first estimate, so ``Y_C = ρ₀ cos θ_C``: selects
    the conditional trajectory (conditional metres, > 0)."""
    smooth_delta_z: bool = True
    """Smooth δ_Z with the same filter (theory §13.17; not stated by the paper)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        if self.window < 2 or self.window % 2:
            raise ValueError(f"window: N must be an even integer ≥ 2, got {self.window}")
        if not self.memory >= 1.0:
            raise ValueError(f"memory: effective memory must be ≥ 1 frame, got {self.memory}")
        if self.gain_rule not in ("inverse", "equivalent"):
            raise ValueError(
                f"gain_rule: expected 'inverse' or 'equivalent', got {self.gain_rule!r}"
            )
        if not (np.isfinite(self.initial_scale) and self.initial_scale > 0.0):
            raise ValueError("initial_scale: Y_C must be a finite positive value")

    @property
    def gain(self) -> float:
        """Exponential-filter gain γ."""
        if self.gain_rule == "inverse":
            return 1.0 / self.memory
        return 2.0 / (self.memory + 1.0)

    def initial_state(self, batch_size: int) -> ABCState:
        """Empty state for ``batch_size`` independent tracks."""
        if batch_size < 1:
            raise ValueError("batch_size: must be ≥ 1")
        W = self.window + 1
        return ABCState(
            azimuth_window=np.zeros((batch_size, W)),
            elevation_window=np.zeros((batch_size, W)),
            count=np.zeros(batch_size, dtype=np.int64),
            slope_angle=np.zeros(batch_size),
            delta=np.zeros((batch_size, 3)),
            anchor=np.zeros((batch_size, 3)),
        )

    def update(
        self,
        state: ABCState,
        azimuth: ArrayLike,
        elevation: ArrayLike,
        mask: ArrayLike | None = None,
    ) -> ABCState:
        """Advance every track by one frame (theory §8.6 steps 1–7).

        ``azimuth``, ``elevation``: the measured angles ``(B,)`` (rad). Where ``mask`` is False
        the image is lost this frame and the track *coasts* (step 7): point C moves one frame
        along the conditional trajectory, ``C ← C + δ̂``, the predicted angles of the new C enter
        the window in place of a measurement, and the estimates α̂, δ̂ are kept — so when the
        image returns the window is still uniformly spaced and estimation continues. The
        angles passed for such tracks are ignored (they must still be finite). A track that
        loses the image before its first estimate restarts its warm-up.
        """
        if state.window != self.window + 1:
            raise ValueError("state: window length does not match this predictor's N")
        N, g = self.window, self.gain
        az, el, m = measurement_arrays(azimuth, elevation, state.batch_size, mask)
        was_ready = state.ready
        # coasting: C ← C + δ̂ and its angles (θ_пр^{n+1}, ϕ_пр^{n+1})
        hold = unit_from_zup_angles(state.azimuth_window[:, -1], state.elevation_window[:, -1])
        coast = state.anchor + state.delta
        coast_az, coast_el = zup_angles_from_unit(np.where(was_ready[:, None], coast, hold))
        push = m | was_ready
        th = push_window(state.azimuth_window, np.where(m, az, coast_az), push)
        ph = push_window(state.elevation_window, np.where(m, el, coast_el), push)
        count = np.where(push, state.count + 1, 0)
        ready = count >= N + 1
        first = m & (count == N + 1)

        th_A, th_B, th_C = th[:, 0], th[:, N // 2], th[:, N]
        ph_A, ph_C = ph[:, 0], ph[:, N]
        sA, cA, cC = np.sin(th_A), np.cos(th_A), np.cos(th_C)
        alpha_raw = trajectory_direction(th_A, th_B, th_C)  # tan α = Δ_Y/Δ_X     (5), (6)
        # α̂_n = α̂_{n−1} + γ (α_n − α̂_{n−1}), the difference taken modulo π           (§8.4)
        alpha = np.where(
            first,
            alpha_raw,
            wrap_half_turn(state.slope_angle + g * wrap_half_turn(alpha_raw - state.slope_angle)),
        )

        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # Y_C^{n+1} = Y_C^n + δ̂_Y^n (scale consistency, §8.4);  X_C = Y_C tan θ_C   (4)
            # first estimate: Y_C = ρ₀ cos θ_C puts C on the measured ray (OC′ = ρ₀) also
            # behind OX, where the paper's "any Y_C > 0" would pick the opposite ray
            Y_C = np.where(first, self.initial_scale * cC, state.anchor[:, 1] + state.delta[:, 1])
            X_C = Y_C * np.tan(th_C)
            # θ_P = −α̂;  R = OC′ cos(θ_P − θ_C);  OA′ = R / cos(θ_P − θ_A)            (§8.5)
            theta_P = -alpha
            OC = np.hypot(X_C, Y_C)
            R = OC * np.cos(theta_P - th_C)
            OA = R / np.cos(theta_P - th_A)
            # A: the point of the line through C (direction α̂) seen at θ_A,
            # (X_A, Y_A) = OA′ (sin θ_A, cos θ_A)
            X_A, Y_A = OA * sA, OA * cA
            # Z_A = OA′ tan ϕ_A,  Z_C = OC′ tan ϕ_C                                        (§8.5)
            Z_A, Z_C = OA * np.tan(ph_A), OC * np.tan(ph_C)
            # δ_X = 2Δ_X/N = (X_C − X_A)/N, same for Y;  δ_Z = (Z_C − Z_A)/N
            raw = np.stack([X_C - X_A, Y_C - Y_A, Z_C - Z_A], axis=-1) / N
        anchor = np.stack([X_C, Y_C, Z_C], axis=-1)
        finite = np.all(np.isfinite(raw), axis=-1) & np.all(np.isfinite(anchor), axis=-1)
        # degenerate frame: keep the previous estimates (zero velocity at the first estimate)
        previous = np.where(first[:, None], 0.0, state.delta)
        raw = np.where(finite[:, None], raw, previous)
        anchor = np.where(finite[:, None], anchor, state.anchor)
        # x̂_n = x̂_{n−1} + γ (x_n − x̂_{n−1}), started at the first raw value          (§8.4)
        smoothed = state.delta + g * (raw - state.delta)
        if not self.smooth_delta_z:
            smoothed[:, 2] = raw[:, 2]
        delta = np.where(first[:, None], raw, smoothed)

        upd = ready & m
        coasting = ~m & was_ready
        return ABCState(
            azimuth_window=th,
            elevation_window=ph,
            count=count,
            slope_angle=np.where(upd, alpha, state.slope_angle),
            delta=np.where(upd[:, None], delta, state.delta),
            anchor=np.where(upd[:, None], anchor, np.where(coasting[:, None], coast, state.anchor)),
        )

    def relock(
        self,
        state: ABCState,
        azimuth: ArrayLike,
        elevation: ArrayLike,
        mask: ArrayLike | None = None,
    ) -> ABCState:
        """The state a track re-acquired after a coast resumes from (not in paper 001; theory
        §13.42): call it with the first measurement after the loss, then :meth:`update` with
        the same measurement.

        Coasting fills the window with the conditional trajectory's angles; when the image
        returns, the measurement sits off that line by the prediction's error, and eq. (6) on
        samples A, B from the coast and C measured sees a kink that no straight line has: the
        raw slope, then the prediction, can swing by a half turn and the gate loses the target
        again. Re-locking moves the coasted track onto the new measurement, keeping its motion:
        C′ is the point on the measured ray at the horizontal range of the coasted ``C + δ̂``,
        ``OC′ = |C + δ̂|ₓᵧ``, ``C′ = OC′ (sin θ, cos θ, tan ϕ)``, and the window's samples are
        the angles of ``C′ − (N + 1 − i) δ̂`` (``i = 0 … N``, oldest first), point C is
        ``C′ − δ̂``; ``α̂`` and ``δ̂`` are kept. The next :meth:`update` pushes the measurement,
        the angles of ``C′``, onto a straight, uniformly travelled window.

        Applies where ``mask`` and the track has its estimate; elsewhere, and where ``OC′`` is
        not finite and positive, the state is returned unchanged.
        """
        if state.window != self.window + 1:
            raise ValueError("state: window length does not match this predictor's N")
        az, el, m = measurement_arrays(azimuth, elevation, state.batch_size, mask)
        coast = state.anchor + state.delta
        # OC′ = |C + δ̂|ₓᵧ;  C′ = OC′ (sin θ, cos θ, tan ϕ)
        rho = np.hypot(coast[:, 0], coast[:, 1])
        with np.errstate(invalid="ignore", over="ignore"):
            C = rho[:, None] * np.stack([np.sin(az), np.cos(az), np.tan(el)], axis=-1)
            # samples i = 0 … N at C′ − (N + 1 − i) δ̂
            back = (self.window + 1 - np.arange(self.window + 1, dtype=np.float64))[None, :, None]
            track = C[:, None, :] - back * state.delta[:, None, :]
        ok = (
            m
            & state.ready
            & np.isfinite(rho)
            & (rho > 0.0)
            & np.all(np.isfinite(C), axis=-1)
            & np.all(np.isfinite(track), axis=(1, 2))
        )
        ok &= np.all(np.any(track != 0.0, axis=-1), axis=-1)  # no sample at the origin
        th, ph = zup_angles_from_unit(np.where(ok[:, None, None], track, (0.0, 1.0, 0.0)))
        return ABCState(
            azimuth_window=np.where(ok[:, None], th, state.azimuth_window),
            elevation_window=np.where(ok[:, None], ph, state.elevation_window),
            count=state.count,
            slope_angle=state.slope_angle,
            delta=state.delta,
            anchor=np.where(ok[:, None], C - state.delta, state.anchor),
        )

    def predict(self, state: ABCState, steps: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Predicted azimuth and elevation ``k`` frames after the current one (theory §8.6 step 7).

        ``steps``: k (any shape, ≥ 0). Returns θ, ϕ of shape ``(B, *k.shape)`` (rad). Tracks
        without a first estimate hold their latest measurement.
        """
        k = finite_array(steps, "steps")
        if np.any(k < 0.0):
            raise ValueError("steps: prediction horizon must be non-negative")
        extra = (None,) * k.ndim
        # (X, Y, Z)_пр^{n+k} = (X_C, Y_C, Z_C) + (δ̂_X, δ̂_Y, δ̂_Z) k
        pos = state.anchor[(slice(None), *extra)] + (
            k[..., None] * state.delta[(slice(None), *extra)]
        )
        ready = state.ready[(slice(None), *extra, None)]
        hold = unit_from_zup_angles(state.azimuth_window[:, -1], state.elevation_window[:, -1])
        pos = np.where(ready, pos, hold[(slice(None), *extra)])
        # θ_пр = atan2(X, Y);  ϕ_пр = atan2(Z, OS′),  OS′ = √(X² + Y²)
        return zup_angles_from_unit(pos)


def recentre(state: ABCState, angle: ArrayLike) -> ABCState:
    """``state`` expressed in the carrier frame turned about ``OZ`` by ``angle`` ``(B,)`` (rad):
    azimuths counted from the old azimuth ``ψ`` (``θ′ = θ − ψ``); elevations unchanged.

    A point ``(X, Y)`` at azimuth θ and horizontal range ρ becomes
    ``X′ = ρ sin(θ − ψ) = X cos ψ − Y sin ψ``, ``Y′ = Y cos ψ + X sin ψ``, and the trajectory's
    direction ``α`` (from ``OX``) becomes ``α + ψ`` (modulo π); the window, the point C and the
    increments δ turn alike, so :meth:`ABCPredictor.predict` of the result plus ψ equals that of
    ``state`` (theory §13.20: keep the target away from azimuth ±90°). Later updates agree
    exactly without noise; with noise the scale rule ``Y_C ← Y_C + δ̂_Y`` counts Y in the
    turned frame, which moves the smoothed increments by a small fraction of the noise.
    """
    psi = np.broadcast_to(finite_array(angle, "angle"), (state.batch_size,))
    c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]

    def turn(v: FloatArray) -> FloatArray:
        # (X′, Y′) = (X cos ψ − Y sin ψ, Y cos ψ + X sin ψ), Z unchanged
        x, y = v[:, :1], v[:, 1:2]
        return np.concatenate([x * c - y * s, y * c + x * s, v[:, 2:]], axis=1)

    return ABCState(
        azimuth_window=wrap_angle(state.azimuth_window - psi[:, None]),
        elevation_window=state.elevation_window,
        count=state.count,
        slope_angle=wrap_half_turn(state.slope_angle + psi),
        delta=turn(state.delta),
        anchor=turn(state.anchor),
    )
