"""The quantisation rules for Lava's fixed point: exported policies, edge cases, non-uniform
neurons and a bias the mantissa cannot hold."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from deploy_helpers import (
    RUNS,
)

from snnkart.backends.loading import load_chain
from snnkart.backends.network import ChainNetwork, UnsupportedGraphError
from snnkart.backends.quantize import (
    DECAY_UNITY,
    VTH_HOST,
    VTH_MAX,
    WEIGHT_MAX,
    quantize,
)
from snnkart.rl.trained import LoadedRun

# -- quantisation ------------------------------------------------------------------------------


def _with_layer(chain: ChainNetwork, i: int, **changes: Any) -> ChainNetwork:
    layers = list(chain.layers)
    layers[i] = dataclasses.replace(layers[i], **changes)
    return dataclasses.replace(chain, layers=tuple(layers))


def _check_fixed(chain: ChainNetwork) -> None:
    """Every quantisation rule, for every layer of ``chain``."""
    fixed = quantize(chain)
    assert len(fixed.layers) == len(chain.layers)
    for i, (layer, q) in enumerate(zip(chain.layers, fixed.layers, strict=True)):
        beta = float(layer.beta[0])
        assert q.dv == round((1 - beta) * DECAY_UNITY), (i, beta)
        assert q.du == 4095
        assert 1 <= q.vth <= VTH_MAX
        assert 0 <= q.bias_exp <= 7
        assert q.bias_mant.dtype.kind == "i" and np.all(np.abs(q.bias_mant) <= 4095)
        theta = float(layer.threshold[0])
        if i == 0:
            assert q.weight is None and q.vth == VTH_HOST and q.scale == VTH_HOST / theta
            assert np.all(q.bias_mant == 0)
            continue
        assert q.weight is not None and q.weight.dtype.kind == "i"
        assert np.all(q.weight % 2 == 0)
        assert q.weight.min() >= -256 and q.weight.max() <= WEIGHT_MAX
        exact = layer.weight.astype(np.float64) * q.scale
        assert np.max(np.abs(q.weight - exact)) <= 1.0 + 1e-9  # nearest even integer
        assert q.vth == max(round(theta * q.scale), 1)
        target = layer.bias.astype(np.float64) * q.scale * 64
        err = np.abs(q.effective_bias - target)
        bound = (2 ** (q.bias_exp - 1) if q.bias_exp else 0) + 0.5  # rounding of the mantissa
        assert np.all(err <= bound), (i, err.max(), q.bias_exp)


def test_quantize_exported_policy(excited: dict[str, tuple[LoadedRun, Path]]) -> None:
    for name in RUNS:
        chain, manifest = load_chain(excited[name][1])
        _check_fixed(chain)
        q = quantize(chain).layers[1]
        assert q.weight is not None and int(np.abs(q.weight).max()) == WEIGHT_MAX
        assert q.dv == round((1 - manifest.layers[1].beta) * DECAY_UNITY) == 410  # beta 0.9


def test_quantize_edge_cases(exported: Path) -> None:
    chain, _ = load_chain(exported)
    layer = chain.layers[1]
    # large biases need an exponent
    big_bias = _with_layer(chain, 1, bias=np.linspace(-6.0, 6.0, layer.size).astype(np.float32))
    _check_fixed(big_bias)
    assert quantize(big_bias).layers[1].bias_exp > 0
    # tiny weights against the threshold: vth is capped at 17 bits, the weights lose resolution
    tiny = _with_layer(
        chain, 1, weight=(layer.weight * 1e-4).astype(np.float32), bias=np.zeros_like(layer.bias)
    )
    q = quantize(tiny).layers[1]
    assert q.vth == VTH_MAX and q.scale == VTH_MAX / float(layer.threshold[0])
    _check_fixed(tiny)
    for beta in (0.001, 0.5, 0.9, 0.95, 0.999):
        _check_fixed(_with_layer(chain, 0, beta=np.full(chain.sizes[0], beta)))
        _check_fixed(_with_layer(chain, 1, beta=np.full(layer.size, beta)))
    for theta in (0.25, 1.0, 3.0):
        _check_fixed(_with_layer(chain, 1, threshold=np.full(layer.size, theta)))
    # beta = 0 needs dv = 4096, one more than 12 bits hold: the largest decay is used
    assert quantize(_with_layer(chain, 1, beta=np.zeros(layer.size))).layers[1].dv == 4095


@pytest.mark.parametrize("field", ["beta", "threshold"])
def test_quantize_refuses_non_uniform_neurons(field: str, exported: Path) -> None:
    chain, _ = load_chain(exported)
    n = chain.sizes[1]
    values = np.linspace(0.5, 0.9, n) if field == "beta" else np.linspace(0.5, 1.5, n)
    bad = _with_layer(chain, 1, **{field: values})
    with pytest.raises(UnsupportedGraphError, match="non-uniform") as info:
        quantize(bad)
    assert repr(chain.layers[1].neuron) in str(info.value)  # names the LIF node ('3')
    assert ("decay" if field == "beta" else "threshold") in str(info.value)


# -- quantisation: a bias the 13-bit mantissa cannot hold (last: it needs a fix in quantize) ---


def test_quantize_bias_fits_or_is_refused(exported: Path) -> None:
    """A bias the 13-bit mantissa cannot hold at the chosen scale (small weights, bias half the
    threshold) must be represented (a smaller scale) or refused, not silently saturated: the
    fixed-point network would otherwise spike differently from the float one."""
    chain, _ = load_chain(exported)
    layer = chain.layers[1]
    weight = (layer.weight / np.abs(layer.weight).max() * 0.01).astype(np.float32)
    weak = _with_layer(chain, 1, weight=weight, bias=np.full(layer.size, 0.5, np.float32))
    try:
        fixed = quantize(weak)
    except UnsupportedGraphError as exc:
        assert "bias" in str(exc) and "'3'" in str(exc)
        return
    q = fixed.layers[1]
    represented = q.effective_bias / (q.scale * 64)  # the bias the fixed-point network adds
    assert np.all(np.abs(q.bias_mant) <= 4095), q.bias_mant
    np.testing.assert_allclose(represented, 0.5, rtol=0.01, err_msg="the bias was saturated")
    _check_fixed(weak)
