"""The optimiser every snnkart training builds, without paying for ``torch._dynamo``.

torch's optimisers import ``torch._dynamo`` (and sympy) the first time they are used: 1.4-2.3 s
of every snnkart process that trains, most of a small run's start-up. Two wrappers do it:
``torch._disable_dynamo`` around ``add_param_group``, ``zero_grad``, ``state_dict`` and
``load_state_dict``, and ``_use_grad_for_differentiable`` around ``step``, whose only other work
is to turn gradients off and mark graph breaks for ``torch.compile``. snnkart never compiles, so
:class:`Adam` runs torch's own ``Adam.step`` body under ``torch.no_grad()`` (what that wrapper does
for a non-differentiable optimiser), and :func:`adam` fills the first wrapper's cache
(``__dynamo_disable``) with the method itself when dynamo has not been imported. The arithmetic is
torch's Adam, bit for bit (tests/test_optim.py); on a torch whose wrappers differ, torch's own
methods run.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable

import torch

_LAZY = ("add_param_group", "zero_grad", "state_dict", "load_state_dict")


def _skip_dynamo_import() -> None:
    if "torch._dynamo" in sys.modules:
        return  # already paid for: keep torch's own behaviour
    for name in _LAZY:
        method = getattr(torch.optim.Optimizer, name, None)
        inner = getattr(method, "__wrapped__", None)
        code = getattr(method, "__code__", None)
        if inner is None or code is None or not code.co_filename.endswith("_compile.py"):
            continue  # a torch whose optimiser is not wrapped this way: nothing to skip
        if getattr(inner, "__dynamo_disable", None) is None:
            setattr(inner, "__dynamo_disable", inner)


def _body(step: object) -> Callable[..., object] | None:
    """torch's ``Adam.step`` function itself, under whatever wrappers torch has put on it."""
    while step is not None:
        code = getattr(step, "__code__", None)
        if code is not None and code.co_name == "step" and code.co_filename.endswith("adam.py"):
            return step  # type: ignore[return-value]
        step = getattr(step, "__wrapped__", None)
    return None


_ADAM_STEP = _body(torch.optim.Adam.step)


class Adam(torch.optim.Adam):
    """torch's Adam whose ``step`` does not import ``torch._dynamo`` (see the module)."""

    def step(self, closure: Callable[[], float] | None = None) -> float | None:  # type: ignore[override]
        if _ADAM_STEP is None or self.defaults["differentiable"]:
            return super().step(closure)
        with torch.no_grad():
            return _ADAM_STEP(self, closure)  # type: ignore[return-value]


def adam(params: Iterable[torch.nn.Parameter], lr: float, eps: float, foreach: bool | None) -> Adam:
    """torch's Adam over ``params`` (``foreach``: torch's argument, None for its default)."""
    _skip_dynamo_import()
    return Adam(params, lr=lr, eps=eps, foreach=foreach)
