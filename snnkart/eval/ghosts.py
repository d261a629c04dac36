"""Replay of training: the karts of many training episodes drawn together on the track.

Training writes ``trajectories/iter_NNNNNN.npz`` (positions ``[steps, envs, 2]`` and episode
ends) every iteration, so a crashed run keeps what it recorded. Each episode becomes a
"ghost" that starts at time 0. ``batch`` mode plays one training iteration after the other
(all its episodes together); ``all`` mode plays every recorded episode at once, coloured from
blue (early in training) to red (late), with that legend in the side panel. :func:`race_frames`
draws a comparison instead: up to four trained policies' karts on one track, one colour each,
the legend naming them.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snnkart.errors import ReplayError

REPLAY_MODES = ("batch", "all")
RACE_COLOURS = [(66, 135, 245), (230, 70, 60), (60, 180, 75), (245, 160, 40)]
"""Blue, red, green, orange: distinct on the track's dark background."""
Line = tuple[str, str] | tuple[str, str, tuple[int, int, int]]  # (label, value[, colour])


@dataclass
class Ghost:
    iteration: int
    positions: np.ndarray  # [length, 2]


def load_ghosts(run_dir: Path) -> list[Ghost]:
    files = sorted((Path(run_dir) / "trajectories").glob("iter_*.npz"))
    if not files:
        raise ReplayError(
            f"{run_dir} has no recorded trajectories (trajectories/iter_*.npz); "
            "train with run.trajectories = true"
        )
    ghosts = []
    for f in files:
        iteration = int(f.stem.split("_")[1])
        with np.load(f) as data:
            pos, ends = data["positions"], data["episode_end"]
        for e in range(pos.shape[1]):
            start = 0
            for end in [*np.flatnonzero(ends[:, e]), pos.shape[0] - 1]:
                if end >= start:
                    ghosts.append(Ghost(iteration, pos[start : end + 1, e]))
                start = end + 1
    return ghosts


def _colour(frac: float) -> tuple[int, int, int]:
    """Blue (early) to red (late)."""
    return (int(60 + 195 * frac), int(90 + 60 * (1 - abs(2 * frac - 1))), int(255 - 195 * frac))


def frames(
    ghosts: list[Ghost], mode: str, every: int = 1
) -> Iterator[tuple[np.ndarray, list[tuple[int, int, int]], list[Line]]]:
    """Yield (positions, colours, panel lines) per shown time step."""
    if mode not in REPLAY_MODES:
        raise ReplayError(f"unknown replay mode {mode!r}; choose {' or '.join(REPLAY_MODES)}")
    iterations = sorted({g.iteration for g in ghosts})
    last = max(iterations)
    if mode == "all":
        groups = [("all iterations", ghosts)]
    else:
        groups = [(f"{it} / {last}", [g for g in ghosts if g.iteration == it]) for it in iterations]
    legend: list[Line] = (
        [("early", f"iteration {iterations[0]}", _colour(iterations[0] / max(last, 1))),
         ("late", f"iteration {last}", _colour(1.0))] if mode == "all" else []
    )  # fmt: skip
    for label, group in groups:
        horizon = max(len(g.positions) for g in group)
        colours_all = [_colour(g.iteration / max(last, 1)) for g in group]
        for t in range(0, horizon, every):
            alive = [i for i, g in enumerate(group) if t < len(g.positions)]
            pos = np.asarray([group[i].positions[t] for i in alive]).reshape(-1, 2)
            yield (
                pos,
                [colours_all[i] for i in alive],
                [("iteration", label), ("karts", f"{len(alive)} / {len(group)}"),
                 ("time", f"{t / 60:.2f} s"), *legend],
            )  # fmt: skip


@dataclass
class Racer:
    """One policy's episode in a comparison: its legend label, path and how it ended."""

    label: str  # the run's name
    kind: str  # e.g. "SNN steer"
    positions: np.ndarray  # [length, 2] px
    outcome: str  # e.g. "finished 3.42 s", "crashed", "stood still", "time limit"


def race_frames(
    racers: list[Racer], every: int = 1
) -> Iterator[tuple[np.ndarray, list[tuple[int, int, int]], list[Line]]]:
    """Yield (positions, colours, legend lines) per shown time step: every racer's kart in
    its colour while it drives; the legend shows each one's outcome once it has ended."""
    if not 1 <= len(racers) <= len(RACE_COLOURS):
        raise ReplayError(f"compare 1 to {len(RACE_COLOURS)} runs, got {len(racers)}")
    horizon = max(len(r.positions) for r in racers)
    for t in [*range(0, horizon, every), horizon - 1]:
        alive = [i for i, r in enumerate(racers) if t < len(r.positions)]
        pos = np.asarray([racers[i].positions[t] for i in alive]).reshape(-1, 2)
        lines: list[Line] = [("time", f"{t / 60:.2f} s")]
        for i, r in enumerate(racers):
            state = "driving" if t < len(r.positions) - 1 else r.outcome
            lines += [(r.label, r.kind, RACE_COLOURS[i]), ("", state, RACE_COLOURS[i])]
        yield pos, [RACE_COLOURS[i] for i in alive], lines
