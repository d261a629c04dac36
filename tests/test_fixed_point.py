"""Fixed point against the *trained* float policy, independently of the code under test.

The Lava parity tests compare Lava with the numpy reference in the same arithmetic: both use
``quantize()`` and the same host codec, so a quantisation bug is invisible to them. Here the
quantised network is dequantised (integers divided by their scale) and compared, layer by
layer, with the torch policy's own parameters and currents, each within a bound derived from
its quantisation step:

- weights are even integers: ``|w / S - W| <= 1 / S``;
- thresholds and the host current are rounded: ``<= 0.5 / S``;
- a bias ``mant * 2**exp`` in units of ``1 / (64 S)``, rounded to those units and then to the
  mantissa: ``<= (0.5 + 0.5 * 2**exp) / (64 S)``;
- decays are 12-bit: ``|(1 - dv / 4096) - beta| <= 0.5 / 4096``.

The torch side normalises observations with the training code (``normalize_obs``), not with
the deployment codec, and reads the weights from the policy, not from the NIR file.
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

from pathlib import Path

import numpy as np
import pytest
import torch
from tiny_runs import train_tiny

from snnkart.backends.loading import load_chain
from snnkart.backends.quantize import ACT_SHIFT, DECAY_UNITY, HOST_CURRENT_MAX, quantize
from snnkart.backends.reference import NIRReference
from snnkart.export.nir_export import export_nir
from snnkart.rl.ppo import normalize_obs
from snnkart.rl.trained import LoadedRun, load_run

OBSERVATIONS = 300


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[LoadedRun, Path, np.ndarray]:
    """A tiny steer SNN (current encoding), its export and recorded observations."""
    base = tmp_path_factory.mktemp("fixed")
    run = load_run(train_tiny(base / "run", "steer", "snn"))
    nir_path, _ = export_nir(run, base / "policy.nir")
    env = run.config.make_env(track=run.track)
    rng = np.random.default_rng(0)
    observations = []
    obs, _ = env.reset(seed=0)
    while len(observations) < OBSERVATIONS:
        observations.append(obs)
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, _ = env.reset(seed=int(rng.integers(10_000)))
    env.close()
    return run, nir_path, np.stack(observations)


def _torch_layers(run: LoadedRun) -> list[dict[str, np.ndarray | float]]:
    snn = run.policy.snn  # type: ignore[union-attr]
    layers = []
    for fc, lif in ((snn.fc1, snn.lif1), (snn.fc2, snn.lif2)):
        layers.append({
            "W": fc.weight.detach().double().numpy(),
            "b": fc.bias.detach().double().numpy(),
            "beta": float(lif.beta.detach().reshape(-1)[0]),
            "theta": float(lif.threshold.detach().reshape(-1)[0]),
        })  # fmt: skip
    return layers


def test_dequantised_parameters_match_the_trained_policy(
    trained: tuple[LoadedRun, Path, np.ndarray],
) -> None:
    run, nir_path, _ = trained
    chain, _ = load_chain(nir_path)
    fixed = quantize(chain)
    for i, (q, f) in enumerate(zip(fixed.layers, _torch_layers(run), strict=True)):
        beta_q = 1.0 - q.dv / DECAY_UNITY
        assert abs(beta_q - f["beta"]) <= 0.5 / DECAY_UNITY + 1e-9, (i, beta_q, f["beta"])
        assert abs(q.vth / q.scale - f["theta"]) <= 0.5 / q.scale + 1e-9 * f["theta"], i
        assert q.du == DECAY_UNITY - 1  # no synaptic memory, as in snntorch's Leaky
        if i == 0:
            continue  # the host computes layer 0's current (next test)
        W, b = f["W"], f["b"]
        assert q.weight is not None and np.all(q.weight % 2 == 0)
        err_w = np.abs(q.weight / q.scale - W)
        assert err_w.max() <= 1.0 / q.scale * (1 + 1e-9), (i, err_w.max(), 1.0 / q.scale)
        # rounded twice: to 1/(64 S), then to the mantissa's 2**exp of those
        bias = q.effective_bias / (q.scale * 2**ACT_SHIFT)
        bound = (0.5 + 0.5 * 2.0**q.bias_exp) / (q.scale * 2**ACT_SHIFT) * (1 + 1e-9)
        assert np.abs(bias - b).max() <= bound, (i, np.abs(bias - b).max(), bound)


def test_host_current_matches_the_trained_first_layer(
    trained: tuple[LoadedRun, Path, np.ndarray],
) -> None:
    """The integer current the host sends Lava, dequantised, is the trained policy's first
    layer current on the same observation, within half a quantisation step."""
    run, nir_path, observations = trained
    fixed_reference = NIRReference(nir_path, "fixed")
    scale = fixed_reference.fixed.layers[0].scale
    f = _torch_layers(run)[0]
    norm = normalize_obs(run.obs_rms, run.config.ppo, observations).astype(np.float64)
    torch_current = norm @ f["W"].T + f["b"]  # (obs, n1), the training code's normalisation
    sent = np.stack([fixed_reference.codec.encode(obs)[0] for obs in observations])
    unclipped = np.abs(torch_current * scale) < HOST_CURRENT_MAX - 1
    assert unclipped.mean() > 0.99
    err = np.abs(sent / scale - torch_current)[unclipped]
    assert err.max() <= 0.5 / scale + 1e-6 * np.abs(torch_current).max(), err.max()
    # saturated entries still fire (or stay silent) exactly like the float current
    theta = f["theta"]
    assert np.array_equal((sent / scale > theta)[~unclipped], (torch_current > theta)[~unclipped])


def test_layer_two_current_matches_for_the_same_spikes(
    trained: tuple[LoadedRun, Path, np.ndarray],
) -> None:
    """Dense input of layer 2 for the float policy's own layer-1 spikes: the dequantised
    integer current is the float one within the weights' and bias' rounding."""
    run, nir_path, observations = trained
    q = quantize(load_chain(nir_path)[0]).layers[1]
    f = _torch_layers(run)[1]
    snn = run.policy.snn  # type: ignore[union-attr]
    norm = torch.from_numpy(normalize_obs(run.obs_rms, run.config.ppo, observations))
    with torch.no_grad():
        current1 = snn.fc1(norm)
        mem = torch.zeros_like(current1)
        spikes = []
        for _ in range(run.config.snn.num_steps):
            spk, mem = snn.lif1(current1, mem)
            spikes.append(spk)
    s = torch.stack(spikes).reshape(-1, current1.shape[1]).double().numpy()
    float_current = s @ f["W"].T + f["b"]
    fixed_current = (s @ q.weight.T + q.effective_bias / 2**ACT_SHIFT) / q.scale
    bound = (s.sum(axis=1, keepdims=True) + (0.5 + 0.5 * 2.0**q.bias_exp) / 2**ACT_SHIFT) / q.scale
    assert s.sum() > 0, "layer 1 never fired: the comparison would be vacuous"
    assert np.all(np.abs(fixed_current - float_current) <= bound * (1 + 1e-9) + 1e-9)


# -- closed loop, on a policy that drives -----------------------------------------------------

FIXTURE = Path(__file__).resolve().parent / "data" / "policies" / "grid-snn"
"""A grid/small_S SNN trained for 300k steps with the defaults (seed 1), optimizer state
dropped; made by ``scripts/make_test_policy.py``."""
EPISODES = 20
FIRST_SEED = 10_000


class _Shadowed:
    """Drives with ``primary`` and counts how often ``shadow`` picks the same action."""

    def __init__(self, primary: object, shadow: NIRReference) -> None:
        self.primary, self.shadow = primary, shadow
        self.steps = self.same = 0

    def reset(self) -> None:
        self.primary.reset()  # type: ignore[attr-defined]
        self.shadow.reset()

    def predict(self, obs: np.ndarray) -> object:
        action = self.primary.predict(obs)  # type: ignore[attr-defined]
        self.steps += 1
        self.same += int(action == self.shadow.predict(obs))
        return action


def test_fixed_point_drives_like_the_trained_policy(tmp_path: Path) -> None:
    """On 20 seeded episodes: the fixed-point network picks the trained policy's action on at
    least 98 % of the steps it drives, and finishes within 5 points of it."""
    from snnkart.eval.episodes import EvalSummary, run_episodes
    from snnkart.rl.trained import TorchPredictor

    run = load_run(FIXTURE)
    nir_path, _ = export_nir(run, tmp_path / "policy.nir")
    env = run.config.make_env(track=run.track)
    try:
        by_torch = _Shadowed(TorchPredictor(run, seed=FIRST_SEED), NIRReference(nir_path, "fixed"))
        torch_runs = run_episodes(env, by_torch, EPISODES, FIRST_SEED)
        by_fixed = _Shadowed(NIRReference(nir_path, "fixed"), NIRReference(nir_path, "float32"))
        fixed_runs = run_episodes(env, by_fixed, EPISODES, FIRST_SEED)
    finally:
        env.close()
    torch_success = EvalSummary.of(torch_runs).success_rate
    fixed_success = EvalSummary.of(fixed_runs).success_rate
    agreement = by_torch.same / by_torch.steps
    print(f"\nfixed vs torch: {agreement:.2%} identical actions over {by_torch.steps} steps; "
          f"success torch {torch_success:.0%}, fixed {fixed_success:.0%}")  # fmt: skip
    assert torch_success >= 0.8, "the fixture does not drive: the comparison would be weak"
    assert agreement >= 0.98
    assert abs(torch_success - fixed_success) <= 0.05 + 1e-9
    assert by_fixed.same / by_fixed.steps >= 0.98  # the fixed driver vs float32 reference
