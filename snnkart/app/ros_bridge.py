"""``snnkart ros sim`` and ``snnkart ros drive``: the workflows behind the commands."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from snnkart.errors import DeployError
from snnkart.io import write_json

ODOM_ORIGINS = ("track", "spawn")


def _check_origin(odom_origin: str) -> None:
    if odom_origin not in ODOM_ORIGINS:
        raise DeployError(f"--odom-origin must be track or spawn, not {odom_origin!r}")


def run_sim(
    track: str, seed: int, lock_step: bool, out: Path | None, timeout: float,
    max_steps: int | None, odom_origin: str = "track",
) -> dict[str, Any]:  # fmt: skip
    from snnkart.envs import make
    from snnkart.ros.rospy_import import init_node
    from snnkart.ros.sim import SimBridge

    _check_origin(odom_origin)
    init_node("snnkart_sim")
    env = make("gazebo", track=track)
    try:
        result = SimBridge(env, seed, lock_step, timeout, odom_origin).run(max_steps)
    finally:
        env.close()
    record = dataclasses.asdict(result)
    if out is not None:
        write_json(out, record)
    return record


def _policy(policy: Path, backend: str, precision: str) -> tuple[Any, Any]:
    """The predictor and the env it was trained for (a gazebo env)."""
    if backend == "torch":
        from snnkart.rl.trained import TorchPredictor, load_run

        run = load_run(policy)
        env = run.config.make_env(track=run.track)
        predictor: Any = TorchPredictor(run)
    else:
        from snnkart.backends.registry import open_backend
        from snnkart.eval.deploy import make_policy_env

        if policy.suffix != ".nir":
            raise DeployError(f"--backend {backend} runs an exported policy.nir, not {policy}")
        predictor = open_backend(policy, backend, precision)
        env = make_policy_env(predictor.manifest, None, None)
    name = getattr(env.unwrapped, "env_name", "?")
    if name != "gazebo":
        env.close()
        raise DeployError(
            f"the policy was trained on the {name} env; the ROS bridge drives the gazebo env's "
            "differential-drive robot"
        )
    return predictor, env


def run_drive(
    policy: Path, backend: str, precision: str, lock_step: bool, timeout: float,
    max_seconds: float | None, max_linear: float | None = None, max_angular: float | None = None,
    odom_origin: str = "track",
) -> dict[str, Any]:  # fmt: skip
    from snnkart.ros.convert import OdomFrame
    from snnkart.ros.node import DriveNode
    from snnkart.ros.rospy_import import check_master, init_node

    _check_origin(odom_origin)
    check_master()  # before loading anything heavy
    predictor, env = _policy(policy, backend, precision)
    try:
        frame = OdomFrame.at_spawn(env.unwrapped.track) if odom_origin == "spawn" else None
        init_node("snnkart_drive")
        node = DriveNode(
            env, predictor, lock_step, timeout, limits=(max_linear, max_angular), frame=frame
        )
        result = node.spin(max_seconds)
    finally:
        env.close()
        close = getattr(predictor, "close", None)
        if close is not None:
            close()
    lat = sorted(result.latencies or [])
    return {
        "commands": result.commands,
        "stopped": result.stopped,
        "finished": result.finished,
        "latency_ms_median": 1000 * lat[len(lat) // 2] if lat else None,
        "latency_ms_p95": 1000 * lat[int(0.95 * (len(lat) - 1))] if lat else None,
    }
