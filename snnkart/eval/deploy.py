"""``snnkart deploy``: run an exported policy (``.nir`` + manifest) in closed loop on a backend,
checking it step by step against the numpy reference, and write metrics, counts and parity.

Backends: ``lava-sim`` (Lava's CPU-simulated Loihi, ``--precision float|fixed``) and
``nir-ref`` (the numpy reference; ``float32``, or the Lava arithmetics ``float64|fixed``).
Every env step of a Lava run is shadowed by two references on the same observation:

- the same-arithmetic reference (float64 for Lava float, fixed for Lava fixed), which must
  agree bit for bit: any differing window is counted and reported (it should be 0);
- the float32 reference in torch's order (what the trained policy computes): the fraction of
  identical actions and the spike flips per million neuron-steps measure what the backend's
  arithmetic (float64, or the quantisation) changes.

Only the two exported files are read, never the training code.
"""

from __future__ import annotations

import contextlib
import platform
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from snnkart import faults
from snnkart.backends.base import SpikeCounts
from snnkart.backends.loading import load_policy
from snnkart.backends.registry import BACKENDS
from snnkart.contract.manifest import Manifest, ManifestError
from snnkart.envs.tracks import track_label
from snnkart.errors import DeployError, DeployWriteError, ParityError
from snnkart.eval.episodes import EpisodeResult, EvalSummary, run_episodes
from snnkart.eval.parity import CheckedPredictor, check_parity, open_backends
from snnkart.eval.policy_env import TrackChoice, make_policy_env, resolve_track
from snnkart.eval.request import DeployRequest
from snnkart.io import write_json

DEPLOY_SCHEMA = "snnkart/deploy/v1"


def check_writable(out_dir: Path) -> None:
    """Fail before the run, not after it, if ``out_dir`` cannot take files."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out_dir):
            pass
    except OSError as exc:
        raise DeployError(
            f"cannot write results to {out_dir}: {exc.strerror or exc}; choose another --out"
        ) from exc


def run_deploy(
    request: DeployRequest, on_episode: Any = None, on_step: Any = None
) -> dict[str, Any]:
    """Run the request's seeded episodes; return (and write to ``out/deploy.json``) the record.

    Ctrl-C and SIGTERM (:mod:`snnkart.faults`) are taken between env steps: the backend is
    stopped, nothing is written and :class:`~snnkart.faults.Interrupted` is raised."""
    nir_path, backend, precision = request.nir_file, request.backend, request.precision
    seed, out_dir = request.seed, request.out
    policy = load_policy(nir_path)  # fails fast on a bad file before starting Lava
    chain, manifest = policy.chain, policy.manifest
    choice = resolve_track(manifest, request.track)
    gym_env = make_policy_env(manifest, request.env, choice.track)
    if out_dir is not None:
        check_writable(out_dir)
    with contextlib.ExitStack() as stack:
        stack.callback(gym_env.close)
        stack.enter_context(faults.caught())  # entered after gym_env.close: exits before it
        t0 = time.perf_counter()
        primary, exact, float32 = open_backends(policy, backend, request.arithmetic, seed)
        stack.push(primary.__exit__)  # stops Lava on success, error and Ctrl-C
        run = _Run(CheckedPredictor(primary, exact, float32), time.perf_counter() - t0)
        run.play(gym_env, request.episodes, seed, on_step, on_episode)
    record = {
        "schema": DEPLOY_SCHEMA,
        "backend": backend,
        "precision": precision if backend == "lava-sim" else primary.arithmetic,
        "nir_file": str(nir_path),
        "manifest": _manifest_summary(manifest),
        "network": _network(chain),
        "env": {
            "env": gym_env.unwrapped.env_name,
            **choice.record(),
            "track_label": choice.label,
            "action_mode": gym_env.unwrapped.action_mode,
        },
        "first_seed": seed,
        **run.results(),
        "machine": {"python": platform.python_version(), "machine": platform.machine()},
        "versions": manifest.versions,
        "episodes": run.per_episode,
    }
    if out_dir is not None:
        _write(out_dir / "deploy.json", record)
    check_parity(record)
    return record


class _Run:
    """The episodes of one deploy: per-episode counts, wall time and the checked predictor."""

    def __init__(self, checked: CheckedPredictor, startup: float) -> None:
        self.checked, self.startup = checked, startup
        self.per_episode: list[dict[str, Any]] = []
        self.summary: EvalSummary | None = None
        self.wall = 0.0

    def play(self, env: Any, episodes: int, seed: int, on_step: Any, on_episode: Any) -> None:
        primary = self.checked.primary
        before = primary.counts.as_dict()

        def episode_done(result: EpisodeResult) -> None:
            nonlocal before
            self.per_episode.append(
                {**asdict(result), "counts": _counts_delta(primary.counts, before)}
            )
            before = primary.counts.as_dict()
            if on_episode is not None:
                on_episode(result)

        wall = time.perf_counter()
        results = run_episodes(
            env, self.checked, episodes, seed, on_step=on_step, on_episode=episode_done
        )
        self.wall = time.perf_counter() - wall
        self.summary = EvalSummary.of(results)

    def results(self) -> dict[str, Any]:
        """The record's summary, counts, parity, timing and quantisation."""
        primary, steps = self.checked.primary, self.checked.parity.env_steps
        assert self.summary is not None
        return {
            "summary": asdict(self.summary),
            "counts": primary.counts.as_dict(),
            "counts_note": (
                "spikes, synops (spikes x fan-out) and neuron_updates of the policy's T logical "
                "SNN steps per env step; pipeline_overhead: the Lava pipeline's fill and drain "
                "steps (L Dense delays per window), not part of the policy's computation"
            ),
            "parity": self.checked.parity.as_dict(),
            "timing": {
                "startup_s": self.startup,
                "wall_s": self.wall,
                "ms_per_env_step": 1000 * self.checked.step_seconds / max(steps, 1),
            },
            "quantization": None if primary.fixed is None else primary.fixed.describe(),
        }


def _network(chain: Any) -> dict[str, Any]:
    """The chain's shape, for the energy report's counts."""
    return {
        "n_in": chain.n_in,
        "sizes": list(chain.sizes),
        "n_out": chain.n_out,
        "readout": chain.readout_weight is not None,
        "input_scale": chain.input_scale is not None,
    }


def _manifest_summary(manifest: Manifest) -> dict[str, Any]:
    return {
        "num_steps": manifest.num_steps,
        "encoding": manifest.encoding,
        "population": manifest.population,
        "layers": [asdict(layer) for layer in manifest.layers],
        "action_mode": manifest.action_mode,
        "training": manifest.training,
    }


def _write(path: Path, record: dict[str, Any]) -> None:
    try:
        faults.fault_point("deploy-write")
        write_json(path, record)
    except OSError as exc:
        raise DeployWriteError(
            f"the run finished but {path} could not be written: {exc.strerror or exc}; "
            "its summary is printed above; free space or choose another --out and run again",
            record,
        ) from exc


def _counts_delta(now: SpikeCounts, before: dict[str, Any]) -> dict[str, Any]:
    cur = now.as_dict()
    out: dict[str, Any] = {"env_steps": cur["env_steps"] - before["env_steps"]}
    for key in ("spikes", "synops", "neuron_updates"):
        out[key] = [x - y for x, y in zip(cur[key], before[key], strict=True)]
    out["pipeline_overhead"] = {
        key: [
            x - y
            for x, y in zip(
                cur["pipeline_overhead"][key], before["pipeline_overhead"][key], strict=True
            )
        ]
        for key in cur["pipeline_overhead"]
    }
    return out


def summary_lines(record: dict[str, Any]) -> list[str]:
    """What ``snnkart deploy`` prints."""
    s, p, c, t = record["summary"], record["parity"], record["counts"], record["timing"]
    n = max(c["env_steps"], 1)
    e = record["env"]
    lines = [
        f"{record['backend']} ({record['precision']}) on {e['env']}/"
        f"{e.get('track_label', e['track'])}, {s['episodes']} episodes: success "
        f"{s['success_rate']:.0%}, return {s['mean_return']:.2f}, crashes {s['crashes']}, "
        f"time-outs {s['timeouts']}",
    ]
    if e.get("track_override"):
        trained = e["trained_track"]
        lines.append(
            f"note: track {e['track_label']} is not the track the policy was trained on "
            f"({track_label(trained['name'], trained.get('given'))})"
        )
    if p["same_arithmetic_reference"] is not None:
        lines.append(
            f"parity vs numpy reference ({p['same_arithmetic_reference']}, same arithmetic): "
            f"{p['same_arithmetic_mismatched_windows']} of {p['env_steps']} env steps differ "
            f"(spike rasters), {p['same_arithmetic_mismatched_actions']} actions differ"
        )
    if p["env_steps"] and "float32_identical_action_fraction" in p:
        lines.append(
            f"agreement with the float32 policy (torch order): "
            f"{p['float32_identical_action_fraction']:.2%} identical actions, "
            f"{p['float32_spike_flips_per_million_neuron_steps']:.0f} spike flips per million "
            "neuron-steps"
        )
    lines.append(
        "per env step (policy): spikes "
        + ", ".join(f"L{i}: {x / n:.1f}" for i, x in enumerate(c["spikes"]))
        + "; synops "
        + ", ".join(f"L{i}: {x / n:.0f}" for i, x in enumerate(c["synops"]))
    )
    o = c["pipeline_overhead"]
    lines.append(
        "pipeline overhead per env step (fill/drain, not the policy): spikes "
        + ", ".join(f"L{i}: {x / n:.2f}" for i, x in enumerate(o["spikes"]))
        + "; neuron updates "
        + ", ".join(f"L{i}: {x / n:.0f}" for i, x in enumerate(o["neuron_updates"]))
    )
    lines.append(f"{t['ms_per_env_step']:.1f} ms per env step, start-up {t['startup_s']:.1f} s")
    return lines


__all__ = [
    "BACKENDS",
    "DeployError",
    "DeployRequest",
    "DeployWriteError",
    "ManifestError",
    "ParityError",
    "TrackChoice",
    "check_parity",
    "make_policy_env",
    "resolve_track",
    "run_deploy",
    "summary_lines",
]
