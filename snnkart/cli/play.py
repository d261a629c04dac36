"""Drive a kart with the keyboard (``snnkart play``).

The keys are polled every step, so holding a key keeps acting. W/A/S/D drive (grid: up, left,
down, right; gazebo: accelerate, turn left, brake, turn right; steer: throttle, steer left,
brake, steer right), Space also brakes in gazebo and steer, R restarts the episode, P saves a
screenshot (:mod:`snnkart.envs.overlay`) and Esc or closing the window quits; the keys are also shown at the bottom of the window. When an episode
ends, one line with its outcome and return is printed and a new episode starts; standing still
is printed once per spell, not again for each episode that ends because no key was pressed.

pygame is imported only when the window is polled; the key-to-action mappings are plain
functions of :class:`Keys`, so they can be used and tested without pygame.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple


class Keys(NamedTuple):
    """The driving keys held during one step."""

    w: bool
    a: bool
    s: bool
    d: bool
    space: bool


def grid_action(keys: Keys) -> int:
    """0 none, 1 up (W), 2 down (S), 3 left (A), 4 right (D); D > A > S > W as the original."""
    if keys.d:
        return 4
    if keys.a:
        return 3
    if keys.s:
        return 2
    if keys.w:
        return 1
    return 0


def gazebo_action(keys: Keys) -> int:
    """0 none, 1 accelerate (W), 2 brake (S or Space), 3 left (A), 4 right (D); D > A > brake > W."""
    if keys.d:
        return 4
    if keys.a:
        return 3
    if keys.s or keys.space:
        return 2
    if keys.w:
        return 1
    return 0


def steer_action(keys: Keys) -> int:
    """The steer env's action ``3 * throttle + steer`` for the held keys.

    Throttle: 0 brake (S or Space; wins over W), 1 coast, 2 throttle (W). Steer: 0 left (A),
    1 straight (neither or both of A and D), 2 right (D).
    """
    throttle = 0 if keys.s or keys.space else 2 if keys.w else 1
    steer = 1 if keys.a == keys.d else 0 if keys.a else 2
    return 3 * throttle + steer


KEY_ACTIONS: dict[str, Callable[[Keys], int]] = {
    "grid": grid_action,
    "gazebo": gazebo_action,
    "steer": steer_action,
}
"""Discrete action of each env for the held keys."""

KEY_HELP: dict[str, str] = {
    "grid": "W/A/S/D move up/left/down/right",
    "gazebo": "W accelerate, S or Space brake, A/D turn",
    "steer": "W throttle, S or Space brake, A/D steer",
}


def episode_outcome(info: Mapping[str, object], truncated: bool) -> str:
    """How an episode ended, from the ``info`` of its last step."""
    if info["lap_finished"]:
        return f"finished in {info['lap_time']:.2f} s"
    if info["crashed"]:
        return "hit a wall"
    if info["stood_still"]:
        return "stood still too long"
    if truncated:
        return "time limit"
    raise ValueError("the episode has not ended")


def run_play(
    env_name: str,
    track: str,
    max_steps: int | None = None,
    seed: int | None = None,
    on_step: Callable[[int], None] | None = None,
    record: Path | None = None,
) -> int:
    """Open a window and drive ``env_name`` on ``track`` with the keyboard until Esc.

    Args:
        env_name: any spelling accepted by :func:`snnkart.envs.resolve_env_name`.
        track: built-in track name or track file.
        max_steps: quit after this many steps (demos, tests); None = until the window closes.
        seed: seed of the first episode.
        on_step: called with the step index at the start of every step, before the events
            are read (tests post key events from it).
        record: save every step to this recording (:mod:`snnkart.envs.recording`) at the end.

    Returns:
        The number of episodes that ended (finish, crash, standing still or time limit);
        episodes restarted with R or cut short by quitting are not counted.
    """
    from snnkart.envs import make, resolve_env_name
    from snnkart.envs.base import KartEnv
    from snnkart.envs.overlay import draw_key_help

    name = resolve_env_name(env_name)
    to_action = KEY_ACTIONS[name]
    env = _recorded(make(name, track=track, render_mode="human"), record)
    kart = env.unwrapped
    assert isinstance(kart, KartEnv)
    help_line = f"{KEY_HELP[name]}; R restart, P screenshot, Esc quit"
    kart.overlays.append(lambda surface: draw_key_help(surface, help_line))
    episodes, idle = 0, False  # idle: stood still, no key since; say it once per spell
    try:
        env.reset(seed=seed)  # opens the window, so pygame's events and keys work from here
        print(f"{name} on {kart.track.name}: {help_line}")
        step = 0
        while max_steps is None or step < max_steps:
            if on_step is not None:
                on_step(step)
            command, keys = _poll()
            if command == "quit":
                return episodes
            if command == "restart":
                env.reset()
            idle = idle and not any(keys) and command == "drive"
            _, _, terminated, truncated, info = env.step(to_action(keys))
            step += 1
            if terminated or truncated:
                episodes += 1
                if not (idle and info["stood_still"]):
                    print(f"{episode_outcome(info, truncated)}, return {kart.episode_return:+.2f}")
                idle = bool(info["stood_still"])
                env.reset()
    finally:
        _save(env, record)
        env.close()
    return episodes


def _recorded(env: Any, record: Path | None) -> Any:
    """``env``, wrapped to record every step when ``record`` is given."""
    if record is None:
        return env
    from snnkart.envs.recording import RecordingWrapper

    return RecordingWrapper(env, "human")


def _save(env: Any, record: Path | None) -> None:
    """Write what was recorded (if anything) to ``record`` and say so."""
    if record is None or not env.recorded_steps:
        return
    rec = env.recording().save(record)
    print(f"recorded {env.recorded_steps:,} steps to {rec}")


def _poll() -> tuple[str, Keys]:
    """This step's command (``quit`` on Esc or a closed window, ``restart`` on R, else
    ``drive``) and the driving keys held."""
    import pygame

    command = "drive"
    for event in pygame.event.get():
        if event.type == pygame.QUIT or (
            event.type == pygame.KEYDOWN and event.key == pygame.K_ESCAPE
        ):
            return "quit", Keys(False, False, False, False, False)
        if event.type == pygame.KEYDOWN and event.key == pygame.K_r:
            command = "restart"
        if event.type == pygame.KEYDOWN and event.key == pygame.K_p:
            pygame.event.post(event)  # the window saves the screenshot (snnkart.envs.overlay)
    held = pygame.key.get_pressed()
    keys = Keys(
        w=held[pygame.K_w],
        a=held[pygame.K_a],
        s=held[pygame.K_s],
        d=held[pygame.K_d],
        space=held[pygame.K_SPACE],
    )
    return command, keys
