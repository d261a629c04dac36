"""``snnkart replay``: the episodes recorded during training, many karts at once, in a window
or to a GIF/MP4."""

from __future__ import annotations

from pathlib import Path

from snnkart.app.reporter import Reporter
from snnkart.envs.constants import RENDER_FPS
from snnkart.errors import UsageError


def run_replay(run_dir: Path, mode: str, out: Path | None, every: int, reporter: Reporter) -> None:
    from snnkart.envs.render import Renderer
    from snnkart.eval.replay import frames, load_ghosts
    from snnkart.eval.video import check_video_path, video_writer
    from snnkart.rl.checkpoint import load_checkpoint
    from snnkart.rl.config import read_run_config
    from snnkart.rl.run_dir import checkpoint_track

    if every < 1:
        raise UsageError(f"--every must be >= 1, got {every}")
    if out is not None:
        check_video_path(out)
    cfg = read_run_config(run_dir)
    ghosts = load_ghosts(run_dir)
    latest = run_dir / "checkpoint.pt"  # carries the track, which may have moved since
    track = checkpoint_track(load_checkpoint(latest)[1], cfg, latest) if latest.is_file() else None
    env = cfg.make_env(track=track).unwrapped
    renderer = Renderer(env, human=out is None)  # type: ignore[arg-type]
    try:
        if out is None:
            for positions, colours, lines in frames(ghosts, mode, every):
                renderer.draw_ghosts(positions, colours, lines)
                if renderer.quit_requested():
                    break
        else:
            with video_writer(out, fps=RENDER_FPS / every) as writer:
                for positions, colours, lines in frames(ghosts, mode, every):
                    writer.append_data(renderer.draw_ghosts(positions, colours, lines))
            reporter.message(f"replay of {len(ghosts)} episodes written to {out}")
    finally:
        renderer.close()
        env.close()
