"""The results protocol (docs/results.md): which training seeds and tracks are tuning data, on
which defaults may be chosen, and which are reporting data, which no choice may touch.

Every study config declares one (``data = "tuning"`` or ``data = "reporting"``) and may use only
that kind's seeds and tracks; :func:`data_problem` refuses a mix, naming the seed or track.
A track is known by its name (a built-in) or its file's stem (``benchmarks/tracks/ring.toml`` is
the ring).

One exception, for the comparison with kart-simulator: a reporting study may *train* on the
original's two tracks (``small_S``, ``big_S``, :data:`TASK_TRACKS`), because they define the task
that comparison is about; its seeds are still reporting seeds, and every table marks results on
those tracks as tuning tracks. Tracks a reporting study only evaluates on (``eval_tracks``) may
be those two as well, marked the same way. ``random`` (a new generated track per reset) is
training data of either kind: it never draws a reporting track.
"""

from __future__ import annotations

from typing import Literal

from snnkart.envs.trackgen import reporting_track_names
from snnkart.envs.tracks import RANDOM_TRACK, short_name

DataKind = Literal["tuning", "reporting"]
"""What a study's runs are for: choosing defaults, or the published numbers."""

TUNING_SEEDS = range(1, 101)
"""Training seeds 1-100: free to tune on."""
FIRST_REPORTING_SEED = 101
"""Training seeds 101 and up: reporting only."""
TUNING_TRACKS: tuple[str, ...] = ("small_S", "big_S", "ring", "hairpins")
"""The tracks defaults were (or may be) chosen on."""
TASK_TRACKS: tuple[str, ...] = ("small_S", "big_S")
"""The original's two tracks: tuning tracks a reporting study may still train and evaluate on
(the task of the comparison with kart-simulator), marked as tuning tracks where reported."""
REPORTING_TRACKS: tuple[str, ...] = ("zigzag", "bends", *reporting_track_names())
"""The tracks no choice has touched: zigzag, bends, and the generated tracks of the committed
seed list ``snnkart.envs.trackgen.REPORTING_SEEDS`` (``benchmarks/tracks/generated/``), which
``track="random"`` never draws."""


def data_problem(kind: DataKind, seeds: list[int], tracks: list[str]) -> str | None:
    """What in ``seeds`` and ``tracks`` is not ``kind`` data, in one line; None when all is
    (``random`` and, in a reporting study, the :data:`TASK_TRACKS` are allowed: see above)."""
    if kind == "tuning":
        seed = next((s for s in seeds if s not in TUNING_SEEDS), None)
        allowed, seed_rule = (*TUNING_TRACKS, RANDOM_TRACK), "1-100"
    else:
        seed = next((s for s in seeds if s < FIRST_REPORTING_SEED), None)
        allowed = (*REPORTING_TRACKS, *TASK_TRACKS, RANDOM_TRACK)
        seed_rule = f"{FIRST_REPORTING_SEED} and up"
    if seed is not None:
        return f"seed {seed} is not {kind} data ({kind} studies use seeds {seed_rule})"
    track = next((t for t in tracks if short_name(t) not in allowed), None)
    if track is not None:
        return (
            f"track {track!r} is not {kind} data ({kind} studies use the tracks "
            f"{', '.join(_short(allowed))})"
        )
    return None


def is_tuning_track(track: str) -> bool:
    """Whether results on ``track`` are marked as on a tuning track."""
    return short_name(track) in TUNING_TRACKS


def _short(tracks: tuple[str, ...]) -> list[str]:
    """Track names for a message, the generated ones summed up."""
    generated = [t for t in tracks if t in reporting_track_names()]
    named = [t for t in tracks if t not in generated]
    return named + ([f"the {len(generated)} generated tracks"] if generated else [])
