"""pygame renderer of the kart envs: the track on the left, a telemetry panel on the right.

``KartEnv.render()`` creates one :class:`Renderer` lazily and calls :meth:`Renderer.draw` per
frame. In ``rgb_array`` mode the frame is drawn off screen and returned as an ``(H, W, 3)``
uint8 array; only pygame's font module is initialised, so no display (and no
``SDL_VIDEODRIVER`` setting, which would leak into later windows of the process) is needed.
In ``human`` mode a window is opened; without a display (Linux with neither ``DISPLAY`` nor
``WAYLAND_DISPLAY``) the SDL ``dummy`` video driver is used unless one is already chosen; the
window carries the HUD of :mod:`snnkart.envs.overlay`, and P saves it as a PNG.

pygame is imported only here, so ``import snnkart`` and headless training never load it.
The static parts (background, metre grid, walls, panel title) are drawn once into a surface;
checkpoints, LIDAR rays, the kart and the telemetry are redrawn every frame.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from snnkart.envs.config import EnvConfig
from snnkart.envs.constants import KART_RADIUS_PX, PIXELS_PER_METRE, WORLD_SIZE_PX
from snnkart.envs.palette import (  # the colours, shared with envs.overlay
    BACKGROUND,
    CHECKPOINT_LATER,
    CHECKPOINT_NEXT,
    CHECKPOINT_PASSED,
    FINISH_DARK,
    FINISH_LIGHT,
    GRID,
    KART,
    KART_MARK,
    NEGATIVE,
    PANEL,
    PANEL_RULE,
    POSITIVE,
    RAY,
    RAY_HIT,
    TEXT,
    TEXT_DIM,
    WALL,
    Colour,
)
from snnkart.envs.tracks import Track

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
import pygame  # after the prompt switch


class DrawnEnv(Protocol):
    """What the renderer reads from an env (:class:`snnkart.envs.base.KartEnv` has it all)."""

    @property
    def config(self) -> EnvConfig: ...
    @property
    def track(self) -> Track: ...
    @property
    def metadata(self) -> dict[str, Any]: ...
    @property
    def env_name(self) -> str: ...
    @property
    def egocentric(self) -> bool: ...
    @property
    def activity(self) -> list[tuple[str, float]]: ...
    @property
    def overlays(self) -> list[Any]: ...
    @property
    def position(self) -> tuple[float, float]: ...
    @property
    def heading(self) -> float: ...
    @property
    def speed_m_s(self) -> float: ...
    @property
    def next_checkpoint(self) -> int: ...
    @property
    def lap_finished(self) -> bool: ...
    @property
    def elapsed_time(self) -> float: ...
    @property
    def lidar_distances(self) -> np.ndarray: ...
    @property
    def lidar_hits(self) -> np.ndarray: ...
    @property
    def last_action(self) -> Any: ...
    @property
    def last_reward_terms(self) -> dict[str, float]: ...
    @property
    def episode_return(self) -> float: ...
    def describe_action(self, action: Any) -> str: ...


PANEL_WIDTH_PX = 360.0
"""Width of the side panel at ``render_scale`` 1."""


class ColourBar(NamedTuple):
    """A legend for colours on a scale (replay: early to late iterations): a title, the colours
    from one end to the other, and the labels of both ends."""

    title: str
    colours: Sequence[Colour]
    low: str
    high: str


def _has_display() -> bool:
    """Whether a window can be opened (only Linux and BSD may lack a display server)."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Renderer:
    """Draws one kart env; see the module docstring.

    Args:
        env: the (unwrapped) env to draw; read on every :meth:`draw`.
        human: open a window and show the frames in real time instead of returning arrays.
    """

    def __init__(self, env: DrawnEnv, human: bool) -> None:
        self.env = env
        self.human = human
        self.scale = s = float(env.config.render_scale)
        self.track_width = round(WORLD_SIZE_PX * s)
        self.size = (self.track_width + round(PANEL_WIDTH_PX * s), round(WORLD_SIZE_PX * s))
        self._clock: pygame.time.Clock | None = None
        self._closed = False
        if human:
            if not _has_display():
                os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
            pygame.display.init()
            self._frame = pygame.display.set_mode(self.size)
            pygame.display.set_caption(f"snnkart — {env.env_name} on {env.track.name}")
            self._clock = pygame.time.Clock()
        else:
            self._frame = pygame.Surface(self.size)
        pygame.font.init()
        self._pad = round(18 * s)
        self._title_font = pygame.font.Font(None, max(12, round(40 * s)))
        self._font = pygame.font.Font(None, max(10, round(27 * s)))
        self._small_font = pygame.font.Font(None, max(9, round(22 * s)))
        self._line_height = round(self._font.get_linesize() * 1.3)
        self._kart_radius = KART_RADIUS_PX * s
        self._finish_squares = self._checkered(env.track.finish.a, env.track.finish.b)
        self._panel_top = 0  # set by _draw_static, below the panel title
        self._sprites: dict[tuple[Colour, int], pygame.Surface] = {}  # see _ghost_sprite
        self._static = self._draw_static()
        self._hud: Any = None  # the window's heads-up display (snnkart.envs.overlay)
        self.screenshots: list[Any] = []  # paths saved with P
        if human:
            from snnkart.envs.overlay import Hud

            self._hud = Hud(env, s, self.track_width, self.size[1])

    # -- public API ----------------------------------------------------------------------------

    def draw(self) -> np.ndarray | None:
        """Draw the current state; return the RGB frame, or None in human mode."""
        frame = self._frame
        frame.blit(self._static, (0, 0))
        self._draw_checkpoints(frame)
        self._draw_lidar(frame)
        self._draw_kart(frame)
        self._draw_telemetry(frame)
        for overlay in self.env.overlays:  # callables drawing on the frame, e.g. key help
            overlay(frame)
        if self._hud is not None:
            self._hud(frame)
        return self._present(frame)

    def _present(self, frame: pygame.Surface) -> np.ndarray | None:
        if not self.human:
            return np.ascontiguousarray(pygame.surfarray.array3d(frame).transpose(1, 0, 2))
        from snnkart.envs.overlay import take_screenshots

        pygame.event.pump()
        self.screenshots += take_screenshots(frame)
        pygame.display.flip()
        assert self._clock is not None
        self._clock.tick(self.env.metadata["render_fps"])
        return None

    def draw_ghosts(
        self,
        positions: np.ndarray,
        colours: list[Colour],
        lines: Sequence[tuple[Any, ...]],
        alpha: int = 255,
        bar: ColourBar | None = None,
    ) -> np.ndarray | None:
        """Draw the track with many karts (replay): ``positions`` ``[k, 2]`` px, one colour each,
        at opacity ``alpha`` (0-255; overlapping karts add up, so a pile shows its size), and
        ``lines`` of (label, value[, colour]) in the side panel (a legend names colours in their
        own colour), then ``bar`` if given. Returns the frame as :meth:`draw`."""
        frame = self._frame
        frame.blit(self._static, (0, 0))
        width = max(1, round(2 * self.scale))
        for cp in self.env.track.checkpoints[:-1]:
            pygame.draw.line(frame, CHECKPOINT_LATER, self._screen(cp.a), self._screen(cp.b), width)
        for colour, square in self._finish_squares:
            pygame.draw.polygon(frame, colour, square)
        for (x, y), colour in zip(positions, colours, strict=True):
            sprite = self._ghost_sprite(colour, alpha)
            cx, cy = self._screen((x, y))
            frame.blit(sprite, (cx - sprite.get_width() / 2, cy - sprite.get_height() / 2))
        y = self._panel_top
        for line in lines:  # (label, value) or (label, value, colour)
            y = self._row(frame, y, line[0], line[1], line[2] if len(line) > 2 else TEXT)
        if bar is not None:
            self._draw_colour_bar(frame, y, bar)
        if self._hud is not None:
            self._hud.draw_fps(frame)
        return self._present(frame)

    def _ghost_sprite(self, colour: Colour, alpha: int) -> pygame.Surface:
        """A replayed kart: a ring at opacity ``alpha`` filled at half that (cached)."""
        key = (colour, alpha)
        if key not in self._sprites:
            r = self._kart_radius
            side = math.ceil(2 * r) + 2
            sprite = pygame.Surface((side, side), pygame.SRCALPHA)
            centre = (side / 2, side / 2)
            pygame.draw.circle(sprite, (*colour, alpha // 2), centre, r)
            pygame.draw.circle(sprite, (*colour, alpha), centre, r, max(1, round(2 * self.scale)))
            self._sprites[key] = sprite
        return self._sprites[key]

    def _draw_colour_bar(self, frame: pygame.Surface, y: int, bar: ColourBar) -> int:
        """Draw ``bar`` across the panel below ``y``: title, gradient, end labels; return the
        top of what follows."""
        y = self._rule(frame, y)
        left, right = self.track_width + self._pad, self.size[0] - self._pad
        title = self._small_font.render(bar.title, True, TEXT_DIM)
        frame.blit(title, (left, y))
        y += round(title.get_height() * 1.4)
        height, n = max(6, self._line_height // 2), len(bar.colours)
        for k, colour in enumerate(bar.colours):
            x0, x1 = left + (right - left) * k // n, left + (right - left) * (k + 1) // n
            pygame.draw.rect(frame, colour, (x0, y, x1 - x0, height))
        y += height + round(4 * self.scale)
        low, high = (self._small_font.render(t, True, TEXT) for t in (bar.low, bar.high))
        frame.blit(low, (left, y))
        frame.blit(high, (right - high.get_width(), y))
        return y + low.get_height()

    def quit_requested(self) -> bool:
        """Whether the user closed the window or pressed Esc since the last call."""
        return any(
            e.type == pygame.QUIT or (e.type == pygame.KEYDOWN and e.key == pygame.K_ESCAPE)
            for e in pygame.event.get()
        )

    def close(self) -> None:
        """Close the window (human mode); safe to call more than once."""
        if self.human and not self._closed:
            pygame.display.quit()
        self._closed = True

    # -- static layer --------------------------------------------------------------------------

    def _draw_static(self) -> pygame.Surface:
        s = self.scale
        surf = pygame.Surface(self.size)
        surf.fill(BACKGROUND)
        step = PIXELS_PER_METRE * s  # one line per metre
        for k in range(1, math.ceil(WORLD_SIZE_PX / PIXELS_PER_METRE)):
            c = round(k * step)
            pygame.draw.line(surf, GRID, (c, 0), (c, self.size[1]))
            pygame.draw.line(surf, GRID, (0, c), (self.track_width, c))
        width = max(2, round(3.5 * s))
        for line in self.env.track.walls:
            pts = [self._screen(p) for p in line]
            pygame.draw.lines(surf, WALL, False, pts, width)
            for p in pts:  # round joints, so sharp corners have no notches
                pygame.draw.circle(surf, WALL, p, width / 2)

        pygame.draw.rect(surf, PANEL, (self.track_width, 0, self.size[0], self.size[1]))
        pygame.draw.line(surf, PANEL_RULE, (self.track_width, 0), (self.track_width, self.size[1]))
        x, y = self.track_width + self._pad, self._pad
        title = self._title_font.render(self.env.env_name, True, TEXT)
        surf.blit(title, (x, y))
        y += title.get_height() + round(4 * s)
        track = self._font.render(f"on {self.env.track.name}", True, TEXT_DIM)
        surf.blit(track, (x, y))
        self._panel_top = y + track.get_height() + self._pad
        return surf

    # -- dynamic layers ------------------------------------------------------------------------

    def _draw_checkpoints(self, frame: pygame.Surface) -> None:
        env = self.env
        s = self.scale
        cps = env.track.checkpoints
        nxt = env.next_checkpoint
        thin, thick = max(1, round(2 * s)), max(2, round(4 * s))
        for i, cp in enumerate(cps[:-1]):
            if i < nxt:
                colour, width = CHECKPOINT_PASSED, thin
            elif i == nxt:
                colour, width = CHECKPOINT_NEXT, thick
            else:
                colour, width = CHECKPOINT_LATER, thin
            pygame.draw.line(frame, colour, self._screen(cp.a), self._screen(cp.b), width)
        if nxt == len(cps) - 1 and not env.lap_finished:
            a, b = self._screen(cps[-1].a), self._screen(cps[-1].b)
            pygame.draw.line(frame, CHECKPOINT_NEXT, a, b, 3 * thick)
        for colour, square in self._finish_squares:
            pygame.draw.polygon(frame, colour, square)

    def _draw_lidar(self, frame: pygame.Surface) -> None:
        env = self.env
        origin = self._screen(env.position)
        dot = max(2, round(3 * self.scale))
        for hit, distance in zip(env.lidar_hits, env.lidar_distances, strict=True):
            end = self._screen(hit)
            pygame.draw.aaline(frame, RAY, origin, end)
            if distance < 1.0:
                pygame.draw.circle(frame, RAY_HIT, end, dot)

    def _draw_kart(self, frame: pygame.Surface) -> None:
        env = self.env
        cx, cy = self._screen(env.position)
        r = self._kart_radius
        pygame.draw.circle(frame, KART, (cx, cy), r)
        pygame.draw.circle(frame, KART_MARK, (cx, cy), r, max(1, round(1.5 * self.scale)))
        if env.egocentric:
            h = env.heading
            tip = (cx + r * math.cos(h), cy + r * math.sin(h))
            pygame.draw.line(frame, KART_MARK, (cx, cy), tip, max(2, round(3 * self.scale)))

    def _draw_telemetry(self, frame: pygame.Surface) -> None:
        env = self.env
        n = len(env.track.checkpoints)
        checkpoint = "finished" if env.lap_finished else f"{env.next_checkpoint + 1} / {n}"
        y = self._panel_top
        for label, value in (
            ("speed", f"{env.speed_m_s:.2f} m/s"),
            ("lap time", f"{env.elapsed_time:.2f} s"),
            ("next checkpoint", checkpoint),
            ("action", env.describe_action(env.last_action)),
        ):
            y = self._row(frame, y, label, value, TEXT)
        y = self._row(frame, y, "return", f"{env.episode_return:+.3f}", TEXT)
        y = self._rule(frame, y)
        heading = self._small_font.render("reward terms, last step", True, TEXT_DIM)
        frame.blit(heading, (self.track_width + self._pad, y))
        y += round(heading.get_height() * 1.6)
        for name, term in env.last_reward_terms.items():
            colour = POSITIVE if term > 0 else NEGATIVE if term < 0 else TEXT_DIM
            y = self._row(frame, y, name, f"{term:+.3f}", colour)
        if env.activity:
            self._draw_activity(frame, self._rule(frame, y))

    def _draw_activity(self, frame: pygame.Surface, y: int) -> None:
        """The driving spiking policy's firing rate per layer in the last env step, as bars."""
        heading = self._small_font.render("spiking layers, last step", True, TEXT_DIM)
        frame.blit(heading, (self.track_width + self._pad, y))
        y += round(heading.get_height() * 1.6)
        left, right = self.track_width + self._pad, self.size[0] - self._pad
        for label, rate in self.env.activity:
            y = self._row(frame, y, label, f"{100 * rate:.0f} % firing", TEXT)
            width = right - left
            bar = max(0, min(width, round(width * rate)))
            height = max(3, self._line_height // 3)
            pygame.draw.rect(frame, PANEL_RULE, (left, y - self._pad // 3, width, height))
            pygame.draw.rect(frame, POSITIVE, (left, y - self._pad // 3, bar, height))
            y += height

    # -- helpers -------------------------------------------------------------------------------

    def _screen(self, p: tuple[float, float] | np.ndarray) -> tuple[float, float]:
        return (float(p[0]) * self.scale, float(p[1]) * self.scale)

    def _row(self, frame: pygame.Surface, y: int, label: str, value: str, colour: Colour) -> int:
        """Draw ``label`` left and ``value`` right-aligned; return the next row's top."""
        left = self.track_width + self._pad
        frame.blit(self._font.render(label, True, TEXT_DIM), (left, y))
        text = self._font.render(value, True, colour)
        frame.blit(text, (self.size[0] - self._pad - text.get_width(), y))
        return y + self._line_height

    def _rule(self, frame: pygame.Surface, y: int) -> int:
        """Draw a horizontal separator in the panel; return the top of what follows."""
        y += self._pad // 2
        left, right = self.track_width + self._pad, self.size[0] - self._pad
        pygame.draw.line(frame, PANEL_RULE, (left, y), (right, y))
        return y + self._pad

    def _checkered(
        self, a: tuple[float, float], b: tuple[float, float]
    ) -> list[tuple[Colour, list[tuple[float, float]]]]:
        """Squares of a two-row chequered band along the finish line ``a``-``b``."""
        (ax, ay), (bx, by) = self._screen(a), self._screen(b)
        length = math.hypot(bx - ax, by - ay)
        ux, uy = (bx - ax) / length, (by - ay) / length
        nx, ny = -uy, ux
        q = max(3.0, 7.0 * self.scale)
        squares = []
        for i in range(math.ceil(length / q)):
            t0, t1 = i * q, min((i + 1) * q, length)
            for row, (o0, o1) in enumerate(((-q, 0.0), (0.0, q))):
                colour = FINISH_LIGHT if (i + row) % 2 == 0 else FINISH_DARK
                corners = [
                    (ax + ux * t + nx * o, ay + uy * t + ny * o)
                    for t, o in ((t0, o0), (t1, o0), (t1, o1), (t0, o1))
                ]
                squares.append((colour, corners))
        return squares
