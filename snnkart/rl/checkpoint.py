"""Checkpoints: torch state dicts (loaded with ``weights_only=True``) + JSON metadata.

The metadata carries the versions, the training config and the *env spec* with its hash (env,
track geometry, action mode, observation layout, env config), so a checkpoint is never used
silently with another env. Files are written atomically.
"""

from __future__ import annotations

import io
import json
import platform
from collections.abc import Mapping
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any, TypedDict

import torch

from snnkart.envs.base import KartEnv
from snnkart.envs.spec import env_spec, revision_mismatch, spec_differences, spec_hash
from snnkart.errors import CheckpointError, CheckpointWriteError
from snnkart.faults import fault_point
from snnkart.io import atomic_path
from snnkart.rl.rollout import ProgressState

CHECKPOINT_SCHEMA = "snnkart/checkpoint/v1"


class Generators(TypedDict, total=False):
    """How a checkpoint restores the minibatch shuffling (one of the two), and the optional
    training state: ``reward_rms``, the running return variance of ``ppo.norm_reward``."""

    numpy_seed: int  # a history checkpoint: the minibatch shuffling is re-seeded from it
    numpy_state: Mapping[str, object]  # a latest-only one: the generator's own state
    reward_rms: dict[str, torch.Tensor]


class CheckpointState(Generators):
    """What a checkpoint's .pt holds besides its metadata (``meta_json``)."""

    policy: dict[str, torch.Tensor]
    optimizer: dict[str, object]
    obs_rms: dict[str, torch.Tensor]
    progress: ProgressState
    torch_rng: torch.Tensor


class EvalScore(TypedDict):
    """A periodic evaluation (:mod:`snnkart.rl.periodic_eval`; ``best.pt``'s ``eval``)."""

    success_rate: float
    mean_return: float
    global_step: int
    iteration: int
    episodes: int
    seed: int


class _Meta(ProgressState):
    policy: str
    env_spec: dict[str, object]  # snnkart.envs.spec.env_spec
    env_spec_hash: str
    config: dict[str, object]  # the training config, as config.toml has it
    track: dict[str, str] | None  # snnkart.envs.tracks.embed_track (None: not a kart env)
    stopped_early: bool


class CheckpointMeta(_Meta, total=False):
    """A checkpoint's metadata as training writes it (:func:`save_checkpoint` adds ``schema``
    and ``versions``); ``eval``: the best checkpoint's evaluation."""

    eval: EvalScore


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for pkg in ("snnkart", "torch", "snntorch", "gymnasium", "numpy", "pymunk", "nir"):
        try:
            out[pkg] = importlib_metadata.version(pkg)
        except importlib_metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def save_checkpoint(path: Path, state: CheckpointState, meta: CheckpointMeta) -> None:
    """Write ``path`` (.pt, tensors and plain values) and ``path.with_suffix('.json')``.

    The metadata is also stored inside the .pt file, which is replaced atomically, so the pair
    can never disagree: a process killed between the two renames leaves a .json that
    :func:`load_checkpoint` ignores in favour of the copy inside the .pt."""
    record = {"schema": CHECKPOINT_SCHEMA, "versions": versions(), **meta}
    text = json.dumps(record, indent=2) + "\n"
    buffer = io.BytesIO()  # serialised first: torch's own file writer hides why a write failed
    torch.save({**state, "meta_json": text}, buffer)
    try:
        with atomic_path(path) as tmp:
            tmp.write_bytes(buffer.getvalue())
            fault_point("checkpoint")  # tests: interrupted while a checkpoint is written
        with atomic_path(path.with_suffix(".json")) as tmp:
            tmp.write_text(text)
    except OSError as exc:
        raise CheckpointWriteError(
            f"cannot write the checkpoint {exc.filename or path}: {exc.strerror or exc}"
        ) from exc


def load_checkpoint(path: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """The state dict and metadata of ``path``; the metadata comes from inside the .pt file
    (checkpoints written before it was stored there: from the .json beside it)."""
    path = Path(path)
    meta_path = path.with_suffix(".json")
    if not path.is_file():
        raise CheckpointError(
            f"no checkpoint at {path} (needs {path.name}); "
            "train first or pass the right run directory"
        )
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for corrupt files
        raise CheckpointError(f"{path}: cannot read the checkpoint ({exc})") from exc
    inner = state.pop("meta_json", None)
    source = path
    try:
        if isinstance(inner, str):
            meta = json.loads(inner)
        elif meta_path.is_file():
            meta, source = json.loads(meta_path.read_text()), meta_path
        else:
            raise CheckpointError(
                f"no checkpoint metadata for {path} (an older checkpoint needs {meta_path.name} "
                "beside it); train first or pass the right run directory"
            )
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"{source}: corrupt checkpoint metadata ({exc})") from exc
    if meta.get("schema") != CHECKPOINT_SCHEMA:
        raise CheckpointError(
            f"{source}: schema {meta.get('schema')!r} is not {CHECKPOINT_SCHEMA!r}"
        )
    return state, meta


def check_compatible(meta: Mapping[str, object], env: KartEnv, source: str) -> None:
    """Raise a clear error if the checkpoint was trained on a different env spec."""
    spec = env_spec(env)
    if meta.get("env_spec_hash") == spec_hash(spec):
        return
    saved = meta.get("env_spec")
    saved = saved if isinstance(saved, dict) else {}
    mismatch = revision_mismatch(saved.get("revision"))
    if mismatch:
        raise CheckpointError(f"{source} was trained on {mismatch}; retrain the run")
    diffs = spec_differences(saved, spec)
    raise CheckpointError(
        f"{source} was trained for another env ({'; '.join(diffs) or 'env spec differs'}); "
        "evaluate it on the env it was trained on"
    )
