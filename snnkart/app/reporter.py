"""How a workflow tells its caller what it is doing, without printing.

The command line passes :class:`snnkart.cli.console.ConsoleReporter` (rich progress bars and
lines on the terminal); library users and tests pass :class:`Silent`, or their own.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Any, Protocol


class Task(Protocol):
    def advance(self) -> None:
        """One unit of the task done (an episode)."""

    def step(self) -> None:
        """One sub-step done (an env step), shown as a running count."""


class Reporter(Protocol):
    def message(self, text: str) -> None:
        """One line for the user (a stage begins, where files were written, a result)."""

    def progress(
        self, label: str, total: int | None = None, steps: str | None = None
    ) -> contextlib.AbstractContextManager[Task]:
        """A task of ``total`` units (None: unknown), with a count of sub-steps named
        ``steps`` if given."""

    def training(
        self, total: int, completed: int
    ) -> contextlib.AbstractContextManager[Callable[[dict[str, Any]], None]]:
        """Training of ``total`` env steps from ``completed``; the context yields a function
        taking each iteration's record (``global_step``, ``charts/...``)."""


class Silent:
    """A reporter that keeps the messages (``messages``) and shows nothing."""

    def __init__(self) -> None:
        self.messages: list[str] = []

    def message(self, text: str) -> None:
        self.messages.append(text)

    @contextlib.contextmanager
    def progress(
        self, label: str, total: int | None = None, steps: str | None = None
    ) -> Iterator[Task]:
        yield _NoTask()

    @contextlib.contextmanager
    def training(self, total: int, completed: int) -> Iterator[Callable[[dict[str, Any]], None]]:
        yield lambda record: None


class _NoTask:
    def advance(self) -> None:
        pass

    def step(self) -> None:
        pass
