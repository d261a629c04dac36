"""``snnkart report`` and ``snnkart plot``: the energy report and the figures of a deployed
policy."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.console import ConsoleReporter, print_headline, print_sd_answer
from snnkart.cli.guard import ForceOpt, guard, refuse_other_files

ControlHzOpt = Annotated[
    float | None,
    typer.Option(
        "--control-hz",
        help="decisions per second, for static power and average power (default: the env's "
        "own rate: 60 Hz for the kart envs, a gymnasium env's render_fps)",
    ),
]


def report(
    deploy_dir: Annotated[Path, typer.Argument(help="a deployment: the --out of snnkart deploy")],
    ann: Annotated[
        Path | None, typer.Option("--ann", help="an ANN run to compare with (trained, evaluated)")
    ] = None,
    profile: Annotated[
        list[str] | None,
        typer.Option(
            "--profile",
            "-p",
            help="hardware profile name or TOML file (repeat); default: every built-in one",
        ),
    ] = None,
    host_profile: Annotated[
        str | None,
        typer.Option(
            help="digital profile pricing the SNN's host-side work (default: the "
            "profile of the ANN it is compared with)"
        ),
    ] = None,
    sweep: Annotated[
        Path | None,
        typer.Option(
            help="a study.json of SNN variants (studies/sparsity.toml): the accuracy-energy figure"
        ),
    ] = None,
    step: Annotated[int, typer.Option(help="env step shown in the raster figure")] = 20,
    sanafe: Annotated[
        bool,
        typer.Option(
            "--sanafe",
            help="a sigma-delta deployment: replay its messages on SANA-FE's Loihi model and "
            "check the goal there too (a LIF deployment runs SANA-FE whenever it is installed)",
        ),
    ] = False,
    control_hz: ControlHzOpt = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="directory (default: the deployment's)")
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Energy per inference and per episode of the deployed spiking policy against the ANN
    baseline on hardware profiles, with the task performance of both: report.json, .md, .html."""
    from snnkart.app.report import run_report
    from snnkart.report.document import REPORT_FILES

    if out is not None:  # its default, the deployment's directory, holds the deployment too
        refuse_other_files(out, {*REPORT_FILES, "deploy.json"}, force)

    reporter = ConsoleReporter()
    record = guard(
        lambda: run_report(
            deploy_dir, ann, profile, out, reporter, host_profile, sweep, step, sanafe, control_hz
        )
    )
    _print(record)


def _print(record: dict[str, object]) -> None:
    """The report's headline: a sigma-delta report's answer, else the LIF energy table."""
    from snnkart.report.document import headline

    if record.get("kind") == "sigma-delta":
        from snnkart.report.first_screen import sd_sentence
        from snnkart.report.sigma_delta_document import chip_rows

        print_sd_answer(record, sd_sentence(record), chip_rows(record))
    else:
        print_headline(record, headline(record))


plot_app = typer.Typer(help="Figures of a deployed policy.", no_args_is_help=True)


@plot_app.command("raster")
def plot_raster(
    nir_file: Annotated[Path, typer.Argument(help="policy.nir (its manifest beside it)")],
    step: Annotated[int, typer.Option(help="env step of the episode to show (0-based)")] = 20,
    seed: Annotated[int, typer.Option(help="seed of the episode")] = 10_000,
    track: Annotated[
        str | None, typer.Option("--track", "-t", help="default: the manifest's")
    ] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="PNG to write")] = Path("raster.png"),
) -> None:
    """Spike raster and membrane traces of every layer for one env step (float32 reference)."""
    from snnkart.app.plot import run_plot_raster

    guard(lambda: run_plot_raster(nir_file, step, seed, track, out, ConsoleReporter()))
