"""The counts protocol: what a network family's counts per inference say to the one pricing
routine (:func:`snnkart.energy.pricing.terms`).

A family's counts (:class:`~snnkart.energy.counts.SnnCounts` for LIF chains,
:class:`~snnkart.energy.sigma_delta_counts.SigmaDeltaCounts` for sigma-delta ones,
:class:`~snnkart.energy.counts.AnnCounts` for an ANN, which has no chip) report their activity
as typed items: on the chip, :class:`Activity` (a count of one chip operation, with the part of
the energy it belongs to and what it is), and on the host, the digital operations
(:class:`HostOp`) and how many weights the host reads them from. The
pricing routine multiplies every item by its profile's price; nothing in it knows a family.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from snnkart.energy.profiles import Profile


@dataclass(frozen=True)
class Activity:
    """``count`` chip operations ``op`` (a price of the chip profile) per inference, in the
    energy ``part`` (synaptic ops, neuron updates, spikes, messages, routing, host link)."""

    part: str
    what: str
    count: float
    op: str


@dataclass(frozen=True)
class HostOp:
    """One item of host-side work per inference: what it is, the operation, how many."""

    what: str
    op: str  # a digital profile's operation: mac, add, mult, weight_read
    count: float


class Counted(Protocol):
    """A family's counts per inference, as the pricing routine asks for them."""

    @property
    def host_parameters(self) -> int:
        """The weights the host reads its work's operands from (its memory array's size)."""
        ...

    def host_work(self) -> Sequence[HostOp]:
        """The host's digital operations per inference."""
        ...

    def prices_for(self, chip: Profile) -> Profile:
        """``chip`` with the prices this family derives from it (a graded message's), or
        ``chip`` itself."""
        ...

    def chip_activity(self, chip: Profile) -> list[Activity]:
        """The chip's operations per inference on ``chip`` (as :meth:`prices_for` left it:
        placement and routing depend on the chip)."""
        ...
