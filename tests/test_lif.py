"""The fused LIF kernel equals snntorch's ``Leaky`` (reset to zero, no reset delay)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import snntorch as snn
import torch
from snntorch import surrogate

from snnkart.rl.config import SNNConfig
from snnkart.rl.lif import fused_cuba_layer, fused_lif_layer
from snnkart.rl.policies import SpikingActor

RTOL = 1e-5
ATOL = 1e-6

SHAPES = [(8, 4, 16), (16, 3, 33), (5, 1, 7)]
BETAS = [0.0, 0.5, 0.95]
THRESHOLDS = [0.5, 1.0]
SLOPES = [25.0, 5.0]


def _leaky(beta: float, threshold: float, slope: float) -> snn.Leaky:
    return snn.Leaky(
        beta=torch.tensor(beta),
        threshold=torch.tensor(threshold),
        spike_grad=surrogate.fast_sigmoid(slope=slope),
        reset_mechanism="zero",
        reset_delay=False,
        learn_beta=True,
        learn_threshold=True,
    )


def _reference(x: torch.Tensor, lif: snn.Leaky) -> tuple[torch.Tensor, torch.Tensor]:
    """snntorch stepped T times from mem = 0: spikes [T, B, N] and post-reset membranes."""
    mem = torch.zeros(x.shape[1:])
    spikes, mems = [], []
    for t in range(x.shape[0]):
        spk, mem = lif(x[t], mem)
        spikes.append(spk)
        mems.append(mem)
    return torch.stack(spikes), torch.stack(mems)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("shape", SHAPES)
def test_fused_lif_matches_snntorch(seed: int, shape: tuple[int, int, int]) -> None:
    for beta, threshold, slope in itertools.product(BETAS, THRESHOLDS, SLOPES):
        g = torch.Generator().manual_seed(seed * 1000 + hash(shape) % 997)
        x = torch.randn(shape, generator=g) * 0.8 + 0.3
        upstream = torch.randn(shape, generator=g)  # random dL/dspikes

        lif = _leaky(beta, threshold, slope)
        x_ref = x.clone().requires_grad_(True)
        spk_ref, mem_ref = _reference(x_ref, lif)
        (spk_ref * upstream).sum().backward()

        x_fused = x.clone().requires_grad_(True)
        beta_f = torch.tensor(beta, requires_grad=True)
        thr_f = torch.tensor(threshold, requires_grad=True)
        spk_fused = fused_lif_layer(x_fused, beta_f, thr_f, slope)
        (spk_fused * upstream).sum().backward()

        case = f"seed={seed} shape={shape} beta={beta} thr={threshold} slope={slope}"
        assert 0.05 < spk_ref.mean().item() < 0.95, case  # the inputs make it spike
        assert spk_fused.dtype == spk_ref.dtype and spk_fused.shape == spk_ref.shape
        assert torch.equal(spk_fused, spk_ref), case

        # d/d input: elementwise, atol scaled by the gradients' magnitude
        g_ref = x_ref.grad
        assert g_ref is not None and x_fused.grad is not None
        atol_x = ATOL * max(1.0, g_ref.abs().max().item())
        torch.testing.assert_close(x_fused.grad, g_ref, rtol=RTOL, atol=atol_x, msg=case)

        # d/d beta = sum_t>0 dL/dU_t * U_{t-1}(post-reset), and dL/dU_t = dL/dI_t: a sum of
        # T*B*N float32 terms, so atol is scaled by the sum of their magnitudes.
        beta_terms = (g_ref[1:].abs() * mem_ref[:-1].detach().abs()).sum().item()
        atol_b = ATOL * max(1.0, beta_terms)
        assert lif.beta.grad is not None and beta_f.grad is not None
        torch.testing.assert_close(
            beta_f.grad, lif.beta.grad.reshape(()), rtol=RTOL, atol=atol_b, msg=case
        )
        # d/d threshold = -sum dL/dS_total * surrogate; scale by the summed gradient magnitudes
        thr_terms = (g_ref.abs().sum() + upstream.abs().sum()).item()
        atol_t = ATOL * max(1.0, thr_terms)
        assert lif.threshold.grad is not None and thr_f.grad is not None
        torch.testing.assert_close(
            thr_f.grad, lif.threshold.grad.reshape(()), rtol=RTOL, atol=atol_t, msg=case
        )
        if beta > 0.0:
            assert lif.beta.grad.abs().item() > 0.0, case  # the test exercises a real gradient
        assert lif.threshold.grad.abs().item() > 0.0, case


ALPHAS = [0.0, 0.6, 0.9]


def _synaptic(alpha: float, beta: float, threshold: float, slope: float) -> snn.Synaptic:
    return snn.Synaptic(
        alpha=torch.tensor(alpha), beta=torch.tensor(beta), threshold=torch.tensor(threshold),
        spike_grad=surrogate.fast_sigmoid(slope=slope), reset_mechanism="zero",
        reset_delay=False, learn_alpha=True, learn_beta=True, learn_threshold=True,
    )  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("shape", SHAPES)
def test_fused_cuba_lif_matches_snntorch_synaptic(seed: int, shape: tuple[int, int, int]) -> None:
    """Spikes identical, gradients of input, alpha, beta and threshold equal to float32
    rounding, against snntorch's ``Synaptic`` stepped T times from I = U = 0."""
    for alpha, beta, threshold, slope in itertools.product(ALPHAS, BETAS, THRESHOLDS, SLOPES[:1]):
        g = torch.Generator().manual_seed(seed * 1000 + hash(shape) % 997)
        x = torch.randn(shape, generator=g) * 0.8 + 0.3 * (1 - alpha)
        upstream = torch.randn(shape, generator=g)
        lif = _synaptic(alpha, beta, threshold, slope)
        x_ref = x.clone().requires_grad_(True)
        syn, mem = torch.zeros(shape[1:]), torch.zeros(shape[1:])
        spikes = []
        for t in range(shape[0]):
            spk, syn, mem = lif(x_ref[t], syn, mem)
            spikes.append(spk)
        spk_ref = torch.stack(spikes)
        (spk_ref * upstream).sum().backward()

        x_fused = x.clone().requires_grad_(True)
        params = [torch.tensor(v, requires_grad=True) for v in (alpha, beta, threshold)]
        spk_fused = fused_cuba_layer(x_fused, *params, slope)
        (spk_fused * upstream).sum().backward()

        case = f"seed={seed} shape={shape} alpha={alpha} beta={beta} thr={threshold}"
        assert 0.05 < spk_ref.mean().item() < 0.95, case
        assert torch.equal(spk_fused, spk_ref), case
        assert x_ref.grad is not None and x_fused.grad is not None
        scale = max(1.0, x_ref.grad.abs().sum().item() + upstream.abs().sum().item())
        torch.testing.assert_close(x_fused.grad, x_ref.grad, rtol=RTOL,
                                   atol=ATOL * max(1.0, x_ref.grad.abs().max().item()), msg=case)  # fmt: skip
        for mine, ref in zip(params, (lif.alpha, lif.beta, lif.threshold), strict=True):
            assert mine.grad is not None and ref.grad is not None
            torch.testing.assert_close(mine.grad, ref.grad.reshape(()), rtol=1e-4,
                                       atol=ATOL * scale, msg=case)  # fmt: skip
        assert lif.threshold.grad.abs().item() > 0.0, case
        if alpha > 0.0:
            assert lif.alpha.grad.abs().item() > 0.0, case  # a real gradient is compared


def test_fused_lif_float32_no_input_mutation() -> None:
    x = torch.randn(6, 2, 5) + 0.5
    before = x.clone()
    out = fused_lif_layer(x, torch.tensor(0.9), torch.tensor(1.0), 25.0)
    assert out.dtype == torch.float32 and out.shape == x.shape
    assert torch.equal(x, before)
    assert set(np.unique(out.numpy()).tolist()) <= {0.0, 1.0}


@pytest.mark.parametrize("neuron", ["lif", "cuba"])
@pytest.mark.parametrize("encoding", ["current", "rate"])
@pytest.mark.parametrize("learn", [False, True])
def test_spiking_actor_fused_equals_unfused(encoding: str, learn: bool, neuron: str) -> None:
    cfg = SNNConfig(
        num_steps=6,
        hidden=(24, 20),
        beta=0.85,
        threshold=0.8,
        encoding=encoding,  # type: ignore[arg-type]
        learn_beta=learn,
        learn_threshold=learn,
        surrogate_slope=10.0,
        neuron=neuron,  # type: ignore[arg-type]
        alpha=0.4,
        learn_alpha=learn,
    )
    torch.manual_seed(3)
    actor = SpikingActor(n_in=11, n_out=4, cfg=cfg)
    obs01 = torch.rand(9, 11)
    spikes = actor.encode(obs01) if encoding == "rate" else None
    upstream = torch.randn(9, 4)

    results = {}
    for fused in (False, True):
        actor.zero_grad()
        out, rates, records = actor(obs01, spikes, fused=fused)
        (out * upstream).sum().backward()
        grads = {n: p.grad.clone() for n, p in actor.named_parameters() if p.grad is not None}
        results[fused] = (out.detach(), rates.detach(), [r.detach() for r in records], grads)

    (o0, r0, s0, g0), (o1, r1, s1, g1) = results[False], results[True]
    assert torch.equal(o1, o0)
    assert torch.equal(r1, r0)
    assert all(torch.equal(a, b) for a, b in zip(s1, s0, strict=True))
    assert 0.0 < r0.min().item() and r0.max().item() < 1.0  # both layers spike, not saturated
    assert g1.keys() == g0.keys()
    if learn:
        assert {"lif1.beta", "lif1.threshold", "lif2.beta", "lif2.threshold"} <= g0.keys()
    if learn and neuron == "cuba":
        assert {"lif1.alpha", "lif2.alpha"} <= g0.keys()
    for name in g0:
        scale = max(1.0, g0[name].abs().max().item())
        torch.testing.assert_close(g1[name], g0[name], rtol=RTOL, atol=1e-5 * scale, msg=name)
