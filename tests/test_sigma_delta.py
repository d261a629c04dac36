"""The sigma-delta reference (snnkart/backends/sigma_delta.py): equal to the quantised ReLU
network with zero thresholds, a hand-counted 3-step run, and bit-exact with Lava's own
Delta + Dense + SigmaDelta + Sigma processes run open loop."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from snnkart.backends.sigma_delta import (
    SigmaDeltaChain,
    SigmaDeltaSpec,
    lava_fixed_weights,
    relu_network,
)
from snnkart.errors import DeployError


def _random_spec(seed: int, vth: float, **kwargs: object) -> SigmaDeltaSpec:
    rng = np.random.default_rng(seed)
    sizes = (5, 8, 6, 3)
    weights = tuple(rng.integers(-40, 41, (sizes[i + 1], sizes[i])) for i in range(3))
    biases = tuple(rng.integers(-30, 31, n) for n in sizes[1:3])
    return SigmaDeltaSpec(weights=weights, biases=biases, vth=(vth, vth), **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("arithmetic", "exps"),
    [("fixed", (0, 0, 0)), ("fixed", (1, 1, 0)), ("fixed", (0, 0, -1)), ("float64", (1, 1, 0))],
)
def test_zero_thresholds_equal_the_quantised_relu_network_after_the_pipeline_delay(
    arithmetic: str, exps: tuple[int, int, int]
) -> None:
    spike_exp, state_exp, weight_exp = exps
    spec = _random_spec(
        0, 0, arithmetic=arithmetic, spike_exp=spike_exp, state_exp=state_exp,
        weight_exp=weight_exp,
    )  # fmt: skip
    xs = np.random.default_rng(1).integers(-10, 11, (40, 5))
    xs[10:20] = xs[9]  # a stretch of repeated observations: no input messages, same output
    chain = SigmaDeltaChain(spec)
    out = chain.run(xs)
    ann = relu_network(spec, xs)
    d = spec.delay
    assert d == 3
    np.testing.assert_array_equal(out[d:], ann[:-d])
    # the fill: biases reach the readout layer by layer; step d - 1 sees the network on x = 0
    np.testing.assert_array_equal(out[d - 1], relu_network(spec, 0 * xs[:1])[0])
    assert not out[0].any()
    assert np.count_nonzero(ann) > 50
    assert chain.message_counts()[12:19, 0].sum() == 0  # repeated input sends nothing


def test_a_shift_that_drops_set_bits_floors_every_delta_apart() -> None:
    # weight_exp = -2 drops a bit that the even (mixed-sign) weights do not keep at zero:
    # the chain then drifts from the network (docs/sigma-delta.md, "When it is exact").
    spec = _random_spec(0, 0, weight_exp=-2)
    xs = np.random.default_rng(1).integers(-10, 11, (40, 5))
    diff = SigmaDeltaChain(spec).run(xs)[3:] - relu_network(spec, xs)[:-3]
    assert np.abs(diff).max() > 0


def test_state_persists_across_calls_until_reset() -> None:
    spec = _random_spec(0, 0)
    xs = np.random.default_rng(2).integers(-10, 11, (12, 5))
    chain = SigmaDeltaChain(spec)
    whole = chain.run(xs)
    chain.reset()
    parts = np.concatenate([chain.run(xs[:5]), chain.run(xs[5:])])
    np.testing.assert_array_equal(whole, parts)


def test_hand_computed_message_count_on_a_three_step_input() -> None:
    # x = 1, 0, 2 into W1 = 2, bias 1, vth 2, readout W2 = 1 (docs/sigma-delta.md, "Example"):
    # step 0: input d = 1 (msg); hidden act = relu(0 + 1) = 1, d = 1 < 2: none, residue 1
    # step 1: input d = -1 (msg); sigma = 2, act = 3, d = 3 - 1 + 1 = 3: msg 3, residue 0
    # step 2: input d = 2 (msg); sigma = 2 - 2 = 0, act = 1, d = 1 - 3 = -2: msg -2
    spec = SigmaDeltaSpec(
        weights=(np.array([[2]]), np.array([[1]])), biases=(np.array([1]),), vth=(2,)
    )
    chain = SigmaDeltaChain(spec)
    out = chain.run(np.array([[1], [0], [2]]))
    np.testing.assert_array_equal(chain.message_counts(), [[1, 0], [1, 1], [1, 1]])
    np.testing.assert_array_equal(chain.payload_bits(), [[8, 0], [8, 8], [8, 8]])
    np.testing.assert_array_equal(chain.synaptic_events(), [[1, 0], [1, 1], [1, 1]])
    np.testing.assert_array_equal(out[:, 0], [0, 0, 3])


def test_fixed_point_weights_are_clipped_and_truncated_as_lavas_dense_does() -> None:
    # measured on Lava (/work/shared/reference/lava-closed-loop.md section 8, item 8): mixed
    # signs drop the least significant bit and clip to 254; one-signed matrices keep 0..255
    mixed = lava_fixed_weights(np.array([[3, -3, 5, 1, -1, 300]]))
    np.testing.assert_array_equal(mixed, [[2, -4, 4, 0, -2, 254]])
    np.testing.assert_array_equal(lava_fixed_weights(np.array([[3, 300, 0]])), [[3, 255, 0]])
    np.testing.assert_array_equal(lava_fixed_weights(np.array([[-3, -300]])), [[-3, -255]])


def test_mismatched_layers_are_one_clear_error() -> None:
    with pytest.raises(DeployError, match="one bias and one threshold per hidden layer"):
        SigmaDeltaSpec(weights=(np.ones((2, 2)), np.ones((1, 2))), biases=(), vth=())
    with pytest.raises(DeployError, match="Dense 1 takes 3 inputs but layer 0 has 2"):
        SigmaDeltaSpec(weights=(np.ones((2, 2)), np.ones((1, 3))), biases=(np.zeros(2),), vth=(0,))


LAVA_RUN = r"""
import sys
import numpy as np
from lava.magma.core.run_conditions import RunSteps
from lava.magma.core.run_configs import Loihi2SimCfg
from lava.proc.dense.process import Dense
from lava.proc.io.sink import RingBuffer as Sink
from lava.proc.io.source import RingBuffer as Source
from lava.proc.sdn.process import ActivationMode, Delta, Sigma, SigmaDelta

z = np.load(sys.argv[1])
xs, n = z["xs"], int(z["xs"].shape[0])
L, tag = int(z["layers"]), str(z["tag"])
exps = dict(spike_exp=int(z["spike_exp"]), state_exp=int(z["state_exp"]),
            cum_error=bool(z["cum_error"]))
fixed = tag == "fixed_pt"
dk = {"num_weight_bits": 8, "weight_exp": int(z["weight_exp"])} if fixed else {}
src = Source(data=xs.T)
enc = Delta(shape=(xs.shape[1],), vth=z["vth_in"].item(), **exps)
src.s_out.connect(enc.a_in)
senders, sinks = [enc], []
for i in range(L + 1):
    w = z[f"w{i}"]
    dense = Dense(weights=w, num_message_bits=8, **dk)
    sink = Sink(shape=(senders[-1].s_out.shape[0],), buffer=n)
    senders[-1].s_out.connect([dense.s_in, sink.a_in])
    sinks.append(sink)
    if i < L:
        sd = SigmaDelta(shape=(w.shape[0],), vth=z["vth"][i].item(), bias=z[f"b{i}"],
                        act_mode=ActivationMode.RELU, **exps)
        dense.a_out.connect(sd.a_in)
        senders.append(sd)
    else:
        out = Sigma(shape=(w.shape[0],))
        dense.a_out.connect(out.a_in)
        sink = Sink(shape=(w.shape[0],), buffer=n)
        out.s_out.connect(sink.a_in)
        sinks.append(sink)
try:
    src.run(condition=RunSteps(num_steps=n), run_cfg=Loihi2SimCfg(select_tag=tag))
    got = {f"s{i}": s.data.get().T for i, s in enumerate(sinks)}
finally:
    src.stop()
np.savez(sys.argv[2], **got)
"""


@pytest.mark.lava
@pytest.mark.timeout(180)
@pytest.mark.parametrize(
    ("arithmetic", "exps", "cum_error"),
    [
        ("fixed", (0, 0, 0), False),
        ("fixed", (1, 1, -1), False),
        ("fixed", (0, 1, 0), True),
        ("float64", (0, 0, 0), False),
    ],
)
def test_reference_is_bit_exact_with_lavas_own_processes(
    arithmetic: str, exps: tuple[int, int, int], cum_error: bool, tmp_path: Path
) -> None:
    spike_exp, state_exp, weight_exp = exps
    spec = _random_spec(
        3, 6, arithmetic=arithmetic, vth_in=2, spike_exp=spike_exp, state_exp=state_exp,
        weight_exp=weight_exp, cum_error=cum_error,
    )  # fmt: skip
    xs = np.random.default_rng(4).integers(-12, 13, (20, 5))
    xs[8:12] = xs[7]
    chain = SigmaDeltaChain(spec)
    out = np.empty((len(xs), 3), chain.dtype)
    sent: list[tuple[np.ndarray, ...]] = []
    for t, x in enumerate(xs):
        out[t] = chain.step(x)
        sent.append(chain.sent)
    arrays = {f"w{i}": w for i, w in enumerate(spec.weights)}
    arrays |= {f"b{i}": b for i, b in enumerate(spec.biases)}
    tag = "fixed_pt" if arithmetic == "fixed" else "floating_pt"
    np.savez(
        tmp_path / "spec.npz", xs=xs, layers=len(spec.biases), tag=tag, vth=np.array(spec.vth),
        vth_in=np.array(spec.vth_in), spike_exp=spike_exp, state_exp=state_exp,
        weight_exp=weight_exp, cum_error=cum_error, **arrays,
    )  # fmt: skip
    run = subprocess.run(
        [sys.executable, "-c", LAVA_RUN, str(tmp_path / "spec.npz"), str(tmp_path / "out.npz")],
        capture_output=True, text=True, timeout=150,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    got = np.load(tmp_path / "out.npz")
    n_layers = len(spec.biases) + 1
    for i in range(n_layers):  # every value every layer sent, step by step
        np.testing.assert_array_equal(got[f"s{i}"], np.stack([s[i] for s in sent]))
    lava_counts = np.stack([np.count_nonzero(got[f"s{i}"], axis=1) for i in range(n_layers)], 1)
    np.testing.assert_array_equal(lava_counts, chain.message_counts())
    assert max(np.abs(got[f"s{i}"]).max() for i in range(n_layers)) > 255  # graded, > 8 bits
    np.testing.assert_array_equal(got[f"s{n_layers}"], out)
    assert np.count_nonzero(out) > 20 and 0 < lava_counts.sum() < lava_counts.size * 8


def test_spec_from_block_puts_each_layers_unit_into_integer_weights() -> None:
    """Fixed point: W_int = round(W s_in / s_out), b_int = round(b / s); the integer chain at
    zero thresholds equals the real network to within the units' rounding; float64 keeps the
    real weights and scales the thresholds by each unit."""
    from snnkart.backends.sigma_delta import input_integers, spec_from_block
    from snnkart.contract.sigma_delta import SigmaDeltaBlock, SigmaDeltaLayer

    rng = np.random.default_rng(3)
    w = [rng.normal(0, 0.5, (6, 4)), rng.normal(0, 0.5, (2, 6))]
    b = [rng.normal(0, 0.1, 6), np.zeros(2)]
    block = SigmaDeltaBlock(
        layers=(SigmaDeltaLayer("fc1", 6, act_scale=3e-4, vth=5),),
        readout_node="fc2", input_scale=0.04, out_scale=3e-6, vth_in=1,
    )  # fmt: skip
    fixed = spec_from_block(block, w, b, "fixed")
    np.testing.assert_array_equal(fixed.weights[0], np.rint(w[0] * 0.04 / 3e-4))
    np.testing.assert_array_equal(fixed.biases[0], np.rint(b[0] / 3e-4))
    assert fixed.vth == (5.0,) and fixed.vth_in == 1
    flt = spec_from_block(block, w, b, "float64")
    assert flt.vth == (5 * 3e-4,) and flt.vth_in == 0.04
    z = rng.uniform(-2, 2, (5, 4))
    x = input_integers(block, z)
    zero = SigmaDeltaSpec(fixed.weights, fixed.biases, (0.0,), "fixed")
    out = relu_network(zero, x) * block.out_scale
    real = np.maximum(z @ w[0].T + b[0], 0) @ w[1].T
    np.testing.assert_allclose(out, real, atol=0.05)
    assert np.abs(out - real).max() > 0  # the units' rounding is real, and small
