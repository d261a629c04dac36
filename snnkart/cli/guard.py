"""How a command ends: a user error is ``error: ...`` and an exit status, Ctrl-C and SIGTERM
say what was kept, anything else is a bug and shows its traceback."""

from __future__ import annotations

from collections.abc import Callable, Collection
from pathlib import Path
from typing import Annotated, Any, NoReturn, TypeVar

import typer

from snnkart.errors import SnnkartError

T = TypeVar("T")


def fail(message: str, code: int = 2) -> NoReturn:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code)


def guard(call: Callable[[], T], interrupted: str | None = None) -> T:
    """Run a workflow, turning its failures into the command's exit status: 2 for bad input
    (``error: ...``), 4 for a parity mismatch (its summary is already shown), 130/143 for
    Ctrl-C/SIGTERM with ``interrupted`` saying what was kept. Anything else is a bug and
    propagates with its traceback."""
    import warnings

    from snnkart.errors import ParityError

    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return call()
    except KeyboardInterrupt as exc:
        if interrupted is None:
            raise
        interrupted_exit(exc, interrupted)
    except ParityError as exc:
        fail(str(exc), code=4)
    except SnnkartError as exc:
        fail(str(exc))


def _one_line_warning(
    message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any
) -> None:
    """snnkart's own warnings (a user's concern, e.g. another env version) as one line."""
    typer.secho(f"warning: {message}", fg=typer.colors.YELLOW, err=True)


def interrupted_exit(exc: KeyboardInterrupt, what: str) -> NoReturn:
    """Report Ctrl-C/SIGTERM and exit with the shell's status for it (130, 143)."""
    from snnkart.faults import Interrupted

    code = exc.exit_code if isinstance(exc, Interrupted) else 130
    name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
    typer.secho(f"interrupted ({name}): {what}", fg=typer.colors.YELLOW, err=True)
    raise typer.Exit(code)


ForceOpt = Annotated[
    bool, typer.Option("--force", help="write into an --out that holds other files (deletes none)")
]


def refuse_other_files(out: Path, own: Collection[str] = (), force: bool = False) -> None:
    """Stop before writing into an ``--out`` directory that holds files other than the
    command's own (``own``: the names it writes there; hidden files, such as a killed atomic
    write's temporary, do not count), unless ``force``; --force deletes nothing, the command
    only adds and replaces its own files."""
    if force or not out.is_dir():
        return
    other = sorted(p.name for p in out.iterdir() if p.name not in own and p.name[0] != ".")
    if other:
        shown = ", ".join(other[:3]) + (f" and {len(other) - 3} more" if len(other) > 3 else "")
        fail(
            f"{out} already holds other files ({shown}); choose an empty or new --out, or "
            "pass --force to write into it anyway (nothing is deleted)"
        )
