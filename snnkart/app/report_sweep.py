"""``snnkart report --sweep study.json``: a study's runs priced, for the accuracy-energy figure
(not the deployment's own numbers)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from snnkart.contract.records import Reading, RecordError, from_data
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.pricing import ann_terms, terms, total
from snnkart.energy.profiles import Profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.errors import ReportError
from snnkart.report.study_record import STUDY, RunRecord, StudyRecord


def _read_sweep(path: Path) -> StudyRecord:
    """A study record (``snnkart study``'s ``study.json``), refused with a one-line reason."""
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ReportError(f"--sweep {path}: not a readable study.json ({exc})") from exc
    if isinstance(data, dict) and data.get("benchmark") == "bench_sparsity":
        raise ReportError(
            f"--sweep {path}: written by bench_sparsity, an older snnkart; run "
            "`snnkart study studies/sparsity.toml` again and pass its study.json"
        )
    if not isinstance(data, dict) or not str(data.get("schema", "")).startswith(
        STUDY.tag_of(0)[:-1]
    ):
        schema = data.get("schema") if isinstance(data, dict) else None
        raise ReportError(
            f"--sweep {path}: not a study.json (schema {schema!r}); pass the "
            "study.json of `snnkart study`"
        )
    source = f"--sweep {path}"
    try:  # the JSON parsed above, read as the record (not written out and parsed again)
        return from_data(StudyRecord, data, Reading(STUDY, source, STUDY.version_of(data, source)))
    except RecordError as exc:
        raise ReportError(str(exc)) from None


def _point(run: RunRecord, label: str, chip: Profile, host: Profile) -> dict[str, Any]:
    """One run priced (:func:`~snnkart.energy.pricing.terms`, whatever its family);
    ``label`` is its kind's name for it (:meth:`StudySettings.run_label`)."""
    base = {"point": run.variant or f"{run.env}-{run.policy}", "seed": run.seed}
    kind = {"kind": label}
    if run.sigma_delta_counts is not None:
        sd = SigmaDeltaCounts.from_dict(run.sigma_delta_counts)
        return {
            **base,
            "num_steps": 1,
            "sizes": list(sd.sizes),
            "success_rate": run.eval_success_rate,
            "energy_pj": total(terms(sd, chip, host)),
            **kind,
        }
    counts = run.eval_counts_per_step
    assert counts is not None
    return {
        **base,
        "num_steps": counts.num_steps,
        "sizes": counts.sizes,
        "success_rate": run.eval_success_rate,
        "energy_pj": total(terms(SnnCounts.of_sweep(counts), chip, host)),
        **kind,
    }


def _ann_shape(runs: list[RunRecord]) -> tuple[str, AnnCounts]:
    """The ANN the runs are compared with: 64-64 on the first LIF run's inputs and outputs (as
    before sigma-delta runs), else the first sigma-delta run's own shape."""
    lif = [r.eval_counts_per_step for r in runs if r.sigma_delta_counts is None]
    if lif and lif[0] is not None:
        first = lif[0]
        obs_dim = first.network.n_in // (first.population or 1)
        return "64-64", AnnCounts((obs_dim, 64, 64, first.network.n_out))
    sd = SigmaDeltaCounts.from_dict(runs[0].sigma_delta_counts or {})
    return "-".join(map(str, sd.sizes)), AnnCounts((sd.n_in, *sd.sizes, sd.n_out), sd.action_mode)


def sweep_section(
    path: Path, chip: Profile, host: Profile, digital: list[Profile]
) -> dict[str, Any]:
    """A study's SNN runs, priced: each run's energy per inference on ``chip`` (host work on
    ``host``) from the counts of its evaluation on the reference (a sigma-delta run's with
    :func:`snnkart.energy.pricing.terms`), with its kind (:meth:`~snnkart.report.study_record.StudySettings.run_label`: from the settings it trained with), and the
    ANN's (:func:`_ann_shape`) on each digital profile. A run's point is its variant (its cell
    without variants)."""
    record = _read_sweep(path)
    if record.schema == STUDY.tag_of(1):
        raise ReportError(
            f"--sweep {path}: written by an older snnkart (no counts per env step); run "
            "`snnkart study` with its config again (runs and evaluations are reused)"
        )
    runs = [
        r
        for r in record.runs
        if r.eval_counts_per_step is not None or r.sigma_delta_counts is not None
    ]
    if not runs:
        raise ReportError(
            f"--sweep {path}: no run of this study has counts (SNNs evaluated on the reference); "
            "run a study of spiking policies, e.g. studies/sparsity.toml"
        )
    label = record.study.run_label
    points = [_point(r, label(r.track, r.env, r.policy, r.variant), chip, host) for r in runs]
    shape, ann = _ann_shape(runs)
    ann_pj = {f"{shape} on {d.name}": total(ann_terms(ann, d)) for d in digital}
    envs = sorted({r.env for r in runs})
    commit = (record.machine or {}).get("commit")
    return {
        "file": str(path),
        "env": ", ".join(envs),
        "commit": commit,
        "profile": chip.name,
        "host_profile": host.name,
        "points": points,
        "ann_64_64_pj": ann_pj,
    }
