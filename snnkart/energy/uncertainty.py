"""How sure the SNN/ANN verdict is: every price range of a comparison sampled together (Monte
Carlo), and each uncertain quantity moved alone across its range.

Each price a comparison uses is drawn from its range ``[low, high]``: log-uniformly where
``high / low > 10`` (:data:`LOG_UNIFORM_ABOVE`: a range over more than a decade gives an order
of magnitude, not a value), uniformly otherwise and from a range that starts at 0, and not at
all where ``low == high``. A price that is one physical quantity on both
sides (:data:`SHARED`) is drawn once per sample: one uniform quantile ``u`` per quantity, each
price taking the value at ``u`` of its own range, so equal ranges give equal values and the
reads of two array sizes (the SNN host's 8 KB, the ANN's 32 KB) move together. Every term is
``count x price``, so an energy is the terms' coefficients (a vector over the prices) times the
sampled prices (a matrix, one row per sample): no comparison is rebuilt per sample. The verdict
per pair: the median SNN/ANN ratio, its 5th-95th percentile and P(the SNN costs less).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from snnkart.contract.energy_record import (
    Joint,
    JointPrice,
    OneAtATime,
    SampledPrice,
    SamplingMethod,
    Spread,
)
from snnkart.energy.pricing import Term
from snnkart.energy.profiles import Price, Profile

SAMPLES = 10_000
SEED = 0
"""The default Monte Carlo: 10,000 Latin-hypercube samples from ``numpy.random.default_rng(0)``
(with Loihi 2's three-decade ranges the 95th percentile of the ratio moves by about 1 % from
seed to seed, the median by 0.4 %)."""
LOG_UNIFORM_ABOVE = 10.0
"""A range with ``high / low`` above this is sampled log-uniformly, else uniformly."""
SHARED: dict[str, str] = {
    "mac": "digital multiply-accumulate",
    "add": "digital add",
    "mult": "digital multiply",
    "weight_read": "on-chip SRAM read",
    "sram_read_8kb": "on-chip SRAM read",
    "sram_read_32kb": "on-chip SRAM read",
    "sram_read_1mb": "on-chip SRAM read",
    "dram_read": "DRAM read",
}
"""Digital prices that are one physical quantity wherever a profile of the same technology
(its ``technology`` string) names them: the operation -> the quantity drawn once per sample.
The SNN's host work and the ANN on two such profiles (or on one) move together; the SRAM reads
of every array size are one quantity (Horowitz's rows, one table, high or low together). A
price not listed here, or on a profile that states no technology, is drawn on its own, once for
both sides when both use the same profile."""


@dataclass(frozen=True)
class Draw:
    """How one price is sampled: its range, its distribution, and the quantity it draws."""

    profile: str
    op: str
    value: float
    low: float
    high: float
    distribution: str  # fixed, uniform or log-uniform
    quantity: str  # one quantile per quantity and sample

    def at(self, u: np.ndarray) -> np.ndarray:
        """The price at quantiles ``u`` of its range."""
        if self.distribution == "fixed":
            return np.full_like(u, self.low)
        if self.distribution == "log-uniform":
            return self.low * (self.high / self.low) ** u
        return self.low + (self.high - self.low) * u

    def as_dict(self) -> SampledPrice:
        return {
            "profile": self.profile,
            "op": self.op,
            "pj": self.value,
            "low_pj": self.low,
            "high_pj": self.high,
            "distribution": self.distribution,
            "quantity": self.quantity,
        }


def distribution(price: Price) -> str:
    """``fixed`` (no range), ``log-uniform`` (high / low > 10, low > 0) or ``uniform``."""
    if price.high == price.low:
        return "fixed"
    if price.low > 0 and price.high / price.low > LOG_UNIFORM_ABOVE:
        return "log-uniform"
    return "uniform"


def quantity(profile: Profile, op: str) -> str:
    """The quantity a price draws: a :data:`SHARED` one at the profile's technology, or the
    price's own."""
    if profile.kind == "digital" and op in SHARED and profile.technology.strip():
        return f"{SHARED[op]}, {profile.technology.strip()}"
    return f"{profile.name}.{op}"


def _draws(profiles: dict[str, Profile], keys: Iterable[tuple[str, str]]) -> list[Draw]:
    out = []
    for name, op in keys:
        price = profiles[name].prices[op]
        out.append(
            Draw(
                name,
                op,
                price.value,
                price.low,
                price.high,
                distribution(price),
                quantity(profiles[name], op),
            )
        )
    return out


def _coefficients(
    terms: Sequence[Term], profiles: dict[str, Profile], index: dict[tuple[str, str], int]
) -> np.ndarray:
    """Per price, what it multiplies in ``terms``: energy = coefficients . prices. A term may
    price a multiple of the profile's figure (``price_pj = k x value``); its coefficient is
    ``count x k`` (``k = 1`` where the figure is 0)."""
    coef = np.zeros(len(index))
    for t in terms:
        if t.profile not in profiles:
            raise ValueError(f"term {t.what!r} names profile {t.profile!r}, not in the comparison")
        value = profiles[t.profile].prices[t.op].value
        if not value and t.price_pj:
            raise ValueError(f"term {t.what!r}: priced {t.price_pj} pJ on a figure of 0")
        coef[index[t.profile, t.op]] += t.count * (t.price_pj / value if value else 1.0)
    return coef


def sample_prices(draws: Sequence[Draw], samples: int, seed: int) -> np.ndarray:
    """``samples x len(draws)`` prices in pJ: one uniform quantile per quantity and sample, Latin
    hypercube (each quantity's samples fall one in each of ``samples`` equal bins, paired at
    random across quantities), the quantities in sorted order so that a seed gives the same
    numbers whatever else is drawn."""
    rng = np.random.default_rng(seed)
    names = sorted({d.quantity for d in draws})
    u = (
        rng.permuted(np.tile(np.arange(samples), (len(names), 1)), axis=1)
        + rng.random((len(names), samples))
    ) / samples
    row = {name: i for i, name in enumerate(names)}
    return np.stack([d.at(u[row[d.quantity]]) for d in draws], axis=1)


def _spread(x: np.ndarray) -> Spread:
    with np.errstate(invalid="ignore"):  # a ratio over an ANN priced at 0 is infinite
        lo, mid, hi = np.percentile(x, [5.0, 50.0, 95.0])
    return {"median": _finite(mid), "p05": _finite(lo), "p95": _finite(hi)}


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def joint(
    snn: Sequence[Term],
    ann: Sequence[Term],
    profiles: Iterable[Profile],
    samples: int = SAMPLES,
    seed: int = SEED,
) -> Joint:
    """The SNN's and the ANN's energies (terms ``snn`` and ``ann``, priced on ``profiles``)
    with every price drawn from its range together: the ratio's median, 90 % interval
    (5th-95th percentile) and the probability that the SNN costs less."""
    if samples < 1:
        raise ValueError(f"samples must be at least 1, got {samples}")
    by_name = {p.name: p for p in profiles}
    keys = list(dict.fromkeys((t.profile, t.op) for t in [*snn, *ann]))
    index = {k: i for i, k in enumerate(keys)}
    draws = _draws(by_name, keys)
    c_snn = _coefficients(snn, by_name, index)
    c_ann = _coefficients(ann, by_name, index)
    prices = sample_prices(draws, samples, seed)
    e_snn, e_ann = prices @ c_snn, prices @ c_ann
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(e_ann > 0, e_snn / e_ann, np.where(e_snn > 0, np.inf, np.nan))
    defined = ratio[~np.isnan(ratio)]
    return {
        "samples": samples,
        "seed": seed,
        "ratio": _spread(defined) if defined.size else Spread(median=None, p05=None, p95=None),
        "p_snn_cheaper": float(np.mean(e_snn < e_ann)),
        "snn_pj": _spread(e_snn),
        "ann_pj": _spread(e_ann),
        "shared": _shared(draws, c_snn, c_ann),
        "one_at_a_time": one_at_a_time(draws, c_snn, c_ann),
        "prices": [
            JointPrice(**d.as_dict(), sides=_sides([i], c_snn, c_ann))
            for i, d in enumerate(draws)
            if d.distribution != "fixed"
        ],
    }


def _shared(draws: Sequence[Draw], c_snn: np.ndarray, c_ann: np.ndarray) -> list[str]:
    """The uncertain quantities both sides pay for (each drawn once per sample)."""
    snn = {d.quantity for d, c in zip(draws, c_snn, strict=True) if c and d.distribution != "fixed"}
    ann = {d.quantity for d, c in zip(draws, c_ann, strict=True) if c and d.distribution != "fixed"}
    return sorted(snn & ann)


def one_at_a_time(draws: Sequence[Draw], c_snn: np.ndarray, c_ann: np.ndarray) -> list[OneAtATime]:
    """Each uncertain quantity alone at the low and the high end of its range (a shared one on
    both sides at once), every other price at its value: the ratio at either end, the widest
    swing first (the single input that moves the verdict most)."""
    central = np.array([d.value for d in draws])
    rows: list[OneAtATime] = []
    for q in sorted({d.quantity for d in draws if d.distribution != "fixed"}):
        moved = [i for i, d in enumerate(draws) if d.quantity == q]
        ends = np.tile(central, (2, 1))
        for i in moved:
            ends[:, i] = draws[i].at(np.array([0.0, 1.0]))
        e_snn, e_ann = ends @ c_snn, ends @ c_ann
        ratios = [float(a / b) if b > 0 else None for a, b in zip(e_snn, e_ann, strict=True)]
        rows.append(
            {
                "quantity": q,
                "prices": [f"{draws[i].profile}.{draws[i].op}" for i in moved],
                "sides": _sides(moved, c_snn, c_ann),
                "ratio_low": ratios[0],
                "ratio_high": ratios[1],
            }
        )
    return sorted(rows, key=_swing, reverse=True)


def _sides(moved: list[int], c_snn: np.ndarray, c_ann: np.ndarray) -> list[str]:
    """Which sides pay for the prices ``moved``: SNN, ANN or both."""
    return [side for side, c in (("SNN", c_snn), ("ANN", c_ann)) if c[moved].any()]


def _swing(row: OneAtATime) -> float:
    lo, hi = row["ratio_low"], row["ratio_high"]
    if lo is None or hi is None or min(lo, hi) <= 0:
        return float("inf") if lo != hi else 0.0
    return abs(float(np.log(hi / lo)))


def method() -> SamplingMethod:
    """What :func:`joint` does, for the report to state."""
    return {
        "samples": SAMPLES,
        "seed": SEED,
        "rule": "Monte Carlo (Latin hypercube), each price drawn from its range: log-uniform "
        f"where high / low > {LOG_UNIFORM_ABOVE:g}, otherwise uniform (and from a range that "
        "starts at 0), fixed where low = high; a shared quantity drawn once per sample (one "
        "quantile of each side's range); the interval is the 5th-95th percentile of the SNN/ANN "
        "ratio, P(SNN cheaper) the share of samples in which the SNN costs less",
        "shared": dict(SHARED),
        "shared_when": "the same operation on digital profiles of the same technology",
    }
