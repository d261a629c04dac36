"""The demo job: a rendered rollout of the scripted driver, written to a GIF."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

from snnkart.envs.base import KartEnv
from snnkart.envs.constants import RENDER_FPS
from snnkart.eval.video import video_writer


def scripted_gif(
    env_name: str, track: str, out: str | Path, seed: int = 0, every: int = 3
) -> dict[str, Any]:
    """Drive one episode with :class:`~snnkart.eval.drivers.ScriptedDriver` and save every
    ``every``-th frame as a GIF at real-time speed. Returns the episode summary."""
    from rich.progress import Progress

    from snnkart.envs import make
    from snnkart.eval.drivers import ScriptedDriver, drive_episode

    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    env = cast(KartEnv, make(env_name, track=track, render_mode="rgb_array").unwrapped)
    try:
        with Progress(transient=True) as progress, video_writer(out, RENDER_FPS / every) as writer:
            task = progress.add_task(f"driving {env_name} on {track}", total=env.max_episode_steps)

            def record(e: KartEnv) -> None:
                progress.advance(task)
                if e.episode_steps % every == 0:
                    writer.append_data(e.render())

            result = drive_episode(env, seed=seed, driver=ScriptedDriver(env), on_step=record)
            writer.append_data(env.render())
    finally:
        env.close()
    return result
