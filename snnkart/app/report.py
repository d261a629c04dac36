"""``snnkart report``: the deployed spiking policy's energy against the ANN baseline.

Counts come from the deployment (``deploy.json``: Lava's or the reference's counts, proven equal
step by step); prices from hardware profiles; every energy in ``report.json`` is a list of
``count x price`` terms naming the profile entry and its source.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

from snnkart.app.report_sd import sd_report, stateful_note
from snnkart.app.report_sweep import sweep_section
from snnkart.app.reporter import Reporter
from snnkart.app.sanafe_report import sanafe_section
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.records import RecordError, to_data
from snnkart.contract.report_record import (
    AnnRunTask,
    AnnSection,
    ComparisonRow,
    DeploySection,
    LifReport,
    Memory,
    Sensitivity,
    SensitivityRow,
    SnnSection,
    StateNote,
    Static,
    Sweep,
    Task,
    TermRecord,
    lif_report,
)
from snnkart.contract.sanafe_record import SanafeSection
from snnkart.energy.break_even import break_even
from snnkart.energy.counts import AnnCounts, SnnCounts, placement
from snnkart.energy.pricing import (
    Comparison,
    Term,
    ann_terms,
    breakdown,
    not_published,
    terms,
    total,
)
from snnkart.energy.profiles import (
    DEFAULT_CHIPS,
    DEFAULT_DIGITAL,
    Profile,
    load_profile,
    memory_row,
)
from snnkart.energy.uncertainty import joint, method
from snnkart.errors import ReportError

REPORT_SCHEMA = "snnkart/report/v3"
"""v2: each comparison's ``uncertainty`` and its break-even in T and width; the top-level
``uncertainty`` says how the prices were sampled. v3: a sigma-delta deployment's report
(``kind: "sigma-delta"``, :mod:`snnkart.app.report_sd`); a stateful LIF deployment's ``state``;
a LIF report otherwise as in v2."""
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


def _memory_first(digital: list[Profile]) -> list[Profile]:
    """The memory-inclusive digital profiles first: the fair baseline leads the sensitivity."""
    return sorted(digital, key=lambda p: not p.prices_memory)


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
        results = run_episodes(gym_env, TorchPredictor(run, seed=record.first_seed),
                               episodes, record.first_seed)  # fmt: skip
    finally:
        gym_env.close()
    summary = EvalSummary.of(results)
    steps = sum(r.length for r in results)
    task: AnnRunTask = {
        "run": str(ann_dir), "global_step": run.meta.get("global_step"),
        "episodes": episodes, "first_seed": record.first_seed,
        "success_rate": summary.success_rate, "mean_lap_time": summary.mean_lap_time,
        "mean_return": summary.mean_return, "steps_per_episode": steps / episodes,
        "int8": int8_task(run, lambda: run.config.make_env(track=run.track),
                          record.first_seed, episodes),
    }  # fmt: skip
    return AnnCounts(widths, run.config.action_mode, "ANN run"), task


def _snn_section(snn: SnnCounts, record: DeployRecord) -> SnnSection:
    net, s = snn.net, record.summary
    return {
        "task": {
            "success_rate": s.success_rate,
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
    return {"label": ann.label, "widths": list(ann.widths), "macs": ann.macs,
            "neurobench": ann.neurobench(), "footprint": ann.footprint(), "task": task}  # fmt: skip


def _comparisons(snn: SnnCounts, anns: dict[str, tuple[AnnCounts, AnnRunTask | None]],
                 chips: list[Profile], digital: list[Profile], host: Profile | None,
                 snn_return: float) -> list[ComparisonRow]:  # fmt: skip
    """Every SNN profile against every ANN on every digital profile: energy per inference, per
    episode and per unit of return (None when the mean return is not positive, or for an ANN
    that was not run), the ratio with every price range sampled together, and the break-even
    in spike density, T and width. The SNN's host work is priced on ``host``, else on the ANN's
    profile."""
    from snnkart.eval.ann_int8 import task_on

    rows: list[ComparisonRow] = []
    for chip in chips:
        for key, (ann, float_task) in anns.items():
            for dig in digital:
                task = task_on(float_task, dig.name)  # int8 datapath: the int8 ANN's, measured
                s_terms = terms(snn, chip, host or dig)
                e_snn = total(s_terms)
                a_terms = ann_terms(ann, dig)
                e_ann = total(a_terms)
                if e_ann <= 0:
                    raise ReportError(
                        f"profile {dig.name} prices the ANN at 0 pJ (every price it uses is 0), "
                        "so the SNN/ANN ratio is undefined; give it non-zero prices"
                    )
                cmp = Comparison(snn, ann, chip, host or dig, dig)
                where = placement(snn.net.sizes, chip)
                rows.append({
                    "snn_profile": chip.name, "host_profile": (host or dig).name, "ann": key,
                    "ann_profile": dig.name, "snn_pj": e_snn, "ann_pj": e_ann,
                    "ratio": e_snn / e_ann if e_ann else None,
                    "memory": _memory(snn, ann, host or dig, dig),
                    "placement": where.as_dict() if where else None,
                    "static": cast(Static, cmp.with_static()),  # the record it writes
                    "not_published": not_published(chip, host or dig, dig),
                    "ann_success_rate": task["success_rate"] if task else None,
                    "ann_success": _ann_success(task, float_task),
                    "snn_per_episode_pj": e_snn * snn.steps_per_episode,
                    "ann_per_episode_pj": e_ann * task["steps_per_episode"] if task else None,
                    "snn_per_return_pj": _per_return(e_snn * snn.steps_per_episode, snn_return),
                    "ann_per_return_pj": _per_return(
                        e_ann * task["steps_per_episode"], task["mean_return"]
                    ) if task else None,
                    "snn_breakdown_pj": breakdown(s_terms), "ann_breakdown_pj": breakdown(a_terms),
                    "snn_terms": _records(s_terms), "ann_terms": _records(a_terms),
                    "break_even": break_even(cmp),
                    "uncertainty": joint(s_terms, a_terms, (chip, host or dig, dig)),
                })  # fmt: skip
    return rows


def _records(priced: Sequence[Term]) -> list[TermRecord]:
    """The terms as ``report.json`` lists them (:meth:`Term.as_dict` writes the record)."""
    return [cast(TermRecord, t.as_dict()) for t in priced]


def _memory(snn: SnnCounts, ann: AnnCounts, host: Profile, digital: Profile) -> Memory:
    """Each side's weight footprint and the memory array it is read from (its own row)."""
    snn_bytes = host.weight_bytes(snn.net.host_parameters)
    ann_bytes = digital.weight_bytes(ann.parameters)
    return {"snn_host_weight_bytes": snn_bytes, "snn_host_array": memory_row(snn_bytes),
            "ann_weight_bytes": ann_bytes, "ann_array": memory_row(ann_bytes)}  # fmt: skip


def _ann_success(task: Task | None, float_task: AnnRunTask | None) -> str:
    """Where the ANN's success on a profile comes from."""
    if task is None:
        return "not run"
    if task is not float_task:
        return "measured: the ANN quantised to int8, on the deployment's episodes"
    return "measured: the float ANN, on the deployment's episodes"


def _per_return(energy: float, mean_return: float) -> float | None:
    return energy / mean_return if mean_return > 0 else None


def _deploy_section(record: DeployRecord, deploy_dir: Path, snn: SnnCounts) -> DeploySection:
    """Where the counts come from: the deployment, its env and track, and its parity."""
    return {
        "file": str(deploy_dir),
        "backend": record.backend,
        "precision": record.precision,
        "nir_file": record.nir_file,
        "env": record.env.env,
        "track": record.env.track,
        "track_given": record.env.track_given,
        "track_source": record.env.track_source,
        "episodes": snn.episodes,
        "env_steps": snn.env_steps,
        "first_seed": record.first_seed,
        "parity": to_data(record.parity),
    }


def _anns(snn: SnnCounts, record: DeployRecord,
          ann_dir: Path | None) -> dict[str, tuple[AnnCounts, AnnRunTask | None]]:  # fmt: skip
    """The ANN baselines: the same widths (taking the observation itself, not a population
    code of it), and the user's ANN run if given."""
    net = snn.net
    widths = (net.obs_dim, *net.sizes, net.n_out) if net.readout else (net.obs_dim, *net.sizes)
    anns: dict[str, tuple[AnnCounts, AnnRunTask | None]] = {
        "same_width": (AnnCounts(widths, net.action_mode,
                                 f"ANN {'-'.join(map(str, net.sizes))} (same widths)"), None),
    }  # fmt: skip
    if ann_dir is not None:
        anns["run"] = _ann_run(ann_dir, record)
    return anns


def build_report(deploy_dir: Path, ann_dir: Path | None, profiles: list[str] | None,
                 host: str | None = None, sweep: Path | None = None,
                 sanafe: bool = False) -> dict[str, object]:  # fmt: skip
    """Everything the report says, as one JSON-ready record (a :class:`LifReport`, or a
    sigma-delta deployment's :class:`~snnkart.contract.report_record.SdReport`)."""
    record = read_deploy(deploy_dir)
    chips, digital, host_profile = _profiles(profiles, host)
    fair = host_profile or _memory_first(digital)[0]
    if record.counts.sigma_delta is not None:
        if ann_dir is not None:
            raise ReportError(
                "--ann: a sigma-delta deployment is compared with the ANN of its own shape "
                "(fp32 and int8, memory-inclusive); run snnkart report without --ann"
            )
        sd = sd_report(record, deploy_dir, chips, host_profile, DRIVES, sanafe)
        sd["sweep"] = None if sweep is None else sweep_section(sweep, chips[0], fair, digital)
        return {"schema": REPORT_SCHEMA, **sd}
    snn = SnnCounts.of_deploy(record)
    net = snn.net
    anns = _anns(snn, record, ann_dir)
    success = record.summary.success_rate
    report: LifReport = {
        "schema": REPORT_SCHEMA,
        "deploy": _deploy_section(record, deploy_dir, snn),
        "drives": success >= DRIVES,
        "network": {
            "n_in": net.n_in,
            "obs_dim": net.obs_dim,
            "sizes": list(net.sizes),
            "n_out": net.n_out,
            "num_steps": net.num_steps,
            "encoding": net.encoding,
        },
        "snn": _snn_section(snn, record),
        "ann": {key: _ann_section(a, task) for key, (a, task) in anns.items()},
        "host_profile": host_profile.name if host_profile else "the ANN's profile",
        "profiles": {
            p.name: p.describe()
            for p in [*chips, *digital, *([host_profile] if host_profile else [])]
        },
        "comparisons": _comparisons(
            snn, anns, chips, digital, host_profile, record.summary.mean_return
        ),
        "uncertainty": method(),
        "sensitivity": _sensitivity(snn, anns["same_width"][0], chips, digital, host_profile),
        "sweep": None if sweep is None else _sweep(sweep, chips[0], fair, digital),
        "sanafe": cast(SanafeSection, sanafe_section(record, deploy_dir, snn)),  # 2nd chip model
    }
    state = stateful_note(record)
    if state is not None:
        report["state"] = cast(StateNote, state)
    return dict(report)  # a plain dict: the document writers take any JSON mapping


def _sensitivity(
    snn: SnnCounts,
    ann: AnnCounts,
    chips: list[Profile],
    digital: list[Profile],
    host: Profile | None,
) -> list[Sensitivity]:
    """One price at a time, for each chip against the same-width ANN on each digital profile
    (the memory-inclusive first); :meth:`Comparison.sensitivity` writes the rows."""
    return [
        {
            "snn_profile": c.name,
            "ann_profile": d.name,
            "rows": cast(list[SensitivityRow], Comparison(snn, ann, c, host or d, d).sensitivity()),
        }
        for c in chips
        for d in _memory_first(digital)
    ]


def _sweep(path: Path, chip: Profile, host: Profile, digital: list[Profile]) -> Sweep:
    """The study's runs priced (:func:`sweep_section`, which writes this record)."""
    return cast(Sweep, sweep_section(path, chip, host, digital))


def run_report(deploy_dir: Path, ann_dir: Path | None, profiles: list[str] | None,
               out: Path | None, reporter: Reporter, host: str | None = None,
               sweep: Path | None = None, step: int = 0,
               sanafe: bool = False) -> dict[str, object]:  # fmt: skip
    """Build the report and write ``report.json``, ``report.md`` and ``report.html``."""
    from snnkart.report.document import write_report

    out = out or (deploy_dir if deploy_dir.is_dir() else deploy_dir.parent)
    with reporter.progress("report", 3) as task:
        report = build_report(deploy_dir, ann_dir, profiles, host, sweep, sanafe)
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
    found = next((p for p in (recorded, base.parent / recorded.name, base / recorded.name)
                  if p.is_file()), None)  # fmt: skip
    if found is None:
        reporter.message(f"note: no raster figure: the NIR file {recorded} is not there")
        return None
    track = None if d.get("track_source") in ("embedded", None) else d.get("track_given")
    try:
        return trace_step(found, step, seed=d["first_seed"], track=track)
    except SnnkartError as exc:
        reporter.message(f"note: no raster figure: {exc}")
        return None
