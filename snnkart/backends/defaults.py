"""Where a trained policy runs, by name, and what each backend's ``--precision`` takes: the one
table every door reads (``snnkart eval``, ``deploy``, ``nir run`` and ``ros drive``, the Python
API, the process pool's worker) for its defaults, its checks and its ``--help``.

========  ==============================  ==============================================  =======
backend   runs                            ``--precision`` words (arithmetic)              default
========  ==============================  ==============================================  =======
torch     the trained network (float32)   none: it runs as it trained                     -
nir-ref   the numpy reference             float32, float64, float (float64), fixed        fixed
lava-sim  Lava's simulated Loihi          float (float64), fixed                          fixed
========  ==============================  ==============================================  =======

Both NIR backends default to ``fixed``: Lava's bit-accurate fixed point, the arithmetic of the
project's parity claim (lava-sim is bit-exact with nir-ref in it) and of every study's
evaluation; torch's ``float32`` order of operations is asked for by name.

It imports nothing heavy (no numpy): the command line reads it at start-up for its help.
:data:`snnkart.backends.registry.PRECISIONS` is read from it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from snnkart.errors import UsageError, did_you_mean

if TYPE_CHECKING:
    from snnkart.backends.base import Arithmetic


@dataclass(frozen=True)
class BackendInfo:
    """One backend: what it runs, its ``--precision`` words with the arithmetic each means
    (none: torch) and the word it runs in when none is given."""

    runs: str
    precisions: dict[str, Arithmetic]
    default: str | None


TABLE: dict[str, BackendInfo] = {
    "torch": BackendInfo("the trained torch network, in float32", {}, None),
    "nir-ref": BackendInfo(
        "the numpy reference",
        {"float32": "float32", "float64": "float64", "float": "float64", "fixed": "fixed"},
        "fixed",
    ),
    "lava-sim": BackendInfo(
        "Lava's simulated Loihi", {"float": "float64", "fixed": "fixed"}, "fixed"
    ),
}
"""The backends by name: see the module docstring."""
BACKENDS = tuple(TABLE)
"""Every backend a trained policy runs on: torch, nir-ref, lava-sim."""
NIR_BACKENDS = tuple(name for name, info in TABLE.items() if info.precisions)
"""The backends that run an exported NIR policy: nir-ref, lava-sim."""
DEFAULT_PRECISIONS = {name: TABLE[name].default for name in NIR_BACKENDS}
"""Per NIR backend, the ``--precision`` word it runs in when none is given."""


def _choices(names: tuple[str, ...] | list[str]) -> str:
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def check_backend(backend: str, allowed: tuple[str, ...] = BACKENDS) -> BackendInfo:
    """The table's entry for ``backend``, or a one-line error naming the ones ``allowed``."""
    if backend not in allowed:
        raise UsageError(
            f"unknown backend {backend!r}{did_you_mean(backend, allowed)}; choose "
            f"{_choices(allowed)}"
        )
    return TABLE[backend]


def precision_word(
    backend: str, precision: str | None, allowed: tuple[str, ...] = BACKENDS
) -> str | None:
    """The ``--precision`` word ``backend`` (one of ``allowed``) runs in: ``precision``, else
    the backend's default (None on torch, which runs as it trained and ignores a precision)."""
    info = check_backend(backend, allowed)
    if not info.precisions:
        return None
    word = info.default if precision is None else precision
    if word not in info.precisions:
        elsewhere = [n for n in NIR_BACKENDS if word in TABLE[n].precisions]
        hint = f" ({word} runs on {_choices(elsewhere)})" if elsewhere else ""
        raise UsageError(
            f"--precision for {backend} is {_choices(list(info.precisions))}, not {word!r}{hint}"
        )
    return word


def arithmetic_of(backend: str, precision: str | None) -> Arithmetic:
    """The arithmetic a NIR backend runs in when asked for ``precision`` (None: its default)."""
    info = TABLE[backend]
    word = precision_word(backend, precision, NIR_BACKENDS)
    assert word is not None
    return info.precisions[word]


def precision_help(backends: tuple[str, ...] = NIR_BACKENDS) -> str:
    """The ``--precision`` help of a command taking ``backends``: each one's words, from the
    table (its default is :func:`default_help`'s)."""
    parts = []
    for name in backends:
        words = [w if w == a else f"{w} ({a})" for w, a in TABLE[name].precisions.items()]
        parts.append(f"{name}: {_choices(words)}" if words else f"{name} takes none")
    return "; ".join(parts)


def default_help(backends: tuple[str, ...] = NIR_BACKENDS) -> str:
    """What ``[default: ...]`` shows for ``--precision``: the NIR backends' default word, or
    each backend's when they differ."""
    named = [n for n in backends if TABLE[n].precisions]
    defaults = {TABLE[n].default for n in named}
    if len(defaults) == 1:
        return str(defaults.pop())
    return ", ".join(f"{n} {TABLE[n].default}" for n in named)
