"""``snnkart export``: a trained policy as a NIR graph and the manifest beside it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import fail
from snnkart.errors import SnnkartError
from snnkart.rl import kinds


def export(
    run_dir: Annotated[Path, typer.Argument(help="a training run (snn, sdnn, or a ReLU ann)")],
    nir_format: Annotated[
        bool, typer.Option("--nir", help="export to NIR (the only format)")
    ] = False,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="NIR file to write")] = None,
    checkpoint: Annotated[Path | None, typer.Option(help="default: the run's latest")] = None,
    sigma_delta: Annotated[
        bool,
        typer.Option(
            "--sigma-delta",
            help="convert a ReLU ANN run to a sigma-delta network (no retraining); sdnn runs "
            "export as one anyway",
        ),
    ] = False,
    target: Annotated[
        float | None,
        typer.Option(
            "--sigma-delta-target",
            help="sigma-delta: share of recorded steps whose action the calibrated thresholds keep",
            show_default="the run's sdnn.calibration_target, 0.95",
        ),
    ] = None,
    episodes: Annotated[
        int | None,
        typer.Option(
            "--calibration-episodes",
            help="sigma-delta: seeded episodes recorded for the calibration",
            show_default="the run's sdnn.calibration_episodes, 3",
        ),
    ] = None,
) -> None:
    """Export a policy to NIR, with a manifest of what NIR does not carry: a spiking policy,
    or a sigma-delta one (a sdnn run, or a ReLU ANN with --sigma-delta) as its affine layers
    with calibrated message thresholds."""
    if not nir_format:
        fail("choose an export format: --nir")
    from snnkart.export.nir_export import export_nir
    from snnkart.export.sigma_delta_export import Calibration, export_sigma_delta
    from snnkart.rl.trained import load_run

    try:
        options = Calibration(target, episodes)
        run = load_run(run_dir, checkpoint)
        path = out or run_dir / "policy.nir"
        if sigma_delta or kinds.family(run.config.policy).graded:
            nir_path, manifest = export_sigma_delta(run, path, options)
        elif target is not None or episodes is not None:
            fail("--sigma-delta-target and --calibration-episodes are for sigma-delta exports")
        else:
            nir_path, manifest = export_nir(run, path)
    except SnnkartError as exc:
        fail(str(exc))
    typer.echo(f"NIR graph written to {nir_path}\nmanifest written to {manifest}")
