"""Golden outputs: what snnkart's commands produce from explicit configs, recorded once.

A refactor must not change them. ``produce(tmp)`` runs the real commands (through typer's
runner, in this process) on the configs in this folder and on the committed grid SNN fixture,
and gathers what they wrote into one JSON-able dict; ``scripts/record_golden.py`` stores it as
``expected.json`` and ``tests/test_golden.py`` compares a fresh run with it: integers, booleans
and strings exactly, floats within a relative 1e-6 (they move with torch versions and CPU
instruction sets; ``constraints.txt`` pins the versions). Rasters are compared by hash, so
exactly.

Only the configs here are used, never the defaults, which later issues may change.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

HERE = Path(__file__).resolve().parent
FIXTURE = HERE.parent / "data" / "policies" / "grid-snn"
EXPECTED = HERE / "expected.json"
RTOL = 1e-6

# Values that are measurements of this machine or paths of this run, not outputs.
VOLATILE = {
    "charts/SPS",
    "charts/rollout_SPS",
    "charts/update_seconds",
    "timing",
    "machine",
    "versions",
    "nir_file",
    "run",
    "checkpoint",
    "date",
    "created",
    "wall_s",
    "startup_s",
}


def _invoke(args: list[str]) -> None:
    from typer.testing import CliRunner

    from snnkart.cli import app

    result = CliRunner().invoke(app, args)
    if result.exit_code != 0:
        raise AssertionError(
            f"snnkart {' '.join(args)} exited {result.exit_code}:\n{result.output}"
        )


def _strip(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if k not in VOLATILE}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def _sha(arrays: list[np.ndarray]) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _train_and_eval(tmp: Path) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for kind in ("ann", "snn"):
        run_dir = tmp / f"train-{kind}"
        _invoke(["train", "--config", str(HERE / f"train-{kind}.toml"), "--out", str(run_dir)])
        rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
        meta = json.loads((run_dir / "checkpoint.json").read_text())
        _invoke(["eval", str(run_dir), "--episodes", "2", "--seed", "500"])
        evaluation = json.loads((run_dir / "eval.json").read_text())
        out[kind] = {
            "metrics": _strip(rows),
            "progress": {
                k: meta[k] for k in ("global_step", "episodes", "finishes", "first_finish_step")
            },
            "eval": _strip({"summary": evaluation["summary"], "episodes": evaluation["episodes"]}),
            "actions": _torch_actions(run_dir, steps=120),
        }
    return out


def _torch_actions(run_dir: Path, steps: int) -> list[Any]:
    """The deterministic policy's actions in closed loop from seed 500."""
    from snnkart.rl.trained import TorchPredictor, load_run

    run = load_run(run_dir)
    env = run.config.make_env(track=run.track)
    predictor = TorchPredictor(run, seed=0)
    actions: list[Any] = []
    try:
        obs, _ = env.reset(seed=500)
        for _ in range(steps):
            action = predictor.predict(obs)
            actions.append(np.asarray(action).tolist())
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                obs, _ = env.reset(seed=501)
    finally:
        env.close()
    return actions


def _export(tmp: Path) -> tuple[Path, dict[str, Any]]:
    nir_path = tmp / "fixture.nir"
    _invoke(["export", "--nir", str(FIXTURE), "--out", str(nir_path)])
    return nir_path, describe_export(nir_path)


def describe_export(nir_path: Path) -> dict[str, Any]:
    """The graph's nodes and edges, the hash of every array, and the manifest."""
    import nir

    graph = nir.read(str(nir_path))
    arrays = {}
    for name, node in sorted(graph.nodes.items()):
        for field, value in sorted(vars(node).items()):
            if isinstance(value, np.ndarray) and value.dtype != object:
                arrays[f"{name}.{field}"] = _sha([value])
    from snnkart.contract.manifest import Manifest

    # the manifest as today's code reads it (fields added since take their defaults)
    manifest = json.loads(Manifest.read(nir_path.with_suffix(".manifest.json")).to_json())
    return {
        "nodes": sorted(graph.nodes),
        "edges": sorted(map(list, graph.edges)),
        "arrays": arrays,
        "manifest": _strip(manifest),
    }


DEPLOYS = (
    ("nir-ref", "float32", 2),
    ("nir-ref", "float64", 1),
    ("nir-ref", "fixed", 2),
    ("lava-sim", "float", 1),
    ("lava-sim", "fixed", 1),
)


def _deploy(
    tmp: Path, nir_path: Path, runs: tuple[tuple[str, str, int], ...] = DEPLOYS
) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for backend, precision, episodes in runs:
        target = tmp / f"deploy-{backend}-{precision}"
        _invoke(
            [
                "deploy",
                str(nir_path),
                "--backend",
                backend,
                "--precision",
                precision,
                "--episodes",
                str(episodes),
                "--seed",
                "700",
                "--out",
                str(target),
            ]
        )
        record = json.loads((target / "deploy.json").read_text())
        out[f"{backend} {precision}"] = _strip(
            {
                k: record[k]
                for k in ("summary", "counts", "parity", "quantization", "episodes")
                if k in record
            }
        )
    if runs is DEPLOYS:
        out["rasters"] = _rasters(nir_path, steps=60)
    return out


def deploy(tmp: Path, nir_path: Path, runs: tuple[tuple[str, str, int], ...]) -> dict[str, Any]:
    """``snnkart deploy`` of ``nir_path`` for each (backend, precision, episodes) of ``runs``."""
    return _deploy(tmp, nir_path, runs)


def _rasters(nir_path: Path, steps: int) -> dict[str, Any]:
    """Every window's raster and readout, and the actions, on the observations of a closed-loop
    run of the float32 reference, for each backend and arithmetic."""
    from snnkart.backends.reference import NIRReference
    from snnkart.backends.registry import open_backend
    from snnkart.eval.closed_loop import make_policy_env

    driver = NIRReference(nir_path, "float32")
    env = make_policy_env(driver.manifest, None, None)
    observations = []
    try:
        obs, _ = env.reset(seed=900)
        for _ in range(steps):
            observations.append(np.asarray(obs))
            obs, _, terminated, truncated, _ = env.step(driver.predict(obs))
            if terminated or truncated:
                obs, _ = env.reset(seed=901)
    finally:
        env.close()
    out = {}
    predictors = {
        f"nir-ref {m}": lambda m=m: NIRReference(nir_path, m)
        for m in ("float32", "float64", "fixed")
    }
    predictors |= {
        f"lava-sim {p}": lambda p=p: open_backend(nir_path, "lava-sim", p)
        for p in ("float", "fixed")
    }
    for name, make in predictors.items():
        predictor = make()
        rasters, readouts, actions = [], [], []
        try:
            for obs in observations:
                window, readout = predictor.step(obs)
                rasters.append(window.raster)
                readouts.append(np.asarray(readout, dtype=np.float64))
                actions.append(np.asarray(predictor.codec.decode(readout)).tolist())
        finally:
            if hasattr(predictor, "close"):
                predictor.close()
        out[name] = {
            "rasters_sha256": _sha(rasters),
            "readouts": np.asarray(readouts).round(12).tolist(),
            "actions": actions,
        }
    return out


def produce(tmp: Path) -> dict[str, Any]:
    tmp.mkdir(parents=True, exist_ok=True)
    nir_path, export = _export(tmp)
    return {
        "train": _train_and_eval(tmp),
        "export": export,
        "deploy": _deploy(tmp, nir_path),
    }


def differences(expected: Any, actual: Any, path: str = "") -> list[str]:
    """Where ``actual`` departs from ``expected``: exact for everything but floats (rtol 1e-6)."""
    if isinstance(expected, dict) and isinstance(actual, dict):
        out = []
        for k in sorted(set(expected) | set(actual)):
            if k not in actual or k not in expected:
                out.append(f"{path}/{k}: {'missing' if k not in actual else 'new'}")
            else:
                out += differences(expected[k], actual[k], f"{path}/{k}")
        return out
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return [f"{path}: length {len(actual)} != {len(expected)}"]
        out = []
        for i, (e, a) in enumerate(zip(expected, actual, strict=True)):
            out += differences(e, a, f"{path}[{i}]")
        return out
    if isinstance(expected, float) or isinstance(actual, float):
        if isinstance(expected, bool) or isinstance(actual, bool):
            return [] if expected == actual else [f"{path}: {actual!r} != {expected!r}"]
        if expected is None or actual is None:
            return [] if expected == actual else [f"{path}: {actual!r} != {expected!r}"]
        if math.isnan(expected) and math.isnan(actual):
            return []
        if math.isclose(expected, actual, rel_tol=RTOL, abs_tol=1e-12):
            return []
        return [f"{path}: {actual!r} != {expected!r} (rtol {RTOL})"]
    return [] if expected == actual else [f"{path}: {actual!r} != {expected!r}"]
