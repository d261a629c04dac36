"""``snnkart ros sim`` and ``snnkart ros drive``: the bridge to ROS 1 (rospy)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from snnkart.backends.defaults import precision_help
from snnkart.cli.guard import guard

ros_app = typer.Typer(
    help="Drive a differential-drive robot over ROS (ROS_MASTER_URI) with a deployed policy.",
    no_args_is_help=True,
)
OriginOpt = Annotated[
    str,
    typer.Option(
        help="track: odometry is in the track's frame; spawn: odometry counts from the track's "
        "spawn, as a real robot's wheel odometry counts from where it was switched on",
    ),
]
LockOpt = Annotated[
    bool,
    typer.Option(
        "--lock-step/--real-time",
        help="lock-step: one simulation step per command; real time: 60 steps per second",
    ),
]


@ros_app.command("sim")
def sim(
    policy: Annotated[
        Path | None,
        typer.Option(
            help="the policy `ros drive` runs (a gazebo run or its policy.nir): simulate the env "
            "it was trained for, its track and env config"
        ),
    ] = None,
    track: Annotated[
        str | None,
        typer.Option("--track", "-t", help="default: the policy's track, else small_S"),
    ] = None,
    seed: Annotated[int, typer.Option(help="seed of the episode")] = 10_000,
    lock_step: LockOpt = True,
    timeout: Annotated[float, typer.Option(help="lock-step: seconds to wait for a command")] = 30,
    max_steps: Annotated[int | None, typer.Option(help="end after this many steps")] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="episode record (JSON)")] = None,
    odom_origin: OriginOpt = "track",
) -> None:
    """Play Gazebo's part: the gazebo env publishes /scan, /odom and /clock and applies /cmd_vel.

    With --policy, a --track other than the one the policy was trained on is refused: the
    driver computes the checkpoint features of its observation on the policy's track."""
    from snnkart.app.ros_bridge import run_sim

    record = guard(
        lambda: run_sim(track, seed, lock_step, out, timeout, max_steps, odom_origin, policy),
        "the simulation stopped",
    )
    summary = {k: v for k, v in record.items() if k != "positions"}
    typer.echo(json.dumps(summary))


@ros_app.command("drive")
def drive(
    policy: Annotated[Path, typer.Argument(help="a gazebo run (torch) or its policy.nir")],
    backend: Annotated[str, typer.Option(help="torch, nir-ref or lava-sim")] = "torch",
    precision: Annotated[str, typer.Option(help=precision_help())] = "fixed",
    lock_step: LockOpt = True,
    timeout: Annotated[
        float, typer.Option(help="stop the robot when scans or odometry are this old, s")
    ] = 2.0,
    max_seconds: Annotated[float | None, typer.Option(help="stop after this long")] = None,
    max_linear: Annotated[
        float | None, typer.Option(help="the robot's speed limit, m/s (default: the env's)")
    ] = None,
    max_angular: Annotated[
        float | None, typer.Option(help="the robot's turn-rate limit, rad/s (default: the env's)")
    ] = None,
    odom_origin: OriginOpt = "track",
) -> None:
    """Subscribe to /scan and /odom, run the policy, publish /cmd_vel within the robot's limits;
    a zero Twist on stale input, a failed backend, Ctrl-C and exit."""
    from snnkart.app.ros_bridge import run_drive

    summary = guard(
        lambda: run_drive(
            policy,
            backend,
            precision,
            lock_step,
            timeout,
            max_seconds,
            max_linear,
            max_angular,
            odom_origin,
        ),
        "the robot was stopped (zero cmd_vel)",
    )
    typer.echo(json.dumps(summary))
