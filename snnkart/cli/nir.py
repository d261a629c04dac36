"""``snnkart nir info`` and ``snnkart nir run``: NIR graphs from any library."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from snnkart.backends.defaults import (
    NIR_BACKENDS,
    default_help,
    precision_help,
    precision_word,
)
from snnkart.cli.guard import guard

nir_app = typer.Typer(
    help="Inspect and run NIR graphs, from snnkart or any other library.", no_args_is_help=True
)

GraphArg = Annotated[Path, typer.Argument(help="a NIR graph (.nir)")]
DtOpt = Annotated[
    float | None,
    typer.Option(
        "--dt",
        help="time step in seconds (NIR records none; snntorch exports use 1e-4, lava-dl 1); "
        "default: the manifest's, for graphs snnkart exported",
    ),
]
DiscOpt = Annotated[
    str | None,
    typer.Option(
        "--discretisation",
        help="euler (decay 1 - dt/tau; snntorch, the NIR paper's Lava mapping) or exact "
        "(exp(-dt/tau)); default: the manifest's, else euler",
    ),
]


@nir_app.command("info")
def info(
    graph: GraphArg,
    dt: DtOpt = None,
    discretisation: DiscOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
) -> None:
    """Nodes, edges, shapes, neuron parameters, parameter count, and what runs on nir-ref and
    on lava-sim (and why not), with the per-step decays the chosen dt implies."""
    from snnkart.app.nir_notes import policy_notes
    from snnkart.app.nir_tools import run_nir_info

    facts = guard(lambda: run_nir_info(graph, dt, discretisation))
    notes = guard(lambda: policy_notes(graph))
    if as_json:
        typer.echo(json.dumps({**facts.as_dict(), "notes": notes}, indent=2))
        return
    neuron = facts.parameter_count - facts.weight_count
    typer.echo(
        f"{graph}: {len(facts.nodes)} nodes, {len(facts.edges)} edges, "
        f"{facts.parameter_count:,} parameters ({facts.weight_count:,} weights and biases "
        f"+ {neuron:,} neuron parameters)"
    )
    for node in facts.nodes:
        shapes = f"in {node.input_shape} out {node.output_shape}"
        typer.echo(f"  {node.name}: {node.kind} ({shapes})")
        for key, value in node.parameters.items():
            typer.echo(f"      {key} {value}")
    typer.echo("  edges: " + ", ".join(f"{a} -> {b}" for a, b in facts.edges))
    for cycle in facts.recurrence:
        typer.echo(f"  cycle: {cycle}")
    if facts.normalisation is not None:
        typer.echo(
            f"  {facts.normalisation}: the observation's normalisation (a diagonal Affine: the "
            "graph takes raw observations); the host applies it, so it is not counted above"
        )
    if facts.dt is None:
        typer.echo(f"dt: none ({facts.dt_source}); pass --dt to see the decays it implies")
    else:
        typer.echo(f"dt: {facts.dt:g} s from {facts.dt_source}, {facts.discretisation}")
        for layer in facts.layers:
            typer.echo("  " + _layer_line(layer))
    if facts.state is not None:
        typer.echo(f"state: {facts.state}")
    typer.echo(f"nir-ref: {facts.reference}")
    if facts.reference == "supported" and facts.dt is None:
        typer.echo("lava-sim: unknown until a time step is given (--dt): it decides the decays")
    elif facts.reference == "supported":
        lava = "supported" if not facts.lava else "not supported"
        typer.echo(f"lava-sim: {lava}")
        for name, why in facts.lava.items():
            typer.echo(f"  {name}: {why}")
    for line in notes:
        typer.echo(line)


def _layer_line(layer: dict[str, Any]) -> str:
    parts = [f"{layer['neuron']} ({layer['size']} neurons): beta {layer['beta']}"]
    if layer["alpha"] is not None:
        parts.append(f"alpha {layer['alpha']}")
    parts.append(f"input gain {layer['gain']}")
    if layer["syn_gain"] is not None:
        parts.append(f"current input gain {layer['syn_gain']}")
    if layer["leak"] != 0:
        parts.append(f"leak {layer['leak']}")
    parts.append(f"threshold {layer['threshold']}")
    return ", ".join(parts)


@nir_app.command("run")
def run(
    graph: GraphArg,
    input_file: Annotated[
        Path, typer.Option("--input", help=".npy array [N, n_in]: currents, or spikes as 0/1")
    ],
    steps: Annotated[int | None, typer.Option(help="run the first N steps (default: all)")] = None,
    backend: Annotated[str, typer.Option(help="nir-ref or lava-sim")] = "nir-ref",
    precision: Annotated[
        str | None, typer.Option(help=precision_help(), show_default=default_help())
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help=".npz: every layer's spikes and readout")
    ] = None,
    check: Annotated[
        bool,
        typer.Option(
            help="also run the reference of the same arithmetic and the float32 reference, and "
            "count the spikes that differ"
        ),
    ] = False,
    dt: DtOpt = None,
    discretisation: DiscOpt = None,
) -> None:
    """Run a graph open loop on given input from zero state: every layer's spikes and the
    readout, optionally checked against the reference (exit 4 if not bit-exact). It runs in
    fixed point unless --precision says otherwise, as every backend does by default."""
    word = guard(lambda: precision_word(backend, precision, NIR_BACKENDS))
    options = (steps, backend, word, out, check, dt, discretisation)
    guard(lambda: _run(graph, input_file, options, precision is None))


def _run(graph: Path, input_file: Path, options: tuple[Any, ...], defaulted: bool) -> None:
    """``nir run``; when the default fixed point refuses a graph that the reference runs in
    float32 (a graph from another library whose neurons Lava's cannot express), the error
    names that fix."""
    from snnkart.app.nir_tools import load_open_chain, run_nir_run
    from snnkart.backends.defaults import TABLE
    from snnkart.errors import SnnkartError, UnsupportedGraphError

    steps, backend, word, out, check, dt, discretisation = options
    try:
        run_nir_run(graph, input_file, steps, backend, word, out, check, dt, discretisation, _show)
    except UnsupportedGraphError as exc:
        words = TABLE[backend].precisions
        floats = [w for w, a in words.items() if a == "float32"]
        if not defaulted or words[word] != "fixed" or not floats:
            raise
        try:
            load_open_chain(graph, dt, discretisation)
        except SnnkartError:
            raise exc from None
        raise UnsupportedGraphError(
            f"{exc} (in fixed point, {backend}'s default; --precision {floats[0]} runs it)"
        ) from exc


def _show(summary: dict[str, Any]) -> None:
    typer.echo(
        f"{summary['graph']} on {summary['backend']} ({summary['arithmetic']}), "
        f"{summary['steps']} steps; spikes per layer: {summary['spikes']}"
    )
    for c in summary["checks"]:
        verdict = "bit-exact" if c["bit_exact"] else f"flipped spikes {c['flips']}"
        typer.echo(f"  against {c['b']}: {verdict} ({c['spikes_a']} vs {c['spikes_b']} spikes)")
    if "out" in summary:
        typer.echo(f"wrote {summary['out']}")


@nir_app.command("manifest")
def manifest(
    graph: GraphArg,
    env: Annotated[str, typer.Option("--env", "-e", help="grid, gazebo or steer")],
    dt: Annotated[
        float, typer.Option("--dt", help="time step in seconds the graph was trained with")
    ],
    track: Annotated[str, typer.Option("--track", "-t", help="track to drive")] = "small_S",
    encoding: Annotated[
        str, typer.Option(help="current (observation as input current), rate or population")
    ] = "current",
    readout: Annotated[
        str | None, typer.Option(help="the Affine/Linear node read out (checked against the graph)")
    ] = None,
    num_steps: Annotated[int, typer.Option(help="T: SNN steps per env step")] = 8,
    action_mode: Annotated[str, typer.Option(help="discrete or continuous")] = "discrete",
    population: Annotated[
        int | None, typer.Option(help="population encoding: receptive fields per observation")
    ] = None,
    discretisation: DiscOpt = None,
    force: Annotated[bool, typer.Option(help="replace an existing manifest")] = False,
) -> None:
    """Write the manifest that lets `snnkart deploy` drive the kart with a graph from another
    library, after checking it against the env's observation and action sizes."""
    from snnkart.app.nir_manifest import write_manifest

    out = guard(
        lambda: write_manifest(
            graph,
            env,
            track,
            encoding,
            readout,
            dt,
            discretisation or "euler",
            num_steps,
            action_mode,
            population,
            force,
        )
    )
    typer.echo(f"wrote {out}; run it with: snnkart deploy {graph} --backend nir-ref")
