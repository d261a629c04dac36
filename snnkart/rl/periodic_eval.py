"""Periodic evaluation and the best checkpoint (the ``eval`` section of the train config).

Every ``eval.every_steps`` env steps (off at 0, the default) the deterministic policy drives
``eval.episodes`` seeded episodes, as the ``stop`` checks do (:func:`snnkart.rl.stopping.
seeded_episodes`): a fresh env, seeds ``eval.seed``, ``eval.seed + 1``, ..., nothing drawn from
the training generators, so training computes exactly what it would without them. Each
evaluation is recorded in the iteration's line of ``metrics.jsonl`` (``eval/success_rate``,
``eval/mean_return``, ``eval/best``); one that beats every earlier one writes ``best.pt``.

Best means the highest success rate, ties broken by the higher mean return: a policy that
finishes more laps is better, whatever its return; among equals, the return ranks how far and
how cleanly it drives. The best score lives in ``best.pt``'s metadata (``eval``), so a resumed
run keeps comparing against it.
"""

from __future__ import annotations

import json
from collections.abc import Callable

from snnkart.envs.tracks import Track
from snnkart.rl.checkpoint import CheckpointMeta, CheckpointState, EvalScore
from snnkart.rl.config import TrainConfig
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import Progress
from snnkart.rl.run_dir import RunDir
from snnkart.rl.stopping import seeded_episodes

Checkpoint = Callable[[], tuple[CheckpointState, CheckpointMeta]]
"""Builds the state dict and metadata of the policy as it is now (without drawing from any
of training's generators)."""


def eval_due(cfg: TrainConfig, progress: Progress) -> bool:
    """An evaluation is due when the run crossed a multiple of ``eval.every_steps`` not yet
    handled."""
    every = cfg.eval.every_steps
    return every > 0 and progress.global_step // every > progress.eval_mark


def score_key(score: EvalScore) -> tuple[float, float]:
    """What ranks evaluations: the success rate, then the mean return."""
    return (float(score["success_rate"]), float(score["mean_return"]))


class PeriodicEval:
    """Runs the evaluations that are due and keeps the best policy in ``best.pt``."""

    def __init__(self, cfg: TrainConfig, out: RunDir) -> None:
        self.cfg = cfg
        self.out = out
        self.best: EvalScore | None = None
        """The best evaluation so far (of this run's ``best.pt``, also before a resume)."""
        meta = out.best.with_suffix(".json")
        if out.best.is_file() and meta.is_file():
            self.best = json.loads(meta.read_text()).get("eval")

    def __call__(
        self,
        progress: Progress,
        policy: ActorCritic,
        obs_rms: RunningMeanStd,
        track: Track,
        interrupted: Callable[[], bool],
        checkpoint: Checkpoint,
    ) -> dict[str, float]:
        """Evaluate if due; write ``best.pt`` if it beats the best; return what the metrics
        record (nothing if no evaluation was due or an interrupt cut it short: it is then
        still due)."""
        if not eval_due(self.cfg, progress):
            return {}
        ev = self.cfg.eval
        scores = seeded_episodes(
            self.cfg, policy, obs_rms, track, ev.episodes, ev.seed, interrupted
        )
        if scores is None:
            return {}
        progress.eval_mark = progress.global_step // ev.every_steps
        score: EvalScore = {
            "success_rate": scores[0],
            "mean_return": scores[1],
            "global_step": progress.global_step,
            "iteration": progress.iteration,
            "episodes": ev.episodes,
            "seed": ev.seed,
        }
        best = self.best is None or score_key(score) > score_key(self.best)
        if best:
            state, meta = checkpoint()
            self.out.save_best(state, {**meta, "eval": score})
            self.best = score
        return {"eval/success_rate": scores[0], "eval/mean_return": scores[1], "eval/best": best}
