"""Physical constants of the kart world, each defined once with its unit.

Track coordinates are pixels in screen orientation (x right, y down), as in the original
kart-simulator; angles are measured from +x towards +y, i.e. clockwise on screen.
"""

from __future__ import annotations

PIXELS_PER_METRE: float = 100.0
"""Track scale: 100 px = 1 m (the original's ``PPM``)."""

DT: float = 1.0 / 60.0
"""Physics time step in seconds; one env step is exactly one ``pymunk.Space.step(DT)``."""

KART_RADIUS_M: float = 0.192
"""Kart (or robot) body radius in metres: 19.2 px, the TurtleBot3 Burger size."""

KART_RADIUS_PX: float = KART_RADIUS_M * PIXELS_PER_METRE

KART_MASS_KG: float = 1.0
"""Body mass in kg (the original's ``bot_weight``); with mass 1 an impulse equals a speed change."""

DRAG_PER_STEP: float = 1.005
"""Coasting drag: the velocity is divided by this factor after every step (x0.7414 per second)."""

RENDER_FPS: int = 60

WORLD_SIZE_PX: float = 1000.0
"""Track coordinates shown on screen: 0 .. 1000 px on each axis."""


def px(metres: float) -> float:
    """Convert metres to track pixels."""
    return metres * PIXELS_PER_METRE


def metres(pixels: float) -> float:
    """Convert track pixels to metres."""
    return pixels / PIXELS_PER_METRE
