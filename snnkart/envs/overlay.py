"""What is drawn over rendered frames for a viewer: the track view zoomed to the track's
extent, an episode/seed counter, a banner with an episode's outcome, a legend of the lines, and
a key help line for ``snnkart play``.

:class:`FilmOverlay` turns one :class:`~snnkart.envs.render.Renderer` frame (``[H, W, 3]``
uint8: the 1000 x 1000 px world on the left, the telemetry panel on the right) into one video
frame: the track's bounding box plus a margin, scaled to the frame's height, with the counter
top left, the legend bottom left, an optional banner across the middle, and the panel unchanged
on the right. :func:`draw_key_help` writes one line at the bottom of a window. A HUD extends
this module.
"""

from __future__ import annotations

import os

import numpy as np

from snnkart.envs.render import (
    CHECKPOINT_LATER,
    CHECKPOINT_NEXT,
    CHECKPOINT_PASSED,
    NEGATIVE,
    POSITIVE,
    RAY,
    RAY_HIT,
    TEXT,
    TEXT_DIM,
    WORLD_SIZE_PX,
    Colour,
)
from snnkart.envs.tracks import Track

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
import pygame  # after the prompt switch

VIEW_MARGIN_PX = 40.0
"""World pixels kept around the track's bounding box in the zoomed view."""

LEGEND: tuple[tuple[str, Colour], ...] = (
    ("next checkpoint", CHECKPOINT_NEXT),
    ("passed", CHECKPOINT_PASSED),
    ("to come", CHECKPOINT_LATER),
    ("LIDAR rays", RAY),
    ("ray hit", RAY_HIT),
)
"""The lines of the track view and their colours, as the legend lists them."""

SHADE: Colour = (0, 0, 0)


class FilmOverlay:
    """Zooms and annotates the frames of one track; see the module docstring.

    Args:
        track: the track drawn in the frames (its bounds set the view).
        frame_shape: ``(H, W, 3)`` of the renderer's frames.
        scale: the renderer's ``render_scale`` (screen px per world px).
    """

    def __init__(self, track: Track, frame_shape: tuple[int, ...], scale: float) -> None:
        pygame.font.init()
        track_width = round(WORLD_SIZE_PX * scale)  # the world part of a frame; then the panel
        height = frame_shape[0]
        xmin, ymin, xmax, ymax = track.bounds
        left = max(0, int((xmin - VIEW_MARGIN_PX) * scale))
        top = max(0, int((ymin - VIEW_MARGIN_PX) * scale))
        right = min(track_width, int(np.ceil((xmax + VIEW_MARGIN_PX) * scale)))
        bottom = min(height, int(np.ceil((ymax + VIEW_MARGIN_PX) * scale)))
        self.view = (left, top, right - left, bottom - top)
        """The part of the world shown, screen px of the renderer: (left, top, width, height)."""
        zoom = height / self.view[3]
        self.view_size = (2 * max(1, round(self.view[2] * zoom / 2)), height)  # even: MP4
        self.track_width = track_width
        self.size = (self.view_size[0] + frame_shape[1] - track_width, height)
        """(width, height) of the frames :meth:`compose` returns."""
        unit = height / 800
        self._font = pygame.font.Font(None, max(12, round(26 * unit)))
        self._banner_font = pygame.font.Font(None, max(16, round(44 * unit)))
        self._pad = max(4, round(10 * unit))

    def compose(self, frame: np.ndarray, counter: str, banner: str | None = None) -> np.ndarray:
        """The zoomed, annotated frame for one renderer ``frame``; ``banner`` ends with the
        outcome's word (``finished``/``crashed``/...) in green when it starts with
        ``finished``, else red."""
        source = pygame.surfarray.make_surface(frame.transpose(1, 0, 2))
        out = pygame.Surface(self.size)
        view = source.subsurface(pygame.Rect(self.view))
        out.blit(pygame.transform.smoothscale(view, self.view_size), (0, 0))
        panel = source.subsurface(
            pygame.Rect(self.track_width, 0, frame.shape[1] - self.track_width, frame.shape[0])
        )
        out.blit(panel, (self.view_size[0], 0))
        self._label(out, counter, (self._pad, self._pad), self._font, TEXT)
        self._legend(out)
        if banner is not None:
            colour = POSITIVE if banner.startswith("finished") else NEGATIVE
            text = self._banner_font.render(banner, True, colour)
            x = (self.view_size[0] - text.get_width()) // 2
            y = (self.view_size[1] - text.get_height()) // 2
            self._label(out, banner, (max(self._pad, x), y), self._banner_font, colour)
        return np.ascontiguousarray(pygame.surfarray.array3d(out).transpose(1, 0, 2))

    def _legend(self, out: pygame.Surface) -> None:
        """One row per line colour, bottom left: a short stroke, then its name."""
        row = self._font.get_linesize()
        y = self.size[1] - self._pad - row * len(LEGEND)
        stroke = 3 * self._pad
        width = 3 * self._pad + stroke + max(self._font.size(name)[0] for name, _ in LEGEND)
        box = pygame.Surface((width, row * len(LEGEND) + self._pad))
        box.set_alpha(170)
        box.fill(SHADE)
        out.blit(box, (0, y - self._pad // 2))
        for name, colour in LEGEND:
            middle = y + row // 2
            pygame.draw.line(
                out, colour, (self._pad, middle), (self._pad + stroke, middle), max(2, row // 6)
            )
            out.blit(self._font.render(name, True, TEXT_DIM), (2 * self._pad + stroke, y))
            y += row

    def _label(
        self,
        out: pygame.Surface,
        text: str,
        at: tuple[int, int],
        font: pygame.font.Font,
        colour: Colour,
    ) -> None:
        """``text`` on a translucent dark box, so it reads over walls and rays."""
        image = font.render(text, True, colour)
        box = pygame.Surface((image.get_width() + 2 * self._pad, image.get_height() + self._pad))
        box.set_alpha(170)
        box.fill(SHADE)
        out.blit(box, (at[0] - self._pad, at[1] - self._pad // 2))
        out.blit(image, at)


def draw_key_help(surface: pygame.Surface, text: str) -> None:
    """``text`` in one line at the bottom left of ``surface`` (the play window's key help)."""
    pygame.font.init()
    font = pygame.font.Font(None, max(12, surface.get_height() // 40))
    image = font.render(text, True, TEXT)
    pad = max(4, surface.get_height() // 100)
    box = pygame.Surface((image.get_width() + 2 * pad, image.get_height() + pad))
    box.set_alpha(170)
    box.fill(SHADE)
    y = surface.get_height() - image.get_height() - pad
    surface.blit(box, (0, y - pad // 2))
    surface.blit(image, (pad, y))
