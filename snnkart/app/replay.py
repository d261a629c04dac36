"""``snnkart replay``: the episodes recorded during training, many karts at once, in a window
or to a GIF/MP4."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from snnkart.app.reporter import Reporter
from snnkart.envs.constants import RENDER_FPS
from snnkart.errors import UsageError


def run_replay(run_dir: Path, mode: str, out: Path | None, every: int, reporter: Reporter) -> None:
    from snnkart.eval.ghosts import frames, load_ghosts
    from snnkart.eval.video import check_video_path
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
    _show(env, frames(ghosts, mode, every), out, every)
    if out is not None:
        reporter.message(f"replay of {len(ghosts)} episodes written to {out}")


def _show(env: Any, shown: Iterator[tuple[Any, Any, Any]], out: Path | None, every: int) -> None:
    """Draw (positions, colours, panel lines) frames of many karts on ``env``'s track: in a
    window (until closed), or to the GIF/MP4 ``out``. Closes the env."""
    from snnkart.envs.render import Renderer
    from snnkart.eval.video import video_writer

    renderer = Renderer(env, human=out is None)
    try:
        if out is None:
            for positions, colours, lines in shown:
                renderer.draw_ghosts(positions, colours, lines)
                if renderer.quit_requested():
                    break
        else:
            with video_writer(out, fps=RENDER_FPS / every) as writer:
                for positions, colours, lines in shown:
                    writer.append_data(renderer.draw_ghosts(positions, colours, lines))
    finally:
        renderer.close()
        env.close()


def run_compare(run_dirs: list[Path], out: Path | None, seed: int, track: str | None,
                every: int, reporter: Reporter) -> list[dict[str, object]]:  # fmt: skip
    """Up to four trained policies drive one seeded episode each on one track (the first
    run's, or ``track``), drawn together in distinct colours with a legend: in a window, or
    to a GIF/MP4. Returns how each episode ended."""
    from snnkart.eval.ghosts import RACE_COLOURS, race_frames
    from snnkart.eval.video import check_video_path

    if not 1 <= len(run_dirs) <= len(RACE_COLOURS):
        raise UsageError(f"--compare takes 1 to {len(RACE_COLOURS)} runs, got {len(run_dirs)}")
    if every < 1:
        raise UsageError(f"--every must be >= 1, got {every}")
    if out is not None:
        check_video_path(out)
    racers, env = _race(run_dirs, seed, track)
    _show(env, race_frames(racers, every), out, every)
    if out is not None:
        reporter.message(f"comparison of {len(racers)} runs written to {out}")
    return [{"run": str(d), "label": r.label, "outcome": r.outcome}
            for d, r in zip(run_dirs, racers, strict=True)]  # fmt: skip


def _recorder(path: list[tuple[float, float]]) -> Any:
    """An ``on_step`` that appends the kart's position to ``path``."""
    return lambda env: path.append(env.unwrapped.position)


def _race(run_dirs: list[Path], seed: int, track: str | None) -> tuple[list[Any], Any]:
    """Each run's deterministic episode (seed ``seed``) on the shared track, as racers; and an
    env of the first run on that track to draw them on."""
    import numpy as np

    from snnkart.envs.tracks import load_track
    from snnkart.eval.episodes import run_episodes
    from snnkart.eval.ghosts import Racer
    from snnkart.rl.trained import TorchPredictor, load_run

    runs = [load_run(d) for d in run_dirs]
    shared = load_track(track) if track is not None else runs[0].track
    racers = []
    for run_dir, run in zip(run_dirs, runs, strict=True):
        env = run.config.make_env(track=shared)
        path: list[tuple[float, float]] = []
        try:
            (result,) = run_episodes(env, TorchPredictor(run, seed=seed), 1, seed,
                                     on_step=_recorder(path))  # fmt: skip
        finally:
            env.close()
        outcome = (f"finished {result.lap_time:.2f} s" if result.finished else "crashed"
                   if result.crashed else "stood still" if result.stood_still else "time limit")  # fmt: skip
        kind = f"{run.config.policy.upper()} {run.config.env}"
        racers.append(Racer(Path(run_dir).name, kind, np.asarray(path, dtype=np.float32), outcome))
    return racers, runs[0].config.make_env(track=shared).unwrapped
