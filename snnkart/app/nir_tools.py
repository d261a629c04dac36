"""``snnkart nir info`` and ``snnkart nir run``: any NIR graph, inspected and run open loop.

A graph snnkart exported has its manifest beside it, which records the time step its time
constants were written with; any other graph needs ``--dt`` (NIR carries none, and libraries
differ: snntorch writes 1e-4 s, lava-dl 1) and may need ``--discretisation exact``.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from snnkart.backends.base import Arithmetic
from snnkart.backends.graph_info import GraphInfo, describe_graph
from snnkart.backends.loading import read_graph
from snnkart.backends.network import ChainNetwork, UnsupportedGraphError, chain_from_graph
from snnkart.backends.open_loop import OpenLoopResult, check_inputs, compare, run_open_loop
from snnkart.backends.quantize import quantize
from snnkart.backends.registry import arithmetic_for
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.errors import DeployError, NIRFileError, ParityError
from snnkart.io import write_bytes

DT_HINT = "snntorch exports use 1e-4 s, lava-dl 1; use the dt the graph was trained with"


def resolve_dt(path: Path, dt: float | None) -> tuple[float | None, str]:
    """The time step to discretise with and where it comes from: ``--dt``, else the manifest
    of a snnkart export beside the graph, else none."""
    if dt is not None:
        if not (np.isfinite(dt) and dt > 0):
            raise DeployError(f"--dt must be a positive number of seconds, not {dt}")
        return dt, "--dt"
    mpath = manifest_path(path)
    if mpath.is_file():
        return Manifest.read(mpath).nir_dt, f"the manifest ({mpath.name})"
    return None, "NIR graphs record no time step, and no --dt was given"


def resolve_discretisation(path: Path, given: str | None) -> str:
    """``--discretisation`` if given, else the manifest's (a snnkart export), else euler."""
    if given is not None:
        return given
    mpath = manifest_path(path)
    return Manifest.read(mpath).discretisation if mpath.is_file() else "euler"


STATE_PERSISTS = (
    "membranes carry across env steps (manifest state_persists): each env step runs T + L Lava "
    "steps with no reset and the state is zeroed only at an episode's start; the NIR file alone "
    "(plain LIF nodes) does not say so, and a reader who resets the LIF state per input runs "
    "another policy"
)
"""What ``snnkart nir info`` says about a stateful LIF export (docs/stateful.md)."""


def run_nir_info(path: Path, dt: float | None, discretisation: str | None) -> GraphInfo:
    graph = read_graph(path)
    step, source = resolve_dt(path, dt)
    info = describe_graph(graph, step, source, resolve_discretisation(path, discretisation))
    mpath = manifest_path(path)
    if mpath.is_file() and Manifest.read(mpath).state_persists:
        info.state = STATE_PERSISTS
    return info


def load_open_chain(path: Path, dt: float | None, discretisation: str | None) -> ChainNetwork:
    discretisation = resolve_discretisation(path, discretisation)
    step, _ = resolve_dt(path, dt)
    if step is None:
        raise DeployError(f"{path}: the graph records no time step; pass --dt ({DT_HINT})")
    try:
        return chain_from_graph(read_graph(path), step, discretisation)
    except UnsupportedGraphError as exc:
        raise NIRFileError(f"{path}: {exc}") from exc


def read_input(path: Path) -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise DeployError(f"no input file at {path}; give a .npy array of shape [N, n_in]")
    try:
        return np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise DeployError(f"{path}: not a .npy array ({exc})") from exc


def run_nir_run(
    path: Path,
    input_path: Path,
    steps: int | None,
    backend: str,
    precision: str,
    out: Path | None,
    check: bool,
    dt: float | None,
    discretisation: str | None,
    show: Callable[[dict[str, object]], None] = lambda summary: None,
) -> dict[str, object]:
    """Run the graph open loop; with ``check``, also on the reference of the same arithmetic
    (when the backend is lava-sim) and the float32 reference, and compare spike for spike.
    ``show`` sees the summary before a mismatch with the same arithmetic raises."""
    arithmetic = arithmetic_for(backend, precision)
    chain = load_open_chain(path, dt, discretisation)
    inputs = check_inputs(read_input(input_path), chain.n_in, steps)
    fixed = quantize(chain) if arithmetic == "fixed" else None
    result = run_open_loop(chain, inputs, backend, arithmetic, fixed)
    checks: list[dict[str, object]] = []  # snnkart.backends.open_loop.compare's, per reference
    summary: dict[str, object] = {
        "graph": str(path),
        "backend": backend,
        "arithmetic": arithmetic,
        "steps": int(inputs.shape[0]),
        "spikes": {n: int(result.layer(i).sum()) for i, n in enumerate(result.names)},
        "checks": checks,
    }
    if check:
        others: list[tuple[str, Arithmetic]] = []
        if backend != "nir-ref":
            others.append(("nir-ref", arithmetic))
        if arithmetic != "float32":
            others.append(("nir-ref", "float32"))
        for other_backend, other_arith in others:
            other = run_open_loop(chain, inputs, other_backend, other_arith, fixed)
            checks.append(compare(result, other))
    if out is not None:
        _write_npz(out, result, summary)
        summary["out"] = str(out)
    show(summary)
    same = [c for c in checks if str(c["b"]).endswith(arithmetic)]
    if same and not same[0]["bit_exact"]:
        raise ParityError(
            f"{backend} {arithmetic} differs from the reference of the same arithmetic: "
            f"{same[0]['flips']} flipped spikes",
            summary,
        )
    return summary


def _write_npz(out: Path, result: OpenLoopResult, summary: dict[str, object]) -> None:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **result.arrays(), summary=np.array(json.dumps(summary)))
    write_bytes(out, buffer.getvalue())
