"""A tiny env of a user's own, registered as ``MyDictEnv-v0`` when this module is imported.

Import it as ``my_envs`` (``tests/`` is on the path in the suite, as for ``tiny_runs``): the
name ``tests`` is taken by a ``tests`` package that lava-nc installs into site-packages, so
``tests.my_envs`` does not import. The env ids are ``my_envs:MyDictEnv-v0`` (gymnasium's
``module:EnvId``) and ``my_envs:MyDictEnv`` (an entry point).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

ENV_ID = "MyDictEnv-v0"
MAX_STEPS = 20


class MyDictEnv(gym.Env[dict[str, np.ndarray], np.ndarray]):
    """Move a point towards a target in the unit square.

    ## Description
    A point starts at a random place and a target at another; each step moves the point by a
    tenth of the action.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: the move in x and y, in tenths of the square's half-width.

    ## Observation Space
    ``Dict`` of two Boxes:

    | key      | space                     | meaning                 |
    |----------|---------------------------|-------------------------|
    | position | Box(-1, 1, (2,), float32) | the point               |
    | target   | Box(-1, 1, (2,), float32) | the target (stays put)  |

    ## Rewards
    Minus the distance from the point (after the move) to the target: it depends on the action.

    ## Starting State
    Point and target uniform in the square, from ``self.np_random``.

    ## Episode End
    Terminated within 0.05 of the target; truncated after ``max_steps`` steps (20), also when
    made directly without a TimeLimit.

    ## Arguments
    ``max_steps`` (int, 20), ``step_size`` (float, 0.1).

    ## Version History
    v0: the first.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "render_fps": 10}

    def __init__(
        self, max_steps: int = MAX_STEPS, step_size: float = 0.1, render_mode: str | None = None
    ) -> None:
        box = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = spaces.Dict({"position": box, "target": box})
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.max_steps, self.step_size, self.render_mode = max_steps, step_size, render_mode
        self._position = np.zeros(2, np.float32)
        self._target = np.zeros(2, np.float32)
        self._steps = 0

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        move = self.step_size * np.clip(np.asarray(action, np.float32), -1.0, 1.0)
        self._position = np.clip(self._position + move, -1.0, 1.0).astype(np.float32)
        self._steps += 1
        distance = float(np.linalg.norm(self._position - self._target))
        terminated = distance < 0.05
        truncated = not terminated and self._steps >= self.max_steps
        return self._obs(), -distance, terminated, truncated, {"distance": distance}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        self._position = self.np_random.uniform(-1.0, 1.0, 2).astype(np.float32)
        self._target = self.np_random.uniform(-1.0, 1.0, 2).astype(np.float32)
        self._steps = 0
        return self._obs(), {}

    def _obs(self) -> dict[str, np.ndarray]:
        return {"position": self._position.copy(), "target": self._target.copy()}


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point=f"{__name__}:MyDictEnv", max_episode_steps=MAX_STEPS)
if "CartPole20-v0" not in gym.registry:  # CartPole with a pass mark a tiny run can reach
    gym.register(
        id="CartPole20-v0",
        entry_point="gymnasium.envs.classic_control.cartpole:CartPoleEnv",
        max_episode_steps=500,
        reward_threshold=20.0,
    )


class TwoStepEnv(gym.Env[np.ndarray, int]):
    """Every episode is two steps of reward 1; the second ends it by termination
    (``end="terminate"``) or by truncation (``end="truncate"``, a time limit of its own). The
    observation is ``[step / 2, 0.5]``, so the final one is always ``[1, 0.5]``."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, end: str = "truncate") -> None:
        self.end = end
        self.observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = spaces.Discrete(2)
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.steps = 0
        return self._obs(), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.steps += 1
        last = self.steps == 2
        return (
            self._obs(),
            1.0,
            last and self.end == "terminate",
            last and self.end != "terminate",
            {},
        )

    def _obs(self) -> np.ndarray:
        return np.array([self.steps / 2, 0.5], dtype=np.float32)


class PickEnv(gym.Env[np.ndarray, np.ndarray]):
    """Pick the shown pair: the observation one-hot codes a target pair ``(i, j)``, ``i`` in
    ``1..2`` and ``j`` in ``0..2``; the action is ``MultiDiscrete([2, 3], start=[1, 0])`` and
    earns 1 for each component equal to the target's. Ten steps an episode (a new target each
    step). Every action reaching :meth:`step` is checked to lie in the space (the test of
    snnkart's joint-action wrapper)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "render_fps": 10}

    def __init__(self, nvec: tuple[int, ...] = (2, 3)) -> None:
        self.observation_space = spaces.Box(0.0, 1.0, (5,), np.float32)
        self.action_space = spaces.MultiDiscrete(list(nvec), start=[1] + [0] * (len(nvec) - 1))
        self.steps = 0
        self.target = np.array([1, 0])

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.steps = 0
        return self._draw(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        assert self.action_space.contains(action), action
        reward = float(np.sum(np.asarray(action) == self.target))
        self.steps += 1
        return self._draw(), reward, False, self.steps >= 10, {}

    def _draw(self) -> np.ndarray:
        self.target = np.array([1 + self.np_random.integers(2), self.np_random.integers(3)])
        obs = np.zeros(5, np.float32)
        obs[self.target[0] - 1] = 1.0
        obs[2 + self.target[1]] = 1.0
        return obs
