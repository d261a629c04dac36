"""The errors a user can cause, all subclasses of :class:`SnnkartError`.

The command line turns a ``SnnkartError`` into ``error: <message>`` and an exit status; its
message names the problem and what to do. Any other exception is a bug in snnkart and shows
its traceback. Each class keeps the built-in base it had (``ValueError`` for bad input,
``RuntimeError`` for a state that cannot be used), so ``except ValueError`` still catches it.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any


class SnnkartError(Exception):
    """A problem with the user's input, files or machine, reported without a traceback."""


class ConfigError(SnnkartError, ValueError):
    """An invalid training configuration."""


class EnvError(SnnkartError, ValueError):
    """An unknown env, action mode or env setting."""


class TrackError(SnnkartError, ValueError):
    """A track file is missing, malformed or geometrically invalid."""


class CheckpointError(SnnkartError, ValueError):
    """A checkpoint is missing, unreadable or does not fit the env or code."""


class CheckpointWriteError(CheckpointError):
    """A checkpoint could not be written (disk full, read-only, ...); the previous one is
    intact (files are replaced atomically)."""


class RunError(SnnkartError, RuntimeError):
    """A run directory cannot be used as asked (exists already, nothing to resume, ...)."""


class ExportError(SnnkartError, ValueError):
    """A run cannot be exported to NIR (not a spiking policy, non-uniform layers, ...)."""


class ManifestError(SnnkartError, ValueError):
    """A manifest is missing, malformed or inconsistent with its NIR graph."""


class NIRFileError(SnnkartError, ValueError):
    """A NIR file is missing or unreadable."""


class UnsupportedGraphError(SnnkartError, ValueError):
    """A NIR graph that the backends cannot run; the message names the node and why."""


class BackendError(SnnkartError, RuntimeError):
    """A backend failed while running (its worker died, timed out or reported an error)."""


class DeployError(SnnkartError, ValueError):
    """Bad deploy input: the message names the problem and what to do."""


class ParityError(DeployError):
    """The backend differed from its same-arithmetic reference; ``record`` holds the run (a
    :class:`snnkart.contract.deploy_record.DeployRecord`: this module sits below it)."""

    def __init__(self, message: str, record: Any) -> None:
        super().__init__(message)
        self.record = record


class DeployWriteError(DeployError):
    """The run finished but its record could not be written; ``record`` holds it (a
    :class:`snnkart.contract.deploy_record.DeployRecord`)."""

    def __init__(self, message: str, record: Any) -> None:
        super().__init__(message)
        self.record = record


class ReplayError(SnnkartError, ValueError):
    """A replay cannot be made as asked (no trajectories, unknown mode, ...)."""


class UsageError(SnnkartError, ValueError):
    """Command options that do not go together or are out of range."""


class ProfileError(SnnkartError, ValueError):
    """A hardware profile that cannot be used (missing or unknown keys, bad values)."""


class ReportError(SnnkartError, ValueError):
    """An energy report cannot be made from the inputs given."""


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean X?)`` for the choice closest to a misspelled ``word``, else ``""``."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""
