"""Loading a trained run: its config, policy and frozen observation normalisation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from snnkart.contract.encoding import rate_generator
from snnkart.envs.tracks import Track, embed_track
from snnkart.rl.checkpoint import CheckpointError
from snnkart.rl.config import TrainConfig
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.open_run import open_run
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import normalize_obs


@dataclass
class LoadedRun:
    """A trained run opened for evaluation and export: its policy in evaluation mode."""

    run_dir: Path
    config: TrainConfig
    policy: ActorCritic
    obs_rms: RunningMeanStd
    meta: dict[str, Any]
    checkpoint: Path
    track: Track | None = None
    """The track the policy was trained on (embedded in the checkpoint, or ``config.track``)."""

    def actor_widths(self) -> tuple[int, ...]:
        """The ANN actor's layer widths (obs, hidden..., actions), from its Linear layers."""
        actor = getattr(self.policy, "actor", None)
        modules = actor.modules() if isinstance(actor, torch.nn.Sequential) else []
        linears = [m for m in modules if isinstance(m, torch.nn.Linear)]
        if not linears:
            raise CheckpointError(f"{self.run_dir} is a {self.policy.kind} run, not an ANN run")
        return (linears[0].in_features, *(m.out_features for m in linears))

    def track_record(self) -> dict[str, str]:
        """The trained track as manifests and records carry it (see ``embed_track``)."""
        assert self.track is not None
        return embed_track(self.track, self.config.track)


def load_run(run_dir: str | Path, checkpoint: str | Path | None = None) -> LoadedRun:
    """Load ``run_dir/config.toml`` and a checkpoint (default: the latest), check that it fits
    the env the config describes (:func:`~snnkart.rl.open_run.open_run`), and return the
    policy in evaluation mode."""
    run = open_run(run_dir, checkpoint)
    run.policy.eval()
    return LoadedRun(
        run.run_dir, run.config, run.policy, run.obs_rms, run.meta, run.checkpoint, run.track
    )


class TorchPredictor:
    """Deterministic action of a trained policy (argmax or mean), normalisation frozen."""

    def __init__(self, run: LoadedRun, seed: int = 0) -> None:
        self.run = run
        self.policy = run.policy
        self.seed = seed
        self.generator = torch.Generator().manual_seed(seed)
        self.rng = rate_generator(seed)
        self.discrete = run.policy.discrete
        self.state: torch.Tensor | None = None  # a stateful actor's, from the episode's start

    def reset(self) -> None:
        """An episode starts: a stateful actor's state is zeroed (the deployment does too)."""
        self.state = None

    def predict(self, obs: np.ndarray) -> Any:
        raw = np.asarray(obs, dtype=np.float32)[None]
        norm = normalize_obs(self.run.obs_rms, self.run.config.ppo, raw)
        spikes = self.policy.input_spikes(raw[0], self.rng)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self._next_seed())
            action, self.state = self.policy.act(
                torch.from_numpy(norm), torch.from_numpy(raw), self.state, spikes
            )
        a = action[0].numpy()
        return int(a) if self.discrete else np.clip(a, -1.0, 1.0).astype(np.float32)

    def activity(self) -> list[tuple[str, float]]:
        """The SNN's firing rate per layer in the last ``predict`` (empty for an ANN)."""
        rates = getattr(self.policy, "last_rates", None)
        sizes = self.policy.layer_sizes()
        if rates is None or not sizes:
            return []
        return [
            (f"layer {i + 1} ({n})", float(r))
            for i, (n, r) in enumerate(zip(sizes, rates, strict=True))
        ]

    def _next_seed(self) -> int:
        return int(torch.randint(0, 2**31 - 1, (1,), generator=self.generator))
