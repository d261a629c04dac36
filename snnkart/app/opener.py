"""Opening a trained policy for prediction: the one set of rules every door follows
(``snnkart eval``, ``deploy`` and ``ros drive``, the Python API, the process pool's worker).

A door names a *target*: a run directory (``snnkart train --out``), a checkpoint file in one,
or an exported ``policy.nir`` (its manifest beside it), and optionally a backend and a
precision. :func:`choose` checks all of it before anything heavy is imported, filling in the
precision from the one table of defaults (:mod:`snnkart.backends.defaults`: ``fixed`` on both
NIR backends); :func:`open_predictor` opens what it chose. A run on a NIR backend is exported
to a temporary NIR file first, as ``snnkart eval --backend`` does.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from snnkart.backends.defaults import BACKENDS, precision_word
from snnkart.errors import UsageError

if TYPE_CHECKING:
    from snnkart.backends.loading import Opened
    from snnkart.eval.request import DeployRequest

GIVE = "give a run directory, a checkpoint in one or a policy.nir"


class Predictor(Protocol):
    """A policy that drives: ``predict(obs)`` the action for one observation, ``reset()`` at
    an episode's start, ``close()`` when done (stops Lava's processes; also on leaving a
    ``with`` block)."""

    def predict(self, obs: np.ndarray) -> Any: ...
    def reset(self) -> None: ...
    def close(self) -> None: ...
    def __enter__(self) -> Predictor: ...
    def __exit__(self, *exc: object) -> None: ...


@dataclass(frozen=True)
class Target:
    """What a door was asked to open, checked: a run (its directory and which checkpoint) or
    an exported NIR file, on ``backend`` in ``precision`` (a word of the backend's; None on
    torch)."""

    path: Path
    backend: str
    precision: str | None
    run_dir: Path | None
    """The run's directory; None for a NIR file."""
    checkpoint: str | Path | None = None
    """Which of the run's checkpoints (:func:`snnkart.rl.run_dir.checkpoint_path`)."""
    sigma_delta: bool = False
    """A ReLU ANN run converted to a sigma-delta network before it runs (NIR backends)."""

    @property
    def nir_file(self) -> Path | None:
        """The exported policy, or None for a run (exported when opened)."""
        return self.path if self.run_dir is None else None

    def deploy_request(
        self,
        episodes: int,
        seed: int,
        env: str | None = None,
        track: str | None = None,
        out: Path | None = None,
    ) -> DeployRequest:
        """The closed-loop evaluation of this target (its ``nir_file`` is the run directory
        until :func:`snnkart.app.evaluate.run_eval_exported` exports it)."""
        from snnkart.eval.request import DeployRequest

        assert self.precision is not None, "torch is evaluated by snnkart.app.evaluate.run_eval"
        return DeployRequest(
            self.run_dir or self.path, self.backend, self.precision, episodes, seed, env, track, out
        )


def choose(
    path: str | Path,
    backend: str = "torch",
    precision: str | None = None,
    checkpoint: str | Path | None = None,
    *,
    sigma_delta: bool = False,
    backends: tuple[str, ...] = BACKENDS,
) -> Target:
    """The target ``path`` names on ``backend`` (one of ``backends``) in ``precision`` (None:
    the backend's default, :data:`snnkart.backends.defaults.DEFAULT_PRECISIONS`; torch runs
    as it trained and ignores it), or a one-line error naming the problem and the fix."""
    word = precision_word(backend, precision, backends)
    path = Path(path)
    run_dir = locate(path, exported=backend != "torch")
    if run_dir is None:
        if backend == "torch":
            raise UsageError(
                f"{path} is an exported policy; torch runs a run directory: choose --backend "
                "nir-ref or lava-sim"
            )
        if checkpoint is not None or sigma_delta:
            option = "--checkpoint picks" if checkpoint is not None else "--sigma-delta converts"
            raise UsageError(f"{path} is an exported policy; {option} a run directory's")
    elif path.is_file():  # a checkpoint file: its run, at that checkpoint
        if checkpoint is not None:
            raise UsageError(f"{path} is a checkpoint already; drop --checkpoint {checkpoint}")
        checkpoint = path
    if sigma_delta and backend == "torch":
        raise UsageError("--sigma-delta converts a run for a NIR backend: add --backend nir-ref")
    return Target(path, backend, word, run_dir, checkpoint, sigma_delta)


def locate(path: Path, exported: bool = False) -> Path | None:
    """The run directory ``path`` is (or holds the checkpoint ``path``: the directory with a
    ``config.toml`` beside it or one above, as ``checkpoints/iter_*.pt``), or None for a NIR
    file (any other file); a one-line error for a path that is neither."""
    if not path.exists():
        if path.suffix == ".nir":
            from snnkart.backends.loading import MISSING_HINT

            raise UsageError(f"no NIR file at {path}{MISSING_HINT}")
        raise UsageError(f"{path} does not exist; {GIVE}")
    if path.is_dir():
        from snnkart.app.pipeline import refuse_main_job_folder

        refuse_main_job_folder(path, exported)  # the main job's folder: names its SNN run
        if not (path / "config.toml").is_file():
            raise UsageError(f"{path} is not a run directory (no config.toml); {GIVE}")
        return path
    if path.suffix != ".pt":
        return None
    for folder in (path.parent, path.parent.parent):
        if (folder / "config.toml").is_file():
            return folder
    raise UsageError(f"{path}: a checkpoint outside a run directory (no config.toml beside it)")


class TorchPolicy:
    """A run's torch policy as a :class:`Predictor` (nothing to close); ``run`` is the loaded
    run (:class:`snnkart.rl.trained.LoadedRun`)."""

    def __init__(self, predictor: Any) -> None:
        self._predictor = predictor
        self.run = predictor.run

    def predict(self, obs: np.ndarray) -> Any:
        return self._predictor.predict(obs)

    def reset(self) -> None:
        self._predictor.reset()

    def close(self) -> None:
        """Nothing to stop: the policy runs in this process."""

    def __enter__(self) -> TorchPolicy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_predictor(target: Target, seed: int = 0) -> Predictor:
    """The target's policy, ready to drive: the torch policy of a run, or the NIR backend
    running the exported policy (a run exported first) in the target's precision."""
    if target.backend == "torch":
        from snnkart.rl.trained import TorchPredictor, load_run

        assert target.run_dir is not None
        return TorchPolicy(TorchPredictor(load_run(target.run_dir, target.checkpoint), seed=seed))
    from snnkart.backends.registry import open_backend

    assert target.precision is not None
    return open_backend(read_exported(target), target.backend, target.precision, seed)


def read_exported(target: Target) -> Opened:
    """The target's exported policy, read whole: its NIR file, or the run exported to a
    temporary one (which goes once it is read)."""
    from snnkart.backends.loading import open_policy

    if target.nir_file is not None:
        return open_policy(target.nir_file)
    from snnkart.rl.trained import load_run

    assert target.run_dir is not None
    run = load_run(target.run_dir, target.checkpoint)
    with tempfile.TemporaryDirectory(prefix="snnkart-open-") as tmp:
        if target.sigma_delta:
            from snnkart.export.sigma_delta_export import export_sigma_delta

            nir_file, _ = export_sigma_delta(run, Path(tmp) / "policy.nir")
        else:
            from snnkart.export.nir_export import export_nir

            nir_file, _ = export_nir(run, Path(tmp) / "policy.nir")
        return open_policy(nir_file)
