"""The policy kinds: one registry line each, and one module each (``snnkart.rl.kinds.<name>``)
that declares everything the rest of snnkart asks of the kind (:class:`~snnkart.rl.kinds.base.Kind`).

A line names the kind (its ``policy =`` / ``--policy`` value), the network family it belongs to
(:mod:`snnkart.contract.family`: how export, the backends and the energy model run and count
it) and its one-line help. The line is read without importing the kind's module (no torch for
``snnkart --help``); :func:`kind` imports the module when the kind is used.

Adding a kind: write ``snnkart/rl/kinds/<name>.py`` defining ``KIND`` (docs/adding-a-kind.md),
add its line here. Nothing else names it: training, rollout, checkpoints, behaviour cloning,
evaluation, export, deployment, the report, studies and sweeps ask this registry, the kind's
family or the policy's protocol (:class:`~snnkart.rl.policies.ActorCritic`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from snnkart.contract.family import FAMILIES, Family

if TYPE_CHECKING:
    from snnkart.rl.kinds.base import Kind
    from snnkart.rl.policies import ActorCritic


@dataclass(frozen=True)
class Entry:
    """One registry line: a kind's name, family and help (module: ``snnkart.rl.kinds.<name>``)."""

    name: str
    family_name: str
    help: str

    @property
    def family(self) -> Family:
        return FAMILIES[self.family_name]


REGISTRY: dict[str, Entry] = {
    e.name: e
    for e in (
        Entry("ann", "ann", "an MLP actor (tanh, or ReLU: converts to sigma-delta)"),
        Entry("snn", "lif", "a LIF spiking actor (snntorch); stateful with snn.stateful=true"),
        Entry(
            "sdnn", "sigma_delta", "a sigma-delta actor: a ReLU MLP trained on the chip's integers"
        ),
        Entry("rsnn", "lif", "a recurrent LIF actor: recurrent synapses, state across env steps"),
    )
}


def names() -> tuple[str, ...]:
    """Every kind's name, in registry order."""
    return tuple(REGISTRY)


def entry(name: str) -> Entry:
    """The registry line of ``name``; an unknown name is a ValueError listing the kinds."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(
            f"unknown policy kind {name!r}; choose one of {', '.join(names())}"
        ) from None


def family(name: str) -> Family:
    """The network family of the kind ``name``."""
    return entry(name).family


def choices_help() -> str:
    """The ``--policy`` help: every kind and what it is."""
    return "; ".join(f"{e.name}: {e.help}" for e in REGISTRY.values())


_LOADED: dict[str, Kind] = {}


def kind(name: str) -> Kind:
    """The kind ``name`` (its module imported once; it imports torch)."""
    if name not in _LOADED:
        module = importlib.import_module(f"{__name__}.{entry(name).name}")
        declared = module.KIND
        if declared.name != name:
            raise RuntimeError(f"{module.__name__} declares kind {declared.name!r}, not {name!r}")
        _LOADED[name] = declared
    return _LOADED[name]


def all_kinds() -> tuple[Kind, ...]:
    """Every registered kind, loaded."""
    return tuple(kind(n) for n in names())


def policy_for(cfg: Any, env: Any) -> ActorCritic:
    """The policy of kind ``cfg.policy`` for ``env``'s spaces, built from ``cfg``."""
    from snnkart.rl.kinds.base import PolicySpace

    policy = kind(cfg.policy).build(cfg, PolicySpace.of(env))
    policy.kind = cfg.policy
    return policy


@dataclass(frozen=True)
class Conversion:
    """A study policy that is a registered kind trained with extra settings and evaluated
    converted to another family at export (``ann-sd``: a ReLU ANN run as sigma-delta)."""

    name: str
    trained_as: str
    sets: tuple[str, ...]
    family_name: str
    label: str


CONVERSIONS: dict[str, Conversion] = {
    c.name: c
    for c in (
        Conversion("ann-sd", "ann", ("ann.activation=relu",), "sigma_delta", "ANN converted"),
    )
}

BASELINE = "ann"
"""The kind every spiking kind's learning is set beside in the study tables (same widths)."""


def study_policy(name: str) -> str:
    """``name`` if it is a kind or a conversion a study can train; else a ValueError."""
    if name not in REGISTRY and name not in CONVERSIONS:
        choices = ", ".join((*REGISTRY, *CONVERSIONS))
        raise ValueError(f"unknown policy {name!r}; choose one of {choices}")
    return name


def study_choices_help() -> str:
    """Every study policy and what it is: the kinds, then the conversions."""
    conversions = (
        f"{c.name}: a {c.trained_as} trained with {', '.join(c.sets)} and run as "
        f"{FAMILIES[c.family_name].phrase} with no retraining"
        for c in CONVERSIONS.values()
    )
    return "; ".join((choices_help(), *conversions))


def trained_as(policy: str) -> str:
    """The registered kind a study policy trains as (itself, or a conversion's kind)."""
    conversion = CONVERSIONS.get(policy)
    return policy if conversion is None else conversion.trained_as


def study_family(policy: str) -> Family:
    """The family a study policy is evaluated in (a conversion's target family)."""
    conversion = CONVERSIONS.get(policy)
    return family(policy) if conversion is None else FAMILIES[conversion.family_name]


def run_label(policy: str, cfg: Any) -> str:
    """What a study run of ``policy`` trained with ``cfg`` is called in figures and tables: a
    conversion's label, else its kind's (:attr:`~snnkart.rl.kinds.base.Kind.label`)."""
    conversion = CONVERSIONS.get(policy)
    return conversion.label if conversion is not None else kind(policy).label(cfg)


def compared_to_baseline(policy: str) -> bool:
    """A study policy whose learning the tables give as a share of the baseline's: a binary
    spiking kind (LIF family), trained as itself."""
    fam = study_family(policy)
    return policy not in CONVERSIONS and fam.spiking and not fam.graded
