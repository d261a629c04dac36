"""Stable-Baselines3 PPO trained here as the RL Zoo trains it: the baseline a zoo study sets
snnkart's policies beside (same env version, seeds and budget; the ``bench`` extra).

The zoo's entry (:func:`snnkart.rl.zoo.zoo_settings`) is applied as ``rl_zoo3/exp_manager.py``
applies it: ``n_envs`` copies in a ``DummyVecEnv`` (``make_vec_env`` with the run's seed),
``normalize`` as ``VecNormalize`` with the entry's gamma (observations and rewards unless the
entry says otherwise), ``lin_<x>`` as a linear schedule from x to 0 over the training,
``policy_kwargs`` evaluated with ``dict`` and ``torch.nn`` in scope, every other key passed to
``PPO`` as it is. Evaluation is deterministic, on the env gymnasium makes, observations
normalised with the training's frozen statistics. Training uses one torch thread, as
snnkart's runs in a study do, so that steps per second compare like with like.
"""

from __future__ import annotations

import ast
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypedDict

import numpy as np

from snnkart.errors import UsageError
from snnkart.io import write_json
from snnkart.rl.zoo import ZooSettings

MODEL, NORMALISER, TIMING = "model.zip", "vecnormalize.pkl", "train.json"
_RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "policy_kwargs")


def _sb3() -> Any:
    try:
        import stable_baselines3
    except ImportError:
        raise UsageError(
            "the Stable-Baselines3 baseline needs the bench extra: pip install 'snnkart[bench]'"
        ) from None
    return stable_baselines3


def _schedule(value: object) -> object:
    """``lin_0.001`` as SB3's linear schedule (progress remaining times 0.001), else as is."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value.removeprefix("lin_"))
        return lambda progress_remaining: progress_remaining * start
    return value


class NormaliseKwargs(TypedDict, total=False):
    """VecNormalize's keyword arguments a zoo entry sets."""

    norm_obs: bool
    norm_reward: bool
    gamma: float


class SB3Timing(TypedDict):
    """``train.json``: what an SB3 run trained for and how long it took."""

    global_step: int
    wall_s: float
    steps_per_s: float
    stable_baselines3: str
    zoo_key: str
    zoo_source: str


def _normalize_kwargs(value: object, gamma: object) -> NormaliseKwargs | None:
    """The zoo's ``normalize`` entry as VecNormalize's keyword arguments (None: off)."""
    if value is False or value is None:
        return None
    kwargs = NormaliseKwargs()
    if isinstance(value, str):
        parsed = ast.literal_eval(value)
        if isinstance(parsed, dict):
            kwargs.update(parsed)  # type: ignore[typeddict-item]
    if gamma is not None:
        kwargs["gamma"] = float(gamma)  # type: ignore[arg-type]
    return kwargs


def sb3_arguments(settings: ZooSettings) -> tuple[int, NormaliseKwargs | None, dict[str, Any]]:
    """``(n_envs, VecNormalize kwargs or None, PPO kwargs)`` of a zoo entry."""
    import torch

    values = dict(settings.values)
    kwargs: dict[str, Any] = {k: _schedule(v) for k, v in values.items() if k not in _RUN_KEYS}
    if "policy_kwargs" in values:
        text = str(values["policy_kwargs"])
        kwargs["policy_kwargs"] = eval(text, {"__builtins__": {}, "dict": dict, "nn": torch.nn})
    norm = _normalize_kwargs(values.get("normalize"), values.get("gamma"))
    return int(values.get("n_envs", 1)), norm, kwargs  # type: ignore[call-overload]


def train_sb3(settings: ZooSettings, seed: int, steps: int, run_dir: Path) -> SB3Timing:
    """Train SB3 PPO on ``settings.env_id`` for ``steps`` env steps into ``run_dir`` (model,
    normaliser, ``train.json`` with the wall time); a finished run is reused."""
    timing = run_dir / TIMING
    if timing.is_file() and (run_dir / MODEL).is_file():
        saved: SB3Timing = json.loads(timing.read_text())
        return saved
    sb3 = _sb3()
    import torch
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # as snnkart's study runs train: one thread each, side by side
    n_envs, norm, kwargs = sb3_arguments(settings)
    venv = make_vec_env(settings.env_id, n_envs=n_envs, seed=seed)
    normaliser = None if norm is None else VecNormalize(venv, **norm)
    if normaliser is not None:
        venv = normaliser
    policy = str(settings.values.get("policy", "MlpPolicy"))
    model = sb3.PPO(policy, venv, seed=seed, device="cpu", verbose=0, **kwargs)
    start = time.perf_counter()
    model.learn(total_timesteps=steps)
    wall = time.perf_counter() - start
    run_dir.mkdir(parents=True, exist_ok=True)
    model.save(run_dir / MODEL)
    if normaliser is not None:
        normaliser.save(str(run_dir / NORMALISER))
    venv.close()
    record: SB3Timing = {
        "global_step": int(model.num_timesteps),
        "wall_s": wall,
        "steps_per_s": model.num_timesteps / wall,
        "stable_baselines3": sb3.__version__,
        "zoo_key": settings.key,
        "zoo_source": settings.source,
    }
    write_json(timing, record)
    return record


class SB3Predictor:
    """A trained SB3 model's deterministic action, observations normalised as in training."""

    def __init__(self, run_dir: Path, env_id: str) -> None:
        sb3 = _sb3()
        self.model = sb3.PPO.load(run_dir / MODEL, device="cpu")
        self.normalise: Callable[[Any], Any] = lambda obs: obs
        if (run_dir / NORMALISER).is_file():
            import gymnasium as gym
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            dummy = DummyVecEnv([lambda: gym.make(env_id)])
            stats = VecNormalize.load(str(run_dir / NORMALISER), dummy)
            stats.training = False
            self.normalise = stats.normalize_obs

    def reset(self) -> None:
        """SB3's MLP policies keep no state between episodes."""

    def predict(self, obs: np.ndarray) -> Any:
        action, _ = self.model.predict(self.normalise(obs), deterministic=True)
        return int(action) if np.ndim(action) == 0 else action


class RandomPredictor:
    """Uniform random actions from the env's action space, seeded: the floor of the scores."""

    def __init__(self, space: Any, seed: int) -> None:
        self.space = space
        self.space.seed(seed)

    def reset(self) -> None:
        """No state."""

    def predict(self, obs: np.ndarray) -> Any:
        return self.space.sample()


def describe(settings: ZooSettings) -> dict[str, str | None]:
    """What a record says of the zoo entry the baseline trained with."""
    return {"key": settings.key, "source": settings.source, "note": settings.note}
