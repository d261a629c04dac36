"""``snnkart train``: train a policy of any registered kind with PPO (its options, and what a
failed write during training leaves of the run)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.console import ConsoleReporter
from snnkart.cli.guard import ForceOpt, fail, interrupted_exit, refuse_other_files
from snnkart.errors import CheckpointWriteError, SnnkartError
from snnkart.rl import kinds

_SET_HELP = (
    "any hyperparameter: KEY=VALUE, e.g. ppo.learning_rate=1e-3 or ann.activation=relu "
    "(the ANN's hidden activation; default tanh)"
)


_StepsOption = Annotated[
    int | None,
    typer.Option(
        help="total env steps (with --resume: extend the run to this many)",
        show_default="300000; with --resume the run's own",
    ),
]
_RunDirOption = Annotated[
    Path | None,
    typer.Option("--out", "-o", help="run directory (default: runs/ENV-POLICY-TRACK-sSEED)"),
]
_PretrainBCOption = Annotated[
    Path | None, typer.Option(help="warm-start by behaviour cloning this recording first")
]
_BCEpochsOption = Annotated[int | None, typer.Option(help="--pretrain-bc: epochs of cloning")]


_EnvOption = Annotated[
    str | None,
    typer.Option(
        "--env",
        "-e",
        help="grid, gazebo or steer; a gymnasium id (CartPole-v1), module:EnvId-v0 or "
        "package.module:ClassName",
        show_default="steer",
    ),
]
_EnvKwargsOption = Annotated[
    list[str] | None,
    typer.Option(help="a gymnasium env's keyword argument KEY=VALUE (repeat for more)"),
]
_ZooOption = Annotated[
    bool, typer.Option(help="start from the RL Zoo's PPO settings for --env (--set goes on top)")
]


def train(
    env: _EnvOption = None,
    env_kwargs: _EnvKwargsOption = None,
    zoo: _ZooOption = False,
    track: Annotated[
        str | None,
        typer.Option("--track", "-t", help="big_S, small_S or a file", show_default="small_S"),
    ] = None,
    policy: Annotated[
        str | None, typer.Option(help=kinds.choices_help(), show_default="snn")
    ] = None,
    steps: _StepsOption = None,
    seed: Annotated[int | None, typer.Option(help="random seed", show_default="1")] = None,
    action_mode: Annotated[
        str | None, typer.Option(help="discrete or continuous", show_default="discrete")
    ] = None,
    out: _RunDirOption = None,
    config: Annotated[Path | None, typer.Option("--config", "-c", help="TOML config file")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", help=_SET_HELP)] = None,
    resume: Annotated[bool, typer.Option(help="continue the run in --out")] = False,
    pretrain_bc: _PretrainBCOption = None,
    bc_epochs: _BCEpochsOption = None,
    force: ForceOpt = False,
    wandb: Annotated[bool, typer.Option(help="also log to Weights & Biases (extra)")] = False,
) -> None:
    """Train a policy of any registered kind with PPO; Ctrl-C checkpoints, --resume goes on."""
    from snnkart.app.train import run_training
    from snnkart.envs.tracks import load_track
    from snnkart.rl.config import load_config

    overrides = {
        "env": env,
        "env_kwargs": _env_kwargs(env_kwargs),
        "track": track,
        "policy": policy,
        "total_steps": steps,
        "seed": seed,
        "action_mode": action_mode,
        **_bc_overrides(pretrain_bc, bc_epochs),
    }
    run_dir = out or Path("runs")
    try:
        cfg = load_config(config, overrides, [*_zoo_sets(zoo, env, overrides), *(set_ or [])])
        if not resume and cfg.kart:
            load_track(cfg.track)
        run_dir = out or Path("runs") / _run_name(cfg)
        refuse_other_files(run_dir, (), force or resume or (run_dir / "config.toml").exists())
        extend = steps if resume else None  # a resume keeps the run's length unless --steps
        code = run_training(cfg, run_dir, ConsoleReporter(stderr=True), resume, extend, wandb)
    except KeyboardInterrupt as exc:  # before training began: nothing to save yet
        interrupted_exit(exc, "stopped before training began; the run directory is as it was")
    except (CheckpointWriteError, OSError) as exc:
        fail(_write_failure(exc, run_dir))
    except SnnkartError as exc:
        fail(str(exc))
    raise typer.Exit(code)


def _run_name(cfg: object) -> str:
    """``ENV-POLICY-TRACK-sSEED`` (no track for a gymnasium env; ``:`` as ``_``)."""
    where = f"-{Path(cfg.track).stem}" if cfg.kart else ""  # type: ignore[attr-defined]
    return f"{cfg.env.replace(':', '_')}-{cfg.policy}{where}-s{cfg.seed}"  # type: ignore[attr-defined]


def _env_kwargs(items: list[str] | None) -> dict[str, object] | None:
    from snnkart.envs.resolve import parse_env_kwargs

    return parse_env_kwargs(items) if items else None


def _zoo_sets(zoo: bool, env: str | None, overrides: dict[str, object]) -> list[str]:
    """``--zoo``: the RL Zoo's settings for ``env`` as ``--set`` items, but for what the
    command line sets itself (``--steps``, ``--seed``...)."""
    if not zoo:
        return []
    from snnkart.errors import ConfigError
    from snnkart.rl.zoo import as_overrides, to_snnkart, zoo_settings

    if env is None:
        raise ConfigError("--zoo needs --env: the task whose RL Zoo settings to take")
    given = {k for k, v in overrides.items() if v is not None}
    sets = as_overrides(to_snnkart(zoo_settings(env)))
    return [item for item in sets if item.split("=", 1)[0] not in given]


def _bc_overrides(data: Path | None, epochs: int | None) -> dict[str, object]:
    """The ``bc`` config keys that ``--pretrain-bc`` and ``--bc-epochs`` set."""
    if data is None and epochs is not None:
        fail("--bc-epochs needs --pretrain-bc DATA.npz")
    return {} if data is None else {"bc.data": str(data), "bc.epochs": epochs}


def _write_failure(exc: Exception, run_dir: Path) -> str:
    """A failed write during training: what failed, and what of the run is still good."""
    from snnkart.rl.checkpoint import CheckpointError, load_checkpoint

    if isinstance(exc, OSError):
        what = f"cannot write {exc.filename or 'to ' + str(run_dir)}: {exc.strerror or exc}"
    else:
        what = str(exc)
    try:
        _, meta = load_checkpoint(run_dir / "checkpoint.pt")
        kept = (
            f"the last good checkpoint ({run_dir / 'checkpoint.pt'}, step "
            f"{meta.get('global_step', 0):,}) is intact"
        )
    except CheckpointError:
        kept = "no checkpoint had been written yet"
    return (
        f"{what}; {kept}. Free space or make {run_dir} writable, then continue with: "
        f"snnkart train --resume --out {run_dir}"
    )
