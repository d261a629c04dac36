"""One env step of a deployed policy, seen from inside: the spike raster and membrane traces of
every layer (``snnkart plot raster``, the report's raster figure)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snnkart.errors import UsageError


@dataclass(frozen=True)
class StepTrace:
    env_step: int  # 0-based, within the episode
    seed: int
    raster: np.ndarray  # [T, N] bool, the T logical steps of every layer
    membranes: np.ndarray  # [T, N], before each step's reset
    sizes: tuple[int, ...]
    thresholds: tuple[float, ...]
    action: object


def trace_step(
    nir_path: str | Path, env_step: int, seed: int = 0, track: str | None = None
) -> StepTrace:
    """Drive the episode of ``seed`` with the policy in float32 (the trained arithmetic) and
    record its ``env_step``-th inference."""
    from snnkart.backends.reference import Float32Chain, NIRReference
    from snnkart.eval.policy_env import make_policy_env

    if env_step < 0:
        raise UsageError(f"--step must be >= 0, got {env_step}")
    policy = NIRReference(nir_path, "float32", seed=seed)
    sim = policy.engine
    assert isinstance(sim, Float32Chain)
    env = make_policy_env(policy.manifest, None, track)
    try:
        obs, _ = env.reset(seed=seed)
        for k in range(env_step):
            obs, _, terminated, truncated, _ = env.step(policy.predict(obs))
            if terminated or truncated:
                raise UsageError(
                    f"the episode of seed {seed} ended after {k + 1} env steps; choose --step "
                    f"below {k + 1}"
                )
        raster, membranes = sim.trace(policy.codec.encode(obs))
        last = raster.reshape(raster.shape[0], -1)[:, -policy.chain.sizes[-1] :]
        action = policy.codec.decode(policy.codec.readout_spikes(last))
    finally:
        env.close()
    return StepTrace(
        env_step=env_step,
        seed=seed,
        raster=raster,
        membranes=membranes,
        sizes=policy.chain.sizes,
        thresholds=tuple(float(layer.threshold[0]) for layer in policy.chain.layers),
        action=action,
    )
