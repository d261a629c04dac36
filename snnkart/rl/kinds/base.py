"""What a policy kind declares (:class:`Kind`), and the spaces a policy is built for."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from pydantic import BaseModel

from snnkart.rl.actor_critic import ActorCritic

Defaults = dict[str, dict[str, object]]
"""Config defaults by section: ``{"ppo": {"learning_rate": 1e-3}}``."""


@dataclass(frozen=True)
class PolicySpace:
    """What a policy is built for: the observation's size and true bounds, the action space."""

    obs_dim: int
    action_dim: int
    discrete: bool
    obs_low: np.ndarray
    obs_high: np.ndarray

    @classmethod
    def of(cls, env: gym.Env) -> PolicySpace:
        space = env.action_space
        if isinstance(space, gym.spaces.Discrete):
            discrete, action_dim = True, int(space.n)
        elif isinstance(space, gym.spaces.Box):
            discrete, action_dim = False, int(space.low.shape[0])
        else:
            raise TypeError(f"unsupported action space {space}")
        obs = env.observation_space
        assert isinstance(obs, gym.spaces.Box)
        return cls(
            int(obs.low.shape[0]),
            action_dim,
            discrete,
            obs.low.astype(np.float64),
            obs.high.astype(np.float64),
        )


def _no_problem(cfg: Any) -> None:
    """Every config is fine."""


@dataclass(frozen=True)
class Kind:
    """Everything the rest of snnkart asks of a policy kind.

    - ``build(cfg, space)``: the policy (an :class:`~snnkart.rl.policies.ActorCritic`, which
      answers training's and evaluation's questions: buffer fields, extra loss terms, state);
    - ``section``: the kind's own config section (``[<name>]`` in a config, ``--set
      <name>.key=value``), or None: it reads only the shared ones (``ann``, ``snn``, ``ppo``);
    - ``defaults`` and ``env_defaults``: config defaults for the kind, and for it on one env
      (applied only where the user set nothing; why each is what it is: docs/decisions.md);
    - ``check(cfg)``: raise ValueError naming a setting the kind cannot train with;
    - ``sections_used``: the config sections its network reads (a run's record of its settings);
    - ``label(cfg)``: what a run of the kind with ``cfg`` is called in figures and tables
      (``"stateful LIF"``), from its settings, never from a run's or variant's name.
    """

    name: str
    build: Callable[[Any, PolicySpace], ActorCritic]
    section: type[BaseModel] | None = None
    defaults: Defaults = field(default_factory=dict)
    env_defaults: dict[str, Defaults] = field(default_factory=dict)
    check: Callable[[Any], None] = _no_problem
    sections_used: tuple[str, ...] = ()
    label: Callable[[Any], str] = lambda cfg: str(cfg.policy)
