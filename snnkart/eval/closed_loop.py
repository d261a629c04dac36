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
from snnkart.backends.loading import open_policy
from snnkart.backends.registry import BACKENDS
from snnkart.backends.sigma_delta_counts import SigmaDeltaTotals
from snnkart.contract.deploy_inputs import INPUTS_FILE, DeployInputs
from snnkart.contract.deploy_record import (
    COUNTS_NOTE,
    DEPLOY_SCHEMA,
    SIGMA_DELTA_COUNTS_NOTE,
    Counts,
    DeployedEpisode,
    DeployRecord,
    EnvRecord,
    Machine,
    ManifestSummary,
    OverheadCounts,
    ParityRecord,
    QuantLayer,
    SigmaDeltaCounts,
    Timing,
)
from snnkart.contract.manifest import ManifestError
from snnkart.envs.constants import DT
from snnkart.envs.tracks import track_label
from snnkart.errors import DeployError, DeployWriteError, ParityError
from snnkart.eval.episodes import EpisodeResult, EvalSummary, describe_returns, run_episodes
from snnkart.eval.parity import CheckedPredictor, check_parity, open_backends
from snnkart.eval.policy_env import TrackChoice, make_policy_env, resolve_track
from snnkart.eval.recorded import record_inputs, recorded_inputs
from snnkart.eval.request import DeployRequest


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


def run_deploy(request: DeployRequest, on_episode: Any = None, on_step: Any = None) -> DeployRecord:
    """Run the request's seeded episodes; return (and write to ``out/deploy.json``) the record.

    Ctrl-C and SIGTERM (:mod:`snnkart.faults`) are taken between env steps: the backend is
    stopped, nothing is written and :class:`~snnkart.faults.Interrupted` is raised."""
    nir_path, backend, precision = request.nir_file, request.backend, request.precision
    seed, out_dir = request.seed, request.out
    policy = open_policy(nir_path)  # fails fast on a bad file before starting Lava
    manifest = policy.manifest
    choice = resolve_track(manifest, request.track)  # None: any gymnasium env, no track
    gym_env = make_policy_env(manifest, request.env, None if choice is None else choice.track)
    if out_dir is not None:
        check_writable(out_dir)
    with contextlib.ExitStack() as stack:
        stack.callback(gym_env.close)
        stack.enter_context(faults.caught())  # entered after gym_env.close: exits before it
        t0 = time.perf_counter()
        primary, exact, float32 = open_backends(policy, backend, request.arithmetic, seed)
        stack.push(primary.__exit__)  # stops Lava on success, error and Ctrl-C
        # inputs.npz: what entered the chip and what each layer sent, window by window (LIF
        # chains; a sigma-delta deploy writes deploy.json alone)
        keep = out_dir is not None and primary.records_inputs
        recorder = record_inputs(primary) if keep else None  # type: ignore[arg-type]
        run = _Run(CheckedPredictor(primary, exact, float32), time.perf_counter() - t0)
        run.play(gym_env, request.episodes, seed, on_step, on_episode, _threshold(choice, manifest))
    assert run.summary is not None  # play() ran
    record = DeployRecord(
        schema=DEPLOY_SCHEMA,
        backend=backend,
        precision=precision if backend == "lava-sim" else primary.arithmetic,
        nir_file=str(nir_path),
        manifest=ManifestSummary.of(manifest),
        network=policy.shape(),
        env=_env_record(gym_env, choice, manifest),
        first_seed=seed,
        summary=run.summary,
        counts=run.counts(),
        counts_note=run.counts_note(),
        parity=ParityRecord(**run.checked.parity.as_dict()),
        timing=run.timing(),
        quantization=run.quantization(),
        machine=Machine(python=platform.python_version(), machine=platform.machine()),
        versions=manifest.versions,
        episodes=run.per_episode,
    )
    if out_dir is not None:
        inputs = None if recorder is None else recorded_inputs(primary, recorder, seed)  # type: ignore[arg-type]
        _write(out_dir, record, inputs)
    check_parity(record)
    return record


def _env_record(gym_env: Any, choice: TrackChoice | None, manifest: Any) -> EnvRecord:
    """What the deploy record says of the env: a kart env's track, any other env's name."""
    if choice is None:
        fps = manifest.env.get("render_fps")  # the env's own rate, where it states one
        return EnvRecord(
            env=str(manifest.env.get("env")),
            action_mode=manifest.action_mode,
            control_hz=None if fps is None else float(fps),
        )
    return EnvRecord(
        env=gym_env.unwrapped.env_name,
        **vars(choice.record()),
        track_label=choice.label,
        action_mode=gym_env.unwrapped.action_mode,
        control_hz=1.0 / DT,
    )


def _threshold(choice: TrackChoice | None, manifest: Any) -> float | None:
    """The env's ``reward_threshold`` (any gymnasium env that has one; a kart env has none)."""
    value = manifest.env.get("reward_threshold") if choice is None else None
    return None if value is None else float(value)


class _Run:
    """The episodes of one deploy: per-episode counts, wall time and the checked predictor."""

    def __init__(self, checked: CheckedPredictor, startup: float) -> None:
        self.checked, self.startup = checked, startup
        self.per_episode: list[DeployedEpisode] = []
        self.summary: EvalSummary | None = None
        self.wall = 0.0

    def play(
        self,
        env: Any,
        episodes: int,
        seed: int,
        on_step: Any,
        on_episode: Any,
        reward_threshold: float | None = None,
    ) -> None:
        primary = self.checked.primary
        before = _counts(primary.counts)

        def episode_done(result: EpisodeResult) -> None:
            nonlocal before
            now = _counts(primary.counts)
            self.per_episode.append(DeployedEpisode(**asdict(result), counts=now.minus(before)))
            before = now
            if on_episode is not None:
                on_episode(result)

        wall = time.perf_counter()
        results = run_episodes(
            env, self.checked, episodes, seed, on_step=on_step, on_episode=episode_done
        )
        self.wall = time.perf_counter() - wall
        self.summary = EvalSummary.of(results, reward_threshold)

    def counts(self) -> Counts:
        return _counts(self.checked.primary.counts)

    def counts_note(self) -> str:
        return COUNTS_NOTE if self.checked.primary.float32_form else SIGMA_DELTA_COUNTS_NOTE

    def timing(self) -> Timing:
        steps = self.checked.parity.env_steps
        return Timing(
            startup_s=self.startup,
            wall_s=self.wall,
            ms_per_env_step=1000 * self.checked.step_seconds / max(steps, 1),
        )

    def quantization(self) -> list[QuantLayer] | None:
        fixed = self.checked.primary.fixed
        return None if fixed is None else [QuantLayer(**layer) for layer in fixed.describe()]


def _write(out_dir: Path, record: DeployRecord, inputs: DeployInputs | None) -> None:
    """``deploy.json`` and, beside it, ``inputs.npz`` (written first: a deploy.json is there
    only when its inputs are; None: no inputs file)."""
    path = out_dir / "deploy.json"
    try:
        faults.fault_point("deploy-write")
        if inputs is not None:
            inputs.save(out_dir / INPUTS_FILE)
        try:
            record.write(path)
        except OSError:
            (out_dir / INPUTS_FILE).unlink(missing_ok=True)  # no inputs without their record
            raise
    except OSError as exc:
        raise DeployWriteError(
            f"the run finished but {path} could not be written: {exc.strerror or exc}; "
            "its summary is printed above; free space or choose another --out and run again",
            record,
        ) from exc


def _counts(counts: SpikeCounts | SigmaDeltaTotals) -> Counts:
    """A backend's running counts as the record's."""
    c = counts.as_dict()
    over, sd = c.get("pipeline_overhead"), c.get("sigma_delta")
    return Counts(
        env_steps=c["env_steps"],
        spikes=c["spikes"],
        synops=c["synops"],
        neuron_updates=c["neuron_updates"],
        pipeline_overhead=None if over is None else OverheadCounts(**over),
        sigma_delta=None if sd is None else SigmaDeltaCounts(**sd),
    )


def summary_lines(record: DeployRecord) -> list[str]:
    """What ``snnkart deploy`` prints."""
    s, p, c, t, e = record.summary, record.parity, record.counts, record.timing, record.env
    n = max(c.env_steps, 1)
    if s.success_rate is None:  # any gymnasium env
        first = f"{record.backend} ({record.precision}) on {e.env}, {s.episodes} episodes: "
        first += describe_returns(s)
    else:
        first = (
            f"{record.backend} ({record.precision}) on {e.env}/{e.track_label or e.track}, "
            f"{s.episodes} episodes: success {s.success_rate:.0%}, return {s.mean_return:.2f}, "
            f"crashes {s.crashes}, time-outs {s.timeouts}"
        )
    lines = [first]
    if e.track_override and e.trained_track is not None:
        trained = e.trained_track
        lines.append(
            f"note: track {e.track_label} is not the track the policy was trained on "
            f"({track_label(trained['name'], trained.get('given'))})"
        )
    if p.same_arithmetic_reference is not None:
        lines.append(
            f"parity vs numpy reference ({p.same_arithmetic_reference}, same arithmetic): "
            f"{p.same_arithmetic_mismatched_windows} of {p.env_steps} env steps differ "
            f"({'sent values, readout' if c.sigma_delta else 'spike rasters'}), "
            f"{p.same_arithmetic_mismatched_actions} actions differ"
        )
    if p.env_steps and p.float32_identical_action_fraction is not None:
        lines.append(
            f"agreement with the float32 policy (torch order): "
            f"{p.float32_identical_action_fraction:.2%} identical actions, "
            f"{p.float32_spike_flips_per_million_neuron_steps or 0:.0f} spike flips per million "
            "neuron-steps"
        )
    if c.sigma_delta is not None:
        lines += _sigma_delta_lines(c.sigma_delta, n)
        lines.append(f"{t.ms_per_env_step:.1f} ms per env step, start-up {t.startup_s:.1f} s")
        return lines
    lines.append(
        "per env step (policy): spikes "
        + _per_layer(c.spikes, n, ".1f")
        + "; synops "
        + _per_layer(c.synops, n, ".0f")
    )
    o = c.pipeline_overhead or OverheadCounts(
        [0] * len(c.spikes), [0] * len(c.spikes), [0] * len(c.spikes)
    )
    lines.append(
        "pipeline overhead per env step (fill/drain, not the policy): spikes "
        + _per_layer(o.spikes, n, ".2f")
        + "; neuron updates "
        + _per_layer(o.neuron_updates, n, ".0f")
    )
    lines.append(f"{t.ms_per_env_step:.1f} ms per env step, start-up {t.startup_s:.1f} s")
    return lines


__all__ = [
    "BACKENDS",
    "DEPLOY_SCHEMA",
    "DeployError",
    "DeployRecord",
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


def _sigma_delta_lines(sd: SigmaDeltaCounts, n: int) -> list[str]:
    """The sigma-delta counts per env step, each layer by name."""

    def per(values: list[int], fmt: str) -> str:
        return ", ".join(f"{name} {x / n:{fmt}}" for name, x in zip(sd.layers, values, strict=True))

    return [
        f"per env step ({sd.rows_per_env_step} Lava steps, state kept across env steps and "
        f"episodes): messages {per(sd.messages, '.1f')}; synaptic events "
        f"{per(sd.synaptic_events, '.0f')}",
        f"neuron updates per env step: clocked {per(sd.updates_clocked, '.0f')}; active "
        f"{per(sd.updates_active, '.1f')}; link bits host->chip {sd.host_to_chip_bits / n:.0f}, "
        f"chip->host {sd.chip_to_host_bits / n:.0f}",
    ]


def _per_layer(values: list[float] | list[int], n: int, fmt: str) -> str:
    """Per-layer values divided by ``n``, named as the report and the panel name layers."""
    return ", ".join(f"layer {i + 1}: {x / n:{fmt}}" for i, x in enumerate(values))
