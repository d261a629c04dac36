"""Expert data from the scripted drivers (``snnkart record``), in the recording format of
:mod:`snnkart.envs.recording` that ``snnkart play --record`` writes too."""

from __future__ import annotations

from pathlib import Path

from snnkart.envs.base import KartEnv
from snnkart.envs.recording import Recording, RecordingWrapper
from snnkart.envs.spec import make_env
from snnkart.errors import UsageError, did_you_mean
from snnkart.eval.drivers import ScriptedDriver
from snnkart.eval.episodes import run_episodes

DRIVERS = {"pursuit": ScriptedDriver}
"""The scripted drivers by name: ``pursuit`` follows the checkpoint midpoints (pure pursuit)."""


def record_driver(
    env: str,
    track: str | Path,
    driver: str = "pursuit",
    episodes: int = 10,
    seed: int = 0,
    action_mode: str = "discrete",
    env_config: dict[str, object] | None = None,
) -> Recording:
    """``episodes`` episodes of ``driver`` in ``env`` on ``track`` with seeds ``seed, seed+1,
    ...``, recorded step by step."""
    if driver not in DRIVERS:
        raise UsageError(
            f"unknown driver {driver!r}{did_you_mean(driver, DRIVERS)}; drivers: {', '.join(DRIVERS)}"
        )
    if episodes < 1:
        raise UsageError(f"--episodes must be >= 1, not {episodes}")
    base = make_env(env, track, action_mode=action_mode, config=env_config)
    kart = base.unwrapped
    assert isinstance(kart, KartEnv)
    recorder = RecordingWrapper(base, driver)
    try:
        run_episodes(recorder, DRIVERS[driver](kart), episodes, seed)
        return recorder.recording()
    finally:
        recorder.close()
