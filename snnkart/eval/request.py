"""What a closed-loop deploy is asked to run, checked once where it is made."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from snnkart.backends.base import Arithmetic
from snnkart.backends.defaults import arithmetic_of
from snnkart.errors import DeployError


@dataclass(frozen=True)
class DeployRequest:
    """One ``snnkart deploy`` (or ``snnkart eval --backend nir-ref|lava-sim``): the policy
    file, the backend and its ``--precision`` word, the seeded episodes, an env and track other
    than the manifest's, and the directory for ``deploy.json`` (None: write nothing).

    Made, it is valid: at least one episode, a NIR backend, a precision that backend accepts;
    :attr:`arithmetic` is what that precision means. The backend and the precision have no
    defaults here: a door fills them in from the one table (:mod:`snnkart.backends.defaults`,
    through :func:`snnkart.app.opener.choose`)."""

    nir_file: Path
    backend: str
    precision: str
    episodes: int = 10
    seed: int = 10_000
    env: str | None = None
    track: str | None = None
    out: Path | None = None
    arithmetic: Arithmetic = field(init=False)

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise DeployError(f"--episodes must be >= 1, got {self.episodes}")
        object.__setattr__(self, "nir_file", Path(self.nir_file))
        object.__setattr__(self, "arithmetic", arithmetic_of(self.backend, self.precision))


__all__ = ["DeployRequest"]
