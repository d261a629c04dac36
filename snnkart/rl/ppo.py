"""PPO for ANN and SNN policies: one loop, the policy is a parameter.

Laid out like CleanRL's ``ppo.py`` and split like Stable-Baselines3: an iteration anneals the
learning rate (and entropy coefficient), collects a rollout (:mod:`snnkart.rl.rollout`) into
``[steps, envs, ...]`` tensors (:mod:`snnkart.rl.buffer`), computes GAE under ``no_grad`` and
runs :meth:`Trainer.update`; :mod:`snnkart.rl.run_dir` keeps what the run writes.

The update: per-minibatch advantage normalisation, clipped surrogate, entropy bonus, value loss
(optionally clipped), gradient-norm clipping, optional target-KL early stop; orthogonal init
and running observation normalisation (stored with the checkpoint).
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import torch
from torch import nn

from snnkart import faults
from snnkart.envs.resolve import resolve_env
from snnkart.envs.spec import env_spec, spec_hash
from snnkart.envs.task_env import gym_spec
from snnkart.envs.tracks import Track, embed_track, load_track
from snnkart.errors import RunError
from snnkart.rl.bc import warm_start
from snnkart.rl.buffer import Batch, RolloutBuffer, Sequences, compute_gae, minibatches
from snnkart.rl.checkpoint import CheckpointMeta, CheckpointState, Generators
from snnkart.rl.config import TrainConfig
from snnkart.rl.kinds import policy_for
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.open_run import OpenedRun, open_run
from snnkart.rl.optim import adam
from snnkart.rl.periodic_eval import PeriodicEval
from snnkart.rl.ppo_loss import clipped_surrogate, value_loss
from snnkart.rl.rollout import (
    KART_CHARTS,
    IterationStats,
    Progress,
    Rollout,
    TrainResult,
    normalize_obs,
)
from snnkart.rl.run_dir import RunDir, config_to_train, resolved_env_config
from snnkart.rl.stopping import check, stopped

__all__ = ["Progress", "RunError", "Trainer", "compute_gae", "normalize_obs", "policy_for"]


class Trainer:
    """Trains one policy into one run directory (config, checkpoints, metrics, trajectories)."""

    def __init__(
        self,
        cfg: TrainConfig,
        run_dir: Path,
        resume: bool = False,
        total_steps: int | None = None,
    ) -> None:
        """``resume``: continue the run in ``run_dir`` with its own config and length (``cfg``
        is not used); ``total_steps`` gives it another length (its schedules stretch to it)."""
        self.run_dir = Path(run_dir)
        self.cfg = cfg = config_to_train(cfg, self.run_dir, resume, total_steps)
        self.resumed_length: int | None = None
        """On resume, the length the run was training for before this session."""
        self.out = RunDir(self.run_dir, cfg.run.tensorboard)
        # A resumed run trains on the track its checkpoint carries (the file may have moved),
        # in the env it was trained in, whatever the defaults are today; with cfg's length.
        opened = open_run(self.run_dir) if resume and self.out.latest.is_file() else None
        self.track: Track | None
        if opened is not None:
            self.track = opened.track
            self.resumed_length = opened.schedule.total_steps
            self.cfg = cfg = opened.config.model_copy(update={"total_steps": cfg.total_steps})
        else:
            self.track = load_track(cfg.track) if cfg.kart else None
        torch.set_num_threads(cfg.run.torch_threads)
        p = cfg.ppo
        self.rollout = Rollout(cfg, self.track)
        self.envs, self.karts = self.rollout.envs, self.rollout.karts
        env0 = self.envs.envs[0]
        self.cfg, self.spec = _resolved(cfg, self.rollout)
        cfg = self.cfg
        self.evals = PeriodicEval(cfg, self.out)
        self.obs_dim = int(np.prod(env0.observation_space.shape or (0,)))  # the spec's obs_dim
        torch.manual_seed(cfg.seed)
        self.policy = policy_for(cfg, env0) if opened is None else opened.policy
        self.optimizer = adam(self.policy.parameters(), p.learning_rate, eps=1e-5, foreach=True)
        self.ent_coef = p.ent_coef  # annealed with the learning rate when ppo.anneal_ent
        self.penalty_weights = self.policy.penalty_weights(0.0)  # the kind's extra loss terms
        self.obs_rms = RunningMeanStd.zeros(self.obs_dim)
        # behaviour cloning (cfg.bc) of a new run; a resumed run's checkpoint holds the clone
        self.bc = warm_start(
            self.policy, self.obs_rms, cfg, self.spec, self.run_dir, opened is None
        )
        self.out.write_config(cfg)  # after cloning: a recording refused leaves no run behind
        self.progress = Progress()
        self.rng = np.random.default_rng(cfg.seed)
        if opened is not None:
            self._restore(opened)
        if resume:
            self.out.trim_metrics(self.progress.iteration)
        self.num_iterations = math.ceil(cfg.total_steps / cfg.batch_size)
        self.metrics_path = self.out.metrics_path

    def _restore(self, run: OpenedRun) -> None:
        """Take over an opened run's training state: weights (already in ``run.policy``),
        optimizer, normaliser, counters and random number generators."""
        state = run.state
        self.optimizer.load_state_dict(state["optimizer"])
        self.obs_rms = run.obs_rms
        self.rollout.restore_reward_scaling(state)
        self.progress = run.progress
        torch.set_rng_state(state["torch_rng"])
        if "numpy_state" in state:  # a latest-only checkpoint (:meth:`save` with history off)
            self.rng = np.random.default_rng()
            self.rng.bit_generator.state = state["numpy_state"]
        else:
            self.rng = np.random.default_rng(int(state["numpy_seed"]))

    def save(self, history: bool = True) -> Path:
        """Write ``checkpoint.pt`` (latest) and, with ``history``, a copy in ``checkpoints/``.

        A history checkpoint re-seeds the minibatch shuffling from a drawn seed (as every
        checkpoint did before latest-only ones existed); a latest-only one stores the
        generator's state instead, so writing it every iteration does not change what the
        run computes."""
        return self.out.save(*self._checkpoint(history), self.progress.iteration, history)

    def _checkpoint(self, history: bool = False) -> tuple[CheckpointState, CheckpointMeta]:
        """The checkpoint's state dict and metadata (see :meth:`save`); without ``history``
        nothing is drawn from the run's generators."""
        rng: Generators = (
            {"numpy_seed": int(self.rng.integers(2**62))}
            if history
            else {"numpy_state": self.rng.bit_generator.state}
        )
        state: CheckpointState = {
            "policy": self.policy.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "obs_rms": self.obs_rms.state(),
            "progress": self.progress.state(),
            "torch_rng": torch.get_rng_state(),
            **rng,
            **self.rollout.reward_scaling_state(),
        }
        meta: CheckpointMeta = {
            "policy": self.cfg.policy,
            "env_spec": self.spec,
            "env_spec_hash": spec_hash(self.spec),
            "config": self.cfg.model_dump(mode="json", by_alias=True),
            "track": None if self.track is None else embed_track(self.track, self.cfg.track),
            **self.progress.state(),
            "stopped_early": self.stopped_early,
        }
        return state, meta

    def train(
        self,
        on_iteration: Callable[[dict[str, float | None]], None] | None = None,
        save_every_iteration: bool = False,
    ) -> Progress:
        """Run until ``total_steps`` (or until the ``stop`` rule ends the run); Ctrl-C or
        SIGTERM saves a checkpoint before returning (``self.interrupted_by`` is then the
        signal). The interrupt is taken between env steps; a rollout cut short is dropped, so
        the checkpoint holds the last whole iteration. ``save_every_iteration`` also writes the
        latest checkpoint after every iteration, before ``on_iteration`` (for a worker stopped
        from outside without a signal, as Ray Tune stops its trials)."""
        buf = self._allocate()
        self.out.open_tensorboard()
        self.rollout.reset(seed=self.cfg.seed + 7919 * self.progress.iteration)
        self.policy.train()
        with self._interrupts():
            while self.progress.iteration < self.num_iterations and not self._done():
                record = self._iteration(buf, save_every_iteration)
                if record is None:
                    break
                if on_iteration is not None:
                    on_iteration(record)
            if _interrupted():
                self.save()
        return self.progress

    @property
    def stopped_early(self) -> bool:
        """The ``stop`` rule ended the run before ``total_steps``."""
        return stopped(self.cfg.stop, self.progress)

    def _done(self) -> bool:
        return self.stopped_early or _interrupted()

    @contextlib.contextmanager
    def _interrupts(self) -> Iterator[None]:
        """Ctrl-C/SIGTERM set a flag taken between env steps (:mod:`snnkart.faults`)."""
        stack = contextlib.ExitStack()
        stack.enter_context(faults.caught())
        try:
            yield
        finally:
            self.out.flush()
            self.interrupted_by = faults.consume()
            stack.close()
        self.interrupted = self.interrupted_by is not None

    def _allocate(self) -> RolloutBuffer:
        p, needs = self.cfg.ppo, self.policy.buffer_needs()
        discrete = self.policy.discrete
        return RolloutBuffer.allocate(
            p.rollout_steps,
            p.num_envs,
            self.obs_dim,
            () if discrete else (self.policy.action_dim,),
            discrete,
            self.cfg.snn.num_steps,
            rate=needs.input_spikes,
            previous=needs.previous,
        )

    def _anneal(self) -> None:
        p = self.cfg.ppo
        frac = 1.0 - (self.progress.iteration - 1) / self.num_iterations
        if p.anneal_lr:
            self.optimizer.param_groups[0]["lr"] = frac * p.learning_rate
        self.ent_coef = frac * p.ent_coef if p.anneal_ent else p.ent_coef
        self.penalty_weights = self.policy.penalty_weights(1.0 - frac)

    def _iteration(
        self, buf: RolloutBuffer, save_latest: bool = False
    ) -> dict[str, float | None] | None:
        """One iteration: rollout, GAE, update, record, checkpoint; None if an interrupt cut
        the rollout short (its progress and normaliser updates are then undone)."""
        p = self.cfg.ppo
        it_start = time.perf_counter()
        before = copy.deepcopy((self.progress, self.obs_rms, self.rollout.reward_scaling))
        self.progress.iteration += 1
        self._anneal()
        stats = IterationStats()
        complete = self.rollout.collect(
            self.policy, self.obs_rms, buf, self.progress, stats, _interrupted
        )
        if not complete:
            self.progress, self.obs_rms, self.rollout.reward_scaling = before
            return None
        rollout_time = time.perf_counter() - it_start
        with torch.no_grad():
            last_value = self.rollout.last_value(self.policy, self.obs_rms)
            advantages, returns = compute_gae(
                buf.rewards, buf.values, buf.ends, last_value, p.gamma, p.gae_lambda
            )
        update_start = time.perf_counter()
        flat, seq = buf.flat(advantages, returns), self.rollout.sequences(buf)
        losses = self.update(flat) if seq is None else self.update(flat, seq)
        update_time = time.perf_counter() - update_start
        record = self._record(stats, losses, rollout_time, update_time)
        if self.track is not None:  # the stop rule and periodic evaluation drive a track
            track = self.track
            record.update(
                check(self.cfg, self.progress, self.policy, self.obs_rms, track, _interrupted)
            )
            record.update(
                self.evals(
                    self.progress, self.policy, self.obs_rms, track, _interrupted, self._checkpoint
                )
            )
        self.out.log(record, self.progress.global_step)
        if self.cfg.run.trajectories and self.karts:
            self.out.write_trajectories(
                self.progress.iteration, self.progress.global_step, self.rollout.trajectory()
            )
        if (
            self.progress.iteration % self.cfg.run.checkpoint_every == 0
            or self.progress.iteration == self.num_iterations
            or self.stopped_early
        ):
            self.save()
        elif save_latest:
            self.save(history=False)
        return record

    def update(self, b: Batch, seq: Sequences | None = None) -> dict[str, float]:
        """PPO epochs over shuffled minibatches (``seq``: of whole env sequences, a stateful
        actor's); returns the last epoch's mean losses."""
        p = self.cfg.ppo
        clipfracs: list[float] = []
        first_ratio_dev = float("nan")
        for _epoch in range(p.update_epochs):
            for mb, extra in minibatches(b, p.num_minibatches, self.rng, seq):
                losses, ratio, logratio = self._minibatch_loss(mb, extra)
                with torch.no_grad():
                    approx_kl = ((ratio - 1) - logratio).mean().item()
                    clipfracs.append(((ratio - 1.0).abs() > p.clip_coef).float().mean().item())
                    if math.isnan(first_ratio_dev):
                        first_ratio_dev = (ratio - 1.0).abs().max().item()
                self.optimizer.zero_grad()
                losses["loss"].backward()
                nn.utils.clip_grad_norm_(self.policy.parameters(), p.max_grad_norm, foreach=True)
                self.optimizer.step()
                self.policy.clamp_parameters()
            if p.target_kl is not None and approx_kl > p.target_kl:
                break
        y_pred, y_true = b.values.numpy(), b.returns.numpy()
        var_y = np.var(y_true)
        explained_var = float("nan") if var_y == 0 else float(1 - np.var(y_true - y_pred) / var_y)
        return {
            "losses/policy_loss": losses["policy"].item(),
            "losses/value_loss": losses["value"].item(),
            "losses/entropy": losses["entropy"].item(),
            "losses/approx_kl": approx_kl,
            "losses/clipfrac": float(np.mean(clipfracs)),
            "losses/explained_variance": explained_var,
            "losses/first_minibatch_max_ratio_deviation": first_ratio_dev,
            **({"losses/message_proxy": losses["messages"].item()} if "messages" in losses else {}),
        }

    def _minibatch_loss(
        self, mb: Batch, extra: dict[str, torch.Tensor] | None = None
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor]:
        """The PPO loss of one minibatch, its parts, and the probability ratios."""
        p = self.cfg.ppo
        out = self.policy(
            mb.obs, mb.raw, action=mb.actions, input_spikes=mb.spikes, **(extra or {})
        )
        pg_loss, ratio, logratio = clipped_surrogate(
            out.log_prob, mb.logprobs, mb.advantages, p.clip_coef, p.norm_adv
        )
        v_loss = value_loss(out.value, mb.values, mb.returns, p.clip_coef, p.clip_vloss)
        entropy = out.entropy.mean()
        loss = pg_loss - self.ent_coef * entropy + p.vf_coef * v_loss
        parts = {"policy": pg_loss, "value": v_loss, "entropy": entropy}
        for name, term in self.policy.penalties(out, mb.obs, mb.previous).items():
            parts[name] = term  # the kind's extra loss terms, weighted as it says
            weight = self.penalty_weights.get(name, 0.0)
            if weight > 0.0:
                loss = loss + weight * term
        parts["loss"] = loss
        return parts, ratio, logratio

    def _record(
        self,
        stats: IterationStats,
        losses: dict[str, float],
        rollout_time: float,
        update_time: float,
    ) -> dict[str, float | None]:
        """The iteration's line of ``metrics.jsonl``: counters, then TensorBoard's scalars by
        name (None: nothing to average this iteration)."""
        steps = self.cfg.batch_size
        record: dict[str, float | None] = {
            "iteration": self.progress.iteration,
            "global_step": self.progress.global_step,
            "charts/episodic_return": float(np.mean(stats.returns)) if stats.returns else None,
            "charts/episodic_length": float(np.mean(stats.lengths)) if stats.lengths else None,
            "charts/episodes": len(stats.returns),
            "charts/finishes": stats.finishes,
            "charts/crashes": stats.crashes,
            "charts/lap_time": float(np.mean(stats.lap_times)) if stats.lap_times else None,
            "charts/cumulative_finishes": self.progress.finishes,
            "charts/first_finish_step": self.progress.first_finish_step,
            "charts/learning_rate": self.optimizer.param_groups[0]["lr"],
            "charts/ent_coef": self.ent_coef,
            "charts/SPS": steps / (rollout_time + update_time),
            "charts/rollout_SPS": steps / rollout_time,
            "charts/update_seconds": update_time,
            **losses,
        }
        if self.track is None:  # laps, crashes and lap times are a kart env's
            for key in KART_CHARTS:
                record[key] = None
        record.update(self.policy.metrics(stats.kind, self.penalty_weights))
        return record

    def close(self) -> None:
        self.rollout.close()
        self.out.close()


def _resolved(cfg: TrainConfig, rollout: Rollout) -> tuple[TrainConfig, dict[str, object]]:
    """``cfg`` with a kart env's config in full (config.toml: the whole env), and the spec."""
    if rollout.karts:
        return resolved_env_config(cfg, rollout.karts[0]), env_spec(rollout.karts[0])
    with contextlib.closing(cfg.make_env()) as env:  # as eval and deploy make it
        return cfg, gym_spec(resolve_env(cfg.env), env, cfg.env_kwargs)


def _interrupted() -> bool:
    return faults.pending() is not None


def train(
    cfg: TrainConfig,
    run_dir: Path,
    on_iteration: Callable[[dict[str, float | None]], None] | None = None,
    threads: int | None = None,
    save_every_iteration: bool = False,
) -> TrainResult:
    """One run as a plain function (the launchers' unit of work): train ``cfg`` into
    ``run_dir``, resuming the run already there, calling ``on_iteration`` with every
    iteration's metrics record; return its progress counters and whether it was interrupted.
    ``save_every_iteration``: see :meth:`Trainer.train`."""
    if threads is not None:
        torch.set_num_threads(threads)
    resume = (Path(run_dir) / "config.toml").is_file()
    # a launcher's list says how long each run is: resuming with a longer one extends it
    trainer = Trainer(cfg, run_dir, resume=resume, total_steps=cfg.total_steps if resume else None)
    try:
        progress = trainer.train(on_iteration, save_every_iteration)
    finally:
        trainer.close()
    return {
        **progress.state(),
        "interrupted": trainer.interrupted,
        "stopped_early": trainer.stopped_early,
    }
