"""Expert recordings: what a driver (a person at ``snnkart play --record`` or a scripted driver
at ``snnkart record``) saw and did, step by step, in one ``.npz`` file.

Format ``snnkart/recording/v1`` (numpy ``.npz``, no pickles; docs/training.md, "Expert data"):

======================  ==========================  =============================================
array                   shape, dtype                meaning
======================  ==========================  =============================================
``meta``                0-d str (JSON)              schema, driver, the env's
                                                    :func:`~snnkart.envs.spec.env_spec` and
                                                    ``env_spec_hash``, ``gamma`` of ``returns``,
                                                    one entry per episode (seed, length, return,
                                                    how it ended)
``obs``                 [N, obs_dim] float32        the observation each action was taken on
``actions``             [N] int64 / [N, A] float32  the action taken (discrete / continuous)
``rewards``             [N] float32                 the reward of that step
``terminated``          [N] bool                    the step ended the episode (finish, crash...)
``truncated``           [N] bool                    the episode was cut there (time limit, or
                                                    the driver restarted or quit)
``returns``             [N] float32                 discounted return-to-go with ``meta.gamma``,
                                                    within the step's episode
``episode_starts``      [E] int64                   index of each episode's first step
``seeds``               [E] int64                   the reset seed of each episode
======================  ==========================  =============================================

Every episode is reset with an explicit seed, so re-running the env with the recorded seeds and
actions reproduces the recorded observations (:func:`replay_observations`). A recording is used
only in an env with the same spec (:meth:`Recording.check`): one made in another env, action
mode or observation layout is refused with one line naming the difference.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

import gymnasium as gym
import numpy as np

from snnkart.envs.spec import (
    env_spec,
    layout_of,
    revision_mismatch,
    spec_differences,
    spec_hash,
)
from snnkart.errors import SnnkartError
from snnkart.io import atomic_path

RECORDING_SCHEMA = "snnkart/recording/v1"
RECORDING_GAMMA = 0.995
"""Discount of the recorded ``returns`` (PPO's default ``ppo.gamma``); a user of another gamma
recomputes them from ``rewards`` with :func:`returns_to_go`."""
ARRAYS = (
    "obs",
    "actions",
    "rewards",
    "terminated",
    "truncated",
    "returns",
    "episode_starts",
    "seeds",
)


class RecordingError(SnnkartError, ValueError):
    """A recording file that is missing, malformed, or made in another env."""


RecordedEpisode = TypedDict(
    "RecordedEpisode", {"seed": int, "length": int, "end": str | None, "return": float}
)
"""One episode of a recording: its reset seed, its steps, how it ended (finished, crashed,
stood_still, terminated, time_limit, restarted or stopped) and its return."""


class RecordingMeta(TypedDict):
    """The ``meta`` of a recording (module docstring)."""

    schema: str
    driver: str
    env_spec: dict[str, object]
    env_spec_hash: str
    gamma: float
    episodes: list[RecordedEpisode]


class _OpenEpisode(TypedDict):
    seed: int
    start: int
    end: str | None  # how it ended; None while it runs


def returns_to_go(
    rewards: np.ndarray, episode_starts: np.ndarray, gamma: float = RECORDING_GAMMA
) -> np.ndarray:
    """Discounted sum of each step's reward and the rewards after it in its episode:
    ``G_t = r_t + gamma * G_{t+1}``, restarting at every episode start."""
    out = np.zeros(len(rewards), dtype=np.float64)
    ends = [*episode_starts[1:].tolist(), len(rewards)]
    for start, end in zip(episode_starts.tolist(), ends, strict=True):
        acc = 0.0
        for t in range(end - 1, start - 1, -1):
            acc = float(rewards[t]) + gamma * acc
            out[t] = acc
    return out.astype(np.float32)


@dataclass
class Recording:
    """One recording in memory; :meth:`save` and :meth:`load` are its file round trip."""

    meta: RecordingMeta
    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    episode_starts: np.ndarray
    seeds: np.ndarray
    returns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))

    def __post_init__(self) -> None:
        if len(self.returns) != len(self.rewards):
            self.returns = returns_to_go(self.rewards, self.episode_starts, self.meta["gamma"])
        n = len(self.obs)
        for name in ("actions", "rewards", "terminated", "truncated", "returns"):
            if len(getattr(self, name)) != n:
                raise RecordingError(
                    f"recording: {name} has {len(getattr(self, name))} rows, obs {n}"
                )
        if len(self.seeds) != len(self.episode_starts):
            raise RecordingError("recording: one seed per episode expected")

    @property
    def spec(self) -> dict[str, object]:
        """The :func:`~snnkart.envs.spec.env_spec` of the env it was recorded in."""
        return dict(self.meta["env_spec"])

    @property
    def episodes(self) -> int:
        return len(self.episode_starts)

    def save(self, path: str | Path) -> Path:
        """Write the ``.npz`` atomically (an interrupted write leaves no partial file)."""
        arrays = {name: getattr(self, name) for name in ARRAYS}
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, meta=np.array(json.dumps(self.meta)), **arrays)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> Recording:
        """Read a recording; a file that is not one says what it lacks."""
        p = Path(path)
        if not p.is_file():
            raise RecordingError(
                f"recording {p} does not exist; make one with snnkart record or snnkart play --record"
            )
        try:
            with np.load(p, allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                arrays = {name: data[name] for name in ARRAYS}
        except (OSError, ValueError, KeyError) as exc:
            raise RecordingError(f"{p} is not a snnkart recording ({exc})") from None
        if meta.get("schema") != RECORDING_SCHEMA:
            raise RecordingError(
                f"{p}: schema {meta.get('schema')!r}, this snnkart reads {RECORDING_SCHEMA}"
            )
        return cls(meta=meta, **arrays)

    def check(
        self, spec: Mapping[str, object], source: str = "recording", *, any_track: bool = False
    ) -> None:
        """Refuse (one line naming the difference) unless this recording was made in an env
        with ``spec``; ``any_track``: another track is fine (behaviour cloning), another env,
        action mode, observation layout or env config is not."""
        diffs = recording_differences(self.spec, spec, any_track=any_track)
        if diffs:
            raise RecordingError(
                f"{source} was recorded in another env ({'; '.join(diffs)}); record it again "
                "in this env or use it in the env it was recorded in"
            )


def recording_differences(
    saved: Mapping[str, object], spec: Mapping[str, object], *, any_track: bool = False
) -> list[str]:
    """How the env a recording was made in differs from ``spec``, one short phrase each
    (:func:`~snnkart.envs.spec.spec_differences`, with layouts by field name and env
    configs by the keys that differ)."""
    if spec_differences(saved, spec) and revision_mismatch(saved.get("revision")):
        return [str(revision_mismatch(saved.get("revision")))]
    diffs = []
    for key in ("env", "action_mode", "action_space"):
        if saved.get(key) != spec[key]:
            diffs.append(f"{key.replace('_', ' ')} {saved.get(key)} vs {spec[key]}")
    names = [
        ", ".join(f"{f[0]}[{f[1]}]" if f[1] != 1 else str(f[0]) for f in layout_of(s))
        for s in (saved, spec)
    ]
    if saved.get("observation_layout") != spec["observation_layout"] and not diffs:
        diffs.append(f"observation layout ({names[0]}) vs ({names[1]})")
    changed = _changed_keys(_env_config(saved), _env_config(spec))
    if changed and not diffs:  # another env has another config anyway
        diffs.append(
            f"env config differs in {', '.join(changed[:4])}{' ...' if len(changed) > 4 else ''}"
        )
    if not any_track and saved.get("track_sha256") != spec["track_sha256"]:
        diffs.append(f"track {saved.get('track')} vs {spec['track']}")
    return diffs


def _env_config(spec: Mapping[str, object]) -> Mapping[str, object]:
    config = spec.get("env_config")
    return config if isinstance(config, dict) else {}


def _changed_keys(a: Mapping[str, object], b: Mapping[str, object], prefix: str = "") -> list[str]:
    """The dotted keys whose values differ between two nested dicts."""
    out = []
    for key in sorted(set(a) | set(b)):
        x, y = a.get(key), b.get(key)
        if isinstance(x, dict) and isinstance(y, dict):
            out += _changed_keys(x, y, f"{prefix}{key}.")
        elif x != y:
            out.append(f"{prefix}{key}")
    return out


class RecordingWrapper(gym.Wrapper):  # type: ignore[type-arg]
    """Records every step of the env it wraps; :meth:`recording` returns what was recorded.

    Each reset gets an explicit seed (drawn from ``seed`` when the caller gives none), so the
    recording replays. An episode cut short by a reset or by :meth:`recording` ends truncated.
    """

    def __init__(self, env: gym.Env, driver: str, seed: int | None = None) -> None:
        super().__init__(env)
        self.driver = driver
        self.spec_ = env_spec(env.unwrapped)  # type: ignore[arg-type]
        self._seeds = np.random.default_rng(seed)
        self._rows: list[tuple[Any, ...]] = []
        self._episodes: list[_OpenEpisode] = []
        self._obs: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, object] | None = None) -> Any:
        self._end("restarted")
        seed = int(self._seeds.integers(2**31)) if seed is None else int(seed)
        obs, info = self.env.reset(seed=seed, options=options)
        self._episodes.append({"seed": seed, "start": len(self._rows), "end": None})
        self._obs = np.asarray(obs, dtype=np.float32).copy()
        return obs, info

    def step(self, action: Any) -> Any:
        if self._obs is None:
            raise RecordingError("reset the env before stepping it")
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._rows.append(
            (self._obs, np.asarray(action).copy(), float(reward), bool(terminated), bool(truncated))
        )
        self._obs = np.asarray(obs, dtype=np.float32).copy()
        if terminated or truncated:
            self._end(_outcome(info, terminated))
        return obs, reward, terminated, truncated, info

    def _end(self, how: str) -> None:
        """Close the open episode (if it has steps), truncating its last step if cut."""
        if self._obs is None:
            return
        self._obs = None
        episode = self._episodes[-1]
        if len(self._rows) == episode["start"]:
            self._episodes.pop()  # reset again before any step: nothing to keep
            return
        if how in ("restarted", "stopped"):
            self._rows[-1] = (*self._rows[-1][:4], True)
        episode["end"] = how

    @property
    def recorded_steps(self) -> int:
        return len(self._rows)

    def recording(self) -> Recording:
        """Everything recorded so far (an open episode ends ``stopped``)."""
        self._end("stopped")
        if not self._rows:
            raise RecordingError("nothing was recorded: no step was taken")
        obs, actions, rewards, terminated, truncated = (
            np.array(c) for c in zip(*self._rows, strict=True)
        )
        starts = np.array([e["start"] for e in self._episodes], dtype=np.int64)
        ends = [*starts[1:].tolist(), len(rewards)]
        episodes: list[RecordedEpisode] = [
            {
                "seed": e["seed"],
                "length": end - e["start"],
                "end": e["end"],
                "return": float(rewards[e["start"] : end].sum()),
            }
            for e, end in zip(self._episodes, ends, strict=True)
        ]
        meta: RecordingMeta = {
            "schema": RECORDING_SCHEMA,
            "driver": self.driver,
            "env_spec": self.spec_,
            "env_spec_hash": spec_hash(self.spec_),
            "gamma": RECORDING_GAMMA,
            "episodes": episodes,
        }
        discrete = np.issubdtype(actions.dtype, np.integer)
        return Recording(
            meta,
            obs.astype(np.float32),
            actions.astype(np.int64 if discrete else np.float32),
            rewards.astype(np.float32),
            terminated,
            truncated,
            starts,
            np.array([e["seed"] for e in self._episodes], dtype=np.int64),
        )


def _outcome(info: Mapping[str, object], terminated: bool) -> str:
    if info.get("lap_finished"):
        return "finished"
    if info.get("crashed"):
        return "crashed"
    if info.get("stood_still"):
        return "stood_still"
    return "terminated" if terminated else "time_limit"


def replay_observations(recording: Recording, env: gym.Env) -> np.ndarray:
    """The observations ``env`` yields when each recorded episode is reset with its seed and
    driven with its recorded actions (equal to ``recording.obs`` when the recording is
    faithful); refuses an env with another spec."""
    recording.check(env_spec(env.unwrapped), "the recording")  # type: ignore[arg-type]
    out = np.zeros_like(recording.obs)
    ends = [*recording.episode_starts[1:].tolist(), len(recording.obs)]
    for start, end, seed in zip(
        recording.episode_starts.tolist(), ends, recording.seeds.tolist(), strict=True
    ):
        obs, _ = env.reset(seed=int(seed))
        for t in range(start, end):
            out[t] = obs
            obs, *_ = env.step(recording.actions[t])
    return out
