"""The demo job: a rendered rollout of the scripted driver, written to a GIF."""

from __future__ import annotations

from pathlib import Path
from typing import cast

from snnkart.app.reporter import Reporter
from snnkart.envs.base import KartEnv
from snnkart.envs.constants import RENDER_FPS
from snnkart.errors import UsageError
from snnkart.eval.episodes import EpisodeResult
from snnkart.eval.video import video_writer


def scripted_gif(
    env_name: str, track: str, out: str | Path, reporter: Reporter, seed: int = 0, every: int = 3
) -> EpisodeResult:
    """Drive one episode with :class:`~snnkart.eval.drivers.ScriptedDriver` and save every
    ``every``-th frame as a GIF at real-time speed. Returns the episode summary."""
    from snnkart.envs import make
    from snnkart.eval.drivers import ScriptedDriver, drive_episode

    if every < 1:
        raise UsageError(f"every must be >= 1, got {every}")
    env = cast(KartEnv, make(env_name, track=track, render_mode="rgb_array").unwrapped)
    try:
        with (
            reporter.progress(f"driving {env_name} on {track}", env.max_episode_steps) as task,
            video_writer(out, RENDER_FPS / every) as writer,
        ):

            def record(e: KartEnv) -> None:
                task.advance()
                if e.episode_steps % every == 0:
                    writer.append_data(e.render())

            result = drive_episode(env, seed=seed, driver=ScriptedDriver(env), on_step=record)
            writer.append_data(env.render())
    finally:
        env.close()
    return result
