"""What is drawn over rendered frames for a viewer: the track view zoomed to the track's
extent, an episode/seed counter, a banner with an episode's outcome, a legend of the lines, and
a key help line for ``snnkart play``.

:class:`FilmOverlay` turns one :class:`~snnkart.envs.render.Renderer` frame (``[H, W, 3]``
uint8: the 1000 x 1000 px world on the left, the telemetry panel on the right) into one video
frame: the track's bounding box plus a margin, scaled to the frame's height, with the counter
top left, the legend bottom left, an optional banner across the middle, and the panel unchanged
on the right. :func:`draw_key_help` writes one line at the bottom of a window.

The heads-up display (:class:`Hud`) of the windows of ``snnkart play``, ``eval --render``
and ``replay`` is a translucent box in the corner of the track view farthest from the track
(:class:`HudLayout` names where each element is, in frame pixels); for the kart drawn it shows:

- text rows: position (m), heading (degrees), speed, lap time, best lap (over the episodes
  shown), checkpoints passed, and the frames per second of the window;
- the last action as three indicators: accelerate (green when on), brake (red when on) and a
  steering bar whose marker sits left or right of the middle;
- a mini LIDAR view: the rays around the kart, heading up (egocentric envs), hits as dots.

The side panel next to the track view keeps the reward terms of the last step and, for
spiking policies, the per-layer activity (:class:`~snnkart.envs.render.Renderer`). ``replay``
draws many karts at once, so its HUD is the frame rate only (:meth:`Hud.draw_fps`). ``P``
saves the window as a PNG (:func:`save_screenshot`).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.envs import palette
from snnkart.envs.constants import PIXELS_PER_METRE, WORLD_SIZE_PX
from snnkart.envs.palette import Colour
from snnkart.envs.tracks import Track

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
import pygame  # after the prompt switch

VIEW_MARGIN_PX = 40.0
"""World pixels kept around the track's bounding box in the zoomed view."""

LEGEND: tuple[tuple[str, Colour], ...] = (
    ("next checkpoint", palette.CHECKPOINT_NEXT),
    ("passed", palette.CHECKPOINT_PASSED),
    ("to come", palette.CHECKPOINT_LATER),
    ("LIDAR rays", palette.RAY),
    ("ray hit", palette.RAY_HIT),
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
        self._label(out, counter, (self._pad, self._pad), self._font, palette.TEXT)
        self._legend(out)
        if banner is not None:
            colour = palette.POSITIVE if banner.startswith("finished") else palette.NEGATIVE
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
            out.blit(self._font.render(name, True, palette.TEXT_DIM), (2 * self._pad + stroke, y))
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
    image = font.render(text, True, palette.TEXT)
    pad = max(4, surface.get_height() // 100)
    box = pygame.Surface((image.get_width() + 2 * pad, image.get_height() + pad))
    box.set_alpha(170)
    box.fill(SHADE)
    y = surface.get_height() - image.get_height() - pad
    surface.blit(box, (0, y - pad // 2))
    surface.blit(image, (pad, y))


# -- the HUD of the windows ------------------------------------------------------------------

ROWS = ("position", "heading", "speed", "lap time", "best lap", "checkpoints", "fps")
"""The text rows of the HUD, top to bottom."""


class HudLayout:
    """Where each HUD element is in a frame of ``size`` (w, h) whose track view is
    ``track_width`` px wide at ``scale`` screen px per world px: :attr:`regions` maps
    ``box``, ``text``, ``throttle``, ``brake``, ``steer`` and ``lidar`` to rects; ``text`` has
    one row per name of :data:`ROWS`, :attr:`row_height` px each. The box takes the corner
    that covers least of the track's bounding box and not the ``kart`` (frame px)."""

    def __init__(
        self,
        scale: float,
        track_width: int,
        height: int,
        track_bounds: tuple[float, ...],
        kart: tuple[float, float] | None = None,
    ) -> None:
        s = scale
        self.pad = max(4, round(10 * s))
        self.font_size = max(10, round(24 * s))
        self.row_height = round(self.font_size * 0.8)
        width = round(250 * s)
        indicator = round(36 * s)
        mini = width - 2 * self.pad
        box_h = (
            self.pad
            + len(ROWS) * self.row_height
            + self.pad
            + indicator
            + self.pad
            + mini
            + self.pad
        )
        left, top = _corner(track_width, height, (width, box_h), track_bounds, s, kart)
        inner = left + self.pad
        y = top + self.pad
        text = pygame.Rect(inner, y, mini, len(ROWS) * self.row_height)
        y = text.bottom + self.pad
        throttle = pygame.Rect(inner, y, indicator, indicator)
        brake = pygame.Rect(throttle.right + self.pad, y, indicator, indicator)
        steer = pygame.Rect(
            brake.right + self.pad, y, inner + mini - brake.right - self.pad, indicator
        )
        lidar = pygame.Rect(inner, throttle.bottom + self.pad, mini, mini)
        self.regions = {
            "box": pygame.Rect(left, top, width, box_h),
            "text": text,
            "throttle": throttle,
            "brake": brake,
            "steer": steer,
            "lidar": lidar,
        }


def _corner(
    track_width: int,
    height: int,
    size: tuple[int, int],
    bounds: tuple[float, ...],
    s: float,
    kart: tuple[float, float] | None = None,
) -> tuple[int, int]:
    """The top-left of a ``size`` box in the corner of the track view that covers least of
    the track's bounding box ``bounds`` (world px), never one near the ``kart`` (frame px)
    while another is free of it."""
    w, h = size
    near = 60 * s  # px around the kart kept clear
    xmin, ymin, xmax, ymax = (b * s for b in bounds)
    best: tuple[float, tuple[int, int]] | None = None
    for left in (0, track_width - w):
        for top in (0, height - h):
            dx = max(0.0, min(left + w, xmax) - max(left, xmin))
            dy = max(0.0, min(top + h, ymax) - max(top, ymin))
            cost = dx * dy
            if kart is not None and left - near < kart[0] < left + w + near:
                cost += 2.0 * w * h if top - near < kart[1] < top + h + near else 0.0
            if best is None or cost < best[0]:
                best = (cost, (left, top))
    assert best is not None
    return best[1]


def controls(env: Any) -> tuple[float, float]:
    """The last action as (accelerate - brake, steer), each in [-1, 1] (steer > 0: right)."""
    action = env.last_action
    if action is None:
        return 0.0, 0.0
    if env.action_mode == "discrete":
        name = env.ACTION_NAMES[int(action)]
        forward = any(w in name for w in ("throttle", "accelerate", "up"))
        back = any(w in name for w in ("brake", "down"))
        steer = -1.0 if "left" in name else 1.0 if "right" in name else 0.0
        return (1.0 if forward else -1.0 if back else 0.0), steer
    values = np.clip(np.asarray(action, dtype=np.float64).ravel(), -1.0, 1.0)
    return float(values[0]), float(values[1]) if values.size > 1 else 0.0


class Hud:
    """Draws the HUD of ``env`` (the renderer's :class:`~snnkart.envs.render.DrawnEnv`) on
    frames of the renderer's ``size`` and ``scale``; see the module docstring."""

    def __init__(self, env: Any, scale: float, track_width: int, height: int) -> None:
        pygame.font.init()
        self.env = env
        self._frame_geometry = (scale, track_width, height)
        self.layout = HudLayout(scale, track_width, height, env.track.bounds)
        self._font = pygame.font.Font(None, self.layout.font_size)
        self._range_px = env.config.lidar.range_m * PIXELS_PER_METRE
        self.best_lap: float | None = None
        self.fps = 0.0
        self._last: float | None = None

    def __call__(self, frame: pygame.Surface) -> None:
        self._tick()
        env, (scale, track_width, height) = self.env, self._frame_geometry
        kart = (env.position[0] * scale, env.position[1] * scale)
        self.layout = HudLayout(scale, track_width, height, env.track.bounds, kart)
        regions = self.layout.regions
        if env.lap_finished:
            lap = env.elapsed_time
            self.best_lap = lap if self.best_lap is None else min(self.best_lap, lap)
        shade = pygame.Surface(regions["box"].size)
        shade.set_alpha(170)
        shade.fill(SHADE)
        frame.blit(shade, regions["box"].topleft)
        for k, (label, value) in enumerate(zip(ROWS, self._values(), strict=True)):
            self._row(frame, regions["text"], k, label, value)
        throttle, steer = controls(env)
        self._indicator(
            frame, regions["throttle"], "acc", palette.POSITIVE if throttle > 0 else None
        )
        self._indicator(frame, regions["brake"], "brk", palette.NEGATIVE if throttle < 0 else None)
        self._steer(frame, regions["steer"], steer)
        self._lidar(frame, regions["lidar"])

    def draw_fps(self, frame: pygame.Surface) -> None:
        """The frame rate alone, top left of the track view (replay: many karts, no one's HUD)."""
        self._tick()
        text = self._font.render(f"fps {self.fps:.0f}", True, palette.TEXT)
        frame.blit(text, (self.layout.pad, self.layout.pad))

    def _tick(self) -> None:
        now = time.perf_counter()
        if self._last is not None and now > self._last:
            rate = 1.0 / (now - self._last)
            self.fps = rate if self.fps == 0.0 else 0.9 * self.fps + 0.1 * rate
        self._last = now

    def _values(self) -> list[str]:
        env = self.env
        x, y = env.position
        n = len(env.track.checkpoints)
        passed = n if env.lap_finished else env.next_checkpoint
        best = "-" if self.best_lap is None else f"{self.best_lap:.2f} s"
        return [
            f"{x / PIXELS_PER_METRE:.2f}, {y / PIXELS_PER_METRE:.2f} m",
            f"{math.degrees(env.heading) % 360:.0f} deg",
            f"{env.speed_m_s:.2f} m/s",
            f"{env.elapsed_time:.2f} s",
            best,
            f"{passed} / {n}",
            f"{self.fps:.0f}",
        ]

    def _row(
        self, frame: pygame.Surface, area: pygame.Rect, k: int, label: str, value: str
    ) -> None:
        y = area.top + k * self.layout.row_height
        frame.blit(self._font.render(label, True, palette.TEXT_DIM), (area.left, y))
        text = self._font.render(value, True, palette.TEXT)
        frame.blit(text, (area.right - text.get_width(), y))

    def _indicator(
        self, frame: pygame.Surface, rect: pygame.Rect, label: str, on: Colour | None
    ) -> None:
        """A square lit in colour ``on`` (None: off, an outline), with its label."""
        if on is not None:
            pygame.draw.rect(frame, on, rect)
        pygame.draw.rect(frame, palette.PANEL_RULE, rect, 1)
        text = self._font.render(label, True, SHADE if on is not None else palette.TEXT_DIM)
        frame.blit(text, text.get_rect(center=rect.center))

    def _steer(self, frame: pygame.Surface, rect: pygame.Rect, steer: float) -> None:
        """A bar with a marker at ``steer`` (-1 left .. 1 right) and a tick at the middle."""
        pygame.draw.rect(frame, palette.PANEL_RULE, rect, 1)
        middle = rect.centerx
        pygame.draw.line(frame, palette.TEXT_DIM, (middle, rect.top), (middle, rect.bottom - 1))
        half = rect.width // 2 - 4
        x = middle + round(steer * half)
        marker = pygame.Rect(0, 0, 6, rect.height - 6)
        marker.center = (x, rect.centery)
        pygame.draw.rect(frame, palette.CHECKPOINT_NEXT, marker)

    def _lidar(self, frame: pygame.Surface, rect: pygame.Rect) -> None:
        """The rays around the kart at the centre of ``rect``, heading up when egocentric."""
        env = self.env
        pygame.draw.rect(frame, palette.PANEL_RULE, rect, 1)
        cx, cy = rect.center
        radius = rect.width / 2 - 3
        turn = -math.pi / 2 - env.heading if env.egocentric else 0.0
        c, s = math.cos(turn), math.sin(turn)
        px, py = env.position
        for (hx, hy), distance in zip(env.lidar_hits, env.lidar_distances, strict=True):
            dx, dy = (hx - px) / self._range_px, (hy - py) / self._range_px
            end = (cx + radius * (c * dx - s * dy), cy + radius * (s * dx + c * dy))
            pygame.draw.aaline(frame, palette.RAY, (cx, cy), end)
            if distance < 1.0:
                pygame.draw.circle(frame, palette.RAY_HIT, end, 2)
        pygame.draw.circle(frame, palette.TEXT, (cx, cy), 3)


def save_screenshot(surface: pygame.Surface, directory: Path | None = None) -> Path:
    """Write ``surface`` as ``snnkart-<time>.png`` in ``directory`` (default: the working
    directory), a new name each time; return the path."""
    folder = directory or Path.cwd()
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = folder / f"snnkart-{stamp}.png"
    k = 1
    while path.exists():
        k += 1
        path = folder / f"snnkart-{stamp}-{k}.png"
    pygame.image.save(surface, str(path))
    return path


SCREENSHOT_KEY = pygame.K_p
"""The key that saves a screenshot in every snnkart window."""


def take_screenshots(surface: pygame.Surface, directory: Path | None = None) -> list[Path]:
    """Save ``surface`` once for each :data:`SCREENSHOT_KEY` pressed since the last call
    (see :func:`save_screenshot`); other key presses stay queued for the window's loop."""
    saved = []
    for event in pygame.event.get(pygame.KEYDOWN):
        if event.key == SCREENSHOT_KEY:
            saved.append(save_screenshot(surface, directory))
        else:
            pygame.event.post(event)
    return saved
