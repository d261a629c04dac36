"""The main job (``snnkart demo``): train a spiking policy, export it to NIR, and drive the kart
with it on Lava's simulated Loihi, on built-in defaults.

Steps, each writing into ``out`` (default ``runs/demo``) and skipped when already complete:

1. ``snnkart train --env grid --track small_S --policy snn --steps 400000 --seed 1`` into
   ``out/snn`` (resumable; about 3 to 4 minutes here).
2. Score the torch policy and the fixed-point reference (the bit-exact twin of Lava fixed) on the
   same 50 seeded episodes: the quantisation's effect on the success rate.
3. ``snnkart export --nir`` to ``out/policy.nir`` (+ manifest).
4. ``snnkart deploy --backend lava-sim`` in fixed point and in float, each step checked against
   the numpy reference, results in ``out/deploy-lava-sim-<precision>/deploy.json``.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

from snnkart import faults
from snnkart.app.reporter import Reporter
from snnkart.io import write_json

DEMO_ENV = "grid"
DEMO_TRACK = "small_S"
DEMO_STEPS = 400_000
DEMO_SEED = 1
QUANT_EPISODES = 50
EVAL_SEED = 10_000


def run_pipeline(
    out: Path,
    reporter: Reporter,
    steps: int = DEMO_STEPS,
    lava_episodes: int = 5,
    episodes: int = QUANT_EPISODES,
) -> dict[str, Any] | None:
    """Run the four steps; None if training was interrupted (Ctrl-C saves a checkpoint, and
    running the command again resumes)."""
    with faults.caught():  # Ctrl-C and SIGTERM are taken between env steps
        out.mkdir(parents=True, exist_ok=True)
        run_dir = out / "snn"
        if _train(run_dir, steps, reporter) != 0:
            reporter.message(
                f"training interrupted; run the same command again to resume {run_dir}"
            )
            return None
        nir_path = _export(run_dir, out, reporter)
        quant = _quantisation(run_dir, nir_path, out, episodes, reporter)
        records = _deploy(nir_path, out, lava_episodes, reporter)
        reporter.message(
            f"\nfiles: run {run_dir}, policy {nir_path}, quantisation "
            f"{out / 'quantization.json'}, Lava results "
            f"{out}/deploy-lava-sim-{{fixed,float}}/deploy.json"
        )
        return {"quantization": quant, "deploy": records}


def _train(run_dir: Path, steps: int, reporter: Reporter) -> int:
    from snnkart.app.train import run_training
    from snnkart.rl.checkpoint import load_checkpoint
    from snnkart.rl.config import load_config, read_run_config

    if (run_dir / "checkpoint.pt").exists():
        _, meta = load_checkpoint(run_dir / "checkpoint.pt")
        if meta.get("global_step", 0) >= steps:
            reporter.message(f"[1/4] using the trained run in {run_dir}")
            return 0
        reporter.message(f"[1/4] resuming the run in {run_dir}")
        return run_training(read_run_config(run_dir), run_dir, reporter, resume=True)
    reporter.message(
        f"[1/4] training an SNN on {DEMO_ENV}/{DEMO_TRACK} for {steps:,} steps -> {run_dir}"
    )
    cfg = load_config(
        overrides={
            "env": DEMO_ENV, "track": DEMO_TRACK, "policy": "snn",
            "total_steps": steps, "seed": DEMO_SEED,
        }
    )  # fmt: skip
    return run_training(cfg, run_dir, reporter, resume=False)


def _export(run_dir: Path, out: Path, reporter: Reporter) -> Path:
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.trained import load_run

    reporter.message("[2/4] exporting the spiking actor to NIR")
    nir_path, manifest_file = export_nir(load_run(run_dir), out / "policy.nir")
    reporter.message(f"      {nir_path}\n      {manifest_file}")
    return nir_path


def _quantisation(
    run_dir: Path, nir_path: Path, out: Path, episodes: int, reporter: Reporter
) -> dict[str, Any]:
    """The torch policy and its fixed-point twin (the bit-exact twin of Lava fixed) on the
    same seeded episodes: the quantisation's effect on the success rate."""
    from snnkart.backends.reference import NIRReference
    from snnkart.eval.episodes import EvalSummary, run_episodes
    from snnkart.rl.trained import TorchPredictor, load_run

    reporter.message(f"[3/4] torch policy vs its fixed-point twin on the same {episodes} episodes")
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
    torch_rate, fixed_rate = summaries["torch"].success_rate, summaries["fixed point"].success_rate
    retained = fixed_rate / torch_rate if torch_rate > 0 else float("nan")
    reporter.message(
        f"      success: torch {torch_rate:.0%}, fixed point {fixed_rate:.0%} "
        f"(keeps {retained:.0%})"
    )
    quant = {
        "episodes": episodes,
        "first_seed": EVAL_SEED,
        "torch": asdict(summaries["torch"]),
        "fixed_reference": asdict(summaries["fixed point"]),
        "success_retained": retained,
    }
    write_json(out / "quantization.json", quant)
    return quant


def _deploy(
    nir_path: Path, out: Path, lava_episodes: int, reporter: Reporter
) -> dict[str, dict[str, Any]]:
    from snnkart.app.deploy import run_deploy_reported

    reporter.message(f"[4/4] deploying on lava-sim ({lava_episodes} episodes fixed, 2 float)")
    records = {}
    for precision, episodes in (("fixed", lava_episodes), ("float", 2)):
        records[precision] = run_deploy_reported(
            nir_path, "lava-sim", precision, episodes, EVAL_SEED, None, None,
            out / f"deploy-lava-sim-{precision}", reporter,
        )  # fmt: skip
    return records
