"""Replay of training: the karts of many training episodes drawn together on the track.

Training writes ``trajectories/iter_NNNNNN.npz`` every iteration (so a crashed run keeps what it
recorded): the kart poses of its rollout, where episodes ended, the reset pose of each episode
begun inside it, and the poses before its first step (see
:meth:`snnkart.rl.rollout.Rollout.trajectory`). :func:`load_ghosts` joins each env's pieces
across rollouts into whole episodes, from the reset pose to the terminal pose, each a "ghost"
that starts at time 0 and belongs to the iteration it ended in (where training counts it).
Episodes still running when training ended (or was interrupted and resumed, which resets the
envs) are not episodes training counted and are left out; so are episodes whose start was not
recorded. ``batch`` mode plays one training iteration after the other (the episodes that ended
in it); ``all`` mode plays every recorded episode at once, translucent and coloured from blue
(early in training) to red (late), with a colour bar in the side panel. :func:`race_frames`
draws a comparison instead: up to four trained policies' karts on one track, one colour each,
the legend naming them.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from snnkart.envs.constants import DT
from snnkart.envs.render import ColourBar
from snnkart.errors import ReplayError

REPLAY_MODES = ("batch", "all")
RACE_COLOURS = [(66, 135, 245), (230, 70, 60), (60, 180, 75), (245, 160, 40)]
"""Blue, red, green, orange: distinct on the track's dark background."""
GHOST_ALPHA = 110
"""Opacity (0-255) of a replayed kart: a pile of karts at the spawn shows how many it holds."""
Colour = tuple[int, int, int]
Line = tuple[str, str] | tuple[str, str, Colour]  # (label, value[, colour])


@dataclass
class Ghost:
    """One whole training episode: the iteration it ended in, and its poses (px) from its reset
    pose to its terminal pose, ``[steps + 1, 2]``."""

    iteration: int
    positions: np.ndarray


@dataclass
class Recorded:
    """The episodes recorded during training, joined across rollouts; and how many were left
    out: still running at the end (``unfinished``), or begun before the first recorded rollout
    (``begun_before``)."""

    ghosts: list[Ghost] = field(default_factory=list)
    unfinished: int = 0
    begun_before: int = 0

    def left_out(self) -> str:
        """What was not shown, as a line for the output ("" if nothing)."""
        parts = [
            f"{n} {what} not shown"
            for n, what in (
                (self.unfinished, "unfinished episodes (still running when training stopped)"),
                (self.begun_before, "episodes begun before the first recorded rollout"),
            )
            if n
        ]
        return "; ".join(parts)


@dataclass
class GhostFrame:
    """One drawn time step: kart positions ``[k, 2]`` px with one colour each, the side panel's
    lines, the karts' opacity, and an optional colour bar below the lines."""

    positions: np.ndarray
    colours: list[Colour]
    lines: list[Line]
    alpha: int = 255
    bar: ColourBar | None = None


TRAJECTORY_KEYS = (
    "positions",
    "episode_end",
    "reset_positions",
    "first_positions",
    "episode_start",
)


def _gymnasium_run(run_dir: Path) -> bool:
    """Whether ``run_dir``'s config trained on any gymnasium env (not a kart env)."""
    config = run_dir / "config.toml"
    if not config.is_file():
        return False
    from snnkart.errors import SnnkartError
    from snnkart.rl.config import read_run_config

    try:
        return not read_run_config(run_dir).kart
    except (SnnkartError, ValueError):  # unreadable config: the trajectories message stands
        return False


def load_ghosts(run_dir: Path) -> Recorded:
    """Every episode recorded in ``run_dir/trajectories``, joined across rollouts."""
    files = sorted((Path(run_dir) / "trajectories").glob("iter_*.npz"))
    if not files and _gymnasium_run(Path(run_dir)):
        raise ReplayError(
            f"{run_dir} trained on a gymnasium env: replay draws kart trajectories on a track; "
            f"film the policy's episodes with its own render instead: snnkart eval {run_dir} "
            "--video episodes.mp4"
        )
    if not files:
        raise ReplayError(
            f"{run_dir} has no recorded trajectories (trajectories/iter_*.npz); "
            "train with run.trajectories = true"
        )
    recorded = Recorded()
    pieces: list[list[np.ndarray] | None] = []  # per env: the open episode's pieces
    for f in files:
        with np.load(f) as data:
            missing = [k for k in TRAJECTORY_KEYS if k not in data]
            if missing:
                raise ReplayError(
                    f"{f} was recorded by an older snnkart, without where episodes start "
                    f"({', '.join(missing)}); train the run again to replay it"
                )
            arrays = {k: data[k] for k in TRAJECTORY_KEYS}
        envs = arrays["positions"].shape[1]
        if len(pieces) != envs:  # the first file, or a resume with another number of envs
            recorded.unfinished += sum(p is not None for p in pieces)
            pieces = [None] * envs
        for e in range(envs):
            pieces[e] = _join(recorded, int(f.stem.split("_")[1]), arrays, e, pieces[e])
    recorded.unfinished += sum(p is not None for p in pieces)
    return recorded


def _join(
    recorded: Recorded,
    iteration: int,
    arrays: dict[str, np.ndarray],
    e: int,
    open_: list[np.ndarray] | None,
) -> list[np.ndarray] | None:
    """Add env ``e``'s part of one rollout to its open episode ``open_`` (None: its start was
    not recorded); the episodes it ends go to ``recorded``. Returns the episode left open."""
    pos, ends = arrays["positions"][:, e], arrays["episode_end"][:, e]
    if arrays["episode_start"][e]:  # envs reset here (training began or resumed)
        recorded.unfinished += open_ is not None
        open_ = [arrays["first_positions"][e][None]]
    cut = 0
    for end in np.flatnonzero(ends):
        if open_ is None:
            recorded.begun_before += 1
        else:
            recorded.ghosts.append(Ghost(iteration, np.concatenate([*open_, pos[cut : end + 1]])))
        open_ = [arrays["reset_positions"][end, e][None]]
        cut = end + 1
    return None if open_ is None else [*open_, pos[cut:]]


def _colour(frac: float) -> Colour:
    """Blue (early) to red (late)."""
    return (int(60 + 195 * frac), int(90 + 60 * (1 - abs(2 * frac - 1))), int(255 - 195 * frac))


def frames(ghosts: list[Ghost], mode: str, every: int = 1) -> Iterator[GhostFrame]:
    """Yield one frame per shown time step (every ``every``-th, and each group's last)."""
    if mode not in REPLAY_MODES:
        raise ReplayError(f"unknown replay mode {mode!r}; choose {' or '.join(REPLAY_MODES)}")
    if not ghosts:
        raise ReplayError("no episode ended in the recorded rollouts; train longer to replay it")
    iterations = sorted({g.iteration for g in ghosts})
    first, last = iterations[0], iterations[-1]
    if mode == "all":
        groups = [("all", ghosts)]
        bar = ColourBar("iteration", [_colour(k / 31) for k in range(32)], str(first), str(last))
    else:
        groups = [(f"{it} / {last}", [g for g in ghosts if g.iteration == it]) for it in iterations]
        bar = None
    for label, group in groups:
        horizon = max(len(g.positions) for g in group)
        colours = [_colour((g.iteration - first) / max(last - first, 1)) for g in group]
        for t in sorted({*range(0, horizon, every), horizon - 1}):
            alive = [i for i, g in enumerate(group) if t < len(g.positions)]
            yield GhostFrame(
                np.asarray([group[i].positions[t] for i in alive]).reshape(-1, 2),
                [colours[i] for i in alive],
                [
                    ("iteration", label),
                    ("karts", f"{len(alive)} / {len(group)}"),
                    ("time", f"{t * DT:.2f} s"),
                ],
                GHOST_ALPHA,
                bar,
            )


@dataclass
class Racer:
    """One policy's episode in a comparison: its legend label, path and how it ended."""

    label: str  # the run's name
    kind: str  # e.g. "SNN steer"
    positions: np.ndarray  # [steps + 1, 2] px, from the reset pose to the terminal pose
    outcome: str  # e.g. "finished 3.42 s", "crashed", "stood still", "time limit"


def race_frames(racers: list[Racer], every: int = 1) -> Iterator[GhostFrame]:
    """Yield one frame per shown time step: every ``every``-th step and each racer's terminal
    step, up to the longest episode's end. A racer's kart drives, then stays at its terminal
    pose; the legend shows its outcome from its terminal step on. The clock is the episode's:
    positions[t] is the pose after ``t`` steps, so the last frame shows the longest one's
    own finish time."""
    if not 1 <= len(racers) <= len(RACE_COLOURS):
        raise ReplayError(f"compare 1 to {len(RACE_COLOURS)} runs, got {len(racers)}")
    ends = [len(r.positions) - 1 for r in racers]
    for t in sorted({*range(0, max(ends), every), *ends}):
        lines: list[Line] = [("time", f"{t * DT:.2f} s")]
        for i, r in enumerate(racers):
            state = "driving" if t < ends[i] else r.outcome
            lines += [(r.label, r.kind, RACE_COLOURS[i]), ("", state, RACE_COLOURS[i])]
        pos = np.asarray([r.positions[min(t, end)] for r, end in zip(racers, ends, strict=True)])
        yield GhostFrame(pos, RACE_COLOURS[: len(racers)], lines)
