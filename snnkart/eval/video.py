"""Writing rendered frames to a GIF or an MP4, atomically and frame by frame, and filming
evaluation episodes with the overlay of :mod:`snnkart.envs.overlay`.

GIFs are written by imageio; MP4s by imageio's ffmpeg plugin, which needs the optional
``imageio-ffmpeg`` package (``pip install 'snnkart[video]'``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from snnkart.contract.eval_record import EpisodeResult
from snnkart.errors import UsageError
from snnkart.io import atomic_path

if TYPE_CHECKING:
    from snnkart.envs.base import KartEnv
    from snnkart.envs.overlay import FilmOverlay

VIDEO_SUFFIXES = (".gif", ".mp4")

MP4_HINT = "writing MP4 needs imageio-ffmpeg; install it with: pip install 'snnkart[video]'"


def check_video_path(path: Path) -> None:
    """Refuse a video file name that is neither .gif nor .mp4, or an .mp4 without ffmpeg."""
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise UsageError(f"{path}: unsupported video format; use a .gif or .mp4 file name")
    if suffix == ".mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise UsageError(MP4_HINT) from None


@contextlib.contextmanager
def video_writer(path: str | Path, fps: float) -> Iterator[Any]:
    """Yield a writer with ``append_data(frame)``; the file appears only when complete."""
    import imageio.v2 as imageio

    path = Path(path)
    check_video_path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".gif":
            writer = imageio.get_writer(tmp, format="GIF", mode="I", duration=1000.0 / fps, loop=0)  # type: ignore[arg-type]
        else:
            writer = imageio.get_writer(tmp, format="FFMPEG", mode="I", fps=fps, macro_block_size=1)  # type: ignore[arg-type]
        try:
            yield writer
        finally:
            writer.close()


BANNER_FRAMES = 8
"""How many times the final frame of a filmed episode is written with its outcome banner."""


def outcome_banner(result: EpisodeResult) -> str:
    """The banner over a filmed episode's final frame: its outcome and return."""
    if result.finished is None:  # any gymnasium env: how it ended, nothing kart-specific
        outcome = "time limit" if result.timed_out else "ended"
    elif result.finished:
        outcome = f"finished in {result.lap_time:.2f} s"
    elif result.crashed:
        outcome = "crashed"
    elif result.stood_still:
        outcome = "stood still"
    else:
        outcome = "time limit"
    return f"{outcome}, return {result.episode_return:+.2f}"


class Film:
    """Films the first ``filmed`` of ``episodes`` seeded episodes of an ``rgb_array`` env into
    ``writer``: every ``every``-th step, then the final step with its outcome banner held for
    :data:`BANNER_FRAMES` frames, all through one :class:`~snnkart.envs.overlay.FilmOverlay`.
    Any other gymnasium env's frames are its own ``rgb_array`` render, as it draws them (no
    overlay: it knows nothing of tracks), the final one held as long.

    Pass :meth:`on_step` and :meth:`on_episode` to :func:`~snnkart.eval.episodes.run_episodes`;
    ``on_frame`` is called after every written frame (a progress bar).
    """

    def __init__(
        self,
        env: KartEnv | Any,
        writer: Any,
        episodes: int,
        first_seed: int,
        filmed: int,
        every: int = 2,
        on_frame: Callable[[], None] | None = None,
    ) -> None:
        self.env, self.writer, self.every, self.on_frame = env, writer, every, on_frame
        self.episodes, self.first_seed, self.filmed = episodes, first_seed, filmed
        self.episode = 0  # index of the episode being run
        self._overlay: FilmOverlay | None = None
        self.kart = hasattr(env, "track")
        self.steps = 0  # steps of the episode being run

    def on_step(self, env: Any) -> None:
        self.steps += 1
        steps = self.env.episode_steps if self.kart else self.steps
        if self.episode < self.filmed and steps % self.every == 0:
            self._write(self._frame())

    def on_episode(self, result: EpisodeResult) -> None:
        if self.episode < self.filmed:
            frame = self._frame(outcome_banner(result))
            for _ in range(BANNER_FRAMES):
                self._write(frame)
        self.episode += 1
        self.steps = 0

    def _frame(self, banner: str | None = None) -> np.ndarray:
        from snnkart.envs.overlay import FilmOverlay

        raw = self.env.render()
        assert raw is not None, "a filmed env renders rgb_array frames"
        if not self.kart:
            return np.asarray(raw)
        if self._overlay is None:
            self._overlay = FilmOverlay(self.env.track, raw.shape, self.env.config.render_scale)
        counter = (
            f"episode {self.episode + 1} / {self.episodes}, seed {self.first_seed + self.episode}"
        )
        return self._overlay.compose(raw, counter, banner)

    def _write(self, frame: np.ndarray) -> None:
        self.writer.append_data(frame)
        if self.on_frame is not None:
            self.on_frame()
