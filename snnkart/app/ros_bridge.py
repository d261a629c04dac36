"""``snnkart ros sim`` and ``snnkart ros drive``: the workflows behind the commands."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any

from snnkart.errors import DeployError
from snnkart.io import write_json

if TYPE_CHECKING:
    from snnkart.app.opener import Target

ODOM_ORIGINS = ("track", "spawn")


def _check_origin(odom_origin: str) -> None:
    if odom_origin not in ODOM_ORIGINS:
        raise DeployError(f"--odom-origin must be track or spawn, not {odom_origin!r}")


def run_sim(
    track: str | None,
    seed: int,
    lock_step: bool,
    out: Path | None,
    timeout: float,
    max_steps: int | None,
    odom_origin: str = "track",
    policy: Path | None = None,
) -> dict[str, Any]:
    """Play Gazebo's part for one episode; with ``policy`` (what ``ros drive`` runs) in the env
    that policy was trained for, its track and env config (:func:`sim_env`)."""
    from snnkart.ros.rospy_import import init_node
    from snnkart.ros.sim import SimBridge

    _check_origin(odom_origin)
    env = sim_env(policy, track)  # refused before ROS starts
    try:
        init_node("snnkart_sim")
        result = SimBridge(env, seed, lock_step, timeout, odom_origin).run(max_steps)
    finally:
        env.close()
    record = dataclasses.asdict(result)
    if out is not None:
        write_json(out, record)
    return record


def sim_env(policy: Path | None, track: str | None) -> Any:
    """The env ``ros sim`` runs: the gazebo env the driving ``policy`` was trained for (its
    track and env config; ``track`` must then be that same track, since the driver computes
    its checkpoint features on it), or without a policy the default gazebo env on ``track``
    (default small_S)."""
    from snnkart.envs import make
    from snnkart.envs.tracks import TrackError, load_track, track_sha256

    if policy is None:
        return make("gazebo", track=track or "small_S")
    env, trained = _policy_env(policy)
    if track is not None:
        try:
            same = track_sha256(load_track(track)) == track_sha256(trained)
        except TrackError as exc:
            env.close()
            raise DeployError(f"--track: {exc}") from exc
        if not same:
            env.close()
            raise DeployError(
                f"--track {track} is not the track {policy} was trained on "
                f"({trained.name}), on which `ros drive` computes its "
                "checkpoint features; drop --track to simulate the policy's own"
            )
    return env


def _policy_env(policy: Path) -> tuple[Any, Any]:
    """The gazebo env ``policy`` (a run directory, a checkpoint in one or its policy.nir) was
    trained for, and the track it was trained on."""
    from snnkart.app.opener import locate

    run_dir = locate(policy)
    if run_dir is None:
        from snnkart.contract.manifest import Manifest, manifest_path
        from snnkart.eval.policy_env import make_policy_env, resolve_track

        manifest = Manifest.read(manifest_path(policy))
        choice = resolve_track(manifest, None)
        trained = None if choice is None else choice.track
        env = make_policy_env(manifest, None, trained)
    else:
        from snnkart.rl.open_run import open_run

        run = open_run(run_dir, policy if policy.is_file() else None)
        trained = run.track
        env = run.config.make_env(track=trained)
    _check_gazebo(env)
    return env, trained


def _check_gazebo(env: Any) -> None:
    """Refuse (closing it) an env that is not the gazebo env: the bridge drives its robot."""
    name = getattr(env.unwrapped, "env_name", "?")
    if name != "gazebo":
        env.close()
        raise DeployError(
            f"the policy was trained on the {name} env; the ROS bridge drives the gazebo env's "
            "differential-drive robot"
        )


def _policy(target: Target) -> tuple[Any, Any]:
    """The target's predictor (a run on a NIR backend is exported first) and the env it was
    trained for (a gazebo env)."""
    from snnkart.app.opener import open_predictor

    predictor: Any = open_predictor(target)
    try:
        if target.backend == "torch":
            env = predictor.run.config.make_env(track=predictor.run.track)
        else:
            from snnkart.eval.policy_env import make_policy_env

            env = make_policy_env(predictor.manifest, None, None)
        _check_gazebo(env)
    except BaseException:
        predictor.close()
        raise
    return predictor, env


def run_drive(
    policy: Path,
    backend: str,
    precision: str | None,
    lock_step: bool,
    timeout: float,
    max_seconds: float | None,
    max_linear: float | None = None,
    max_angular: float | None = None,
    odom_origin: str = "track",
) -> dict[str, Any]:
    """Drive the robot with ``policy`` (a run directory, a checkpoint in one or a policy.nir)
    on ``backend`` in ``precision`` (None: the backend's default, fixed on nir-ref and
    lava-sim; :func:`snnkart.app.opener.choose`)."""
    from snnkart.app.opener import choose
    from snnkart.ros.convert import OdomFrame
    from snnkart.ros.node import DriveNode
    from snnkart.ros.rospy_import import check_master, init_node

    _check_origin(odom_origin)
    target = choose(policy, backend, precision)  # the opener's rules and defaults, cheaply
    check_master()  # before loading anything heavy
    predictor, env = _policy(target)
    try:
        frame = OdomFrame.at_spawn(env.unwrapped.track) if odom_origin == "spawn" else None
        init_node("snnkart_drive")
        node = DriveNode(
            env, predictor, lock_step, timeout, limits=(max_linear, max_angular), frame=frame
        )
        result = node.spin(max_seconds)
    finally:
        env.close()
        predictor.close()
    lat = sorted(result.latencies or [])
    return {
        "commands": result.commands,
        "stopped": result.stopped,
        "finished": result.finished,
        "latency_ms_median": 1000 * lat[len(lat) // 2] if lat else None,
        "latency_ms_p95": 1000 * lat[int(0.95 * (len(lat) - 1))] if lat else None,
    }
