"""The backends by name: each backend's ``--precision`` words and the arithmetic each means,
and, per backend and network family (:data:`snnkart.contract.family.FAMILIES`), the class that
runs a policy of that family on it.

The only module that imports by name (a string in :data:`ENGINES`): a backend's module is
imported when it is opened, so naming the backends costs nothing (``lava-sim``'s module is
never imported by a run on the reference), and no backend module imports this one.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING

from snnkart.backends.base import Arithmetic
from snnkart.backends.defaults import NIR_BACKENDS, TABLE
from snnkart.backends.loading import Opened, open_policy
from snnkart.errors import DeployError, did_you_mean

if TYPE_CHECKING:
    from snnkart.backends.backend import RunningPolicy

PRECISIONS: dict[str, dict[str, Arithmetic]] = {
    name: TABLE[name].precisions for name in sorted(NIR_BACKENDS)
}
"""Per NIR backend, the accepted ``--precision`` words and the arithmetic each means (the
defaults table's, :mod:`snnkart.backends.defaults`)."""
BACKENDS = tuple(PRECISIONS)

ENGINES: dict[tuple[str, str], str] = {
    ("lava-sim", "lif"): "snnkart.backends.lava_sim:LavaSimPredictor",
    ("nir-ref", "lif"): "snnkart.backends.reference:NIRReference",
    ("lava-sim", "sigma_delta"): "snnkart.backends.sigma_delta_lava:SigmaDeltaLava",
    ("nir-ref", "sigma_delta"): "snnkart.backends.sigma_delta_backend:SigmaDeltaReference",
}
"""Per (backend, family), ``module:class`` of the :class:`~snnkart.backends.backend.
RunningPolicy` that runs a policy of that family on the backend (its ``open_engine`` starts
the engine); a new engine or a new family adds lines here."""


def arithmetic_for(backend: str, precision: str) -> Arithmetic:
    """The arithmetic ``--backend backend --precision precision`` asks for."""
    if backend not in PRECISIONS:
        raise DeployError(
            f"unknown backend {backend!r}{did_you_mean(backend, BACKENDS)}; choose one of "
            f"{', '.join(BACKENDS)}"
        )
    words = PRECISIONS[backend]
    if precision not in words:
        raise DeployError(f"--precision for {backend} is {' or '.join(words)}, not {precision!r}")
    return words[precision]


def backend_class(backend: str, family: str = "lif") -> type[RunningPolicy]:
    """The class running a policy of ``family`` on ``backend``."""
    if backend not in PRECISIONS:
        raise DeployError(
            f"unknown backend {backend!r}{did_you_mean(backend, BACKENDS)}; choose one of "
            f"{', '.join(BACKENDS)}"
        )
    if (backend, family) not in ENGINES:
        runs = [b for b, f in ENGINES if f == family]
        raise DeployError(f"{backend} runs no {family} policy; choose {' or '.join(runs)}")
    module, name = ENGINES[backend, family].split(":")
    cls: type[RunningPolicy] = getattr(importlib.import_module(module), name)
    return cls


def make_backend(
    policy: str | Path | Opened, backend: str, arithmetic: Arithmetic, seed: int = 0
) -> RunningPolicy:
    """``backend`` running ``policy`` (a path, or a policy :func:`~snnkart.backends.loading.
    open_policy` read) in ``arithmetic`` (already checked by :func:`arithmetic_for`)."""
    if isinstance(policy, str | Path):
        policy = open_policy(policy)
    cls = backend_class(backend, policy.family)
    if arithmetic not in cls.arithmetics:
        words = [w for w, a in PRECISIONS[backend].items() if a in cls.arithmetics]
        raise DeployError(
            f"a {policy.family.replace('_', '-')} policy runs on {backend} in "
            f"{' or '.join(cls.arithmetics)}, not {arithmetic}: --precision {' or '.join(words)}"
        )
    return cls(policy, arithmetic, seed)


def open_backend(
    policy: str | Path | Opened, backend: str, precision: str, seed: int = 0
) -> RunningPolicy:
    """The backend ``backend`` running ``policy`` in the arithmetic ``precision`` asks for."""
    return make_backend(policy, backend, arithmetic_for(backend, precision), seed)
