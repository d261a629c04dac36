"""The backends by name: each backend's ``--precision`` words and the arithmetic each means,
and the class that opens its engine.

The only module that imports by name (a string in :data:`BACKEND_CLASSES`): a backend's module
is imported when it is opened, so naming the backends costs nothing (``lava-sim``'s module is
never imported by a run on the reference), and no backend module imports this one.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING

from snnkart.backends.base import Arithmetic
from snnkart.backends.loading import LoadedPolicy, open_policy
from snnkart.backends.sdnn_policy import SigmaDeltaPolicy
from snnkart.errors import DeployError, did_you_mean

if TYPE_CHECKING:
    from snnkart.backends.backend import Backend
    from snnkart.backends.sdnn_backend import SigmaDeltaBackend

    AnyBackend = Backend | SigmaDeltaBackend

PRECISIONS: dict[str, dict[str, Arithmetic]] = {
    "lava-sim": {"float": "float64", "fixed": "fixed"},
    "nir-ref": {"float32": "float32", "float64": "float64", "float": "float64", "fixed": "fixed"},
}
"""Per backend, the accepted ``--precision`` words and the arithmetic each means."""
BACKENDS = tuple(PRECISIONS)

BACKEND_CLASSES: dict[str, str] = {
    "lava-sim": "snnkart.backends.lava_sim:LavaSimPredictor",
    "nir-ref": "snnkart.backends.reference:NIRReference",
}
"""Per backend, ``module:class`` of its :class:`~snnkart.backends.backend.Backend` subclass,
whose ``open_engine`` starts its engine; a new engine adds one line here."""
SIGMA_DELTA_CLASSES: dict[str, str] = {
    "lava-sim": "snnkart.backends.sdnn_lava:SigmaDeltaLava",
    "nir-ref": "snnkart.backends.sdnn_backend:SigmaDeltaReference",
}
"""The same for a sigma-delta policy (a manifest with a ``sigma_delta`` block)."""


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


def backend_class(backend: str) -> type[Backend]:
    """The :class:`~snnkart.backends.backend.Backend` subclass of ``backend``."""
    if backend not in BACKEND_CLASSES:
        raise DeployError(
            f"unknown backend {backend!r}{did_you_mean(backend, BACKENDS)}; choose one of "
            f"{', '.join(BACKENDS)}"
        )
    module, name = BACKEND_CLASSES[backend].split(":")
    cls: type[Backend] = getattr(importlib.import_module(module), name)
    return cls


def make_backend(
    policy: str | Path | LoadedPolicy | SigmaDeltaPolicy,
    backend: str,
    arithmetic: Arithmetic,
    seed: int = 0,
) -> AnyBackend:
    """``backend`` running ``policy`` in ``arithmetic`` (already checked by
    :func:`arithmetic_for`): the LIF chain's backend, or the sigma-delta one."""
    if not isinstance(policy, LoadedPolicy | SigmaDeltaPolicy):
        policy = open_policy(policy)
    if isinstance(policy, LoadedPolicy):
        return backend_class(backend)(policy, arithmetic, seed)
    if backend not in SIGMA_DELTA_CLASSES:
        backend_class(backend)  # raises the error naming the backends
    if arithmetic == "float32":
        raise DeployError(
            "a sigma-delta policy runs in Lava's arithmetics only: --precision fixed or float"
        )
    module, name = SIGMA_DELTA_CLASSES[backend].split(":")
    cls: type[SigmaDeltaBackend] = getattr(importlib.import_module(module), name)
    return cls(policy, arithmetic, seed)


def open_backend(
    policy: str | Path | LoadedPolicy | SigmaDeltaPolicy,
    backend: str,
    precision: str,
    seed: int = 0,
) -> AnyBackend:
    """The backend ``backend`` running ``policy`` in the arithmetic ``precision`` asks for."""
    return make_backend(policy, backend, arithmetic_for(backend, precision), seed)
