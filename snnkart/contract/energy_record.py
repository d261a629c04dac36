"""The records the energy estimate writes into ``report.json`` (``snnkart/report/report.schema.json``),
as typed dicts: a profile and its prices, the joint sampling of every price range, the
break-even in spike density, T and width, and issue 34's goal, decided.

:mod:`snnkart.energy` writes them, the report layer and the command line read them; they live
here, below both. Each is the JSON object as written: the keys, in the order the writer puts
them (the order the file keeps), with their types.
"""

from __future__ import annotations

from typing import Literal, TypedDict

# -- hardware profiles (snnkart.energy.profiles) ------------------------------------------------


class PriceRecord(TypedDict):
    """One price of a profile (``profiles.<name>.prices.<op>``): pJ per operation, or per
    second for static power, with its range and evidence."""

    pj: float
    low_pj: float
    high_pj: float
    per: Literal["operation", "second"]
    unit_in_file: str
    tag: str  # measured, pre-silicon, derived or assumed
    source: str


class ProfileRecord(TypedDict):
    """A hardware profile as the report states it (``profiles.<name>``)."""

    name: str
    title: str
    kind: str  # neuromorphic or digital
    technology: str
    notes: str
    file: str
    prices: dict[str, PriceRecord]
    not_published: dict[str, str]
    weight_bits: int
    neurons_per_core: int
    cores_per_tile: int


# -- the joint sampling of the price ranges (snnkart.energy.uncertainty) -------------------------


class Spread(TypedDict):
    """The median and the 5th-95th percentile of a sampled quantity (None: not finite)."""

    median: float | None
    p05: float | None
    p95: float | None


class SampledPrice(TypedDict):
    """How one price is drawn: its value, range, distribution and the quantity it draws."""

    profile: str
    op: str
    pj: float
    low_pj: float
    high_pj: float
    distribution: str  # fixed, uniform or log-uniform
    quantity: str


class JointPrice(SampledPrice):
    """A price the joint sample draws, with the sides (SNN, ANN) that pay for it."""

    sides: list[str]


class OneAtATime(TypedDict):
    """One uncertain quantity alone at either end of its range: the ratio at each end."""

    quantity: str
    prices: list[str]
    sides: list[str]
    ratio_low: float | None
    ratio_high: float | None


class Joint(TypedDict):
    """A comparison's ``uncertainty``: every price range sampled together."""

    samples: int
    seed: int
    ratio: Spread
    p_snn_cheaper: float
    snn_pj: Spread
    ann_pj: Spread
    shared: list[str]
    one_at_a_time: list[OneAtATime]
    prices: list[JointPrice]


class SamplingMethod(TypedDict):
    """The report's top-level ``uncertainty``: how the prices were sampled."""

    samples: int
    seed: int
    rule: str
    shared: dict[str, str]
    shared_when: str


# -- the break-even (snnkart.energy.pricing, snnkart.energy.break_even) --------------------------


class _DensityBreakEven(TypedDict):
    ann_pj: float
    fixed_pj: float
    per_density_pj: float
    density: float | None
    reason: str


class DensityBreakEven(_DensityBreakEven, total=False):
    """How sparse the SNN must be to match the ANN (``density``: spikes relative to today's;
    None where no sparsity breaks even, and then without the scaled counts)."""

    firing_rates: list[float]
    synops: float


class StepsBreakEven(TypedDict):
    """The largest T at which the SNN still costs less (``break_even.num_steps``)."""

    today: int
    ratio_at: dict[str, float | None]
    num_steps: float | None
    largest: int | None
    reason: str


WidthSpan = TypedDict("WidthSpan", {"from": int | None, "to": int | None})
"""Widths ``from`` to ``to`` (None: up to the widest scanned) at which the SNN costs less."""


class WidthBreakEven(TypedDict):
    """The widths at which the SNN costs less (``break_even.width``)."""

    today: int
    scanned: list[int]
    crossings: list[float]
    cheaper: list[WidthSpan]
    ratio_at: dict[str, float | None]
    reason: str


class BreakEven(DensityBreakEven):
    """A comparison's ``break_even``: in spike density, in T and in width."""

    num_steps: StepsBreakEven
    width: WidthBreakEven


class BudgetBreakEven(TypedDict):
    """A sigma-delta deployment's message density (relative to today's) at which an inference
    costs ``budget_pj`` (None where no sparsity reaches it, with the reason)."""

    budget_pj: float
    fixed_pj: float
    per_density_pj: float
    density: float | None
    reason: str


class ScheduleWhatIfs(TypedDict):
    """A sigma-delta deployment's energy per inference as priced and under each other schedule
    (held, or one Lava step per env step) and neuron-update rule (clocked or active)."""

    rule: dict[str, str]
    rows: int
    as_priced_pj: float
    held_clocked_pj: float
    held_active_pj: float
    one_step_clocked_pj: float
    clocked_updates: dict[str, float]
    note: str


# -- issue 34's goal (snnkart.energy.goal) -----------------------------------------------------


class GoalCheck(TypedDict):
    """One bound on one chip: the ratio's spread and whether its 95th percentile is within."""

    chip: str
    baseline: str
    factor: float
    ratio: Spread
    snn_pj: Spread
    ann_pj: Spread
    holds: bool


class PartEnergy(TypedDict):
    """One part of the policy's energy, and the ratio's 95th percentile without it."""

    part: str
    part_pj: Spread
    ratio_p95_without: float | None


class InTheWay(PartEnergy):
    """The part in the way on a chip where a bound fails, with the numbers and in words."""

    chip: str
    baseline: str
    factor: float
    ratio_p95: float | None
    clears: bool
    text: str


class SanafeCheck(TypedDict):
    """One bound on SANA-FE's single energy against the baseline's spread."""

    chip: str
    baseline: str
    factor: float
    snn_pj: float
    ann_pj: Spread
    ratio_p95: float | None
    holds: bool


class ChipGoal(TypedDict):
    """The goal on one chip: both bounds, the term in the way, the chip's static energy."""

    chip: str
    holds: bool
    checks: list[GoalCheck]
    in_the_way: InTheWay | None
    static_pj: float | None


class SanafeGoal(TypedDict):
    holds: bool
    checks: list[SanafeCheck]


class Goal(TypedDict):
    """A sigma-delta report's ``goal``: the verdict on the primary chip, the proxies', and
    SANA-FE's where it ran."""

    rule: str
    primary: ChipGoal
    proxies: list[ChipGoal]
    sanafe: SanafeGoal | None
    holds: bool
    sanafe_run: bool
    verdict: str
