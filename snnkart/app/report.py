"""``snnkart report``: the deployed spiking policy's energy against the ANN baseline.

Counts come from the deployment (``deploy.json``: Lava's or the reference's counts, proven equal
step by step); prices from hardware profiles; every energy in ``report.json`` is a list of
``count x price`` terms naming the profile entry and its source.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any, cast

from snnkart.app.report_comparisons import comparisons, memory_first, sensitivity
from snnkart.app.report_sigma_delta import same_shape_ann, sd_report, stateful_note
from snnkart.app.report_sweep import sweep_section
from snnkart.app.reporter import Reporter
from snnkart.app.sanafe_report import sanafe_section
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import success_share
from snnkart.contract.records import RecordError
from snnkart.contract.report_record import (
    AnnRunTask,
    AnnSection,
    Control,
    LifReport,
    SnnSection,
    StateNote,
    Sweep,
    deploy_section,
    lif_report,
)
from snnkart.contract.sanafe_record import SanafeSection
from snnkart.energy import goal
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.pricing import CONTROL_PERIOD_S
from snnkart.energy.profiles import (
    DEFAULT_CHIPS,
    DEFAULT_DIGITAL,
    Profile,
    load_profile,
)
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.energy.uncertainty import method
from snnkart.errors import ReportError

REPORT_SCHEMA = "snnkart/report/v4"
"""v2: each comparison's ``uncertainty`` and its break-even in T and width; the top-level
``uncertainty`` says how the prices were sampled. v3: a sigma-delta deployment's report
(``kind: "sigma-delta"``, :mod:`snnkart.app.report_sigma_delta`); a stateful LIF deployment's ``state``;
a LIF report otherwise as in v2. v4: ``control`` (the control period, where it comes from, the
pass mark): any gymnasium env's deployment, at its own rate; ``drives`` and a task's
``success_rate`` are null where the env has no pass mark."""
DRIVES = 0.8
"""Below this success rate the SNN does not drive, and the report says so before any energy."""


def read_deploy(deploy_dir: Path) -> DeployRecord:
    path = deploy_dir / "deploy.json" if deploy_dir.is_dir() else deploy_dir
    if not path.is_file():
        raise ReportError(
            f"no deployment at {deploy_dir}: expected a directory with deploy.json, written by "
            "snnkart deploy --out DIR"
        )
    try:
        return DeployRecord.read(path)
    except RecordError as exc:
        raise ReportError(str(exc)) from exc


def _profiles(
    names: list[str] | None, host: str | None
) -> tuple[list[Profile], list[Profile], Profile | None]:
    loaded = [load_profile(n) for n in (names or [*DEFAULT_CHIPS, *DEFAULT_DIGITAL])]
    chips = [p for p in loaded if p.kind == "neuromorphic"]
    digital = [p for p in loaded if p.kind == "digital"]
    if not chips or not digital:
        raise ReportError(
            "--profile: give at least one neuromorphic and one digital profile (the SNN runs "
            f"on the first, the ANN on the second); got {', '.join(p.name for p in loaded)}"
        )
    if host is None:
        return chips, digital, None  # the host is priced like the ANN it is compared with
    host_profile = load_profile(host)
    if host_profile.kind != "digital":
        raise ReportError(f"--host-profile: {host_profile.name} is not a digital profile")
    return chips, digital, host_profile


def _ann_run(ann_dir: Path, record: DeployRecord) -> tuple[AnnCounts, AnnRunTask]:
    """The user's ANN run: its widths, and its task performance on the deployment's episodes."""
    from snnkart.eval.episodes import EvalSummary, run_episodes
    from snnkart.rl.trained import TorchPredictor, load_run

    run = load_run(ann_dir)
    widths = run.actor_widths()
    env = record.env
    if run.config.env != env.env:
        raise ReportError(
            f"--ann {ann_dir} is a {run.config.env} run, the deployment drove {env.env}; "
            "compare policies of the same env"
        )
    if env.track is not None:
        trained = run.track_record()
        if trained["sha256"] != env.track_sha256:
            raise ReportError(
                f"--ann {ann_dir} was trained on track {trained['name']}, the deployment drove "
                f"{env.track}; compare on the same track"
            )
    from snnkart.eval.ann_int8 import int8_task

    gym_env = run.config.make_env(track=run.track)
    episodes = len(record.episodes) or 1
    try:
        results = run_episodes(
            gym_env, TorchPredictor(run, seed=record.first_seed), episodes, record.first_seed
        )
    finally:
        gym_env.close()
    threshold = record.summary.reward_threshold
    summary = EvalSummary.of(results)
    steps = sum(r.length for r in results)
    task: AnnRunTask = {
        "run": str(ann_dir),
        "global_step": run.meta.get("global_step"),
        "episodes": episodes,
        "first_seed": record.first_seed,
        "success_rate": success_share(results, threshold),
        "mean_lap_time": summary.mean_lap_time,
        "mean_return": summary.mean_return,
        "steps_per_episode": steps / episodes,
        "int8": int8_task(
            run,
            lambda: run.config.make_env(track=run.track),
            record.first_seed,
            episodes,
            reward_threshold=threshold,
        ),
    }
    return AnnCounts(widths, run.config.action_mode, "ANN run"), task


def _snn_section(snn: SnnCounts, record: DeployRecord, success: float | None) -> SnnSection:
    net, s = snn.net, record.summary
    return {
        "task": {
            "success_rate": success,
            "mean_lap_time": s.mean_lap_time,
            "mean_return": s.mean_return,
            "episodes": snn.episodes,
            "steps_per_episode": snn.steps_per_episode,
        },
        "per_inference": {
            "spikes": list(snn.spikes),
            "synops_chip": list(snn.synops),
            "neuron_updates": list(snn.neuron_updates),
            "firing_rates": snn.firing_rates(),
            "pipeline_overhead": {
                "spikes": list(snn.overhead_spikes),
                "synops_chip": list(snn.overhead_synops),
                "neuron_updates": list(snn.overhead_neuron_updates),
            },
            "host_ops": [vars(op) for op in snn.host],
            "link_bits": {"host_to_chip": snn.link_bits[0], "chip_to_host": snn.link_bits[1]},
        },
        "neurobench": snn.neurobench(),
        "deployed": snn.deployed(),
        "footprint": snn.footprint(),
        "latency": {
            "logical_steps": net.num_steps,
            "lava_steps_per_action": net.num_steps + net.depth,
            "ms_per_env_step": record.timing.ms_per_env_step,
            "backend": record.backend,
        },
    }


def _ann_section(ann: AnnCounts, task: AnnRunTask | None) -> AnnSection:
    return {
        "label": ann.label,
        "widths": list(ann.widths),
        "macs": ann.macs,
        "neurobench": ann.neurobench(),
        "footprint": ann.footprint(),
        "task": task,
    }


def _anns(
    snn: SnnCounts, record: DeployRecord, ann_dir: Path | None
) -> dict[str, tuple[AnnCounts, AnnRunTask | None]]:
    """The ANN baselines: the same widths (taking the observation itself, not a population
    code of it), and the user's ANN run if given."""
    anns: dict[str, tuple[AnnCounts, AnnRunTask | None]] = {"same_width": (same_width(snn), None)}
    if ann_dir is not None:
        anns["run"] = _ann_run(ann_dir, record)
    return anns


def same_width(snn: SnnCounts) -> AnnCounts:
    """The ANN of the LIF deployment's widths, taking the observation itself (not a population
    code of it)."""
    net = snn.net
    widths = (net.obs_dim, *net.sizes, net.n_out) if net.readout else (net.obs_dim, *net.sizes)
    return AnnCounts(widths, net.action_mode, f"ANN {'-'.join(map(str, net.sizes))} (same widths)")


def priced_deployment(
    record: DeployRecord, chip: str = goal.PRIMARY, baseline: str = goal.INT8
) -> tuple[goal.Priced, AnnCounts]:
    """The deployment (a policy of any family) on ``chip`` against the ANN of its own widths on
    ``baseline``, at the deployment's control rate (the pair :func:`goal.check` samples), and
    that ANN."""
    period, _ = control_period(record, None)
    policy: SnnCounts | SigmaDeltaCounts
    if record.counts.sigma_delta is not None:
        policy = replace(SigmaDeltaCounts.of_deploy(record), period_s=period)
        ann = same_shape_ann(policy)
    else:
        policy = replace(SnnCounts.of_deploy(record), period_s=period)
        ann = same_width(policy)
    return goal.priced_policy(policy, load_profile(chip), load_profile(baseline), ann), ann


def control_period(record: DeployRecord, control_hz: float | None) -> tuple[float, str]:
    """The deployment's control period (one inference per env step) and where it comes from:
    ``--control-hz``, else the env's rate in the record (a kart env's 60 Hz, a gymnasium env's
    ``render_fps``); a gymnasium env that states none is refused in one line."""
    if control_hz is not None:
        if not control_hz > 0:
            raise ReportError(f"--control-hz must be positive, not {control_hz:g}")
        return 1.0 / control_hz, f"--control-hz {control_hz:g}"
    if record.env.control_hz is not None:
        what = "kart env's" if record.env.track is not None else "env's metadata render_fps,"
        return 1.0 / record.env.control_hz, f"the {what} {record.env.control_hz:g} Hz"
    if record.env.track is not None:  # a deployment recorded before control_hz (60 Hz)
        return CONTROL_PERIOD_S, f"the kart env's {1 / CONTROL_PERIOD_S:g} Hz"
    raise ReportError(
        f"the env {record.env.env!r} states no control rate (no render_fps in its metadata); "
        "pass --control-hz (the decisions per second the policy would make)"
    )


def _deployment(
    deploy_dir: Path, ann_dir: Path | None, control_hz: float | None
) -> tuple[DeployRecord, Control, tuple[float | None, bool | None]]:
    """The deploy record, its control section, and its task's success rate and whether that
    passes (:data:`DRIVES`; None: nothing to judge); ``--ann`` refused for a gymnasium env."""
    record = read_deploy(deploy_dir)
    period, period_from = control_period(record, control_hz)
    success, pass_mark = task_success(record)
    control: Control = {"period_s": period, "from": period_from, "pass_mark": pass_mark}
    return record, control, (success, None if success is None else success >= DRIVES)


def task_success(record: DeployRecord) -> tuple[float | None, str]:
    """The share of the deployment's episodes that did the task, and what counts as done: a
    kart env's finished laps; a gymnasium env's episodes whose return reaches its
    ``reward_threshold`` (None where the env has no threshold: nothing to judge)."""
    s = record.summary
    if record.env.track is not None:
        return s.laps, "finished laps"
    share = success_share(record.episodes, s.reward_threshold)
    if share is None:
        return None, f"none: {record.env.env} has no reward_threshold"
    return share, f"return >= the env's {s.reward_threshold:g}"


def build_report(
    deploy_dir: Path,
    ann_dir: Path | None,
    profiles: list[str] | None,
    host: str | None = None,
    sweep: Path | None = None,
    sanafe: bool = False,
    control_hz: float | None = None,
) -> dict[str, object]:
    """Everything the report says, as one JSON-ready record (a :class:`LifReport`, or a
    sigma-delta deployment's :class:`~snnkart.contract.report_record.SdReport`)."""
    record, control, (success, drives) = _deployment(deploy_dir, ann_dir, control_hz)
    period = control["period_s"]
    chips, digital, host_profile = _profiles(profiles, host)
    fair = host_profile or memory_first(digital)[0]
    if record.counts.sigma_delta is not None:
        if ann_dir is not None:
            raise ReportError(
                "--ann: a sigma-delta deployment is compared with the ANN of its own shape "
                "(fp32 and int8, memory-inclusive); run snnkart report without --ann"
            )
        sd = sd_report(record, deploy_dir, chips, host_profile, (success, drives), period, sanafe)
        sd["control"] = control
        sd["sweep"] = None if sweep is None else sweep_section(sweep, chips[0], fair, digital)
        return {"schema": REPORT_SCHEMA, **sd}
    snn = replace(SnnCounts.of_deploy(record), period_s=period)
    net = snn.net
    anns = _anns(snn, record, ann_dir)
    report: LifReport = {
        "schema": REPORT_SCHEMA,
        "deploy": deploy_section(record, deploy_dir, snn.episodes, snn.env_steps),
        "drives": drives,
        "control": control,
        "network": {
            "n_in": net.n_in,
            "obs_dim": net.obs_dim,
            "sizes": list(net.sizes),
            "n_out": net.n_out,
            "num_steps": net.num_steps,
            "encoding": net.encoding,
        },
        "snn": _snn_section(snn, record, success),
        "ann": {key: _ann_section(a, task) for key, (a, task) in anns.items()},
        "host_profile": host_profile.name if host_profile else "the ANN's profile",
        "profiles": {
            p.name: p.describe()
            for p in [*chips, *digital, *([host_profile] if host_profile else [])]
        },
        "comparisons": comparisons(
            snn, anns, chips, digital, host_profile, record.summary.mean_return
        ),
        "uncertainty": method(),
        "sensitivity": sensitivity(snn, anns["same_width"][0], chips, digital, host_profile),
        "sweep": None if sweep is None else _sweep(sweep, chips[0], fair, digital),
        "sanafe": cast(SanafeSection, sanafe_section(record, deploy_dir, snn)),  # 2nd chip model
    }
    state = stateful_note(record)
    if state is not None:
        report["state"] = cast(StateNote, state)
    return dict(report)  # a plain dict: the document writers take any JSON mapping


def _sweep(path: Path, chip: Profile, host: Profile, digital: list[Profile]) -> Sweep:
    """The study's runs priced (:func:`sweep_section`, which writes this record)."""
    return cast(Sweep, sweep_section(path, chip, host, digital))


def run_report(
    deploy_dir: Path,
    ann_dir: Path | None,
    profiles: list[str] | None,
    out: Path | None,
    reporter: Reporter,
    host: str | None = None,
    sweep: Path | None = None,
    step: int = 0,
    sanafe: bool = False,
    control_hz: float | None = None,
) -> dict[str, object]:
    """Build the report and write ``report.json``, ``report.md`` and ``report.html``."""
    from snnkart.report.document import write_report

    out = out or (deploy_dir if deploy_dir.is_dir() else deploy_dir.parent)
    with reporter.progress("report", 3) as task:
        report = build_report(deploy_dir, ann_dir, profiles, host, sweep, sanafe, control_hz)
        task.advance()
        lif = report.get("kind") is None  # the raster figure is a LIF policy's
        trace = _trace(report, deploy_dir, step, reporter) if lif else None
        task.advance()
        paths = write_report(report, out, trace)
        task.advance()
    reporter.message(f"report written to {paths['html']} (and report.json, report.md)")
    return report


def _trace(report: Mapping[str, object], deploy_dir: Path, step: int, reporter: Reporter) -> Any:
    """The raster of one env step on the deployment's track, if its NIR file is still there
    (as recorded, or beside the deployment directory)."""
    from snnkart.errors import SnnkartError
    from snnkart.eval.trace import trace_step

    d = lif_report(report)["deploy"]
    recorded = Path(d.get("nir_file") or "policy.nir")
    base = deploy_dir if deploy_dir.is_dir() else deploy_dir.parent
    found = next(
        (p for p in (recorded, base.parent / recorded.name, base / recorded.name) if p.is_file()),
        None,
    )
    if found is None:
        reporter.message(f"note: no raster figure: the NIR file {recorded} is not there")
        return None
    track = None if d.get("track_source") in ("embedded", None) else d.get("track_given")
    try:
        return trace_step(found, step, seed=d["first_seed"], track=track)
    except SnnkartError as exc:
        reporter.message(f"note: no raster figure: {exc}")
        return None
