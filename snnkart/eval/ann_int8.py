"""The ANN baseline quantised to int8 and measured: calibrated on observations the float policy
recorded on episodes of its own, then driven on the deployment's seeded episodes with the
float ANN shadowing it, so the report's int8 baseline has a measured success rate.

- **Calibration:** the float ANN (deterministic) drives :data:`CALIBRATION_EPISODES` episodes
  with seeds ``first_seed + episodes, ...``, the seeds right after the evaluation's (never one
  of them); every normalised observation it sees calibrates the activation scales
  (:func:`snnkart.rl.int8.quantise_mlp`).
- **Evaluation:** the int8 actor drives the deployment's episodes (seeds ``first_seed`` to
  ``first_seed + episodes - 1``, the env and track the caller makes); on every step the float
  ANN is asked for its action on the same observation, and the steps where both agree are
  counted (discrete: the same action; continuous: every component within
  :data:`ACTION_TOLERANCE`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from snnkart.contract.eval_record import success_share
from snnkart.contract.report_record import AnnRunTask, Int8Task, Task
from snnkart.eval.episodes import EvalSummary, run_episodes
from snnkart.rl.int8 import Int8Mlp, actor_activation, actor_params, quantise_mlp
from snnkart.rl.rollout import normalize_obs
from snnkart.rl.trained import LoadedRun, TorchPredictor

CALIBRATION_EPISODES = 5
"""Episodes the float ANN drives to record calibration observations (a few thousand)."""
ACTION_TOLERANCE = 0.01
"""Continuous actions agree when every component differs by at most this (actions in [-1, 1])."""
INT8_PROFILE_MARK = "int8"
"""A digital profile whose name contains this prices an int8 datapath: the int8 ANN's task."""


def normalised(run: LoadedRun, obs: np.ndarray) -> np.ndarray:
    """The float32 normalised observation the ANN actor takes (frozen normalisation)."""
    raw = np.asarray(obs, dtype=np.float32)[None]
    return normalize_obs(run.obs_rms, run.config.ppo, raw)[0]


class _Recording:
    """The float ANN, recording every normalised observation it is given."""

    def __init__(self, run: LoadedRun, seed: int) -> None:
        self.run, self.float = run, TorchPredictor(run, seed=seed)
        self.observations: list[np.ndarray] = []

    def reset(self) -> None:
        self.float.reset()

    def predict(self, obs: np.ndarray) -> Any:
        self.observations.append(normalised(self.run, obs))
        return self.float.predict(obs)


class Int8Predictor:
    """The int8 actor as a predictor, the float ANN shadowing it on every observation."""

    def __init__(self, run: LoadedRun, net: Int8Mlp, seed: int) -> None:
        self.run, self.net = run, net
        self.discrete = run.policy.discrete
        self.shadow = TorchPredictor(run, seed=seed)
        self.steps = self.agreed = 0
        self.seconds = {"int8": 0.0, "float": 0.0}  # wall time of each forward pass

    def reset(self) -> None:
        self.shadow.reset()

    def predict(self, obs: np.ndarray) -> Any:
        t0 = time.perf_counter()
        action = self.net.act(normalised(self.run, obs)[None], self.discrete)[0]
        t1 = time.perf_counter()
        reference = self.shadow.predict(obs)
        self.seconds["int8"] += t1 - t0
        self.seconds["float"] += time.perf_counter() - t1
        self.steps += 1
        if self.discrete:
            self.agreed += int(action) == int(reference)
            return int(action)
        self.agreed += bool(np.all(np.abs(action - reference) <= ACTION_TOLERANCE))
        return action

    @property
    def agreement(self) -> float | None:
        return self.agreed / self.steps if self.steps else None


def calibration_seeds(first_seed: int, episodes: int, count: int = CALIBRATION_EPISODES) -> range:
    """The calibration episodes' seeds: right after the evaluation's, none of them."""
    return range(first_seed + episodes, first_seed + episodes + count)


def record_observations(run: LoadedRun, make_env: Callable[[], Any], seeds: range) -> np.ndarray:
    """Every normalised observation the float ANN sees on episodes ``seeds`` (n, obs)."""
    recorder = _Recording(run, seeds.start)
    env = make_env()
    try:
        run_episodes(env, recorder, len(seeds), seeds.start)
    finally:
        env.close()
    return np.stack(recorder.observations)


def int8_task(
    run: LoadedRun,
    make_env: Callable[[], Any],
    first_seed: int,
    episodes: int,
    calibration_episodes: int = CALIBRATION_EPISODES,
    reward_threshold: float | None = None,
) -> Int8Task:
    """Quantise the run's actor and drive the episodes ``first_seed, ...``: the int8 ANN's
    task record (the report's ``ann.run.task.int8``)."""
    t0 = time.perf_counter()
    seeds = calibration_seeds(first_seed, episodes, calibration_episodes)
    observations = record_observations(run, make_env, seeds)
    activation = actor_activation(run.policy.actor)
    net = quantise_mlp(actor_params(run.policy.actor), observations, activation)
    t1 = time.perf_counter()
    predictor = Int8Predictor(run, net, first_seed)
    env = make_env()
    try:
        results = run_episodes(env, predictor, episodes, first_seed)
    finally:
        env.close()
    summary = EvalSummary.of(results)
    return {
        "success_rate": success_share(results, reward_threshold),
        "mean_lap_time": summary.mean_lap_time,
        "mean_return": summary.mean_return,
        "episodes": episodes,
        "first_seed": first_seed,
        "steps_per_episode": predictor.steps / episodes,
        "action_agreement": predictor.agreement,
        "agreement_rule": "the float ANN's action on the same observation, every step of the "
        "int8 run: "
        + (
            "the same action"
            if run.policy.discrete
            else f"every component within {ACTION_TOLERANCE}"
        ),
        "calibration": {
            "first_seed": seeds.start,
            "episodes": len(seeds),
            "observations": len(observations),
            "policy": "the float ANN, deterministic",
        },
        "scheme": "post-training int8, symmetric per tensor (weights, layer inputs and "
        "pre-activations), int32 accumulate, integer requantisation, "
        + ("ReLU exact on the int8 pre-activation" if activation == "relu" else "tanh by table"),
        "layers": net.describe(),
        "seconds": {"calibration": t1 - t0, "evaluation": time.perf_counter() - t1},
        "host_ms_per_inference": {
            "int8": 1000 * predictor.seconds["int8"] / max(predictor.steps, 1),
            "float": 1000 * predictor.seconds["float"] / max(predictor.steps, 1),
            "what": "wall time of one forward pass (normalisation included) on this machine's "
            "CPU: the numpy int8 simulation and the torch float32 actor; not a model of a "
            "digital accelerator's latency",
        },
    }


def task_on(task: AnnRunTask | None, profile: str) -> Task | None:
    """The ANN's task on a digital profile: the int8 ANN's measured task on an int8 datapath
    (when it was measured), else the float ANN's."""
    if task is not None and INT8_PROFILE_MARK in profile and task.get("int8"):
        return task["int8"]
    return task
