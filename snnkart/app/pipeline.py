"""The main job (``snnkart demo``): train a spiking policy and its same-width ANN baseline,
export the SNN to NIR, drive the kart with it on Lava's simulated Loihi, and report its energy
against the ANN's, on built-in defaults.

Steps, each writing into ``out`` (default ``runs/demo``) and skipped when already complete:

1. ``snnkart train --env grid --track small_S --policy snn --seed 101`` with the demo's settings
   (:data:`DEMO_SNN_SETTINGS`: the sparse point of the sparsity study) into
   ``out/snn`` (resumable).
2. ``snnkart train --policy ann`` (64-64, the SNN's widths) on the same track into ``out/ann``.
3. ``snnkart export --nir`` to ``out/policy.nir`` (+ manifest).
4. Score the torch policy and the fixed-point reference (the bit-exact twin of Lava fixed) on the
   same 50 seeded episodes: the quantisation's effect on the success rate.
5. ``snnkart deploy --backend lava-sim`` in fixed point and in float, each step checked against
   the numpy reference, results in ``out/deploy-lava-sim-<precision>/deploy.json``.
6. ``snnkart report`` of the fixed-point deployment against the ANN run, in ``out/report``.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import TypedDict

from snnkart import faults
from snnkart.app.reporter import Reporter
from snnkart.contract.deploy_record import DeployRecord
from snnkart.errors import UsageError
from snnkart.io import write_json
from snnkart.rl import kinds

DEMO_ENV = "grid"
DEMO_TRACK = "small_S"
DEMO_STEPS = 300_000
ANN_STEPS = 300_000
DEMO_SEED = 101
"""The main job's training seed: a reporting seed (docs/results.md), so the numbers it prints
and the README quotes from it are data no choice was made on."""
DEMO_SNN_SETTINGS: dict[str, object] = {"snn.num_steps": 4, "snn.rate_reg": 0.05}
"""The demo's own SNN settings on top of the grid SNN defaults (the per-env training defaults
stay as they are): T = 4 and a firing-rate penalty of 0.05, the sparse point of the sparsity
study (why: docs/decisions.md#demo-snn-sparsity)."""
QUANT_EPISODES = 50
EVAL_SEED = 10_000
SNN_RUN, ANN_RUN, POLICY_FILE, REPORT_DIR = "snn", "ann", "policy.nir", "report"
"""Where the main job writes in its ``out``: the SNN run, the ANN run, the exported SNN, the
report; beside them the quantisation's effect (:data:`QUANT_FILE`) and the Lava deployments."""
QUANT_FILE = "quantization.json"
PRECISIONS = ("fixed", "float")
"""The Lava deployments, each in ``out/deploy-lava-sim-<precision>``."""


def main_job_files() -> frozenset[str]:
    """Every name the main job writes in its ``out`` directory."""
    from snnkart.contract.manifest import manifest_path

    deploys = {f"deploy-lava-sim-{p}" for p in PRECISIONS}
    return frozenset(
        {
            SNN_RUN,
            ANN_RUN,
            POLICY_FILE,
            manifest_path(Path(POLICY_FILE)).name,
            QUANT_FILE,
            REPORT_DIR,
            *deploys,
        }
    )


def refuse_main_job_folder(path: Path, exported: bool) -> None:
    """Refuse a main job's ``out`` given where a run (or, ``exported``, a NIR file) is wanted,
    naming what to give instead; any other path passes."""
    if (path / "config.toml").exists() or not (path / SNN_RUN / "config.toml").is_file():
        return
    policy = path / POLICY_FILE if exported and (path / POLICY_FILE).is_file() else path / SNN_RUN
    raise UsageError(
        f"{path} is the main job's folder (snnkart demo), not a run: did you mean {policy} "
        f"(its SNN; the ANN baseline is {path / ANN_RUN})?"
    )


class Quantisation(TypedDict):
    """``quantization.json``: the torch policy and its fixed-point twin on the same episodes."""

    episodes: int
    first_seed: int
    torch: dict[str, object]  # an EvalSummary
    fixed_reference: dict[str, object]
    success_retained: float  # fixed point's success rate / torch's (NaN: torch's is 0)


class PipelineResult(TypedDict):
    """What the six steps made: the quantisation check, the deployments, the energy report."""

    quantization: Quantisation
    deploy: dict[str, DeployRecord]  # by precision
    report: dict[str, object]  # snnkart.app.report.build_report's


def run_pipeline(
    out: Path,
    reporter: Reporter,
    steps: int = DEMO_STEPS,
    lava_episodes: int = 20,
    episodes: int = QUANT_EPISODES,
    ann_steps: int = ANN_STEPS,
) -> PipelineResult | None:
    """Run the six steps; None if training was interrupted (Ctrl-C saves a checkpoint, and
    running the command again resumes)."""
    with faults.caught():  # Ctrl-C and SIGTERM are taken between env steps
        out.mkdir(parents=True, exist_ok=True)
        run_dir, ann_dir = out / SNN_RUN, out / ANN_RUN
        for i, (policy, where, n) in enumerate(
            (("snn", run_dir, steps), ("ann", ann_dir, ann_steps))
        ):
            if _train(policy, where, n, reporter, f"[{i + 1}/6]") != 0:
                reporter.message(
                    f"training interrupted; run the same command again to resume {where}"
                )
                return None
        nir_path = _export(run_dir, out, reporter)
        quant = _quantisation(run_dir, nir_path, out, episodes, reporter)
        records = _deploy(nir_path, out, lava_episodes, reporter)
        report = _report(out / "deploy-lava-sim-fixed", ann_dir, out / REPORT_DIR, reporter)
        reporter.message(
            f"\nfiles: runs {run_dir} and {ann_dir}, policy {nir_path}, quantisation "
            f"{out / QUANT_FILE}, Lava results "
            f"{out}/deploy-lava-sim-{{fixed,float}}/deploy.json, report {out / REPORT_DIR}"
        )
        return {"quantization": quant, "deploy": records, "report": report}


def _train(policy: str, run_dir: Path, steps: int, reporter: Reporter, stage: str) -> int:
    from snnkart.app.train import run_training
    from snnkart.rl.checkpoint import load_checkpoint
    from snnkart.rl.config import load_config, read_run_config

    if (run_dir / "checkpoint.pt").exists():
        _, meta = load_checkpoint(run_dir / "checkpoint.pt")
        if meta.get("global_step", 0) >= steps:
            reporter.message(f"{stage} using the trained run in {run_dir}")
            return 0
        reporter.message(f"{stage} resuming the run in {run_dir}")
        return run_training(read_run_config(run_dir), run_dir, reporter, resume=True)
    spiking = kinds.family(policy).spiking
    what = "an SNN" if spiking else "the same-width ANN baseline"
    reporter.message(
        f"{stage} training {what} on {DEMO_ENV}/{DEMO_TRACK} for {steps:,} steps -> {run_dir}"
    )
    extra = DEMO_SNN_SETTINGS if spiking else {}
    cfg = load_config(
        overrides={
            "env": DEMO_ENV,
            "track": DEMO_TRACK,
            "policy": policy,
            "total_steps": steps,
            "seed": DEMO_SEED,
            **extra,
        }
    )
    return run_training(cfg, run_dir, reporter, resume=False)


def _export(run_dir: Path, out: Path, reporter: Reporter) -> Path:
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.trained import load_run

    reporter.message("[3/6] exporting the spiking actor to NIR")
    nir_path, manifest_file = export_nir(load_run(run_dir), out / POLICY_FILE)
    reporter.message(f"      {nir_path}\n      {manifest_file}")
    return nir_path


def _quantisation(
    run_dir: Path, nir_path: Path, out: Path, episodes: int, reporter: Reporter
) -> Quantisation:
    """The torch policy and its fixed-point twin (the bit-exact twin of Lava fixed) on the
    same seeded episodes: the quantisation's effect on the success rate."""
    from snnkart.backends.reference import NIRReference
    from snnkart.eval.episodes import EvalSummary, run_episodes
    from snnkart.rl.trained import TorchPredictor, load_run

    reporter.message(f"[4/6] torch policy vs its fixed-point twin on the same {episodes} episodes")
    run = load_run(run_dir)
    env = run.config.make_env(track=run.track)
    summaries = {}
    try:
        for label, predictor in (
            ("torch", TorchPredictor(run, seed=EVAL_SEED)),
            ("fixed point", NIRReference(nir_path, "fixed", seed=EVAL_SEED)),
        ):
            with reporter.progress(label, episodes) as task:
                results = run_episodes(
                    env, predictor, episodes, EVAL_SEED, on_episode=lambda r: task.advance()
                )
            summaries[label] = EvalSummary.of(results)
    finally:
        env.close()
    torch_rate, fixed_rate = summaries["torch"].laps, summaries["fixed point"].laps
    retained = fixed_rate / torch_rate if torch_rate > 0 else float("nan")
    reporter.message(
        f"      success: torch {torch_rate:.0%}, fixed point {fixed_rate:.0%} "
        f"(keeps {retained:.0%})"
    )
    quant: Quantisation = {
        "episodes": episodes,
        "first_seed": EVAL_SEED,
        "torch": asdict(summaries["torch"]),
        "fixed_reference": asdict(summaries["fixed point"]),
        "success_retained": retained,
    }
    write_json(out / QUANT_FILE, quant)
    return quant


def _deploy(
    nir_path: Path, out: Path, lava_episodes: int, reporter: Reporter
) -> dict[str, DeployRecord]:
    from snnkart.app.deploy import run_deploy_reported
    from snnkart.eval.request import DeployRequest

    reporter.message(f"[5/6] deploying on lava-sim ({lava_episodes} episodes fixed, 2 float)")
    records = {}
    for precision, episodes in zip(PRECISIONS, (lava_episodes, 2), strict=True):
        request = DeployRequest(
            nir_path,
            "lava-sim",
            precision,
            episodes,
            EVAL_SEED,
            out=out / f"deploy-lava-sim-{precision}",
        )
        records[precision] = run_deploy_reported(request, reporter)
    return records


def _report(deploy_dir: Path, ann_dir: Path, out: Path, reporter: Reporter) -> dict[str, object]:
    from snnkart.app.report import run_report

    reporter.message("[6/6] energy report: the SNN on Loihi-class profiles vs the ANN baseline")
    return run_report(deploy_dir, ann_dir, None, out, reporter)
