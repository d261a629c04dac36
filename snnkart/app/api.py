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
from typing import Any, Protocol

import numpy as np

from snnkart.app.reporter import Silent
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord
from snnkart.errors import UsageError, did_you_mean

BACKENDS = ("torch", "nir-ref", "lava-sim")
"""Where a loaded policy runs: the trained torch policy (a run directory), or its NIR export
on the numpy reference or on Lava's simulated Loihi (a run directory, exported on the fly, or
a ``.nir`` file)."""


def _precision(backend: str, precision: str | None) -> str:
    """The ``--precision`` word a spiking backend runs in: the one given, else its default
    (lava-sim: fixed, Loihi's arithmetic; nir-ref: float32, torch's)."""
    return precision or ("fixed" if backend == "lava-sim" else "float32")


class Predictor(Protocol):
    """A policy that drives: ``predict(obs)`` the action for one observation, ``reset()`` at
    an episode's start, ``close()`` when done (stops Lava's processes; also on leaving a
    ``with`` block)."""

    def predict(self, obs: np.ndarray) -> Any: ...
    def reset(self) -> None: ...
    def close(self) -> None: ...
    def __enter__(self) -> Predictor: ...
    def __exit__(self, *exc: object) -> None: ...


class _TorchPolicy:
    """A run's torch policy as a :class:`Predictor` (nothing to close)."""

    def __init__(self, predictor: Any) -> None:
        self._predictor = predictor

    def predict(self, obs: np.ndarray) -> Any:
        return self._predictor.predict(obs)

    def reset(self) -> None:
        self._predictor.reset()

    def close(self) -> None:
        """Nothing to stop: the policy runs in this process."""

    def __enter__(self) -> _TorchPolicy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def load_policy(
    path: str | Path,
    backend: str = "torch",
    precision: str | None = None,
    checkpoint: str | Path | None = None,
    seed: int = 0,
) -> Predictor:
    """A trained policy, ready to drive: ``path`` is a run directory (``snnkart train --out``)
    or an exported ``policy.nir`` (its manifest beside it).

    ``backend``: ``torch`` (a run directory only), ``nir-ref`` (numpy; ``precision`` float32,
    float64 or fixed, default float32) or ``lava-sim`` (Lava's simulated Loihi; float or fixed,
    default fixed). A run directory on a spiking backend is exported to NIR first, as
    ``snnkart eval --backend`` does. ``checkpoint`` (a run directory): ``"latest"`` (the
    default), ``"best"`` (the best periodic evaluation's, ``eval.every_steps``), an env step
    with a saved checkpoint, or a checkpoint file."""
    path = Path(path)
    if backend not in BACKENDS:
        raise UsageError(
            f"unknown backend {backend!r}{did_you_mean(backend, BACKENDS)}; choose "
            f"{', '.join(BACKENDS)}"
        )
    if not path.exists():
        raise UsageError(f"{path} does not exist; give a run directory or a policy.nir")
    if backend == "torch":
        if not path.is_dir():
            raise UsageError(f"{path}: the torch backend runs a run directory, not a NIR file")
        from snnkart.rl.trained import TorchPredictor, load_run

        return _TorchPolicy(TorchPredictor(load_run(path, checkpoint), seed=seed))
    from snnkart.backends.loading import open_policy as read_policy
    from snnkart.backends.registry import open_backend

    word = _precision(backend, precision)
    if path.is_file():
        return open_backend(read_policy(path), backend, word, seed)
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.trained import load_run

    with tempfile.TemporaryDirectory(prefix="snnkart-api-") as tmp:
        nir_file, _ = export_nir(load_run(path, checkpoint), Path(tmp) / "policy.nir")
        policy = read_policy(nir_file)  # read whole: the file may go once it is loaded
    return open_backend(policy, backend, word, seed)


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

    overrides = {"env": env, "policy": policy, "track": track, "total_steps": total_steps,
                 "seed": seed}  # fmt: skip
    cfg = load_config(config, overrides, list(sets))
    if not resume:
        load_track(cfg.track)
    trainer = Trainer(cfg, Path(out), resume=resume, total_steps=total_steps if resume else None)
    try:
        progress = trainer.train(on_iteration)
    finally:
        trainer.close()
    return {**progress.state(), "interrupted": trainer.interrupted,
            "stopped_early": trainer.stopped_early}  # fmt: skip


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
    torch, nowhere for a spiking backend). ``checkpoint``: which of a run's checkpoints, as
    :func:`load_policy` takes it."""
    from snnkart.app.evaluate import run_eval, run_eval_exported
    from snnkart.eval.request import DeployRequest

    path, target = Path(path), None if out is None else Path(out)
    if not path.exists():
        raise UsageError(f"{path} does not exist; give a run directory or a policy.nir")
    if backend == "torch":
        if not path.is_dir():
            raise UsageError(f"{path}: the torch backend runs a run directory, not a NIR file")
        return run_eval(path, episodes, seed, checkpoint, False, None, target, Silent(), track)
    word = _precision(backend, precision)
    request = DeployRequest(path, backend, word, episodes, seed, track=track, out=target)
    if target is not None:
        return run_eval_exported(path, checkpoint, request, Silent())
    with tempfile.TemporaryDirectory(prefix="snnkart-eval-") as tmp:
        return run_eval_exported(path, checkpoint, replace(request, out=Path(tmp)), Silent())


__all__ = ["BACKENDS", "Predictor", "evaluate", "load_policy", "train"]
