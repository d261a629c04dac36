"""The colours of every snnkart window and film (the renderer's and the overlays'), in one
place so that :mod:`snnkart.envs.render` and :mod:`snnkart.envs.overlay` share them without
importing each other."""

from __future__ import annotations

Colour = tuple[int, int, int]

BACKGROUND: Colour = (18, 20, 26)
GRID: Colour = (27, 30, 38)
WALL: Colour = (200, 202, 210)
PANEL: Colour = (29, 32, 41)
PANEL_RULE: Colour = (62, 66, 80)
CHECKPOINT_PASSED: Colour = (58, 156, 88)
CHECKPOINT_NEXT: Colour = (255, 218, 40)
CHECKPOINT_LATER: Colour = (88, 92, 106)
FINISH_LIGHT: Colour = (240, 240, 240)
FINISH_DARK: Colour = (210, 40, 45)
RAY: Colour = (46, 104, 122)
RAY_HIT: Colour = (90, 220, 255)
KART: Colour = (255, 128, 24)
"""Kart body colour; no other element uses it (tests look for it)."""
KART_MARK: Colour = (40, 24, 8)
TEXT: Colour = (226, 229, 236)
TEXT_DIM: Colour = (138, 144, 160)
POSITIVE: Colour = (110, 212, 124)
NEGATIVE: Colour = (238, 104, 92)
