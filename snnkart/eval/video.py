"""Writing rendered frames to a GIF or an MP4, atomically and frame by frame."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from snnkart.errors import UsageError
from snnkart.io import atomic_path

VIDEO_SUFFIXES = (".gif", ".mp4")


def check_video_path(path: Path) -> None:
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise UsageError(f"{path}: unsupported video format; use a .gif or .mp4 file name")


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
