"""snnkart: spiking-neural-network racing policies, from PPO training to Lava's simulated Loihi.

Importing the package registers the gymnasium environments ``snnkart/Grid-v0``,
``snnkart/Gazebo-v0`` and ``snnkart/Steer-v0``; it does not import torch, pymunk, pygame or Lava.
"""

from __future__ import annotations

from snnkart.envs import ENV_IDS, make, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "make"]

register_envs()
