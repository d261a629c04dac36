"""Re-check that the test suite catches the bugs it claims to catch.

    .venv/bin/python scripts/mutants.py [NAME ...]

Each mutant breaks one claim in memory (a pytest plugin monkeypatches the code at the start
of the session; no file is changed) and runs the tests that guard it; the mutant is *killed*
when that run fails. The script exits non-zero if any mutant survives.

- ``host-current-halved``: the host sends Lava half the first layer's current
  (``FixedPointNetwork.host_current``); guarded by ``tests/test_fixed_point.py``.
- ``final-values-zero``: the PPO time-limit bootstrap drops ``gamma * V(final_obs)``
  (``Rollout.final_values`` returns zeros); guarded by ``tests/test_gae.py``.
- ``deploy-mismatch``: Lava returns one flipped spike in every window from the 6th on
  (``LavaSimPredictor.step``); guarded by the parity tests in ``tests/deploy/``.
- ``parity-guard-off``: ``snnkart deploy`` no longer fails on a parity mismatch
  (``snnkart.eval.closed_loop.check_parity`` does nothing); guarded by
  ``tests/deploy/test_deploy_parity.py``.
- ``sb3-constant-lr``: ``bench_train`` gives Stable-Baselines3 a constant learning rate while
  snnkart anneals it (as it did before issue 13); guarded by ``tests/test_benchmarks.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUTANTS = {
    "host-current-halved": ["tests/test_fixed_point.py"],
    "final-values-zero": ["tests/test_gae.py"],
    "deploy-mismatch": ["tests/deploy", "-k", "bit_exact or cli_deploy"],
    "parity-guard-off": ["tests/deploy/test_deploy_parity.py", "-k", "parity_mismatch"],
    "sb3-constant-lr": ["tests/test_benchmarks.py", "-k", "bench_train"],
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
    else:
        raise SystemExit(f"unknown mutant {name!r}; choose from {', '.join(MUTANTS)}")


def pytest_configure(config: object) -> None:  # the plugin: `-p mutants` with scripts/ on the path
    apply(os.environ["SNNKART_MUTANT"])


def main() -> int:
    names = sys.argv[1:] or list(MUTANTS)
    survived = []
    for name in names:
        env = {**os.environ, "SNNKART_MUTANT": name, "SDL_VIDEODRIVER": "dummy",
               "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "scripts"),
                                                           os.environ.get("PYTHONPATH")]))}  # fmt: skip
        cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "mutants", "-p",
               "no:cacheprovider", *MUTANTS[name]]  # fmt: skip
        result = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        tail = (result.stdout.strip().splitlines() or [""])[-1]
        killed = result.returncode != 0 and "error" not in tail.lower()
        print(f"{name}: {'killed' if killed else 'SURVIVED'} ({tail})")
        if not killed:
            survived.append(name)
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
