"""What every family's manifest says of the run it was exported from: the observation
normaliser's clip and the observation bounds, the action decoding, the env spec it was trained
in (with its hash), the versions, the trained track and where the checkpoint came from."""

from __future__ import annotations

from typing import TypedDict

import numpy as np

from snnkart.envs.spec import spec_hash
from snnkart.rl.checkpoint import versions
from snnkart.rl.trained import LoadedRun


class RunFields(TypedDict):
    """The :class:`~snnkart.contract.manifest.Manifest` fields of this name."""

    obs_clip: float
    obs_low: tuple[float, ...]
    obs_high: tuple[float, ...]
    action_mode: str
    env: dict[str, object]
    versions: dict[str, str]
    track: dict[str, str] | None
    training: dict[str, object]


def action_mode(configured: str, spec: dict[str, object]) -> str:
    """How the readout becomes an action: a kart env's configured mode, any gymnasium env's
    from its action space (``Discrete``: argmax; ``Box``: the readout clipped to [-1, 1])."""
    space = spec.get("action_space") if spec.get("kind") == "gymnasium" else None
    if not isinstance(space, dict):
        return configured
    return "discrete" if space.get("type") == "Discrete" else "continuous"


def run_fields(run: LoadedRun, low: np.ndarray, high: np.ndarray) -> RunFields:
    """The manifest's fields from ``run`` with observation bounds ``low`` and ``high``."""
    cfg, spec = run.config, run.meta["env_spec"]
    return {
        "obs_clip": cfg.ppo.clip_obs,
        "obs_low": tuple(float(x) for x in low),
        "obs_high": tuple(float(x) for x in high),
        "action_mode": action_mode(cfg.action_mode, spec),
        "env": {**spec, "env_spec_hash": spec_hash(spec)},
        "versions": versions(),
        "track": run.track_record() if run.track is not None else None,
        "training": {
            "run": str(run.run_dir),
            "checkpoint": str(run.checkpoint),
            "global_step": run.meta.get("global_step"),
        },
    }
