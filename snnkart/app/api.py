"""The Python API: what ``import snnkart`` offers a script, each a thin, typed face on the
workflows the commands run (``snnkart train``, ``snnkart eval``, ``snnkart deploy``).

    import snnkart

    snnkart.train("runs/grid-snn", env="grid", policy="snn", total_steps=2048)
    policy = snnkart.load_policy("runs/grid-snn")            # torch, the trained policy
    env = snnkart.make("grid", track="small_S")
    obs, _ = env.reset(seed=0)
    action = policy.predict(obs)
    record = snnkart.evaluate("runs/grid-snn", episodes=5)   # record.summary.success_rate

The package exposes these lazily (:func:`snnkart.__getattr__`), so ``import snnkart`` imports
no torch; a function that needs torch imports it when called. Nothing here prints.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from snnkart.app.opener import Predictor, choose, open_predictor
from snnkart.app.reporter import Silent
from snnkart.backends.defaults import BACKENDS
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord


def load_policy(
    path: str | Path,
    backend: str = "torch",
    precision: str | None = None,
    checkpoint: str | Path | None = None,
    seed: int = 0,
) -> Predictor:
    """A trained policy, ready to drive: ``path`` is a run directory (``snnkart train --out``),
    a checkpoint file in one, or an exported ``policy.nir`` (its manifest beside it).

    ``backend``: ``torch`` (a run), ``nir-ref`` (numpy; ``precision`` float32, float64 or
    fixed) or ``lava-sim`` (Lava's simulated Loihi; float or fixed). ``precision`` None is the
    backend's default from the one table (:mod:`snnkart.backends.defaults`): ``fixed`` on both,
    Lava's bit-accurate arithmetic, as ``snnkart eval`` and ``deploy`` take it (nir-ref's
    default here was float32 until the doors were made to agree: pass ``precision="float32"``
    for torch's arithmetic); torch runs as it trained and ignores it. A run on a NIR backend
    is exported to NIR first, as ``snnkart eval --backend`` does. ``checkpoint`` (a run
    directory): ``"latest"`` (the default), ``"best"`` (the best periodic evaluation's,
    ``eval.every_steps``), an env step with a saved checkpoint, or a checkpoint file."""
    return open_predictor(choose(path, backend, precision, checkpoint), seed)


def train(
    out: str | Path,
    config: str | Path | None = None,
    *,
    env: str | None = None,
    policy: str | None = None,
    track: str | None = None,
    total_steps: int | None = None,
    seed: int | None = None,
    sets: Sequence[str] = (),
    resume: bool = False,
    on_iteration: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Train a policy into ``out``, as ``snnkart train`` does: defaults <- ``config`` (a TOML
    file) <- the keyword arguments <- ``sets`` (``"ppo.learning_rate=1e-3"``, ...).

    ``resume``: continue the run in ``out`` at its own length (``total_steps`` extends it).
    ``on_iteration`` gets every iteration's metrics record (the lines of ``metrics.jsonl``).
    Returns the run's progress counters (global_step, finishes, episodes, first_finish_step,
    ...), whether it was interrupted (Ctrl-C saves a checkpoint) and whether it stopped early."""
    from snnkart.envs.tracks import load_track
    from snnkart.rl.config import load_config
    from snnkart.rl.ppo import Trainer

    overrides = {
        "env": env,
        "policy": policy,
        "track": track,
        "total_steps": total_steps,
        "seed": seed,
    }
    cfg = load_config(config, overrides, list(sets))
    if not resume:
        load_track(cfg.track)
    trainer = Trainer(cfg, Path(out), resume=resume, total_steps=total_steps if resume else None)
    try:
        progress = trainer.train(on_iteration)
    finally:
        trainer.close()
    return {
        **progress.state(),
        "interrupted": trainer.interrupted,
        "stopped_early": trainer.stopped_early,
    }


def evaluate(
    path: str | Path,
    episodes: int = 10,
    seed: int = 10_000,
    backend: str = "torch",
    precision: str | None = None,
    track: str | None = None,
    out: str | Path | None = None,
    checkpoint: str | Path | None = None,
) -> EvalRecord | DeployRecord:
    """Score a policy on seeded episodes, as ``snnkart eval`` does: an :class:`EvalRecord` for
    the torch policy of a run directory, a :class:`DeployRecord` on a spiking backend (a run
    directory exported on the fly, or a ``.nir`` file; every env step checked against the
    numpy reference). Both carry ``.summary`` (success rate, returns, lap time, crashes).
    ``out``: where the record is written (default: ``eval.json`` in the run directory for
    torch, nowhere for a spiking backend). ``precision`` and ``checkpoint``: as
    :func:`load_policy` takes them (the precision's default is ``fixed`` on both NIR backends;
    nir-ref's was float32 here until the doors were made to agree)."""
    from snnkart.app.evaluate import run_eval, run_eval_exported

    chosen, target = (
        choose(path, backend, precision, checkpoint),
        None if out is None else Path(out),
    )
    where, which = chosen.run_dir or chosen.path, chosen.checkpoint
    if chosen.backend == "torch":
        return run_eval(where, episodes, seed, which, False, None, target, Silent(), track)
    request = chosen.deploy_request(episodes, seed, track=track, out=target)
    if target is not None:
        return run_eval_exported(where, which, request, Silent())
    with tempfile.TemporaryDirectory(prefix="snnkart-eval-") as tmp:
        return run_eval_exported(where, which, replace(request, out=Path(tmp)), Silent())


__all__ = ["BACKENDS", "Predictor", "evaluate", "load_policy", "train"]
