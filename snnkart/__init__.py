"""snnkart: spiking-neural-network racing policies, from PPO training to Lava's simulated Loihi.

Importing the package registers the gymnasium environments ``snnkart/Grid-v0``,
``snnkart/Gazebo-v0`` and ``snnkart/Steer-v0``; it does not import torch, pymunk, pygame or Lava.
The Python API (:mod:`snnkart.app.api`): :func:`train`, :func:`load_policy`, :func:`evaluate`
and :func:`make`, the first three imported when first used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from snnkart.envs import ENV_IDS, make, register_envs

if TYPE_CHECKING:  # the typed signatures; at run time __getattr__ imports them when used
    from snnkart.app.api import evaluate, load_policy, train

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "evaluate", "load_policy", "make", "train"]

_API = ("evaluate", "load_policy", "train")
"""The Python API (:mod:`snnkart.app.api`), imported on first use: ``import snnkart`` stays
free of torch."""


def __getattr__(name: str) -> Any:
    if name in _API:
        from snnkart.app import api

        return getattr(api, name)
    raise AttributeError(f"module 'snnkart' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})


register_envs()
