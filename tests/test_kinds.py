"""Every registered policy kind, end to end: train (tiny) -> checkpoint -> load -> export to NIR
-> read back -> the numpy reference -> lava-sim fixed, bit-exact step by step. The kinds come
from the registry (:mod:`snnkart.rl.kinds`): a new kind is in this test with no edit to it.

Also: the registry is the one place that names a kind (no module outside it compares a kind's
name to a string or checks a concrete policy class), and the recurrent kind (``rsnn``) writes
its recurrent synapses as cycles that every backend runs.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import nir
import numpy as np
import pytest
from tiny_runs import train_tiny

from snnkart.backends import lava_params
from snnkart.backends.reference import NIRReference
from snnkart.errors import ExportError, ParityError
from snnkart.eval.closed_loop import run_deploy
from snnkart.eval.request import DeployRequest
from snnkart.export.nir_export import export_nir
from snnkart.rl import kinds
from snnkart.rl.trained import TorchPredictor, load_run

PACKAGE = Path(__file__).resolve().parents[1] / "snnkart"
KINDS = kinds.names()


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One tiny grid run of every registered kind."""
    root = tmp_path_factory.mktemp("kinds")
    return {name: train_tiny(root / name, "grid", name, total_steps=256) for name in KINDS}


@pytest.mark.parametrize("name", KINDS)
def test_every_kind_trains_checkpoints_and_drives(trained: dict[str, Path], name: str) -> None:
    run = load_run(trained[name])
    assert run.config.policy == name and run.policy.kind == name
    assert (trained[name] / "checkpoint.pt").is_file()
    predictor = TorchPredictor(run)
    env = run.config.make_env()
    obs, _ = env.reset(seed=3)
    predictor.reset()
    for _ in range(20):
        obs, _, terminated, truncated, _ = env.step(predictor.predict(obs))
        if terminated or truncated:
            break
    env.close()


@pytest.mark.lava
@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", KINDS)
def test_every_kind_exports_and_runs_bit_exact_on_lava(
    trained: dict[str, Path], name: str, tmp_path: Path
) -> None:
    run = load_run(trained[name])
    if not kinds.family(name).spiking:
        with pytest.raises(ExportError, match="only spiking policies"):
            export_nir(run, tmp_path / "policy.nir")
        return
    nir_file, _ = export_nir(run, tmp_path / "policy.nir")
    graph = nir.read(nir_file)  # it reads back as a NIR graph
    assert "input" in graph.nodes and "output" in graph.nodes
    record = run_deploy(DeployRequest(nir_file, "lava-sim", "fixed", 1, seed=21, out=tmp_path))
    assert record.parity.env_steps > 0
    assert record.parity.same_arithmetic_mismatched_windows == 0 and record.bit_exact


# -- the registry is the one place that names a kind --------------------------------------------

KIND_WORDS = {*KINDS, "ann-sd"}
POLICY_CLASSES = {"ANNPolicy", "SNNPolicy", "StatefulSNNPolicy", "SDNNPolicy"}
OUTSIDE = ("rl/kinds/", "rl/policies.py", "rl/actor_critic.py")


def _kind_switches(path: Path) -> list[str]:
    """Lines of ``path`` comparing something to a kind's name, or isinstance-checking a
    concrete policy class."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            for op in operands:
                values = op.elts if isinstance(op, (ast.Tuple, ast.List, ast.Set)) else [op]
                if any(isinstance(v, ast.Constant) and v.value in KIND_WORDS for v in values):
                    found.append(f"{node.lineno}: {ast.unparse(node)}")
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id == "isinstance"
            and len(node.args) == 2
        ):
            names = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
            names |= {n.attr for n in ast.walk(node.args[1]) if isinstance(n, ast.Attribute)}
            if names & POLICY_CLASSES:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


def test_no_module_outside_the_registry_switches_on_a_kind() -> None:
    offenders = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith(OUTSIDE):
            continue
        if lines := _kind_switches(path):
            offenders[rel] = lines
    assert not offenders, f"ask the kinds registry or the policy's protocol instead: {offenders}"


def test_the_checker_finds_a_switch(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(
        "def f(cfg, p):\n"
        "    if cfg.policy == 'snn':\n        return 1\n"
        "    if cfg.policy in ('sdnn', 'x'):\n        return 2\n"
        "    return isinstance(p, SDNNPolicy)\n"
    )
    assert len(_kind_switches(bad)) == 3


def test_policy_choices_and_errors_come_from_the_registry() -> None:
    from snnkart.errors import ConfigError
    from snnkart.rl.config import load_config

    help_text = kinds.choices_help()
    assert all(f"{name}:" in help_text for name in KINDS)
    with pytest.raises(
        ConfigError, match="unknown policy kind 'xnn'; choose one of " + ", ".join(KINDS)
    ):
        load_config(overrides={"policy": "xnn"})


# -- the recurrent kind -----------------------------------------------------------------------

RSNN = ["snn.num_steps=3", "snn.hidden=[16, 12]", "rsnn.recurrent_gain=3.0"]


@pytest.fixture(scope="module")
def recurrent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recurrent run whose recurrent synapses matter (a large recurrent gain), exported."""
    root = tmp_path_factory.mktemp("rsnn")
    run = load_run(train_tiny(root / "run", "grid", "rsnn", total_steps=256, extra_sets=RSNN))
    nir_file, _ = export_nir(run, root / "policy.nir")
    return nir_file


def test_the_recurrent_synapse_is_a_cycle_in_the_graph(recurrent: Path) -> None:
    graph = nir.read(recurrent)
    edges = {tuple(e) for e in graph.edges}
    assert ("3", "rec3") in edges and ("rec3", "3") in edges
    assert isinstance(graph.nodes["rec3"], nir.Linear)
    assert graph.nodes["rec3"].weight.shape == (12, 12)
    chain = NIRReference(recurrent, "fixed").chain
    assert chain.layers[0].recurrent is None and chain.layers[1].recurrent is not None
    assert chain.layers[1].recurrent_node == "rec3"


def test_the_fused_recurrent_update_equals_the_stepped_one() -> None:
    """The PPO update's layer-by-layer sequences (FusedRecurrentLIF) against the rows stepped
    one by one in torch: the same readouts, gradients equal to float32 rounding, from a carried
    state and across episode starts."""
    import torch

    from snnkart.rl.config import load_config
    from snnkart.rl.stateful import stream_step

    cfg = load_config(None, {"env": "grid", "policy": "rsnn"},
                      ["snn.num_steps=2", "snn.hidden=[24, 16, 12]"])  # fmt: skip
    torch.manual_seed(0)
    policy = kinds.policy_for(cfg, cfg.make_env().unwrapped)
    S, E = 12, 3
    obs = torch.randn(S * E, policy.obs_dim) * 3
    state = torch.zeros(E, policy.state_size())
    with torch.no_grad():
        for _ in range(4):
            x = policy.actor_input(obs[:E], obs[:E])
            _, _, state = stream_step(policy.snn, x, state, policy.loops)
    starts = torch.zeros(S, E)
    starts[5, 1] = starts[0, 2] = 1.0
    weights = torch.randn(S * E)
    results = []
    for fused in (False, True):
        policy.cfg = policy.cfg.model_copy(update={"fused": fused})
        policy.zero_grad()
        out = policy(
            obs, obs, action=torch.zeros(S * E, dtype=torch.long), state=state, starts=starts
        )
        ((out.log_prob * weights).sum() + out.rates.sum()).backward()
        grads = {n: p.grad.clone() for n, p in policy.named_parameters() if p.grad is not None}
        results.append((out.log_prob.detach(), grads))
    (stepped, g_stepped), (fused_lp, g_fused) = results
    assert torch.equal(stepped, fused_lp)
    assert "recs.1.weight" in g_fused and g_fused["recs.1.weight"].abs().max() > 0
    for name, grad in g_stepped.items():
        torch.testing.assert_close(g_fused[name], grad, rtol=1e-4, atol=1e-6, msg=name)


def test_the_reference_follows_the_torch_policy_with_its_recurrence(recurrent: Path) -> None:
    """The float32 reference drives as the torch policy does, env step by env step (its state
    carried); without the recurrent synapse the spikes change."""
    run = load_run(recurrent.parent / "run")
    torch_policy, reference = TorchPredictor(run), NIRReference(recurrent, "float32")
    env = run.config.make_env()
    same = steps = 0
    for seed in (5, 6, 7):
        obs, _ = env.reset(seed=seed)
        torch_policy.reset()
        reference.reset()
        for _ in range(60):
            action = torch_policy.predict(obs)
            same += int(action == reference.predict(obs))
            steps += 1
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    env.close()
    assert steps >= 20 and same / steps >= 0.95, f"{same} of {steps} actions equal"
    from snnkart.backends.reference import ChainSimulator

    chain = NIRReference(recurrent, "float32").chain
    layers = list(chain.layers)
    assert layers[1].recurrent is not None
    layers[1] = dataclasses.replace(layers[1], recurrent=np.zeros_like(layers[1].recurrent))
    cut_chain = dataclasses.replace(chain, layers=tuple(layers))
    T = 3
    full = ChainSimulator(chain, T, "float32", persist=True)
    cut = ChainSimulator(cut_chain, T, "float32", persist=True)
    rng = np.random.default_rng(0)
    currents = rng.uniform(0.0, 2.0, size=(40, T, chain.sizes[0])).astype(np.float32)
    diffs = sum(not np.array_equal(full.window(c), cut.window(c)) for c in currents)
    assert diffs > 0, "the recurrent synapse changed no spike: the test policy is too quiet"


@pytest.mark.lava
@pytest.mark.timeout(300)
@pytest.mark.parametrize("precision", ["fixed", "float"])
def test_the_recurrent_graph_is_bit_exact_on_lava(recurrent: Path, precision: str) -> None:
    record = run_deploy(DeployRequest(recurrent, "lava-sim", precision, 4, seed=7))
    assert record.parity.env_steps >= 30
    assert record.parity.same_arithmetic_mismatched_windows == 0 and record.bit_exact


@pytest.mark.lava
@pytest.mark.timeout(300)
def test_lava_without_the_recurrent_dense_is_caught(
    recurrent: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = lava_params.lava_layers

    def dropped(*args, **kwargs):  # type: ignore[no-untyped-def]
        return tuple(dataclasses.replace(p, recurrent=None) for p in real(*args, **kwargs))

    monkeypatch.setattr(lava_params, "lava_layers", dropped)
    with pytest.raises(ParityError, match="differs from the numpy reference"):
        run_deploy(DeployRequest(recurrent, "lava-sim", "fixed", 4, seed=7))


# -- a recurrent graph snnTorch wrote ---------------------------------------------------------

RLEAKY = Path(__file__).parent / "data" / "graphs" / "snntorch-rleaky.nir"
"""snnTorch 1.0's export of Linear -> Leaky -> Linear -> RLeaky -> Linear, and snnTorch's own
simulation of a seeded input beside it (``scripts/make_recurrent_graph.py`` made both)."""


def _open_loop(backend: str, arithmetic: str):  # type: ignore[no-untyped-def]
    from snnkart.backends.network import chain_from_graph
    from snnkart.backends.open_loop import run_open_loop

    chain = chain_from_graph(nir.read(RLEAKY), dt=1e-4)
    inputs = np.load(RLEAKY.with_suffix(".npz"))["inputs"]
    return chain, run_open_loop(chain, inputs, backend, arithmetic)  # type: ignore[arg-type]


def test_snntorchs_recurrent_graph_reads_as_a_cycle_and_matches_snntorch() -> None:
    chain, result = _open_loop("nir-ref", "float32")
    assert chain.layers[1].recurrent_node == "3.w_rec" and chain.layers[0].recurrent is None
    expected = np.load(RLEAKY.with_suffix(".npz"))
    assert expected["layer2"].sum() > 10  # the recurrent layer is active
    assert np.array_equal(result.layer(0), expected["layer1"])
    assert np.array_equal(result.layer(1), expected["layer2"])


@pytest.mark.lava
@pytest.mark.timeout(300)
@pytest.mark.parametrize("arithmetic", ["float64", "fixed"])
def test_snntorchs_recurrent_graph_is_bit_exact_on_lava(arithmetic: str) -> None:
    from snnkart.backends.open_loop import compare

    _, reference = _open_loop("nir-ref", arithmetic)
    _, lava = _open_loop("lava-sim", arithmetic)
    assert reference.logical[:, 10:].sum() > 0
    assert compare(reference, lava)["bit_exact"]


def test_nir_info_names_the_cycle_and_how_it_runs() -> None:
    from typer.testing import CliRunner

    from snnkart.cli.main import app

    result = CliRunner().invoke(app, ["nir", "info", str(RLEAKY)])
    assert result.exit_code == 0, result.output
    cycles = [line for line in result.output.splitlines() if line.strip().startswith("cycle:")]
    assert len(cycles) == 1 and "3.lif -> 3.w_rec -> 3.lif" in cycles[0]
    assert "one step reach its own input at the next" in cycles[0]
