"""Train an SB3 algorithm on a registered env's native vector env, save it, score it.

The run folder (:mod:`.models`) gets the policy weights (``policy.safetensors``: data, no
pickle), the resolved configuration, an evaluation of the trained policy beside the heuristic
rules of the env's default set (:func:`~sensorgym.agents.registry.default_rules`, what
``sensorgym benchmark`` scores), all on one seed and the same evaluation scenarios (a seed disjoint
from training's), and the learning curve on those scenarios (:mod:`.curves`). A run may act
through wrappers (:mod:`.wrappers`) and imitate an expert before RL (:mod:`.experts`), as its
hyperparameters say. What the run cost (wall-clock per phase, samples, the machine) goes to
``cost.json`` (:mod:`.cost`), and every curve point and ARS iteration carries its wall-clock.
"""

from __future__ import annotations

import json
import math
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Any

from rich.progress import Progress
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from sensorgym.agents.registry import RULES, default_rules
from sensorgym.train.checkpoints import CHECKPOINT_DIR, Checkpointer, read_checkpoint
from sensorgym.train.config import (
    ALGORITHMS,
    apply_overrides,
    check_algo_kwargs,
    for_mode,
    load_hyperparams,
    split_run_settings,
)
from sensorgym.train.cost import (
    RunClock,
    load_average,
    machine_record,
    now_utc,
    pretrain_samples,
    write_cost,
)
from sensorgym.train.curves import LearningCurve, write_curve
from sensorgym.train.evaluation import env_params, evaluate, make_sb3_env, simulator_state
from sensorgym.train.experts import Pretrain, pretrain
from sensorgym.train.models import save_run

#: the scenarios every run is evaluated on (its learning curve and ``evaluation.json``), beside
#: the rules: a tuning seed, the same for every run so that runs and sweep configurations compare
#: paired. Never a held-out benchmark seed (10000 and up): a sweep picks its best configuration
#: on these evaluations. (Runs trained before 2026-11-27, the shipped ones among them, were
#: evaluated on their seed + 10000; nothing was chosen on those scores.)
VALIDATION_SEED = 500
#: the run folder's record of a direct policy search's iterations (``model.history``)
SEARCH_FILE = "search.json"


class EpisodeInfoLogger(BaseCallback):
    """Logs the env's own accuracy metrics per finished episode: every numeric entry of the
    ``info`` of the step that ended it (``final_info``: the final bound, position error, drones
    fixed, …) as ``episode/<key>``, averaged over the episodes of a logging interval — next to
    SB3's own scalars in whatever outputs the logger has (TensorBoard with ``--tensorboard``)."""

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"], strict=True):
            if not done:
                continue
            for key, value in info.get("final_info", {}).items():
                if isinstance(value, int | float) and math.isfinite(value):
                    self.logger.record_mean(f"episode/{key}", float(value))
        return True


class RichProgress(BaseCallback):
    """Advances a ``rich`` progress task by the transitions collected (one per env per step)."""

    def __init__(self, progress: Progress, task: Any):
        super().__init__()
        self.progress, self.task = progress, task

    def _on_step(self) -> bool:
        self.progress.update(self.task, completed=self.num_timesteps)
        return True


@dataclass(frozen=True)
class TrainResult:
    """Where a run was saved and how its policy scored."""

    run_dir: Path
    """The run folder (policy weights, config, evaluation)."""
    evaluation: dict[str, dict[str, float]]
    """Policy name → episode-return statistics (``"trained"`` and every rule of the default
    set)."""
    model: BaseAlgorithm | None = None
    """The trained model as it left training (what the run folder's weights reload)."""


def resume_arguments(run_dir: Path) -> dict[str, Any]:
    """The arguments of :func:`train` that the run under ``run_dir`` was started with (from its
    checkpoint; ``ValueError`` if it has none), with ``resume`` set to continue it."""
    run = dict(read_checkpoint(run_dir)["run"])
    params = {k: tuple(v) if isinstance(v, list) else v for k, v in run.pop("params").items()}
    return {**run, "params": params, "out": Path(run["out"]), "resume": Path(run_dir)}


def run_dir_for(out: Path, env_id: str, algo: str, seed: int, agents: bool = False) -> Path:
    """``out/<env id with / as __>/<algo>[-shared]_seed<seed>`` (``-shared``: parameter
    sharing over the env's agents)."""
    name = f"{algo}-shared" if agents else algo
    return Path(out) / env_id.replace("/", "__") / f"{name}_seed{seed}"


def train(
    env_id: str,
    algo: str = "ppo",
    *,
    seed: int = 0,
    timesteps: int | None = None,
    n_envs: int | None = None,
    out: Path = Path("results/train"),
    eval_episodes: int = 64,
    progress: bool = True,
    agents: bool = False,
    torch_threads: int = 1,
    hyperparams: dict[str, Any] | None = None,
    tensorboard: Path | None = None,
    callbacks: Sequence[BaseCallback] = (),
    curve_points: int = 10,
    params: dict[str, Any] | None = None,
    checkpoint_every: int | None = None,
    resume: Path | None = None,
) -> TrainResult:
    """Train ``algo`` on ``env_id`` with its YAML hyperparameters (``timesteps``/``n_envs``
    override them), save the run and evaluate it beside the rules.

    ``agents=True`` trains one policy shared by every agent of the env's PettingZoo version
    (parameter sharing): the slots of the SB3 env are scenarios × agents, each agent sees its
    own observation, and all get the team reward; ``n_envs`` counts scenarios.

    ``torch_threads`` sets torch's intra-op threads for the run (default 1: the policies here
    are small MLPs, one thread is never slower on them, and torch's default thread pool can
    stall a run many times over on a busy 2-core machine); it is restored afterwards.

    ``hyperparams`` override entries of the YAML's (``--hyperparam``, a sweep's sampled
    configuration; a dotted key such as ``pretrain.steps`` one inside a mapping,
    :func:`~sensorgym.train.config.apply_overrides`); the resolved set is saved in
    ``config.yaml``. ``tensorboard``: a folder for TensorBoard event
    files — SB3's scalars plus the env's accuracy metrics per episode
    (:class:`EpisodeInfoLogger`) — in ``<tensorboard>/<env id with __>_<algo>_seed<seed>_1``.
    ``callbacks`` are further SB3 callbacks run during learning.

    ``curve_points``: evaluations of the policy during learning (evenly spaced, plus one
    before it), each over the ``eval_episodes`` evaluation scenarios; written with the rules'
    scores as ``curve.json``/``curve.png`` (0: no curve).

    ``params``: env params fields (``--param NAME=VALUE``, e.g. ``{"n_drones": 4}``) for
    training and evaluation; recorded in ``config.yaml`` so the saved policy refuses an env
    with other ones.

    ``checkpoint_every``: write the run's checkpoint every that many samples
    (:mod:`.checkpoints`); ``resume``: a run folder with a checkpoint, whose run this call
    continues (every other argument but ``progress``, ``torch_threads``, ``tensorboard`` and
    ``callbacks`` is then the checkpoint's; :func:`resume_arguments`).
    """
    import torch

    if torch_threads < 1:
        raise ValueError(f"torch_threads: must be >= 1, got {torch_threads}")
    previous_threads = torch.get_num_threads()
    torch.set_num_threads(torch_threads)
    try:
        return _train(
            env_id,
            algo,
            seed,
            timesteps,
            n_envs,
            out,
            eval_episodes,
            progress,
            agents,
            hyperparams or {},
            tensorboard,
            list(callbacks),
            curve_points,
            dict(params or {}),
            checkpoint_every,
            None if resume is None else read_checkpoint(resume),
        )
    finally:
        torch.set_num_threads(previous_threads)


def _train(
    env_id: str,
    algo: str,
    seed: int,
    timesteps: int | None,
    n_envs: int | None,
    out: Path,
    eval_episodes: int,
    progress: bool,
    agents: bool,
    overrides: dict[str, Any],
    tensorboard: Path | None,
    callbacks: list[BaseCallback],
    curve_points: int,
    params: dict[str, Any],
    checkpoint_every: int | None = None,
    checkpoint: dict[str, Any] | None = None,
) -> TrainResult:
    begin, started, load_start = time.perf_counter(), now_utc(), load_average()
    run_args = {
        "env_id": env_id,
        "algo": algo,
        "seed": seed,
        "timesteps": timesteps,
        "n_envs": n_envs,
        "out": str(out),
        "eval_episodes": eval_episodes,
        "agents": agents,
        "hyperparams": overrides,
        "curve_points": curve_points,
        "params": {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()},
        "checkpoint_every": checkpoint_every,
    }
    hp = apply_overrides(for_mode(load_hyperparams(algo, env_id), agents), overrides)
    if timesteps is not None:
        hp["n_timesteps"] = timesteps
    if n_envs is not None:
        hp["n_envs"] = n_envs
    run, algo_kwargs = split_run_settings(hp)
    check_algo_kwargs(algo, algo_kwargs)
    if run["n_timesteps"] < 1 or run["n_envs"] < 1:
        raise ValueError(f"timesteps and n_envs must be >= 1, got {run}")
    if curve_points < 0:
        raise ValueError(f"curve_points: must be >= 0, got {curve_points}")
    wrappers = run.get("wrappers", [])
    imitation = Pretrain.from_config(run["pretrain"]) if "pretrain" in run else None
    # training-only wrappers (reward shaping) sit outside the policy's wrappers: the policy's
    # spaces are the same, evaluation and the curve score the env's own return
    shaping = run.get("training_wrappers", [])
    env = make_sb3_env(
        env_id, run["n_envs"], seed, agents=agents, wrappers=[*wrappers, *shaping], **params
    )
    tb_log = None if tensorboard is None else str(Path(tensorboard).resolve())
    if checkpoint is None:
        model = ALGORITHMS[algo](
            run["policy"],
            env,
            seed=seed,
            device="cpu",
            verbose=0,
            tensorboard_log=tb_log,
            **algo_kwargs,
        )
    else:  # weights, optimizer and counters from the checkpoint, on the rebuilt env
        model = ALGORITHMS[algo].load(
            checkpoint["model"], env=env, device="cpu", tensorboard_log=tb_log
        )

    # the same evaluation scenarios for all: the policy on its own (wrapped, per-agent) view,
    # the rules on the env's joint one; one random stream per episode, as the benchmark scores
    n_eval = min(16, eval_episodes)
    eval_seed = VALIDATION_SEED
    eval_env = make_sb3_env(env_id, n_eval, eval_seed, episode_streams=True, **params)
    model_env = make_sb3_env(
        env_id, n_eval, eval_seed, agents=agents, wrappers=wrappers, episode_streams=True,
        **params,
    )  # fmt: skip
    rules_begin = time.perf_counter()
    rule_scores: dict[str, dict[str, Any]] = {}
    for rule in default_rules(env_id):  # the benchmark's default set: its best rule among them
        try:
            policy = RULES[env_id][rule](env_params(eval_env), simulator_state(eval_env))
        except ValueError:  # a rule that does not apply to these params (e.g. one platform)
            continue
        rule_scores[rule] = evaluate(policy, eval_env, eval_episodes, eval_seed).as_dict()

    rules_s = time.perf_counter() - rules_begin

    clock = RunClock()  # training starts: imitation, then learning (see .cost)
    clock.start()
    if checkpoint is not None and checkpoint.get("clock"):  # the clock goes on from there
        clock.origin -= checkpoint["clock"]["elapsed_s"]
        clock.eval_s = checkpoint["clock"]["eval_s"]
    if hasattr(model, "clock"):  # ARS stamps its iterations with the run's clock
        model.clock = clock
    if checkpoint is not None:  # imitated before the checkpoint
        pretrain_loss = list(checkpoint.get("pretrain_loss") or [])
    elif imitation is not None:
        pretrain_loss = pretrain(model, env, imitation, seed)
    else:
        pretrain_loss = []
    pretrain_s = clock.elapsed()
    imitated = (  # the transitions the imitation phase collected, every slot's
        0
        if imitation is None
        else pretrain_samples(imitation.steps, imitation.rounds, env.num_envs)
    )
    curve = None
    if curve_points:
        every = max(1, -(-run["n_timesteps"] // curve_points))
        lines = {k: r["mean"] for k, r in rule_scores.items()}
        curve = LearningCurve(
            model_env, eval_episodes, eval_seed, every, clock, lines, pretrain_loss
        )
        if checkpoint is not None and checkpoint.get("curve_points"):
            curve.resume(checkpoint["curve_points"])
    name = run_dir_for(Path("."), env_id, algo, seed, agents)
    saver = []
    if checkpoint_every:
        folder = run_dir_for(out, env_id, algo, seed, agents) / CHECKPOINT_DIR
        saver = [Checkpointer(folder, checkpoint_every, run_args, curve, clock, pretrain_loss)]
    done = 0 if checkpoint is None else int(model.num_timesteps)
    with Progress(disable=not progress) as bar:
        task = bar.add_task(f"{algo} on {env_id}", total=run["n_timesteps"])
        model.learn(
            max(0, run["n_timesteps"] - done),
            callback=[
                RichProgress(bar, task),
                EpisodeInfoLogger(),
                *([curve] if curve is not None else []),
                *saver,
                *callbacks,
            ],
            tb_log_name=f"{name.parent.name}_{name.name}",
            reset_num_timesteps=checkpoint is None,
        )
    training_s, curve_eval_s = clock.elapsed(), clock.eval_s
    env.close()

    run_dir = run_dir_for(out, env_id, algo, seed, agents)
    config = {
        "env": env_id,
        "algo": algo,
        "seed": seed,
        "agents": agents,
        "params": {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()},
        "hyperparams": hp,
        "versions": {
            "sensorgym": version("sensorgym"),
            "stable_baselines3": version("stable-baselines3"),
            "torch": version("torch"),
            "safetensors": version("safetensors"),
            "python": platform.python_version(),
        },
    }
    save_run(model, run_dir, config)  # weights + config.yaml: no pickle, see .models

    final_begin = time.perf_counter()
    trained = evaluate(model, model_env, eval_episodes, eval_seed).as_dict()
    evaluation = {"trained": trained, **rule_scores}
    model_env.close()
    eval_env.close()
    doc = {"episodes": eval_episodes, "seed": eval_seed, "results": evaluation}
    (run_dir / "evaluation.json").write_text(json.dumps(doc, indent=2) + "\n")
    history = getattr(model, "history", None)
    if history:  # a direct policy search's iterations (ARS: seeds, returns, the vector)
        (run_dir / SEARCH_FILE).write_text(json.dumps(history, indent=1) + "\n")
    if curve is not None:
        lines = {k: r["mean"] for k, r in rule_scores.items()}
        write_curve(run_dir, f"{algo} on {env_id}, seed {seed}", curve.points, lines, pretrain_loss)
    final_s = time.perf_counter() - final_begin
    write_cost(
        run_dir,
        {
            "started_utc": started,
            "finished_utc": now_utc(),
            "wall_s": {
                "total": round(time.perf_counter() - begin, 3),
                "rules_evaluation": round(rules_s, 3),
                "pretrain": round(pretrain_s, 3),
                "learn": round(training_s - pretrain_s, 3),
                "training": round(training_s, 3),
                "curve_evaluation": round(curve_eval_s, 3),
                "final_evaluation": round(final_s, 3),
            },
            "samples": {
                "timesteps": int(model.num_timesteps),
                "pretrain": imitated,
                "total": int(model.num_timesteps) + imitated,
            },
            "n_envs": run["n_envs"],
            "eval_episodes": eval_episodes,
            "curve_points": curve_points,
            **({"resumed_at_timesteps": done} if checkpoint is not None else {}),
            "load_average_1min": {"start": load_start, "end": load_average()},
            "machine": machine_record(),
        },
    )
    return TrainResult(run_dir, evaluation, model)
