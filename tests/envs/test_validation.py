"""Bad input gets a clear exception naming the argument at construction, or a finite result
(issue 10, defect 7): huge actions, non-integer counts, infinite noise, an unbounded clip, the
wrong params class. Issue 35: every params field is type-exact — a bool is no count and no
number, a float no count — refused at construction through every door, naming the field."""

from __future__ import annotations

import dataclasses
import types
import typing

import gymnasium as gym
import numpy as np
import pytest

from sensorgym.envs import (
    ENV_IDS,
    PARALLEL_ENVS,
    BearingsManeuverVectorEnv,
    ManeuverParams,
    PlacementParams,
    PointingParams,
    ScanningParams,
)
from sensorgym.envs.worlds.platform import PlatformWorldParams
from sensorgym.trackers.angles.baselines import LineFitPredictor
from sensorgym.trackers.angles.prediction import ABCPredictor
from sensorgym.trackers.stereo.algorithmic_detection import AlgorithmicParams
from sensorgym.trackers.stereo.period_tracking import AlternativeParams, ProposedParams


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_huge_finite_actions_are_clipped_without_a_warning(env_id):
    # the suite turns RuntimeWarnings into errors: an overflow in the finite check would fail
    env = gym.make(env_id)
    env.reset(seed=0)
    obs, reward, *_ = env.step(np.full(env.action_space.shape, 1e308, dtype=np.float64))
    assert np.isfinite(reward) and env.observation_space.contains(obs)
    with pytest.raises(ValueError, match="action"):
        env.step(np.full(env.action_space.shape, np.inf))


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: ManeuverParams(bank_members=2.5), "bank_members"),
        (lambda: ManeuverParams(platforms=2.0), "platforms"),
        (lambda: ManeuverParams(platforms="2"), "platforms"),
        (lambda: PointingParams(n_drones=True), "n_drones"),
        (lambda: PointingParams(n_receivers=3.5), "n_receivers"),
    ],
)
def test_counts_must_be_integers(make, field):
    with pytest.raises(TypeError, match=field):
        make()


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: PointingParams(cue_sigma=(np.inf, 1.0)), "cue_sigma"),
        (lambda: PointingParams(reward_clip=1e308), "reward_clip"),
        (lambda: PlacementParams(reward_clip=1e308), "reward_clip"),
        (lambda: PlacementParams(cue_sigma=(1.0, np.nan)), "cue_sigma"),
    ],
)
def test_unbounded_settings_are_refused(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_scenario_and_step_counts_are_checked_by_name():
    with pytest.raises(TypeError, match="num_envs"):
        BearingsManeuverVectorEnv(num_envs=2.0)
    with pytest.raises(TypeError, match="max_episode_steps"):
        PARALLEL_ENVS["sensorgym/StereoPointing-v0"](max_episode_steps="10")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_wrong_params_class_is_named(env_id):
    with pytest.raises(TypeError, match="params"):
        gym.make(env_id, params=object())


# --- issue 35 item 2: every params field is type-exact (a bool is no count, no number) --------


def _params_type(env_id: str) -> type:
    return type(gym.make(env_id).unwrapped.params)


def _kinds(hint: object) -> set[object]:
    """The types an annotation admits, ``None`` dropped: ``int | None`` -> ``{int}``."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return {a for a in typing.get_args(hint) if a is not type(None)}
    return {hint}


def _fields_of_kind(kind: object) -> list[tuple[str, str]]:
    """``(env id, field)`` of every registered env's params field annotated ``kind`` (or
    ``kind | None``), read from ``dataclasses.fields`` and the resolved annotations."""
    found = []
    for env_id in ENV_IDS:
        params_type = _params_type(env_id)
        hints = typing.get_type_hints(params_type)
        for f in dataclasses.fields(params_type):
            if _kinds(hints[f.name]) == {kind}:
                found.append((env_id, f.name))
    return found


INT_FIELDS = _fields_of_kind(int)
FLOAT_FIELDS = _fields_of_kind(float)


def test_the_field_lists_are_not_empty():
    # the parametrisations below would pass vacuously over an empty list
    assert ("sensorgym/StereoScanning-v0", "max_clutter") in INT_FIELDS
    assert {env_id for env_id, _ in INT_FIELDS} == set(ENV_IDS)
    assert ("sensorgym/StereoPointing-v0", "circle_radius") in FLOAT_FIELDS
    assert {env_id for env_id, _ in FLOAT_FIELDS} == set(ENV_IDS)


def _refused_naming(field: str, make) -> None:
    with pytest.raises((TypeError, ValueError)) as caught:
        make()
    message = str(caught.value)
    assert message.startswith(f"{field}:") and "\n" not in message, message


@pytest.mark.parametrize("env_id, field", INT_FIELDS)
def test_a_bool_for_an_integer_field_is_refused_at_construction(env_id, field):
    """``max_clutter=True`` used to pass the checks and fail at the first step (``TypeError: an
    integer is required``); ``raster_lines=True`` ran as 1. Every door refuses it up front."""
    _refused_naming(field, lambda: gym.make(env_id, **{field: True}))
    _refused_naming(field, lambda: PARALLEL_ENVS[env_id](**{field: True}))
    _refused_naming(
        field,
        lambda: gym.make_vec(
            env_id, num_envs=2, vectorization_mode="vector_entry_point", **{field: True}
        ),
    )
    params_type = _params_type(env_id)
    for bad in (True, False, np.bool_(True), 2.0, np.float64(3.0), "2"):
        _refused_naming(field, lambda bad=bad: params_type(**{field: bad}))


@pytest.mark.parametrize("env_id, field", FLOAT_FIELDS)
def test_a_bool_for_a_real_field_is_refused_at_construction(env_id, field):
    params_type = _params_type(env_id)
    _refused_naming(field, lambda: gym.make(env_id, **{field: True}))
    for bad in (True, np.bool_(False), "1.0", None):
        _refused_naming(field, lambda bad=bad: params_type(**{field: bad}))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_bool_inside_a_pair_of_reals_is_refused(env_id):
    params_type = _params_type(env_id)
    hints = typing.get_type_hints(params_type)
    pairs = [
        f.name
        for f in dataclasses.fields(params_type)
        if tuple[float, float] in _kinds(hints[f.name])
    ]
    assert pairs
    for field in pairs:
        _refused_naming(field, lambda field=field: params_type(**{field: (True, 2.0)}))


def test_the_bearings_world_refuses_a_bool_too():
    for f in dataclasses.fields(PlatformWorldParams):
        _refused_naming(f.name, lambda f=f: PlatformWorldParams(**{f.name: True}))
    with pytest.raises(TypeError, match="world"):
        gym.make("sensorgym/BearingsManeuver-v0", world=object())


def test_integers_of_every_kind_still_pass():
    # numpy integers and Python ints stand for counts; ints for reals; np.bool_ for a flag
    p = ScanningParams(n_drones=np.int64(3), raster_lines=50, circle_radius=100)
    assert p.n_drones == 3 and p.raster_lines == 50 and p.circle_radius == 100
    assert PointingParams(cued_start=np.bool_(False)).cued_start == np.False_
    with pytest.raises(TypeError, match="cued_start: must be True or False, got 1"):
        PointingParams(cued_start=1)


def test_the_message_keeps_its_style():
    with pytest.raises(TypeError, match=r"^max_clutter: must be an integer, got True$"):
        ScanningParams(max_clutter=True)
    with pytest.raises(ValueError, match=r"^raster_lines: must be an integer >= 1, got 0$"):
        ScanningParams(raster_lines=0)
    with pytest.raises(TypeError, match=r"^sector_width: must be a pair of real numbers"):
        ScanningParams(sector_width=(0.1, True))


#: the trackers' params with integer fields (counts, windows, beams), checked like the envs'
TRACKER_PARAMS = (
    AlternativeParams,
    ProposedParams,
    AlgorithmicParams,
    ABCPredictor,
    LineFitPredictor,
)


@pytest.mark.parametrize(
    "params_type, field",
    [
        (p, f.name)
        for p in TRACKER_PARAMS
        for f in dataclasses.fields(p)
        if int in _kinds(typing.get_type_hints(p)[f.name])
    ],
)
def test_tracker_params_refuse_a_bool_for_an_integer_field(params_type, field):
    for bad in (True, np.bool_(True), 2.0):
        _refused_naming(field, lambda bad=bad: params_type(**{field: bad}))


def test_every_tracker_params_has_an_integer_field():
    for p in TRACKER_PARAMS:
        hints = typing.get_type_hints(p)
        assert any(int in _kinds(hints[f.name]) for f in dataclasses.fields(p)), p
