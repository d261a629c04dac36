"""How sure the SNN/ANN verdict is: every price range sampled together (Monte Carlo), and where
the SNN breaks even in T (timesteps) and in width (neurons per layer).

**Joint uncertainty.** Each price a comparison uses is drawn from its range ``[low, high]``:
log-uniformly where ``high / low > 10`` (:data:`LOG_UNIFORM_ABOVE`: a range over more than a
decade gives an order of magnitude, not a value), uniformly otherwise and from a range that
starts at 0, and not at all where ``low == high``. A price that is one physical quantity on both
sides (:data:`SHARED`) is drawn once per sample: one uniform quantile ``u`` per quantity, each
price taking the value at ``u`` of its own range, so equal ranges give equal values and the
reads of two array sizes (the SNN host's 8 KB, the ANN's 32 KB) move together. Every term is
``count x price``, so an energy is the terms' coefficients (a vector over the prices) times the
sampled prices (a matrix, one row per sample): no comparison is rebuilt per sample. The verdict
per pair: the median SNN/ANN ratio, its 5th-95th percentile and P(the SNN costs less).

**Break-even in T and width**, at today's firing rates ``r_i`` (spikes per neuron per SNN step
of layer i, ``N_i`` neurons, ``L - 1`` Dense delays between the spiking layers)::

    neuron updates_i  = N_i x T  +  N_i x (L - 1)         (clocked; the pipeline's fill/drain)
    spikes_i          = r_i x N_i x T  +  fill/drain spikes x N_i / N_i(today)
    chip synops_i     = spikes_i x N_(i+1)                  (the last layer's go to the host)
    host work         = counts.host_ops of the scaled network: the first layer n_in x N_1 MACs
                        and reads (once per env step; T times with rate encoding), the
                        readout N_L x n_out, the encoding and decoding
    ANN               = sum of w_j x w_(j+1) MACs (hidden x hidden: width^2) and as many reads

so the SNN's energy grows linearly in T (the ANN's is fixed), and both grow with the square of
the width. Any other term the pricing builds from the counts scales with them.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from snnkart.energy.counts import AnnCounts, SnnCounts, host_ops
from snnkart.energy.pricing import Comparison, Term
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
STEPS_MAX = 4096
"""The largest T the break-even in T looks at."""
WIDTHS = tuple(sorted({*range(1, 17), *(round(16 * 1.25**k) for k in range(1, 38))}))
"""The widths the break-even in width scans (every one to 16, then 25 % apart to about 60,000);
each change of sign is then solved to the neuron by bisection."""


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

    def as_dict(self) -> dict[str, Any]:
        return {"profile": self.profile, "op": self.op, "pj": self.value, "low_pj": self.low,
                "high_pj": self.high, "distribution": self.distribution,
                "quantity": self.quantity}  # fmt: skip


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
        out.append(Draw(name, op, price.value, price.low, price.high, distribution(price),
                        quantity(profiles[name], op)))  # fmt: skip
    return out


def _coefficients(terms: Sequence[Term], profiles: dict[str, Profile],
                  index: dict[tuple[str, str], int]) -> np.ndarray:  # fmt: skip
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
    u = (rng.permuted(np.tile(np.arange(samples), (len(names), 1)), axis=1)
         + rng.random((len(names), samples))) / samples  # fmt: skip
    row = {name: i for i, name in enumerate(names)}
    return np.stack([d.at(u[row[d.quantity]]) for d in draws], axis=1)


def _spread(x: np.ndarray) -> dict[str, float | None]:
    lo, mid, hi = np.percentile(x, [5.0, 50.0, 95.0])
    return {"median": _finite(mid), "p05": _finite(lo), "p95": _finite(hi)}


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def joint(snn: Sequence[Term], ann: Sequence[Term], profiles: Iterable[Profile],
          samples: int = SAMPLES, seed: int = SEED) -> dict[str, Any]:  # fmt: skip
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
        "ratio": _spread(defined) if defined.size else dict.fromkeys(("median", "p05", "p95")),
        "p_snn_cheaper": float(np.mean(e_snn < e_ann)),
        "snn_pj": _spread(e_snn),
        "ann_pj": _spread(e_ann),
        "shared": _shared(draws, c_snn, c_ann),
        "one_at_a_time": one_at_a_time(draws, c_snn, c_ann),
        "prices": [d.as_dict() for d in draws if d.distribution != "fixed"],
    }


def _shared(draws: Sequence[Draw], c_snn: np.ndarray, c_ann: np.ndarray) -> list[str]:
    """The uncertain quantities both sides pay for (each drawn once per sample)."""
    snn = {d.quantity for d, c in zip(draws, c_snn, strict=True) if c and d.distribution != "fixed"}
    ann = {d.quantity for d, c in zip(draws, c_ann, strict=True) if c and d.distribution != "fixed"}
    return sorted(snn & ann)


def one_at_a_time(draws: Sequence[Draw], c_snn: np.ndarray,
                  c_ann: np.ndarray) -> list[dict[str, Any]]:  # fmt: skip
    """Each uncertain quantity alone at the low and the high end of its range (a shared one on
    both sides at once), every other price at its value: the ratio at either end, the widest
    swing first (the single input that moves the verdict most)."""
    central = np.array([d.value for d in draws])
    rows = []
    for q in sorted({d.quantity for d in draws if d.distribution != "fixed"}):
        moved = [i for i, d in enumerate(draws) if d.quantity == q]
        ends = np.tile(central, (2, 1))
        for i in moved:
            ends[:, i] = draws[i].at(np.array([0.0, 1.0]))
        e_snn, e_ann = ends @ c_snn, ends @ c_ann
        ratios = [float(a / b) if b > 0 else None for a, b in zip(e_snn, e_ann, strict=True)]
        rows.append({"quantity": q, "prices": [f"{draws[i].profile}.{draws[i].op}" for i in moved],
                     "ratio_low": ratios[0], "ratio_high": ratios[1]})  # fmt: skip
    return sorted(rows, key=_swing, reverse=True)


def _swing(row: dict[str, Any]) -> float:
    lo, hi = row["ratio_low"], row["ratio_high"]
    if lo is None or hi is None or min(lo, hi) <= 0:
        return float("inf") if lo != hi else 0.0
    return abs(float(np.log(hi / lo)))


def method() -> dict[str, Any]:
    """What :func:`joint` does, for the report to state."""
    return {
        "samples": SAMPLES,
        "seed": SEED,
        "rule": f"Monte Carlo, Latin hypercube; each price drawn from its range: log-uniform where high / low > "
        f"{LOG_UNIFORM_ABOVE:g}, otherwise uniform (and from a range starting at 0), fixed where "
        "low = high; a shared quantity is drawn once per sample (one quantile of each side's "
        "range); interval: the 5th-95th percentile of the SNN/ANN ratio",
        "shared": dict(SHARED),
        "shared_when": "the same operation on digital profiles of the same technology",
    }


def rescaled(counts: SnnCounts, num_steps: int | None = None,
             sizes: Sequence[int] | None = None) -> SnnCounts:  # fmt: skip
    """The same policy at ``num_steps`` SNN steps and ``sizes`` neurons per layer, at today's
    firing rates (the module's scaling laws); the host work recounted for the new shape."""
    net = counts.net
    new_sizes = tuple(sizes) if sizes is not None else net.sizes
    steps = net.num_steps if num_steps is None else num_steps
    if len(new_sizes) != len(net.sizes) or min(new_sizes) < 1 or steps < 1:
        raise ValueError(
            f"rescale {net.sizes}, T = {net.num_steps} to sizes {new_sizes}, T = {steps}: give "
            "as many layers, each of at least one neuron, and T >= 1"
        )
    t = steps / net.num_steps
    n = [a / b for a, b in zip(new_sizes, net.sizes, strict=True)]
    fan = [*n[1:], 0.0]  # the next layer's growth (the last layer's fan-out is host work)

    def per(values: tuple[float, ...], k: Sequence[float]) -> tuple[float, ...]:
        return tuple(v * ki for v, ki in zip(values, k, strict=True))

    fixed_point = tuple(host_ops(net, fixed_point=True)) == counts.host
    new_net = replace(net, num_steps=steps, sizes=new_sizes)
    return replace(
        counts,
        net=new_net,
        spikes=per(counts.spikes, [x * t for x in n]),
        synops=per(counts.synops, [x * t * f for x, f in zip(n, fan, strict=True)]),
        neuron_updates=per(counts.neuron_updates, [x * t for x in n]),
        overhead_spikes=per(counts.overhead_spikes, n),
        overhead_synops=per(counts.overhead_synops, [x * f for x, f in zip(n, fan, strict=True)]),
        overhead_neuron_updates=per(counts.overhead_neuron_updates, n),
        host=tuple(host_ops(new_net, fixed_point=fixed_point)),
    )


def widened(ann: AnnCounts, factor: float) -> AnnCounts:
    """The ANN with every hidden layer ``factor`` times as wide (at least one neuron)."""
    w = ann.widths
    return replace(ann, widths=(w[0], *(max(1, round(x * factor)) for x in w[1:-1]), w[-1]))


def at_width(cmp: Comparison, width: int) -> Comparison:
    """The comparison with the SNN's widest layer ``width`` neurons wide, its other layers and
    the ANN's hidden layers grown by the same factor."""
    factor = width / max(cmp.snn.net.sizes)
    sizes = [max(1, round(n * factor)) for n in cmp.snn.net.sizes]
    return replace(cmp, snn=rescaled(cmp.snn, sizes=sizes), ann=widened(cmp.ann, factor))


def _excess(cmp: Comparison) -> float:
    """The SNN's energy less the ANN's (pJ per inference): negative where the SNN wins."""
    e_snn, e_ann = cmp.energies()
    return e_snn - e_ann


def _ratio(cmp: Comparison) -> float | None:
    e_snn, e_ann = cmp.energies()
    return e_snn / e_ann if e_ann > 0 else None


def _crossing(f: Any, lo: int, hi: int) -> tuple[int, float]:
    """Bisection between integers ``lo < hi`` where ``f`` changes sign: the last integer on
    ``lo``'s side, and the crossing interpolated linearly between it and the next."""
    f_lo = f(lo) < 0
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if (f(mid) < 0) == f_lo:
            lo = mid
        else:
            hi = mid
    a, b = f(lo), f(hi)
    return lo, lo + (a / (a - b) if a != b else 0.0)


def break_even_steps(cmp: Comparison, steps_max: int = STEPS_MAX) -> dict[str, Any]:
    """The largest T at which the SNN (today's firing rates) still costs less than the ANN:
    its energy grows linearly in T, the ANN's does not."""

    def excess(steps: int) -> float:
        return _excess(replace(cmp, snn=rescaled(cmp.snn, num_steps=steps)))

    today = cmp.snn.net.num_steps
    curve = sorted({today, *(2**k for k in range(8))})
    out: dict[str, Any] = {
        "today": today,
        "ratio_at": {str(s): _ratio(replace(cmp, snn=rescaled(cmp.snn, num_steps=s)))
                     for s in curve},
    }  # fmt: skip
    if excess(1) >= 0:
        at_one = _times(out["ratio_at"]["1"])
        return {**out, "num_steps": None, "largest": None, "reason": f"even at T = 1 the SNN "
                f"costs {at_one} the ANN: no T breaks even"}  # fmt: skip
    if excess(steps_max) < 0:
        return {**out, "num_steps": None, "largest": steps_max, "reason": "the SNN costs less "
                f"at every T up to {steps_max}"}  # fmt: skip
    largest, crossing = _crossing(excess, 1, steps_max)
    return {**out, "num_steps": crossing, "largest": largest, "reason": f"the SNN costs less "
            f"than the ANN for T <= {largest} at today's firing rates"}  # fmt: skip


def break_even_width(cmp: Comparison, widths: Sequence[int] = WIDTHS) -> dict[str, Any]:
    """The widths (neurons of the SNN's widest layer; every hidden layer of both networks
    grown alike) at which the SNN costs less, at today's firing rates: both energies grow with
    the square of the width, so the SNN can win below a width, above one, between two, at
    every width scanned or at none."""

    def excess(width: int) -> float:
        return _excess(at_width(cmp, width))

    grid = sorted(set(widths))
    wins = [excess(w) < 0 for w in grid]
    crossings: list[float] = []
    cheaper: list[list[int | None]] = [[grid[0], None]] if wins[0] else []
    for i in range(len(grid) - 1):
        if wins[i] == wins[i + 1]:
            continue
        last, crossing = _crossing(excess, grid[i], grid[i + 1])
        crossings.append(crossing)
        if wins[i]:
            cheaper[-1][1] = last  # the last width at which the SNN costs less
        else:
            cheaper.append([last + 1, None])
    today = max(cmp.snn.net.sizes)
    shown = sorted({today, *(2**k for k in range(2, 13))})
    return {
        "today": today,
        "scanned": [grid[0], grid[-1]],
        "crossings": crossings,
        "cheaper": [{"from": a, "to": b} for a, b in cheaper],
        "ratio_at": {str(w): _ratio(at_width(cmp, w)) for w in shown},
        "reason": _width_reason(cheaper, grid, _ratio(at_width(cmp, grid[-1]))),
    }


def _times(ratio: float | None) -> str:
    return "an undefined multiple of" if ratio is None else f"{ratio:.3g}x"


def _width_reason(cheaper: list[list[int | None]], grid: list[int], limit: float | None) -> str:
    if not cheaper:
        return (
            f"no width from {grid[0]} to {grid[-1]} breaks even at today's firing rates (at "
            f"{grid[-1]} the SNN costs {_times(limit)} the ANN)"
        )
    spans = [f"from {a} to {b}" if b is not None else f"from {a} up (checked to {grid[-1]})"
             for a, b in cheaper]  # fmt: skip
    return "the SNN costs less than the ANN at widths " + " and ".join(spans)


def break_even(cmp: Comparison) -> dict[str, Any]:
    """The break-even in spike density (:meth:`Comparison.break_even`), in T and in width."""
    return {**cmp.break_even(), "num_steps": break_even_steps(cmp),
            "width": break_even_width(cmp)}  # fmt: skip
