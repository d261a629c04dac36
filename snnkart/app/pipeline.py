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

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import Progress

from snnkart import faults
from snnkart.io import atomic_path

DEMO_ENV = "grid"
DEMO_TRACK = "small_S"
DEMO_STEPS = 400_000
DEMO_SEED = 1
QUANT_EPISODES = 50
EVAL_SEED = 10_000

console = Console()


def _train(run_dir: Path, steps: int) -> int:
    from snnkart.app.train import run_training
    from snnkart.rl.config import load_config, read_run_config

    if (run_dir / "checkpoint.pt").exists():
        meta = (
            json.loads((run_dir / "checkpoint.json").read_text())
            if (run_dir / "checkpoint.json").exists()
            else {}
        )
        if meta.get("global_step", 0) >= steps:
            console.print(f"[1/4] using the trained run in {run_dir}")
            return 0
        console.print(f"[1/4] resuming the run in {run_dir}")
        return run_training(read_run_config(run_dir), run_dir, resume=True)
    console.print(
        f"[1/4] training an SNN on {DEMO_ENV}/{DEMO_TRACK} for {steps:,} steps -> {run_dir}"
    )
    cfg = load_config(
        overrides={
            "env": DEMO_ENV, "track": DEMO_TRACK, "policy": "snn",
            "total_steps": steps, "seed": DEMO_SEED,
        }
    )  # fmt: skip
    return run_training(cfg, run_dir, resume=False)


def _score(predictor: Any, env: Any, label: str, episodes: int) -> Any:
    from snnkart.eval.episodes import EvalSummary, run_episodes

    with Progress(console=console, transient=True) as progress:
        task = progress.add_task(label, total=episodes)
        results = run_episodes(
            env, predictor, episodes, EVAL_SEED, on_episode=lambda r: progress.advance(task)
        )
    return EvalSummary.of(results)


def run_pipeline(
    out: Path, steps: int = DEMO_STEPS, lava_episodes: int = 5, episodes: int = QUANT_EPISODES
) -> dict[str, Any] | None:
    """Run the four steps; None if training was interrupted (Ctrl-C saves a checkpoint, and
    running the command again resumes)."""
    with faults.caught():  # Ctrl-C and SIGTERM are taken between env steps
        return _run(out, steps, lava_episodes, episodes)


def _run(out: Path, steps: int, lava_episodes: int, episodes: int) -> dict[str, Any] | None:
    from snnkart.backends.reference import NIRReference
    from snnkart.cli.main import _deploy_and_print
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.run import TorchPredictor, load_run

    out.mkdir(parents=True, exist_ok=True)
    run_dir = out / "snn"
    if _train(run_dir, steps) != 0:
        console.print(f"training interrupted; run the same command again to resume {run_dir}")
        return None

    console.print("[2/4] exporting the spiking actor to NIR")
    run = load_run(run_dir)
    nir_path, manifest_file = export_nir(run, out / "policy.nir")
    console.print(f"      {nir_path}\n      {manifest_file}")

    console.print(f"[3/4] torch policy vs its fixed-point twin on the same {episodes} episodes")
    env = run.config.make_env(track=run.track)
    try:
        torch_summary = _score(TorchPredictor(run, seed=EVAL_SEED), env, "torch", episodes)
        fixed_summary = _score(
            NIRReference(nir_path, "fixed", seed=EVAL_SEED), env, "fixed point", episodes
        )
    finally:
        env.close()
    retained = (
        fixed_summary.success_rate / torch_summary.success_rate
        if torch_summary.success_rate > 0
        else float("nan")
    )
    console.print(
        f"      success: torch {torch_summary.success_rate:.0%}, fixed point "
        f"{fixed_summary.success_rate:.0%} (keeps {retained:.0%})"
    )
    quant = {
        "episodes": episodes,
        "first_seed": EVAL_SEED,
        "torch": asdict(torch_summary),
        "fixed_reference": asdict(fixed_summary),
        "success_retained": retained,
    }
    with atomic_path(out / "quantization.json") as tmp:
        tmp.write_text(json.dumps(quant, indent=2) + "\n")

    console.print(f"[4/4] deploying on lava-sim ({lava_episodes} episodes fixed, 2 float)")
    records = {}
    for precision, episodes in (("fixed", lava_episodes), ("float", 2)):
        records[precision] = _deploy_and_print(
            nir_path, "lava-sim", precision, episodes, EVAL_SEED, None, None,
            out / f"deploy-lava-sim-{precision}",
        )  # fmt: skip
    console.print(
        f"\nfiles: run {run_dir}, policy {nir_path}, quantisation {out / 'quantization.json'}, "
        f"Lava results {out}/deploy-lava-sim-{{fixed,float}}/deploy.json"
    )
    return {"quantization": quant, "deploy": records}
