"""The track editor's window (``snnkart track edit``): pygame events in, the model's state drawn.

Every edit is :class:`snnkart.envs.track_edit.TrackEditor`'s (its docstring lists the tools
and keys); this module maps screen pixels to track pixels (:data:`SCALE`), pygame events to the
model's calls, and draws the track with the loader's verdict under it. Ctrl+S saves, Esc or
closing the window quits (with unsaved changes, only when asked twice in a row).
"""

from __future__ import annotations

import math
import os
import textwrap
from pathlib import Path

from snnkart.envs.constants import KART_RADIUS_PX, PIXELS_PER_METRE
from snnkart.envs.track_edit import TrackEditor
from snnkart.errors import TrackError

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
import pygame  # after the prompt switch

SCALE = 0.75
"""Screen px per track px: the 1000 x 1000 px world (10 m square) in a 750 px canvas."""
CANVAS = 750
STATUS_H = 96
HELP = (
    "W wall  C checkpoint  S spawn  M move  Del delete  G grid  Ctrl+Z undo  Ctrl+S save  Esc quit"
)
COLOURS = {
    "bg": (24, 26, 30),
    "grid": (44, 48, 54),
    "wall": (220, 220, 220),
    "open": (255, 200, 60),
    "cp": (80, 150, 255),
    "finish": (255, 80, 80),
    "spawn": (90, 220, 120),
    "ok": (90, 220, 120),
    "error": (255, 110, 110),
    "text": (200, 200, 200),
}


class EditorWindow:
    """One editor window over one file; :meth:`run` is the loop, :meth:`handle` one event."""

    def __init__(self, editor: TrackEditor, path: Path) -> None:
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # headless: as the renderer does
        pygame.display.init()
        pygame.font.init()
        self.editor, self.path = editor, path
        self.screen = pygame.display.set_mode((CANVAS, CANVAS + STATUS_H))
        pygame.display.set_caption(f"snnkart track edit {path}")
        self.font = pygame.font.Font(None, 20)
        self.saved_state = editor.state.to_toml()
        self.message = ""
        self.running = True
        self.quitting = False  # asked to quit once with unsaved changes

    def run(self) -> None:
        """Handle events and redraw until the window is closed."""
        clock = pygame.time.Clock()
        while self.running:
            self.pump()
            clock.tick(60)
        pygame.quit()

    def pump(self) -> None:
        """Handle the queued events, then draw one frame."""
        for event in pygame.event.get():
            self.handle(event)
        self.draw()
        pygame.display.flip()

    def handle(self, event: pygame.event.Event) -> None:
        ed = self.editor
        if event.type == pygame.QUIT:
            self.quit()
        elif event.type == pygame.MOUSEBUTTONDOWN:
            ed.press(to_track(event.pos), event.button)
        elif event.type == pygame.MOUSEMOTION and event.buttons[0]:
            ed.drag(to_track(event.pos))
        elif event.type == pygame.MOUSEBUTTONUP:
            ed.release(to_track(event.pos), event.button)
        elif event.type == pygame.KEYDOWN:
            self._key(event)

    def _key(self, event: pygame.event.Event) -> None:
        ctrl = bool(event.mod & pygame.KMOD_CTRL)
        if event.key == pygame.K_ESCAPE:
            self.quit()
            return
        self.quitting = False  # any other key: the next Esc asks again
        if ctrl and event.key == pygame.K_s:
            self.save()
        elif event.key in (pygame.K_DELETE, pygame.K_BACKSPACE):
            self.editor.delete(to_track(pygame.mouse.get_pos()))
        else:
            self.editor.key(pygame.key.name(event.key).lower(), ctrl)

    @property
    def unsaved(self) -> bool:
        return self.editor.state.to_toml() != self.saved_state

    def quit(self) -> None:
        """Close the window; with unsaved changes only when asked twice in a row."""
        if self.unsaved and not self.quitting:
            self.quitting = True
            self.message = "unsaved changes: Esc again quits without saving, Ctrl+S saves"
        else:
            self.running = False

    def save(self) -> None:
        try:
            self.editor.save(self.path)
        except (TrackError, OSError) as exc:
            self.message = str(exc)
            return
        self.saved_state = self.editor.state.to_toml()
        self.message = f"saved {self.path}"

    # -- drawing ----------------------------------------------------------------------------

    def draw(self) -> None:
        s, st, ed = self.screen, self.editor.state, self.editor
        s.fill(COLOURS["bg"])
        for k in range(0, int(CANVAS / SCALE) + 1, int(PIXELS_PER_METRE)):  # a line per metre
            pygame.draw.line(s, COLOURS["grid"], to_screen((k, 0)), to_screen((k, 1000)))
            pygame.draw.line(s, COLOURS["grid"], to_screen((0, k)), to_screen((1000, k)))
        for wall in st.walls:
            colour = COLOURS["open"] if wall is ed.drawing else COLOURS["wall"]
            if len(wall) > 1:
                pygame.draw.lines(s, colour, False, [to_screen(p) for p in wall], 2)
            for p in wall:
                pygame.draw.circle(s, colour, to_screen(p), 3)
        for i, (a, b) in enumerate(st.checkpoints):
            colour = COLOURS["finish" if i == len(st.checkpoints) - 1 else "cp"]
            pygame.draw.line(s, colour, to_screen(a), to_screen(b), 2)
            s.blit(self.font.render(str(i), True, colour), to_screen(a))
        if st.spawn is not None:
            self._draw_spawn(st.spawn, st.heading_deg, st.jitter)
        self._draw_status()

    def _draw_spawn(self, spawn: tuple[float, float], heading_deg: float, jitter: float) -> None:
        centre, h = to_screen(spawn), math.radians(heading_deg)
        tip = (
            spawn[0] + 2 * KART_RADIUS_PX * math.cos(h),
            spawn[1] + 2 * KART_RADIUS_PX * math.sin(h),
        )
        pygame.draw.circle(self.screen, COLOURS["spawn"], centre, round(KART_RADIUS_PX * SCALE), 2)
        pygame.draw.line(self.screen, COLOURS["spawn"], centre, to_screen(tip), 2)
        if jitter > 0:
            corner = to_screen((spawn[0] - jitter, spawn[1] - jitter))
            side = 2 * jitter * SCALE
            pygame.draw.rect(self.screen, COLOURS["spawn"], (*corner, side, side), 1)

    def _draw_status(self) -> None:
        ed = self.editor
        unsaved = " (unsaved)" if self.unsaved else ""
        lines = [
            (
                f"{self.path}{unsaved}  tool: {ed.tool}  grid: {'10 px' if ed.grid else 'off'}",
                "text",
            ),
            (HELP, "text"),
        ]
        verdict = ed.error or "valid: the loader accepts this track"
        lines += [(part, "error" if ed.error else "ok") for part in textwrap.wrap(verdict, 120)[:2]]
        if self.message:
            lines.append((self.message, "text"))
        for k, (text, colour) in enumerate(lines):
            surface = self.font.render(text[:130], True, COLOURS[colour])
            self.screen.blit(surface, (6, CANVAS + 4 + 18 * k))


def to_track(pos: tuple[int, int]) -> tuple[float, float]:
    """Screen px to track px."""
    return (pos[0] / SCALE, pos[1] / SCALE)


def to_screen(p: tuple[float, float]) -> tuple[int, int]:
    """Track px to screen px."""
    return (round(p[0] * SCALE), round(p[1] * SCALE))
