"""``snnkart nir info`` and ``snnkart nir run`` on graphs built with the ``nir`` package alone:
hand-computed spikes, the per-step decays a dt implies, parity with Lava, and bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import nir
import numpy as np
import pytest

SNNKART = str(Path(sys.executable).with_name("snnkart"))
ENV = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1"}
DT = 1e-3


def snnkart(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SNNKART, *args], capture_output=True, text=True, env=ENV, timeout=timeout
    )


def _lif(n: int, tau: float, **kw: Any) -> nir.LIF:
    params = dict(r=np.full(n, tau / DT), v_leak=np.zeros(n), v_threshold=np.ones(n),
                  v_reset=np.zeros(n))  # fmt: skip
    return nir.LIF(tau=np.full(n, tau), **{**params, **kw})


def _if(n: int) -> nir.IF:
    """An integrate-and-fire population with unit input gain (r = 1/dt), reset to 0."""
    return nir.IF(r=np.full(n, 1 / DT), v_threshold=np.full(n, 2.0), v_reset=np.zeros(n))


def _cuba(n: int, tau_syn: float, tau_mem: float) -> nir.CubaLIF:
    return nir.CubaLIF(
        tau_syn=np.full(n, tau_syn), tau_mem=np.full(n, tau_mem), r=np.full(n, tau_mem / DT),
        w_in=np.full(n, tau_syn / DT), v_leak=np.zeros(n), v_threshold=np.ones(n),
        v_reset=np.zeros(n),
    )  # fmt: skip


LI_TAU = 5e-3  # an LI readout: decay 0.8, gain dt r / tau = 2, leak dt v_leak / tau = 0.02


def _with_li(graph: nir.NIRGraph) -> nir.NIRGraph:
    """The graph with an LI node between its readout Affine and the Output."""
    n = int(np.asarray(graph.nodes["ro"].weight).shape[0])
    graph.nodes["li"] = nir.LI(
        tau=np.full(n, LI_TAU), r=np.full(n, 2 * LI_TAU / DT), v_leak=np.full(n, 0.1)
    )
    graph.edges[:] = [e for e in graph.edges if e != ("ro", "out")] + [("ro", "li"), ("li", "out")]
    return graph


def _chain(neurons: list[nir.NIRNode], n_in: int, seed: int = 0) -> nir.NIRGraph:
    """Input -> (Affine -> neuron) per layer -> Affine readout (2 outputs) -> Output."""
    rng = np.random.default_rng(seed)
    nodes: dict[str, Any] = {"in": nir.Input(input_type={"input": np.array([n_in])})}
    edges, prev, width = [], "in", n_in
    for i, neuron in enumerate(neurons):
        n = int(np.asarray(neuron.v_threshold).size)
        w = rng.normal(0.5, 0.8, (n, width)).astype(np.float32)
        bias = 0.05 if i == 0 else 0.0  # Lava cannot run a bias into a CubaLIF behind a Dense
        nodes[f"fc{i}"] = nir.Affine(weight=w, bias=np.full(n, bias, np.float32))
        nodes[f"n{i}"] = neuron
        edges += [(prev, f"fc{i}"), (f"fc{i}", f"n{i}")]
        prev, width = f"n{i}", n
    nodes["ro"] = nir.Affine(weight=np.ones((2, width), np.float32), bias=np.zeros(2, np.float32))
    nodes["out"] = nir.Output(output_type={"output": np.array([2])})
    edges += [(prev, "ro"), ("ro", "out")]
    return nir.NIRGraph(nodes=nodes, edges=edges)


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    rng = np.random.default_rng(1)
    out = {}
    for name, graph in {
        "lif1": _chain([_lif(4, 4e-3)], 3),
        "cuba2": _chain([_cuba(6, 2e-3, 1e-2), _cuba(4, 4e-3, 5e-3)], 3),
        "lif3": _chain([_lif(5, 1e-2), _lif(4, 5e-3), _lif(3, 1e-2)], 3),
        "li": _with_li(_chain([_lif(5, 1e-2), _cuba(4, 2e-3, 5e-3)], 3)),
        "if2": _chain([_if(5), _if(4)], 3),
    }.items():
        out[name] = tmp_path / f"{name}.nir"
        nir.write(out[name], graph)
    out["x"] = tmp_path / "x.npy"
    np.save(out["x"], rng.uniform(0.0, 1.2, (300, 3)))  # a few hundred steps
    return out


def test_info_without_dt_checks_the_structure_and_says_dt_is_missing(files) -> None:
    result = snnkart("nir", "info", str(files["cuba2"]))
    assert result.returncode == 0, result.stderr
    text = result.stdout
    assert "record no time step" in text and "nir-ref: supported" in text
    assert "lava-sim: unknown until a time step is given" in text
    assert "n0: CubaLIF" in text and "tau_syn [6] 0.002" in text
    order = [text.index(k) for k in ("in: Input", "fc0: Affine", "n0: CubaLIF", "ro: Affine")]
    assert order == sorted(order)  # along the edges
    assert "7 nodes" in text
    # weights and biases as the energy report counts them, the neurons' own parameters apart
    assert "132 parameters (62 weights and biases + 70 neuron parameters)" in text


@pytest.mark.parametrize(("how", "beta0", "alpha0"), [
    ("euler", 0.9, 0.5), ("exact", float(np.exp(-0.1)), float(np.exp(-0.5)))
])  # fmt: skip
def test_info_shows_the_decays_a_dt_implies(files, how: str, beta0: float, alpha0: float) -> None:
    result = snnkart("nir", "info", str(files["cuba2"]), "--dt", "1e-3", "--discretisation", how,
                     "--json")  # fmt: skip
    assert result.returncode == 0, result.stderr
    facts = json.loads(result.stdout)
    n0 = facts["layers"][0]
    assert n0["beta"] == pytest.approx(beta0) and n0["alpha"] == pytest.approx(alpha0)
    assert n0["gain"] == pytest.approx(1.0 if how == "euler" else (1 - beta0) * 10)
    assert facts["lava_supported"] is (how == "euler")  # exact: a gain != 1
    # 6x3 + 6 + 7 x 6 (CubaLIF) + 4x6 + 4 + 7 x 4 + 2x4 + 2
    assert facts["parameter_count"] == 18 + 6 + 42 + 24 + 4 + 28 + 8 + 2


def test_info_names_what_lava_cannot_run(tmp_path: Path) -> None:
    graph = _chain([_lif(4, 4e-3, v_reset=np.full(4, 0.2)), _lif(3, 5e-3)], 2)
    graph.nodes["n1"] = _lif(3, 5e-3)
    graph.nodes["n1"].tau[0] = 6e-3  # per-neuron time constants
    path = tmp_path / "g.nir"
    nir.write(path, graph)
    facts = json.loads(snnkart("nir", "info", str(path), "--dt", "1e-3", "--json").stdout)
    assert facts["reference"] == "supported" and not facts["lava_supported"]
    assert "resets to v_reset != 0" in facts["lava"]["n0"]
    assert "non-uniform decay" in facts["lava"]["n1"]


def _hand(graph: nir.NIRGraph, x: np.ndarray) -> list[np.ndarray]:
    """Each layer's spikes by hand: i = alpha i + I (CubaLIF), v = beta v + i, v > 1 fires and
    resets to 0; float64."""
    rasters, inp = [], x
    i = 0
    while f"n{i}" in graph.nodes:
        fc, neuron = graph.nodes[f"fc{i}"], graph.nodes[f"n{i}"]
        cur = inp @ fc.weight.T.astype(np.float64) + fc.bias
        cuba = isinstance(neuron, nir.CubaLIF)
        if isinstance(neuron, nir.IF):
            beta = 1.0
        else:
            beta = 1 - DT / (neuron.tau_mem if cuba else neuron.tau)
        alpha = 1 - DT / neuron.tau_syn if cuba else 0.0
        theta = np.asarray(neuron.v_threshold, dtype=np.float64)
        syn, v = np.zeros(cur.shape[1]), np.zeros(cur.shape[1])
        out = np.zeros(cur.shape, dtype=bool)
        for t in range(cur.shape[0]):
            syn = alpha * syn + cur[t]
            v = beta * v + syn
            out[t] = v > theta
            v[out[t]] = 0.0
        rasters.append(out)
        inp, i = out.astype(np.float64), i + 1
    return rasters


@pytest.mark.parametrize("name", ["lif1", "cuba2", "lif3", "li", "if2"])
def test_run_writes_every_layers_spikes_as_computed_by_hand(files, tmp_path, name) -> None:
    out = tmp_path / "r.npz"
    result = snnkart("nir", "run", str(files[name]), "--input", str(files["x"]), "--dt", "1e-3",
                     "--precision", "float64", "--out", str(out))  # fmt: skip
    assert result.returncode == 0, result.stderr
    data = np.load(out)
    expected = _hand(nir.read(files[name]), np.load(files["x"]))
    for i, spikes in enumerate(expected):
        np.testing.assert_array_equal(data[f"spikes_n{i}"], spikes)
        assert 0 < spikes.sum() < spikes.size
    per_step = expected[-1].sum(axis=1, keepdims=True) * [1.0, 1.0]  # readout weights are 1
    if name == "li":  # v <- 0.8 v + 2 (W s + b) + 0.02, read at every step
        v, trace = np.zeros(2), []
        for x in per_step:
            v = 0.8 * v + 2 * x + 0.02
            trace.append(v)
        per_step = np.array(trace)
    np.testing.assert_allclose(data["readout"], per_step, rtol=1e-5)
    assert json.loads(str(data["summary"]))["steps"] == 300


@pytest.mark.lava
@pytest.mark.timeout(180)
@pytest.mark.parametrize(
    ("name", "precision"),
    [("cuba2", "fixed"), ("cuba2", "float"), ("li", "fixed"), ("if2", "fixed")],
)
def test_run_on_lava_is_bit_exact_with_the_reference(files, name: str, precision: str) -> None:
    result = snnkart("nir", "run", str(files[name]), "--input", str(files["x"]), "--dt", "1e-3",
                     "--backend", "lava-sim", "--precision", precision, "--check",
                     timeout=170)  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    same = "fixed" if precision == "fixed" else "float64"
    assert f"against nir-ref {same}: bit-exact" in result.stdout
    assert "against nir-ref float32" in result.stdout


@pytest.mark.parametrize(("make", "message"), [
    (lambda d: np.save(d / "in.npy", np.zeros((10, 4))), r"shape \[10, 4\]; the graph takes \[N, 3\]"),
    (lambda d: np.save(d / "in.npy", np.array([["a"] * 3] * 5)), "dtype <U1"),
    (lambda d: np.save(d / "in.npy", np.full((5, 3), np.nan)), "NaN"),
    (lambda d: (d / "in.npy").write_text("not numpy"), "not a .npy array"),
    (lambda d: None, "no input file"),
])  # fmt: skip
def test_run_refuses_bad_input_clearly(files, tmp_path, make, message: str) -> None:
    make(tmp_path)
    result = snnkart("nir", "run", str(files["lif1"]), "--input", str(tmp_path / "in.npy"),
                     "--dt", "1e-3")  # fmt: skip
    assert result.returncode == 2
    assert "error:" in result.stderr
    import re

    assert re.search(message, result.stderr), result.stderr


def test_run_needs_a_dt_and_a_runnable_graph(files, tmp_path: Path) -> None:
    result = snnkart("nir", "run", str(files["lif1"]), "--input", str(files["x"]))
    assert result.returncode == 2 and "records no time step; pass --dt" in result.stderr
    branch = _chain([_lif(4, 4e-3)], 3)
    branch.edges.append(("fc0", "ro"))
    cycle = _chain([_lif(4, 4e-3), _lif(4, 4e-3)], 3)
    cycle.edges.append(("n1", "fc1"))  # a recurrent loop (NIR's reader needs the Output kept)
    nan = _chain([_lif(4, 4e-3)], 3)
    nan.nodes["n0"].v_threshold[1] = np.nan
    unknown = _chain([_lif(4, 4e-3)], 3)
    unknown.nodes["n0"] = nir.Delay(delay=np.full(4, 1e-3))
    for graph, message in [
        (branch, "'fc0' feeds"), (cycle, "'n1' feeds ['ro', 'fc1']; only feed-forward"),
        (nan, "NaN"), (unknown, "'n0' is a Delay"),
    ]:  # fmt: skip
        path = tmp_path / "bad.nir"
        nir.write(path, graph)
        result = snnkart("nir", "run", str(path), "--input", str(files["x"]), "--dt", "1e-3")
        assert result.returncode == 2 and message in result.stderr, result.stderr
        info = snnkart("nir", "info", str(path), "--dt", "1e-3")
        assert info.returncode == 0 and message in info.stdout


def _grid_policy(tmp_path: Path, li: bool = False) -> Path:
    """A foreign 2-layer LIF graph of grid's sizes (21 observation values, 5 actions), read out
    through an LI node if ``li``."""
    graph = _chain([_lif(16, 1e-2), _lif(12, 5e-3)], 21, seed=4)
    graph.nodes["ro"] = nir.Affine(
        weight=np.random.default_rng(2).normal(0, 1, (5, 12)).astype(np.float32),
        bias=np.zeros(5, np.float32),
    )
    graph.nodes["out"] = nir.Output(output_type={"output": np.array([5])})
    if li:
        graph = _with_li(graph)
    path = tmp_path / "foreign.nir"
    nir.write(path, graph)
    return path


@pytest.mark.lava
@pytest.mark.timeout(300)
@pytest.mark.parametrize("li", [False, True])
def test_a_foreign_graph_drives_the_kart_with_a_written_manifest(tmp_path: Path, li: bool) -> None:
    import jsonschema

    from snnkart.contract.manifest import SCHEMA_FILE, Manifest, manifest_path

    path = _grid_policy(tmp_path, li)
    result = snnkart("nir", "manifest", str(path), "--env", "grid", "--dt", "1e-3",
                     "--readout", "ro", "--num-steps", "6")  # fmt: skip
    assert result.returncode == 0, result.stderr
    raw = json.loads(manifest_path(path).read_text())
    jsonschema.validate(raw, json.loads(SCHEMA_FILE.read_text()))
    manifest = Manifest.read(manifest_path(path))
    assert manifest.num_steps == 6 and [la.node for la in manifest.layers] == ["n0", "n1"]
    assert manifest.layers[0].beta == pytest.approx(0.9) and manifest.obs_dim == 21
    out = tmp_path / "deploy"
    result = snnkart("deploy", str(path), "--backend", "lava-sim", "--episodes", "1",
                     "--out", str(out), timeout=280)  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr  # 4 if not bit-exact
    record = json.loads((out / "deploy.json").read_text())
    assert record["counts"]["env_steps"] > 0 and sum(record["counts"]["spikes"]) > 0


def test_a_manifest_is_refused_when_the_graph_does_not_fit_the_env(tmp_path: Path) -> None:
    path = _grid_policy(tmp_path)
    for args, message in [
        (["--env", "gazebo"], "takes 21 inputs; env 'gazebo' observes 23"),
        (["--env", "grid", "--action-mode", "continuous"], "gives 5 values; env 'grid' "),
        (["--env", "grid", "--readout", "n1"], "--readout 'n1' is not the graph's readout"),
        (["--env", "grid", "--encoding", "population", "--population", "4"], "x 4 receptive"),
    ]:
        result = snnkart("nir", "manifest", str(path), "--dt", "1e-3", *args)
        assert result.returncode == 2 and message in result.stderr, (args, result.stderr)
    ok = snnkart("nir", "manifest", str(path), "--dt", "1e-3", "--env", "grid")
    assert ok.returncode == 0, ok.stderr
    again = snnkart("nir", "manifest", str(path), "--dt", "1e-3", "--env", "grid")
    assert again.returncode == 2 and "pass --force" in again.stderr


def test_an_li_readout_decides_the_action_from_its_last_membrane(tmp_path: Path) -> None:
    from snnkart.backends.reference import NIRReference

    path = _grid_policy(tmp_path, li=True)
    result = snnkart("nir", "manifest", str(path), "--env", "grid", "--dt", "1e-3")
    assert result.returncode == 0, result.stderr
    reference = NIRReference(path, "float32")
    assert reference.chain.readout_li is not None and reference.chain.readout_node == "ro"
    ro = nir.read(path).nodes["ro"]
    obs = np.random.default_rng(0).uniform(0, 1, 21).astype(np.float32)
    window, out = reference.step(obs)
    last = window.logical[:, -12:].astype(np.float64)
    v = np.zeros(5)
    for s in last:  # decay 0.8, gain 2, leak 0.02
        v = 0.8 * v + 2 * (ro.weight @ s + ro.bias) + 0.02
    np.testing.assert_allclose(out, v, rtol=1e-5)
    rates = ro.weight @ last.mean(axis=0) + ro.bias
    assert last.sum() > 0 and not np.allclose(out, rates)  # not the rate readout


def test_info_takes_dt_and_discretisation_from_the_manifest(tmp_path: Path) -> None:
    path = _grid_policy(tmp_path)
    made = snnkart("nir", "manifest", str(path), "--env", "grid", "--dt", "1e-3",
                   "--discretisation", "exact")  # fmt: skip
    assert made.returncode == 0, made.stderr
    facts = json.loads(snnkart("nir", "info", str(path), "--json").stdout)
    assert facts["dt"] == 1e-3 and facts["discretisation"] == "exact"
    assert facts["layers"][0]["beta"] == pytest.approx(float(np.exp(-0.1)))
    assert "manifest" in facts["dt_source"]


def test_run_defaults_to_fixed_point_and_names_float32_when_lava_cannot(files, tmp_path) -> None:
    """nir run's default is the table's (fixed, as every door's); a graph whose neurons Lava's
    cannot express (a decay per neuron) runs in float32, and the default's error says so."""
    result = snnkart("nir", "run", str(files["lif1"]), "--input", str(files["x"]), "--dt", "1e-3")
    assert result.returncode == 0 and "(fixed)" in result.stdout, result.stderr
    graph = _chain([_lif(4, 4e-3)], 3)
    graph.nodes["n0"].tau[1] = 8e-3
    nir.write(tmp_path / "per-neuron.nir", graph)
    args = ("nir", "run", str(tmp_path / "per-neuron.nir"), "--input", str(files["x"]))
    args = (*args, "--dt", "1e-3")
    result = snnkart(*args)
    assert result.returncode == 2, result.stdout + result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert "non-uniform decay" in line and "--precision float32 runs it" in line, line
    assert snnkart(*args, "--precision", "float32").returncode == 0
    result = snnkart(*args, "--precision", "fixed")  # asked for: the plain error
    assert result.returncode == 2 and "--precision float32" not in result.stderr
