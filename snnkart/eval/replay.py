"""Replay of training: the karts of many training episodes drawn together on the track.

Training writes ``trajectories/iter_NNNNNN.npz`` (positions ``[steps, envs, 2]`` and episode
ends) every iteration, so a crashed run keeps what it recorded. Each episode becomes a
"ghost" that starts at time 0. ``batch`` mode plays one training iteration after the other
(all its episodes together); ``all`` mode plays every recorded episode at once, coloured from
blue (early in training) to red (late).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snnkart.errors import ReplayError

REPLAY_MODES = ("batch", "all")


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
) -> Iterator[tuple[np.ndarray, list[tuple[int, int, int]], list[tuple[str, str]]]]:
    """Yield (positions, colours, panel lines) per shown time step."""
    if mode not in REPLAY_MODES:
        raise ReplayError(f"unknown replay mode {mode!r}; choose {' or '.join(REPLAY_MODES)}")
    iterations = sorted({g.iteration for g in ghosts})
    last = max(iterations)
    if mode == "all":
        groups = [("all iterations", ghosts)]
    else:
        groups = [(f"{it} / {last}", [g for g in ghosts if g.iteration == it]) for it in iterations]
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
                 ("time", f"{t / 60:.2f} s")],
            )  # fmt: skip
