"""Where the SNN breaks even with the ANN in T (timesteps) and in width (neurons per layer), beside
the break-even in spike density (:meth:`Comparison.break_even`).

The counts scale from the deployment's at today's firing rates ``r_i`` (spikes per neuron per
SNN step of layer i, ``N_i`` neurons, ``L - 1`` Dense delays between the spiking layers)::

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

from collections.abc import Callable, Sequence
from dataclasses import replace

from snnkart.contract.energy_record import (
    BreakEven,
    StepsBreakEven,
    WidthBreakEven,
    WidthSpan,
)
from snnkart.energy.counts import AnnCounts, SnnCounts, host_ops
from snnkart.energy.pricing import Comparison

STEPS_MAX = 4096
"""The largest T the break-even in T looks at."""
WIDTHS = tuple(sorted({*range(1, 17), *(round(16 * 1.25**k) for k in range(1, 38))}))
"""The widths the break-even in width scans (every one to 16, then 25 % apart to about 60,000);
each change of sign is then solved to the neuron by bisection."""


def rescaled(
    counts: SnnCounts, num_steps: int | None = None, sizes: Sequence[int] | None = None
) -> SnnCounts:
    """The same policy at ``num_steps`` SNN steps and ``sizes`` neurons per layer, at today's
    firing rates (the module's scaling laws); the host work (if counted) recounted for the new
    shape, in fixed point if it was."""
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
        host=tuple(host_ops(new_net, fixed_point=fixed_point)) if counts.host else (),
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


def _crossing(f: Callable[[int], float], lo: int, hi: int) -> tuple[int, float]:
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


def break_even_steps(cmp: Comparison, steps_max: int = STEPS_MAX) -> StepsBreakEven:
    """The largest T at which the SNN (today's firing rates) still costs less than the ANN:
    its energy grows linearly in T, the ANN's does not."""

    def excess(steps: int) -> float:
        return _excess(replace(cmp, snn=rescaled(cmp.snn, num_steps=steps)))

    today = cmp.snn.net.num_steps
    curve = sorted({today, *(2**k for k in range(8))})
    ratio_at = {str(s): _ratio(replace(cmp, snn=rescaled(cmp.snn, num_steps=s))) for s in curve}
    if excess(1) >= 0:
        at_one = _times(ratio_at["1"])
        reason = f"even at T = 1 the SNN costs {at_one} the ANN: no T breaks even"
        return StepsBreakEven(
            today=today, ratio_at=ratio_at, num_steps=None, largest=None, reason=reason
        )
    if excess(steps_max) < 0:
        reason = f"the SNN costs less at every T up to {steps_max}"
        return StepsBreakEven(
            today=today, ratio_at=ratio_at, num_steps=None, largest=steps_max, reason=reason
        )
    largest, crossing = _crossing(excess, 1, steps_max)
    reason = f"the SNN costs less than the ANN for T <= {largest} at today's firing rates"
    return StepsBreakEven(
        today=today, ratio_at=ratio_at, num_steps=crossing, largest=largest, reason=reason
    )


def break_even_width(cmp: Comparison, widths: Sequence[int] = WIDTHS) -> WidthBreakEven:
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
        "cheaper": [WidthSpan({"from": a, "to": b}) for a, b in cheaper],
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
    spans = [
        f"from {a} to {b}" if b is not None else f"from {a} up (checked to {grid[-1]})"
        for a, b in cheaper
    ]
    return "the SNN costs less than the ANN at widths " + " and ".join(spans)


def break_even(cmp: Comparison) -> BreakEven:
    """The break-even in spike density (:meth:`Comparison.break_even`), in T and in width."""
    density = cmp.break_even()
    return {**density, "num_steps": break_even_steps(cmp), "width": break_even_width(cmp)}
