"""``snnkart replay``: the episodes recorded during training, many karts at once, in a window
or to a GIF/MP4."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from snnkart.app.reporter import Reporter
from snnkart.envs.constants import RENDER_FPS
from snnkart.errors import UsageError

if TYPE_CHECKING:
    from snnkart.eval.ghosts import GhostFrame


def run_replay(
    run_dir: Path, mode: str, out: Path | None, every: int, reporter: Reporter
) -> dict[str, int]:
    """Replay the whole episodes recorded during training (see :mod:`snnkart.eval.ghosts`):
    in a window, or to the GIF/MP4 ``out``. Returns how many episodes were shown (as many as
    training counted, when every rollout was recorded) and how many were left out."""
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
    recorded = load_ghosts(run_dir)
    shown = frames(recorded.ghosts, mode, every)  # checks the mode before a window opens
    latest = run_dir / "checkpoint.pt"  # carries the track, which may have moved since
    track = checkpoint_track(load_checkpoint(latest)[1], cfg, latest) if latest.is_file() else None
    env = cfg.make_env(track=track).unwrapped
    reporter.message(f"replaying {len(recorded.ghosts)} episodes, as training counted them")
    if recorded.left_out():
        reporter.message(recorded.left_out())
    _show(env, shown, out, every)
    if out is not None:
        reporter.message(f"replay written to {out}")
    return {
        "episodes": len(recorded.ghosts),
        "unfinished": recorded.unfinished,
        "begun_before": recorded.begun_before,
    }


def _show(env: Any, shown: Iterator[GhostFrame], out: Path | None, every: int) -> None:
    """Draw frames of many karts on ``env``'s track: in a window (until closed), or to the
    GIF/MP4 ``out``. Closes the env."""
    from snnkart.envs.render import Renderer
    from snnkart.eval.video import video_writer

    renderer = Renderer(env, human=out is None)

    def draw(f: GhostFrame) -> Any:
        return renderer.draw_ghosts(f.positions, f.colours, f.lines, f.alpha, f.bar)

    try:
        if out is None:
            for frame in shown:
                draw(frame)
                if renderer.quit_requested():
                    break
        else:
            with video_writer(out, fps=RENDER_FPS / every) as writer:
                for frame in shown:
                    writer.append_data(draw(frame))
    finally:
        renderer.close()
        env.close()


def run_compare(
    run_dirs: list[Path],
    out: Path | None,
    seed: int,
    track: str | None,
    every: int,
    reporter: Reporter,
) -> list[dict[str, object]]:
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
    return [
        {"run": str(d), "label": r.label, "outcome": r.outcome}
        for d, r in zip(run_dirs, racers, strict=True)
    ]


def _recorder(path: list[tuple[float, float]]) -> Any:
    """An ``on_step`` that appends the kart's position to ``path``."""
    return lambda env: path.append(env.unwrapped.position)


def _reset_pose(env: Any, seed: int) -> tuple[float, float]:
    """Where ``env``'s episode of seed ``seed`` starts (reset is deterministic per seed)."""
    env.reset(seed=seed)
    return env.unwrapped.position  # type: ignore[no-any-return]


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
        try:
            path = [_reset_pose(env, seed)]  # positions[t]: the pose after t steps
            (result,) = run_episodes(
                env, TorchPredictor(run, seed=seed), 1, seed, on_step=_recorder(path)
            )
        finally:
            env.close()
        outcome = (
            f"finished {result.lap_time:.2f} s"
            if result.finished
            else "crashed"
            if result.crashed
            else "stood still"
            if result.stood_still
            else "time limit"
        )
        kind = f"{run.config.policy.upper()} {run.config.env}"
        racers.append(Racer(Path(run_dir).name, kind, np.asarray(path, dtype=np.float32), outcome))
    return racers, runs[0].config.make_env(track=shared).unwrapped
