"""The pymunk world of one track: the kart's body and, as sensors, the walls and the
checkpoint lines. Built once per env and reused for every episode (the original leaked the
whole track into the space on each reset)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import pymunk

from snnkart.envs.constants import KART_MASS_KG, KART_RADIUS_PX
from snnkart.envs.tracks import Checkpoint

_KART, _WALL, _CHECKPOINT = 1, 2, 3


@dataclass(frozen=True)
class World:
    space: pymunk.Space
    body: pymunk.Body


def _sensor(space: pymunk.Space, a: Any, b: Any, kind: int, category: int) -> pymunk.Segment:
    seg = pymunk.Segment(space.static_body, a, b, 0.0)
    seg.sensor = True
    seg.collision_type = kind
    seg.filter = pymunk.ShapeFilter(categories=category)
    space.add(seg)
    return seg


def build_world(
    walls: Iterable[tuple[float, float, float, float]],
    checkpoints: Iterable[Checkpoint],
    on_wall: Callable[[], None],
    on_checkpoint: Callable[[int], None],
) -> World:
    """A gravity-free space with the kart; ``on_wall()`` is called while the kart touches a
    wall, ``on_checkpoint(i)`` while it touches checkpoint line ``i``. Both run from C through
    cffi, which drops any exception raised in them."""
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    body = pymunk.Body(KART_MASS_KG, pymunk.moment_for_circle(KART_MASS_KG, 0, KART_RADIUS_PX))
    kart = pymunk.Circle(body, KART_RADIUS_PX)
    kart.collision_type = _KART
    kart.filter = pymunk.ShapeFilter(categories=0b001, mask=0b110)
    space.add(body, kart)
    for ax, ay, bx, by in walls:
        _sensor(space, (ax, ay), (bx, by), _WALL, 0b010)
    index: dict[pymunk.Shape, int] = {
        _sensor(space, cp.a, cp.b, _CHECKPOINT, 0b100): i for i, cp in enumerate(checkpoints)
    }

    def wall(arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        on_wall()

    def checkpoint(arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        on_checkpoint(index[arbiter.shapes[1]])

    space.on_collision(_KART, _WALL, pre_solve=wall)
    space.on_collision(_KART, _CHECKPOINT, pre_solve=checkpoint)
    return World(space, body)
