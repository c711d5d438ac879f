"""Simulation core of the receiver-pointing environments (multi-receiver stereo tracking).

The simulation contract of every env (:mod:`sensorgym.envs.shells.contract`): pure functions
over frozen, batched values (leading axis ``B`` = scenario) — :func:`spaces`, :func:`reset`
(:func:`start` builds scenarios from given drones and pointing), :func:`step`, :func:`observe`
(the joint view), :func:`observe_agents` (one view per receiver) and :func:`info`.

World frame: ``Y`` up, azimuth measured from ``+Z`` towards ``+X`` (theory §2.2, the 000/003
convention applied to world axes). ``n`` gimballed receivers stand on a circle (theory §10.3 OC-3),
each pointing its narrow field of view (a cone of half-angle ``fov``) at world azimuth and
elevation ``(α_k, ε_k)``. ``m`` drones fly straight lines.

One step (``params.dt`` seconds):

1. the action ``a ∈ [−1, 1]^{n×2}`` slews each receiver by ``a · slew_rate · dt`` in azimuth
   and elevation (elevation held within ``±max_elevation``); the drones move on;
2. receiver ``k`` sees drone ``j`` if the line of sight ``u_kj`` lies inside its cone; it
   measures ``u_kj`` with isotropic angular noise ``σ_ang``
   (:func:`~sensorgym.envs.worlds.stereo_scene.perturb_directions`);
3. the tracker (:mod:`sensorgym.trackers.stereo.kalman`) fixes each drone seen by at least two
   receivers (weighted least squares, covariance ``σ² G⁻¹``) and updates its constant-velocity
   Kalman filter with the fix; with fewer views it only predicts;
4. the reward is the mean over drones of ``clip(ln(σ_ref / σ_pos), −R, R)`` with
   ``σ_pos = √tr I(M)⁻¹`` the Cramér–Rao bound of the receivers that see the drone now, at the
   true geometry: ``I(M) = Σ_k (I − u_k u_kᵀ)/(σ² r_k²)``
   (:mod:`sensorgym.trackers.stereo.information`); fewer than two views (or
   parallel lines of sight) give ``−R``. The bound has no noise draw in it: the reward depends
   only on where the receivers point, and it favours near-orthogonal pairs (theory §10.1 OC-1).

Degenerate inputs never raise inside :func:`step` or :func:`observe`; each has a documented,
finite fallback:

* co-located receivers (two equal places on the circle) are refused by :class:`PointingParams`:
  their lines of sight to any point are parallel, no fix could ever be made;
* a fix is used only if it passes the observability test with its information at its own
  ranges (:func:`~sensorgym.trackers.stereo.information.weighted_fix`) *and* lies at least
  ``MIN_FIX_RANGE`` (1 cm) in front of every receiver that sees it
  (:func:`~sensorgym.trackers.stereo.information.fix_in_front`): near-parallel noisy lines of
  sight from nearby receivers cross at the receivers, where the information looks regular;
* a point within ``MIN_RANGE`` (1e-9 m) of a receiver — a drone flying through it, or the
  tracker's prediction — has the zero line of sight from it (:func:`lines_of_sight`): it is not
  seen, measured as zero, and reads as a zero pointing offset;
* exact fixes (``sigma_ang = 0``) with no process noise make the Kalman innovation covariance
  singular: the update then takes the pseudo-inverse gain and the fix itself
  (:mod:`sensorgym.trackers.stereo.kalman`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgym.envs.shells.contract import EnvSpaces, with_agent_index
from sensorgym.envs.shells.normals import standard_normal_rows
from sensorgym.envs.shells.params_pickle import FieldsOnlyPickle
from sensorgym.envs.shells.rows import MIN_ROWS_PER_THREAD, run_drawn_rows
from sensorgym.envs.stereo_pointing import kernels
from sensorgym.envs.stereo_pointing.kernels import lines_of_sight_batch, pointing_offsets_batch
from sensorgym.trackers.geometry import angles_from_unit, unit_from_angles
from sensorgym.trackers.stereo.information import MAX_REWARD_CLIP
from sensorgym.trackers.stereo.kalman import CVTrack, cv_predict
from sensorgym.trackers.validation import check_fields, count, finite_array

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: params fields whose episodes reach compiled paths the defaults do not: more assignments than
#: the exhaustive search takes (9 receivers, 4 drones), where the assignment rules turn to their
#: polynomial solvers. ``sensorgym compile`` steps the env and decides with every rule at each
#: (:func:`sensorgym.cli.compile.warm`).
COMPILE_VARIANTS: tuple[dict[str, Any], ...] = ({"n_receivers": 9, "n_drones": 4},)


@dataclass(frozen=True)
class PointingParams(FieldsOnlyPickle):
    """Layout, drones, sensors, tracker and reward of the receiver-pointing environments."""

    n_receivers: int = 4
    """Number of gimballed receivers ``n``."""
    circle_radius: float = 50.0
    """Radius of the circle the receivers stand on, centred at the origin, m (theory §10.3 OC-3)."""
    receiver_angles_deg: tuple[float, ...] | None = None
    """Receiver places on the circle, degrees from ``+Z`` towards ``+X``; None spaces the ``n``
    receivers evenly (90° apart for n = 4, the OC-3 example)."""
    n_drones: int = 2
    """Number of drones ``m``."""
    start_distance: tuple[float, float] = (60.0, 150.0)
    """Horizontal distance of a drone's start from the circle centre, drawn uniformly, m."""
    start_altitude: tuple[float, float] = (30.0, 80.0)
    """Height of a drone's start above the receivers, drawn uniformly, m."""
    drone_speed: tuple[float, float] = (5.0, 15.0)
    """Horizontal drone speed, drawn uniformly, m/s; heading uniform over all directions."""
    climb_rate: tuple[float, float] = (-1.0, 1.0)
    """Vertical drone speed, drawn uniformly, m/s."""
    dt: float = 0.2
    """Step length, s."""
    fov: float = float(np.deg2rad(8.0))
    """Half-angle of each receiver's field of view (a cone around the boresight), rad."""
    slew_rate: float = float(np.pi / 2.0)
    """Largest slew rate of a gimbal in azimuth and in elevation, rad/s."""
    max_elevation: float = float(np.deg2rad(85.0))
    """Gimbal elevation limit ``|ε| ≤ max_elevation``, rad."""
    initial_elevation: tuple[float, float] = (0.0, 0.3)
    """Initial boresight elevation, drawn uniformly, rad (azimuth uniform over all directions);
    used when ``cued_start`` is False."""
    cued_start: bool = True
    """Gimbals start on the cue: receiver ``k`` points at drone ``k mod m``'s cued position (the
    tracker's prior), as a cueing radar would hand over. False: random initial pointing, where
    most episodes begin with no drone in any field of view (a hard exploration problem)."""
    sigma_ang: float = 1e-3
    """Isotropic angular noise of a measured direction (σ across the line of sight in each of
    the two directions), rad. 0 gives noise-free measurements."""
    cue_sigma: tuple[float, float] = (5.0, 2.0)
    """The tracker starts from an external cue: truth plus Gaussian errors of these standard
    deviations per axis in position (m) and velocity (m/s), with that covariance."""
    process_noise: float = 1.0
    """Spectral density ``q`` of the filter's white-noise acceleration, m²/s³."""
    sigma_ref: float = 1.0
    """Position accuracy that earns zero reward, m."""
    reward_clip: float = 5.0
    """``R``: the per-drone reward ``ln(σ_ref/σ_pos)`` is clipped to ``[−R, R]``; ``−R`` when a
    drone is not fixed (fewer than two views)."""

    def __post_init__(self) -> None:
        check_fields(self)  # every field of its annotated type: no bool for a count or a number
        count(self.n_receivers, "n_receivers", minimum=2)
        count(self.n_drones, "n_drones")
        if not (np.isfinite(self.circle_radius) and self.circle_radius > 0.0):
            raise ValueError(f"circle_radius: must be positive, got {self.circle_radius}")
        angles = self.receiver_angles_deg
        if angles is not None and (
            len(angles) != self.n_receivers or not np.all(np.isfinite(angles))
        ):
            raise ValueError(
                f"receiver_angles_deg: need {self.n_receivers} finite angles, got {angles}"
            )
        if angles is not None:
            # co-located receivers see every point along parallel lines of sight: no fix ever
            o = self.receiver_positions
            gap = np.linalg.norm(o[:, None] - o[None], axis=-1) + np.eye(self.n_receivers)
            if np.any(gap <= 1e-9 * self.circle_radius):
                raise ValueError(
                    f"receiver_angles_deg: two receivers share a place (angles equal modulo"
                    f" 360°), got {angles}"
                )
        for name in ("start_distance", "start_altitude", "drone_speed", "climb_rate"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ValueError(f"{name}: need finite low <= high, got {(lo, hi)}")
        if self.start_distance[0] <= 0.0 or self.drone_speed[0] < 0.0:
            raise ValueError("start_distance/drone_speed: must be positive / non-negative")
        if not (np.isfinite(self.dt) and self.dt > 0.0):
            raise ValueError(f"dt: must be positive, got {self.dt}")
        if not 0.0 < self.fov < np.pi / 2:
            raise ValueError(f"fov: half-angle must lie in (0, π/2) rad, got {self.fov}")
        if not (np.isfinite(self.slew_rate) and self.slew_rate >= 0.0):
            raise ValueError(f"slew_rate: must be finite and >= 0, got {self.slew_rate}")
        if not 0.0 < self.max_elevation < np.pi / 2:
            raise ValueError(f"max_elevation: must lie in (0, π/2) rad, got {self.max_elevation}")
        lo, hi = self.initial_elevation
        if not -self.max_elevation <= lo <= hi <= self.max_elevation:
            raise ValueError(
                f"initial_elevation: need a range within ±max_elevation, got {(lo, hi)}"
            )
        if not (np.isfinite(self.sigma_ang) and self.sigma_ang >= 0.0):
            raise ValueError(f"sigma_ang: must be finite and >= 0, got {self.sigma_ang}")
        if not (np.all(np.isfinite(self.cue_sigma)) and min(self.cue_sigma) > 0.0):
            raise ValueError(f"cue_sigma: both must be positive, got {self.cue_sigma}")
        if not (np.isfinite(self.process_noise) and self.process_noise >= 0.0):
            raise ValueError(f"process_noise: must be finite and >= 0, got {self.process_noise}")
        if not (np.isfinite(self.sigma_ref) and self.sigma_ref > 0.0):
            raise ValueError(f"sigma_ref: must be positive, got {self.sigma_ref}")
        if not 0.0 < self.reward_clip <= MAX_REWARD_CLIP:
            raise ValueError(
                f"reward_clip: must lie in (0, {MAX_REWARD_CLIP}], got {self.reward_clip}"
            )

    @property
    def receiver_positions(self) -> FloatArray:
        """``(n, 3)`` world positions of the receivers on the circle (height 0), m."""
        if self.receiver_angles_deg is None:
            ang = 2.0 * np.pi * np.arange(self.n_receivers) / self.n_receivers
        else:
            ang = np.deg2rad(np.asarray(self.receiver_angles_deg, dtype=np.float64))
        r = self.circle_radius
        return np.stack([r * np.sin(ang), np.zeros_like(ang), r * np.cos(ang)], -1)

    @functools.cached_property
    def _receivers(self) -> FloatArray:
        """:attr:`receiver_positions`, computed once (read-only) for the compiled kernels."""
        o = np.ascontiguousarray(self.receiver_positions)
        o.flags.writeable = False
        return o

    @functools.cached_property
    def kernel_settings(self) -> NDArray[np.void]:
        """The scalar settings the compiled kernels read, as one read-only record (a
        structured array of one element, dtype :data:`.kernels.SETTINGS`) that they read by
        field name; computed once per params."""
        fields = {
            "slew": self.slew_rate * self.dt,
            "max_elevation": self.max_elevation,
            "dt": self.dt,
            "q": self.process_noise,
            "cos_fov": np.cos(self.fov),
            "sigma_ang": self.sigma_ang,
            "sigma_ref": self.sigma_ref,
            "reward_clip": self.reward_clip,
            "fov": self.fov,
            "length_scale": self.length_scale,
            "velocity_scale": self.velocity_scale,
        }
        record = np.array(
            [tuple(fields[name] for name in kernels.SETTINGS.names)], kernels.SETTINGS
        )
        record.flags.writeable = False
        return record

    @property
    def length_scale(self) -> float:
        """Length (m) that normalises observed positions: the far edge of the start distances."""
        return self.start_distance[1]

    @property
    def velocity_scale(self) -> float:
        """Speed (m/s) that normalises observed velocities: the top drone speed (at least 1 m/s)."""
        return max(self.drone_speed[1], 1.0)

    @property
    def obs_dim(self) -> int:
        """Observation length: ``3n + 3nm + 8m`` (see :func:`observe`)."""
        n, m = self.n_receivers, self.n_drones
        return 3 * n + 3 * n * m + 8 * m


@dataclass(frozen=True)
class PointingState:
    """Batched episode state (leading axis ``B``).

    Derived values: a state made by :func:`step` also carries its observation and diagnostics,
    written by the same compiled kernel (a private attribute, not a field, tagged with the
    params and the field objects they were computed from), so :func:`observe` and :func:`info`
    only read them. A state built any other way (:func:`start`, ``dataclasses.replace``, the
    shells' scenario selection) computes them on the first call and keeps them. States are
    values: never change their arrays in place.
    """

    t: FloatArray
    """(B,) time since the episode start, s."""
    azimuth: FloatArray
    """(B, n) boresight world azimuths ``α_k``, rad in ``[−π, π)``."""
    elevation: FloatArray
    """(B, n) boresight elevations ``ε_k``, rad."""
    drone_position: FloatArray = field(repr=False)
    """(B, m, 3) true drone positions, m (ground truth: never observed)."""
    drone_velocity: FloatArray = field(repr=False)
    """(B, m, 3) true drone velocities, m/s."""
    track: CVTrack = field(repr=False)
    """The tracker the agent sees through: one CV Kalman filter per drone, batch ``(B, m)``."""
    seen: BoolArray = field(repr=False)
    """(B, n, m) which receiver saw which drone on the last step."""
    fixed: BoolArray = field(repr=False)
    """(B, m) which drones got a position fix on the last step."""
    bound: FloatArray = field(repr=False)
    """(B, m) CRLB position RMS ``σ_pos`` of the last step's views, m (inf: no fix)."""

    @property
    def batch_size(self) -> int:
        """Number of scenarios ``B``."""
        return int(self.t.shape[0])


def spaces(params: PointingParams) -> EnvSpaces:
    """Agents ``receiver_0 … receiver_{n−1}``, each slewing its gimbal ``(azimuth, elevation)``;
    the joint view is :func:`observe`, each agent's that plus a one-hot of its index."""
    n = params.n_receivers
    return EnvSpaces.build("receiver", n, params.obs_dim, params.obs_dim + n, 2)


def boresights(azimuth: ArrayLike, elevation: ArrayLike) -> FloatArray:
    """Unit boresight vectors ``(..., 3)`` of world azimuths and elevations (rad)."""
    return unit_from_angles(azimuth, elevation)


def lines_of_sight(params: PointingParams, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit lines of sight ``(B, n, m, 3)`` and ranges ``(B, n, m)`` from each receiver to
    each of ``points (B, m, 3)``.

    A point within ``MIN_RANGE`` (1e-9 m) of a receiver has no direction from it: its line of
    sight is the zero vector (the documented fallback). Such a point is never seen (the cone
    test needs ``u · boresight ≥ cos fov > 0``), is measured as the zero vector
    (:func:`~sensorgym.envs.worlds.stereo_scene.perturb_directions`) and reads as a zero
    pointing offset (:func:`pointing_offsets`).
    """
    p = _c(points)
    B, m = p.shape[:2]
    n = params.n_receivers
    u, r = np.empty((B, n, m, 3)), np.empty((B, n, m))
    lines_of_sight_batch(params._receivers, p, u, r)
    return u, r


def start(
    params: PointingParams,
    drone_position: ArrayLike,
    drone_velocity: ArrayLike,
    azimuth: ArrayLike,
    elevation: ArrayLike,
    rng: np.random.Generator,
) -> PointingState:
    """Scenarios from given drones ``(B, m, 3)`` and pointing ``(B, n)``; the tracker starts
    from the cue (truth plus ``cue_sigma`` errors, drawn from ``rng``)."""
    n, m = params.n_receivers, params.n_drones
    p = finite_array(drone_position, "drone_position", tail=(m, 3))
    v = finite_array(drone_velocity, "drone_velocity", tail=(m, 3))
    az = finite_array(azimuth, "azimuth", tail=(n,))
    el = finite_array(elevation, "elevation", tail=(n,))
    B = p.shape[0]
    if p.ndim != 3 or v.shape != p.shape or az.shape != (B, n) or el.shape != (B, n):
        raise ValueError(f"drone_position/velocity, azimuth/elevation: batch {B} shapes differ")
    return _start(params, _c(p), _c(v), _c(az), _c(el), rng, cued=False)


def _start(
    params: PointingParams,
    p: FloatArray,
    v: FloatArray,
    azimuth: FloatArray,
    elevation: FloatArray,
    rng: np.random.Generator,
    cued: bool,
) -> PointingState:
    """:func:`start` of checked, C-contiguous inputs; ``cued``: then receiver ``k`` aims at
    drone ``k mod m``'s cued position (:func:`aim_at`)."""
    n, m, B = params.n_receivers, params.n_drones, p.shape[0]
    sp, sv = params.cue_sigma
    noise_p = rng.standard_normal(p.shape)
    noise_v = rng.standard_normal(v.shape)
    x, P = np.empty((B, m, 6)), np.empty((B, m, 6, 6))
    az, el = np.empty((B, n)), np.empty((B, n))
    kernels.start_kernel(
        params.kernel_settings, (sp, sv), (p, v), (noise_p, noise_v), (azimuth, elevation),
        (x, P, az, el),
    )  # fmt: skip
    if cued:
        u = np.empty((B, n, 3))
        kernels.cue_lines_batch(params._receivers, x, u)
        az, el = _aim(params, u, az, el)
    return PointingState(
        t=np.zeros(B),
        azimuth=az,
        elevation=el,
        drone_position=p,
        drone_velocity=v,
        track=CVTrack(x, P),
        seen=np.zeros((B, n, m), dtype=bool),
        fixed=np.zeros((B, m), dtype=bool),
        bound=np.full((B, m), np.inf),
    )


class ScenarioDraws(NamedTuple):
    """The random draws of fresh scenarios (:func:`draw_scenario`): per drone ``(B, m)``, per
    receiver ``(B, n)``."""

    distance: FloatArray
    """Horizontal distance ``d`` of a drone's start from the circle centre, m."""
    bearing: FloatArray
    """Bearing ``β`` of the start from the centre, rad (from ``+Z`` towards ``+X``)."""
    height: FloatArray
    """Height ``h`` of the start, m."""
    speed: FloatArray
    """Horizontal speed ``s``, m/s."""
    heading: FloatArray
    """Heading ``ψ``, rad."""
    climb: FloatArray
    """Vertical speed, m/s."""
    azimuth: FloatArray
    """Initial boresight azimuths ``(B, n)``, rad (used as drawn unless ``cued_start``)."""
    elevation: FloatArray
    """Initial boresight elevations ``(B, n)``, rad."""


def draw_scenario(params: PointingParams, rng: np.random.Generator, batch: int) -> ScenarioDraws:
    """The draws of ``batch`` fresh scenarios, in a fixed order so that a seed fixes every
    scenario: each drone's distance, bearing, height, speed, heading and climb (uniform in their
    params ranges, the angles over the full circle), then each receiver's azimuth (full circle)
    and elevation (``initial_elevation``). The random initial pointing is drawn even when the
    start is cued (it stays where a cue gives no direction, :func:`aim_at`)."""
    n, m = params.n_receivers, params.n_drones
    return ScenarioDraws(
        distance=rng.uniform(*params.start_distance, (batch, m)),
        bearing=rng.uniform(-np.pi, np.pi, (batch, m)),
        height=rng.uniform(*params.start_altitude, (batch, m)),
        speed=rng.uniform(*params.drone_speed, (batch, m)),
        heading=rng.uniform(-np.pi, np.pi, (batch, m)),
        climb=rng.uniform(*params.climb_rate, (batch, m)),
        azimuth=rng.uniform(-np.pi, np.pi, (batch, n)),
        elevation=rng.uniform(*params.initial_elevation, (batch, n)),
    )


def reset(
    params: PointingParams,
    rng: np.random.Generator,
    batch: int,
    like: PointingState | None = None,
) -> PointingState:
    """``batch`` fresh scenarios: drones at random places and courses, gimbals on the cue (or at
    random azimuths), the tracker on its cue. Scenarios share nothing: ``like`` is unused."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    m = params.n_drones
    d = draw_scenario(params, rng, batch)
    # p = (d sin β, h, d cos β),  v = (s sin ψ, climb, s cos ψ)
    p, v = np.empty((batch, m, 3)), np.empty((batch, m, 3))
    kernels.drones_kernel(d.distance, d.bearing, d.height, d.speed, d.heading, d.climb, p, v)
    # the tracker on its cue; receiver k on drone k mod m's cued position
    return _start(params, p, v, d.azimuth, d.elevation, rng, cued=params.cued_start)


def aim_at(
    params: PointingParams, points: FloatArray, azimuth: FloatArray, elevation: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Azimuth and elevation ``(B, n)`` that put receiver ``k`` on ``points[:, k] (B, n, 3)``
    (elevation held within ``±max_elevation``); a receiver whose point lies on it (no
    direction) keeps its ``azimuth``/``elevation``."""
    u = np.empty((*np.shape(points)[:-1], 3))
    kernels.aim_lines_batch(params._receivers, _c(points), u)
    return _aim(params, u, _c(azimuth), _c(elevation))


def _aim(
    params: PointingParams, u: FloatArray, azimuth: FloatArray, elevation: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """:func:`aim_at` along the lines of sight ``u (B, n, 3)`` (zero: no direction)."""
    az, el = angles_from_unit(u, check=False)
    kernels.aim_merge(u, azimuth, elevation, params.max_elevation, az, el)
    return az, el


def _c(a: ArrayLike) -> FloatArray:
    """``a`` as a C-contiguous float64 array (no copy if it is one): the one layout the
    compiled kernels are built for."""
    return np.ascontiguousarray(a, dtype=np.float64)


def step(
    params: PointingParams, state: PointingState, action: ArrayLike, rng: np.random.Generator
) -> tuple[PointingState, FloatArray, BoolArray]:
    """Advance every scenario one step under the joint ``action`` ``(B, n, 2)`` (or ``(B, 2n)``).

    Actions outside ``[−1, 1]`` are clipped; NaN or infinite actions raise ``ValueError`` (the
    compiled step checks them: the noise is drawn first). Returns ``(state, reward (B,),
    terminated (B,))``: nothing ends an episode here (always False); the time limit is the
    shells' business. The new state carries its observation and diagnostics
    (:class:`PointingState`).
    """
    n, m, B = params.n_receivers, params.n_drones, state.t.shape[0]
    a = np.asarray(action, dtype=np.float64)
    if a.shape != (B, n, 2):
        if a.size != B * n * 2:
            raise ValueError(f"action: expected {B * n * 2} values (B, n, 2), got shape {a.shape}")
        a = a.reshape(B, n, 2)
    # measure every pair (a fixed number of draws, perturb_directions' draws), use what is seen;
    # a threaded step draws them row range by row range as its chunks start (run_drawn_rows:
    # the same stream)
    noise = np.empty((B, n, m, 3))

    def draw(lo: int, hi: int) -> None:
        if params.sigma_ang > 0.0:
            standard_normal_rows(rng, noise, lo, hi)

    # the state's arrays go in as they are: step, start and the shells make them float64 and
    # C-contiguous (the compiled kernel would take any other layout too, compiled anew)
    args = (params._receivers, params.kernel_settings, state_arrays(state), a, noise)
    t, az, el = np.empty(B), np.empty((B, n)), np.empty((B, n))
    p, x, P = np.empty((B, m, 3)), np.empty((B, m, 6)), np.empty((B, m, 6, 6))
    seen, fixed = np.empty((B, n, m), dtype=bool), np.empty((B, m), dtype=bool)
    bound, reward = np.empty((B, m)), np.empty(B)
    obs, diag = np.empty((B, params.obs_dim), dtype=np.float32), np.empty((kernels.N_DIAG, B))
    v = state.drone_velocity  # the drones fly straight: the new state's is the old one's
    outputs = ((t, az, el, p, v, x, P, seen, fixed, bound), (reward, obs, diag))
    if B < 2 * MIN_ROWS_PER_THREAD:  # what run_drawn_rows does for a batch this small, sooner
        draw(0, B)
        finite = kernels.step_kernel(0, B, *args, *outputs)
    else:
        chunks: list[bool] = []
        kernel_on = lambda lo, hi: chunks.append(kernels.step_kernel(lo, hi, *args, *outputs))  # noqa: E731
        run_drawn_rows(B, draw, kernel_on, key=__name__)
        finite = all(chunks)
    if not finite:
        raise ValueError("action: contains NaN or infinite values")
    new = PointingState(t, az, el, p, state.drone_velocity, CVTrack(x, P), seen, fixed, bound)
    object.__setattr__(new, "_derived", (params, obs, diag, _sources(new)))
    return new, reward, np.zeros(B, dtype=bool)


def predicted_track(params: PointingParams, state: PointingState) -> CVTrack:
    """The tracker's prediction for the next measurement time ``t + dt`` (what the agent aims at)."""
    return cv_predict(state.track, params.dt, params.process_noise)


def pointing_offsets(
    params: PointingParams, azimuth: FloatArray, elevation: FloatArray, points: FloatArray
) -> FloatArray:
    """World-angle offsets ``(B, n, m, 2)`` of ``points (B, m, 3)`` from each boresight, rad:
    ``(wrap(α_kj − α_k), ε_kj − ε_k)`` with ``(α_kj, ε_kj)`` the direction of point ``j``
    from receiver ``k``; slewing by exactly these offsets puts the point on the boresight.
    A point on a receiver (no direction, :func:`lines_of_sight`) reads as a zero offset."""
    p = _c(points)
    B, m = p.shape[:2]
    out = np.empty((B, params.n_receivers, m, 2))
    pointing_offsets_batch(
        params._receivers,
        _c(azimuth),
        _c(elevation),
        p,
        out,
    )
    return out


def observe(params: PointingParams, state: PointingState) -> NDArray[np.float32]:
    """The agent's observation ``(B, obs_dim)`` float32 — own gimbals and the tracker, no truth.

    Blocks in this order (``n`` receivers, ``m`` drones; ``p̂_j``, ``σ̂_j`` the tracker's
    prediction of drone ``j`` for the next measurement, ``L = length_scale``):

    | block       | shape        | meaning                                                  |
    |-------------|--------------|----------------------------------------------------------|
    | gimbals     | ``(n, 3)``   | ``sin α_k``, ``cos α_k``, ``ε_k / (π/2)``                |
    | offsets     | ``(n, m, 3)``| direction of ``p̂_j`` from receiver ``k`` relative to its |
    |             |              | boresight, ``(Δα, Δε) / fov``; and 1.0 if ``k`` saw ``j``|
    |             |              | on the last step, else 0.0                               |
    | drones      | ``(m, 8)``   | ``p̂_j / L`` (world, m) and ``ln(σ̂_j / σ_ref)``,          |
    |             |              | ``σ̂ = √tr P_pp``; ``v̂_j / V`` (world, m/s) and           |
    |             |              | ``ln(σ̂_v,j · 1 s / σ_ref)``, ``σ̂_v = √tr P_vv``          |

    ``V = velocity_scale`` (the top drone speed). The velocity estimate and its uncertainty are
    the tracker's own (the CV filter's state), so a policy can tell where each drone is heading
    and how far its prediction can be trusted.

    Every entry is clipped to ``[−OBS_CLIP, OBS_CLIP]`` (an offset of more than ten
    half-angles reads as ±10).
    """
    return _derived(params, state)[1]


def state_arrays(state: PointingState) -> tuple[NDArray[Any], ...]:
    """The state's arrays in the order the kernels take them (:data:`.kernels.StateArrays`):
    time, gimbals, drones, tracks, who saw whom, the fixes and the bound."""
    return (
        state.t,
        state.azimuth,
        state.elevation,
        state.drone_position,
        state.drone_velocity,
        state.track.x,
        state.track.P,
        state.seen,
        state.fixed,
        state.bound,
    )


def _sources(state: PointingState) -> tuple[object, ...]:
    """The field values the observation and diagnostics are computed from."""
    return (
        state.azimuth,
        state.elevation,
        state.drone_position,
        state.track,
        state.track.x,
        state.track.P,
        state.seen,
        state.fixed,
    )


def _derived(params: PointingParams, state: PointingState) -> tuple[Any, ...]:
    """``(params, observation, diagnostics (N_DIAG, B), sources)`` of ``state``: those :func:`step`
    wrote, else computed by the compiled kernel and kept on the state (:class:`PointingState`).
    They are used only for the same params and the very field objects they were computed from
    (a copy of the state with other fields, e.g. the shells' autoreset merge, recomputes)."""
    d = state.__dict__.get("_derived")
    if (
        d is not None
        and d[0] is params
        and all(a is b for a, b in zip(d[3], _sources(state), strict=True))
    ):
        return d
    B = state.t.shape[0]
    obs, diag = np.empty((B, params.obs_dim), dtype=np.float32), np.empty((kernels.N_DIAG, B))
    arrays = tuple(
        np.ascontiguousarray(a, dtype=bool if a.dtype == bool else np.float64)
        for a in map(np.asarray, state_arrays(state))
    )
    kernels.observe_kernel(params._receivers, params.kernel_settings, arrays, obs, diag)
    d = (params, obs, diag, _sources(state))
    object.__setattr__(state, "_derived", d)
    return d


def observe_agents(params: PointingParams, state: PointingState) -> NDArray[np.float32]:
    """Per-receiver views ``(B, n, obs_dim + n)``: :func:`observe` and a one-hot of the
    receiver's index."""
    return with_agent_index(observe(params, state), params.n_receivers)


def info(params: PointingParams, state: PointingState) -> dict[str, FloatArray]:
    """Diagnostics (ground truth included: for evaluation, never for the policy): the mean
    position error of the tracks, the number of drones fixed and of receiver-drone views; for
    the tail measures (:mod:`sensorgym.train.tail`) the share of drones without a fix and, over the
    fixed drones with a finite bound, the sum and count of their CRLB ``σ_pos`` (m, the
    reward's :attr:`PointingState.bound`)."""
    diag = _derived(params, state)[2]
    return {
        "position_error": diag[kernels.I_ERROR],
        "drones_fixed": diag[kernels.I_FIXED],
        "views": diag[kernels.I_VIEWS],
        # the tail measures' entries, :func:`tail_info` compiled
        "unfixed_share": diag[kernels.I_UNFIXED],
        "fixed_sigma_sum": diag[kernels.I_SIGMA_SUM],
        "fixed_sigma_count": diag[kernels.I_SIGMA_COUNT],
    }


def tail_info(state: PointingState) -> dict[str, FloatArray]:
    """The entries of :func:`info` for the tail measures, read off the state: the share of
    drones without a fix and, over the fixed drones with a finite bound, the sum and count of
    their CRLB ``σ_pos`` (m). The readable form, used by :mod:`.reference`; :func:`info` reads
    the same from the compiled diagnostics."""
    sigma = state.bound
    counted = state.fixed & np.isfinite(sigma)
    return {
        "unfixed_share": (~state.fixed).mean(axis=1),
        "fixed_sigma_sum": np.where(counted, sigma, 0.0).sum(axis=1),
        "fixed_sigma_count": counted.sum(axis=1).astype(np.float64),
    }


def split_observation(
    params: PointingParams, obs: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Inverse of :func:`observe`'s layout: ``(gimbals (N, n, 3), pairs (N, n, m, 3), drones
    (N, m, 8))`` of observations ``(N, obs_dim)``."""
    n, m = params.n_receivers, params.n_drones
    o = np.asarray(obs, dtype=np.float64)
    N = o.shape[0]
    g = o[:, : 3 * n].reshape(N, n, 3)
    pairs = o[:, 3 * n : 3 * n + 3 * n * m].reshape(N, n, m, 3)
    drones = o[:, 3 * n + 3 * n * m :].reshape(N, m, 8)
    return g, pairs, drones


def observed_pointing(
    params: PointingParams, obs: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """What an observation ``(N, obs_dim)`` says about the pointing: boresight azimuths and
    elevations ``(N, n)`` (rad) and the tracker's predicted drone positions ``(N, m, 3)`` (m)."""
    gimbals, _, drones = split_observation(params, obs)
    azimuth = np.arctan2(gimbals[..., 0], gimbals[..., 1])
    elevation = gimbals[..., 2] * (np.pi / 2)
    return azimuth, elevation, drones[..., :3] * params.length_scale


def slew_actions(
    params: PointingParams,
    azimuth: FloatArray,
    elevation: FloatArray,
    points: FloatArray,
    target: ArrayLike,
) -> FloatArray:
    """The slew controller: normalised actions ``(N, 2n)`` that turn receiver ``k`` (boresight
    at ``azimuth``/``elevation (N, n)``) straight at ``points[:, target[:, k]]`` (``points
    (N, m, 3)``, ``target (N, n)`` drone indices) as fast as the gimbal allows, stopping on it
    (the largest step is ``slew_rate · dt``; the elevation stops at its limit)."""
    tgt = np.asarray(target, dtype=np.int64)
    m = points.shape[1]
    if tgt.shape != azimuth.shape or (tgt.size and (tgt.min() < 0 or tgt.max() >= m)):
        raise ValueError(f"target: need drone indices in [0, {m}) of shape {azimuth.shape}")
    offsets = pointing_offsets(params, azimuth, elevation, points)
    off = np.take_along_axis(offsets, tgt[:, :, None, None], axis=2)[:, :, 0]  # (N, n, 2)
    # the gimbal stops at its elevation limit
    lim = params.max_elevation
    d_el = np.clip(elevation + off[..., 1], -lim, lim) - elevation
    step = max(params.slew_rate * params.dt, 1e-12)
    action = np.stack([off[..., 0], d_el], -1) / step
    return np.clip(action, -1.0, 1.0).reshape(off.shape[0], -1)


def assignment_actions(params: PointingParams, obs: ArrayLike, target: ArrayLike) -> FloatArray:
    """:func:`slew_actions` read off observations ``(N, obs_dim)``: receiver ``k`` slews at the
    tracker's predicted position of drone ``target[:, k]`` — the one slew controller the
    assignment rules and the assignment action
    (:class:`~sensorgym.train.env_wrappers.stereo_pointing.AssignmentAction`) share."""
    azimuth, elevation, points = observed_pointing(params, obs)
    return slew_actions(params, azimuth, elevation, points, target)
