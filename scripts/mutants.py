"""Re-check that the test suite catches the bugs it claims to catch.

    .venv/bin/python scripts/mutants.py [NAME ...]

Each mutant breaks one claim in memory (a pytest plugin monkeypatches the code at the start
of the session; no file is changed) and runs the tests that guard it. The plugin writes a
marker file once the mutant is applied. The mutant is *killed* when the marker exists and
pytest exits 1 with at least one failed test; it *survived* when pytest exits 0 with the
marker written. Anything else (not applied, an import error, a usage or collection error:
pytest's exit codes 2-5, or only errors and no failure) is an *error*: the run told nothing.
The script exits 1 if any mutant survived, 2 if none survived but one could not be judged.

- ``host-current-halved``: the host sends Lava half the first layer's current
  (``FixedPointNetwork.host_current``); guarded by ``tests/test_fixed_point.py``.
- ``final-values-zero``: the PPO time-limit bootstrap drops ``gamma * V(final_obs)``
  (``Rollout.final_values`` returns zeros); guarded by ``tests/test_gae.py`` and, on a
  hand-made two-step gymnasium episode, ``tests/test_any_env_train.py``.
- ``deploy-mismatch``: Lava returns one flipped spike in every window from the 6th on
  (``LavaSimPredictor.step``); guarded by the parity tests in ``tests/deploy/``.
- ``parity-guard-off``: ``snnkart deploy`` no longer fails on a parity mismatch
  (``snnkart.eval.closed_loop.check_parity`` does nothing); guarded by
  ``tests/deploy/test_deploy_parity.py``.
- ``sb3-constant-lr``: ``bench_train`` gives Stable-Baselines3 a constant learning rate while
  snnkart anneals it (as it did before issue 13); guarded by ``tests/test_benchmarks.py``.
- ``ppo-no-ratio-clip``: PPO's surrogate drops the ratio clipping
  (``snnkart.rl.ppo_loss.clipped_surrogate``); guarded by ``tests/test_ppo_loss.py``.
- ``ppo-adv-norm-batch``: advantages normalised over the whole batch (in ``Trainer.update``)
  instead of over each minibatch; guarded by ``tests/test_ppo_loss.py``.
- ``ppo-adv-norm-off``: advantages not normalised at all; guarded by ``tests/test_ppo_loss.py``.
- ``synops-fan-in``: synaptic operations counted as spikes x fan-in instead of fan-out
  (``ChainNetwork.fan_out``); guarded by the real-deployment counts test of
  ``tests/test_energy.py``.
- ``updates-one-step-short``: neuron updates count one clocked step fewer per window
  (``split_window``); guarded by the same test.
- ``resume-default-length``: ``train --resume`` trains to the command line's length (the
  default 300,000 steps) instead of the run's own (``snnkart.rl.ppo._resolve_config``);
  guarded by ``tests/test_resume_length.py``.
- ``shared-price-independent``: the joint uncertainty draws a price the SNN's host and the ANN
  share (SRAM reads, digital add/mult/MAC of one technology) independently on each side
  (``snnkart.energy.uncertainty.quantity``); guarded by ``tests/test_uncertainty.py``.
- ``zoo-energy-wide-ann``: the "same widths" ANN a deployment is priced against has twice its
  hidden widths (the width mismatch issue 46 names); guarded by the zoo study's deployed-seed
  test in ``tests/test_zoo_study.py``.
- ``memory-row-8kb``: every side's weights are priced as reads of an 8 KB SRAM whatever their
  footprint (``snnkart.energy.pricing.memory_row``; the choice that flipped the old verdict);
  guarded by ``tests/test_energy_terms.py``.
- ``idle-update-active``: every chip is read as updating only its active neurons, so a clocked
  profile (Loihi) prices a sigma-delta inference's idle neurons at nothing
  (``snnkart.energy.profiles.Profile.rule``); guarded by ``tests/test_sigma_delta_energy.py``.
- ``sd-threshold-strict``: the sigma-delta reference sends a message only when the change is
  strictly above its threshold (Lava's code sends at ``>=``; ``SigmaDeltaChain._encode``);
  guarded by the Lava parity tests of ``tests/test_sigma_delta.py``.
- ``stateful-forgets``: a stateful LIF policy restarts from zero state at every env step in
  torch (``snnkart.rl.policies.stream_step``); guarded by ``tests/test_stateful.py``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUTANTS = {
    "host-current-halved": ["tests/test_fixed_point.py"],
    "final-values-zero": ["tests/test_gae.py", "tests/test_any_env_train.py"],
    "deploy-mismatch": ["tests/deploy", "-k", "bit_exact or cli_deploy"],
    "parity-guard-off": ["tests/deploy/test_deploy_parity.py", "-k", "parity_mismatch"],
    "sb3-constant-lr": ["tests/test_benchmarks.py", "-k", "bench_train"],
    "ppo-no-ratio-clip": ["tests/test_ppo_loss.py"],
    "ppo-adv-norm-batch": ["tests/test_ppo_loss.py"],
    "ppo-adv-norm-off": ["tests/test_ppo_loss.py"],
    "synops-fan-in": ["tests/test_energy.py", "-k", "real_deployment"],
    "updates-one-step-short": ["tests/test_energy.py", "-k", "real_deployment"],
    "resume-default-length": ["tests/test_resume_length.py", "-k", "keeps"],
    "shared-price-independent": ["tests/test_uncertainty.py"],
    "memory-row-8kb": ["tests/test_energy_terms.py"],
    "idle-update-active": ["tests/test_sigma_delta_energy.py"],
    "sd-threshold-strict": ["tests/test_sigma_delta.py", "-k", "bit_exact"],
    "stateful-forgets": ["tests/test_stateful.py", "-k", "torch_policy_equals"],
    "stateful-reference-resets": ["tests/test_stateful.py", "-k", "numpy_references_carry"],
    "bc-wrong-rows": ["tests/test_bc.py", "-k", "own_rows"],
    "reporting-set-unchecked": ["tests/test_study_protocol.py", "-k", "moves"],
    "zoo-energy-wide-ann": ["tests/test_zoo_study.py", "-k", "deploys_bit_exact"],
}


def apply(name: str) -> None:
    """Called by the plugin below inside the pytest process."""
    import numpy as np

    if name == "host-current-halved":
        from snnkart.backends.quantize import FixedPointNetwork

        real = FixedPointNetwork.host_current
        FixedPointNetwork.host_current = lambda self, c: real(self, np.asarray(c) / 2)  # type: ignore[method-assign]
    elif name == "final-values-zero":
        from snnkart.rl.rollout import Rollout

        Rollout.final_values = lambda self, policy, obs_rms, info, truncated: np.zeros(  # type: ignore[method-assign]
            truncated.shape[0]
        )
    elif name == "deploy-mismatch":
        import dataclasses

        from snnkart.backends.lava_sim import LavaSimPredictor

        real_step = LavaSimPredictor.step

        def step(self, obs):  # type: ignore[no-untyped-def]
            window, out = real_step(self, obs)
            self._mutant_calls = getattr(self, "_mutant_calls", 0) + 1
            if self._mutant_calls >= 6:
                raster = window.raster.copy()
                raster[0, 0] ^= True
                window = dataclasses.replace(window, raster=raster)
            return window, out

        LavaSimPredictor.step = step  # type: ignore[method-assign]
    elif name == "parity-guard-off":
        import snnkart.eval.closed_loop

        snnkart.eval.closed_loop.check_parity = lambda record: None
    elif name == "sb3-constant-lr":
        from stable_baselines3 import PPO

        real_init = PPO.__init__

        def init(self, *args, learning_rate=3e-4, **kwargs):  # type: ignore[no-untyped-def]
            constant = learning_rate(1.0) if callable(learning_rate) else learning_rate
            real_init(self, *args, learning_rate=constant, **kwargs)

        PPO.__init__ = init  # type: ignore[method-assign]
    elif name.startswith("ppo-"):
        _apply_ppo(name)
    elif name == "synops-fan-in":
        from snnkart.backends.network import ChainNetwork

        ChainNetwork.fan_out = property(lambda self: (self.n_in, *self.sizes[:-1]))  # type: ignore[method-assign,assignment]
    elif name == "updates-one-step-short":
        import dataclasses

        from snnkart.backends import backend, base, open_loop

        real_split = base.split_window

        def split_window(raster, sizes, *args, **kwargs):  # type: ignore[no-untyped-def]
            window = real_split(raster, sizes, *args, **kwargs)
            fewer = window.neuron_updates - np.asarray(sizes, dtype=np.int64)
            return dataclasses.replace(window, neuron_updates=fewer)

        for module in (base, backend, open_loop):
            module.split_window = split_window  # type: ignore[attr-defined]
    elif name == "resume-default-length":
        import snnkart.rl.ppo

        real_resolve = snnkart.rl.ppo._resolve_config

        def resolve(cfg, run_dir, resume, total_steps):  # type: ignore[no-untyped-def]
            return real_resolve(cfg, run_dir, resume, cfg.total_steps if resume else total_steps)

        snnkart.rl.ppo._resolve_config = resolve  # type: ignore[assignment]
    elif name == "shared-price-independent":
        import snnkart.energy.uncertainty

        snnkart.energy.uncertainty.quantity = lambda profile, op: f"{profile.name}.{op}"  # type: ignore[assignment]
    elif name == "memory-row-8kb":
        import snnkart.energy.pricing

        snnkart.energy.pricing.memory_row = lambda nbytes: "sram_read_8kb"  # type: ignore[assignment]
    elif name == "idle-update-active":
        import dataclasses

        from snnkart.energy.profiles import Profile

        real_rule = Profile.rule

        def rule(self, which):  # type: ignore[no-untyped-def]
            found = real_rule(self, which)
            return (
                dataclasses.replace(found, value="active") if which == "neuron_updates" else found
            )

        Profile.rule = rule  # type: ignore[method-assign]
    elif name == "sd-threshold-strict":
        from snnkart.backends.sigma_delta import SigmaDeltaChain

        real_encode = SigmaDeltaChain._encode

        def encode(self, i, act_new):  # type: ignore[no-untyped-def]
            vth = self.vth[i]
            self.vth[i] = vth + (1 if self.spec.fixed else 1e-9)  # '>=' on vth + 1 is '>'
            try:
                return real_encode(self, i, act_new)
            finally:
                self.vth[i] = vth

        SigmaDeltaChain._encode = encode  # type: ignore[method-assign]
    elif name == "stateful-forgets":
        import torch

        import snnkart.rl.policies

        real_stream = snnkart.rl.policies.stream_step
        snnkart.rl.policies.stream_step = lambda snn, x, state, loops=(): real_stream(  # type: ignore[assignment]
            snn, x, torch.zeros_like(state), loops
        )
    elif name == "stateful-reference-resets":
        from snnkart.backends.reference import _LavaPipeline

        real_window = _LavaPipeline._window

        def window(self, current):  # type: ignore[no-untyped-def]
            self._zero()  # every env step from zero state, as a per-window policy
            return real_window(self, current)

        _LavaPipeline._window = window  # type: ignore[method-assign]
    elif name == "bc-wrong-rows":
        import dataclasses

        import snnkart.rl.bc

        real_clone = snnkart.rl.bc.behaviour_clone

        def clone(policy, obs_rms, cfg, rec):  # type: ignore[no-untyped-def]
            shifted = dataclasses.replace(rec, actions=np.roll(rec.actions, 1))
            return real_clone(policy, obs_rms, cfg, shifted)

        snnkart.rl.bc.behaviour_clone = clone  # type: ignore[assignment]
    elif name == "reporting-set-unchecked":
        import snnkart.app.study_run

        real_problem = snnkart.app.study_run.data_problem
        snnkart.app.study_run.data_problem = lambda kind, seeds, tracks: (  # type: ignore[assignment]
            real_problem(kind, seeds, tracks) if kind == "tuning" else None
        )
    elif name == "zoo-energy-wide-ann":
        import dataclasses

        import snnkart.app.report

        real_width = snnkart.app.report.same_width

        def wide(snn):  # type: ignore[no-untyped-def]
            ann = real_width(snn)
            widths = (ann.widths[0], *(2 * w for w in ann.widths[1:-1]), ann.widths[-1])
            return dataclasses.replace(ann, widths=widths)

        snnkart.app.report.same_width = wide  # type: ignore[assignment]
    else:
        raise SystemExit(f"unknown mutant {name!r}; choose from {', '.join(MUTANTS)}")


def _apply_ppo(name: str) -> None:
    import dataclasses

    import torch

    import snnkart.rl.ppo
    import snnkart.rl.ppo_loss

    real = snnkart.rl.ppo_loss.clipped_surrogate

    def unclipped(log_prob, old_log_prob, advantages, clip_coef, norm_adv):  # type: ignore[no-untyped-def]
        logratio = log_prob - old_log_prob
        ratio = logratio.exp()
        adv = snnkart.rl.ppo_loss.normalise_advantages(advantages) if norm_adv else advantages
        return (-adv * ratio).mean(), ratio, logratio

    def unnormalised(log_prob, old_log_prob, advantages, clip_coef, norm_adv):  # type: ignore[no-untyped-def]
        return real(log_prob, old_log_prob, advantages, clip_coef, False)

    mutant = unclipped if name == "ppo-no-ratio-clip" else unnormalised
    snnkart.rl.ppo_loss.clipped_surrogate = mutant
    snnkart.rl.ppo.clipped_surrogate = mutant  # type: ignore[attr-defined]
    if name == "ppo-adv-norm-batch":
        Trainer = snnkart.rl.ppo.Trainer
        real_update = Trainer.update

        def update(self, b, seq=None):  # type: ignore[no-untyped-def]
            adv = b.advantages
            adv = (adv - adv.mean()) / (adv.std() + 1e-8) if self.cfg.ppo.norm_adv else adv
            return real_update(self, dataclasses.replace(b, advantages=torch.as_tensor(adv)), seq)

        Trainer.update = update  # type: ignore[method-assign]


def pytest_configure(config: object) -> None:  # the plugin: `-p mutants` with scripts/ on the path
    apply(os.environ["SNNKART_MUTANT"])
    Path(os.environ["SNNKART_MUTANT_APPLIED"]).write_text(os.environ["SNNKART_MUTANT"])


def verdict(name: str, returncode: int, stdout: str, applied: Path) -> str:
    """``killed``, ``SURVIVED`` or ``ERROR: why`` for one mutant's pytest run."""
    if not applied.is_file() or applied.read_text() != name:
        return "ERROR: the mutant was never applied"
    if returncode == 0:
        return "SURVIVED"
    if returncode != 1:
        return f"ERROR: pytest exit code {returncode}"
    if not re.search(r"\b\d+ failed\b", stdout):
        return "ERROR: no test failed (errors only)"
    return "killed"


def main() -> int:
    names = sys.argv[1:] or list(MUTANTS)
    unknown = [n for n in names if n not in MUTANTS]
    if unknown:
        raise SystemExit(f"unknown mutant {unknown[0]!r}; choose from {', '.join(MUTANTS)}")
    verdicts = {}
    for name in names:
        with tempfile.TemporaryDirectory(prefix="snnkart-mutant-") as tmp:
            applied = Path(tmp) / "applied"
            env = {**os.environ, "SNNKART_MUTANT": name, "SNNKART_MUTANT_APPLIED": str(applied),
                   "SDL_VIDEODRIVER": "dummy",
                   "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "scripts"),
                                                               os.environ.get("PYTHONPATH")]))}  # fmt: skip
            cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "mutants", "-p",
                   "no:cacheprovider", *MUTANTS[name]]  # fmt: skip
            result = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
            verdicts[name] = verdict(name, result.returncode, result.stdout, applied)
        tail = (result.stdout.strip() or result.stderr.strip() or "no output").splitlines()[-1]
        print(f"{name}: {verdicts[name]} ({tail})")
    if "SURVIVED" in verdicts.values():
        return 1
    return 2 if any(v.startswith("ERROR") for v in verdicts.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
