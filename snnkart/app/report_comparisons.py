"""The LIF report's comparisons (:func:`comparisons`): every SNN profile against every ANN on
every digital profile, each a row of energies, ratio, interval and break-even; and the
one-price-at-a-time sensitivity (:func:`sensitivity`) against the same-width ANN."""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

from snnkart.contract.report_record import (
    AnnRunTask,
    ComparisonRow,
    Memory,
    Sensitivity,
    SensitivityRow,
    Static,
    Task,
    TermRecord,
)
from snnkart.energy.break_even import break_even
from snnkart.energy.counts import AnnCounts, SnnCounts, placement
from snnkart.energy.pricing import (
    Comparison,
    Term,
    ann_terms,
    breakdown,
    not_published,
    terms,
    total,
)
from snnkart.energy.profiles import Profile, memory_row
from snnkart.energy.uncertainty import joint
from snnkart.errors import ReportError


def memory_first(digital: list[Profile]) -> list[Profile]:
    """The memory-inclusive digital profiles first: the fair baseline leads the sensitivity."""
    return sorted(digital, key=lambda p: not p.prices_memory)


def comparisons(
    snn: SnnCounts,
    anns: dict[str, tuple[AnnCounts, AnnRunTask | None]],
    chips: list[Profile],
    digital: list[Profile],
    host: Profile | None,
    snn_return: float,
) -> list[ComparisonRow]:
    """Every SNN profile against every ANN on every digital profile: energy per inference, per
    episode and per unit of return (None when the mean return is not positive, or for an ANN
    that was not run), the ratio with every price range sampled together, and the break-even
    in spike density, T and width. The SNN's host work is priced on ``host``, else on the ANN's
    profile."""
    from snnkart.eval.ann_int8 import task_on

    return [
        _comparison(  # int8 datapath: the int8 ANN's task, measured
            snn, key, ann, task_on(float_task, dig.name), float_task, chip, dig, host, snn_return
        )
        for chip in chips
        for key, (ann, float_task) in anns.items()
        for dig in digital
    ]


def _comparison(
    snn: SnnCounts,
    key: str,
    ann: AnnCounts,
    task: Task | None,
    float_task: AnnRunTask | None,
    chip: Profile,
    dig: Profile,
    host: Profile | None,
    snn_return: float,
) -> ComparisonRow:
    """One row of :func:`comparisons`: the SNN on ``chip`` against the ANN ``key`` on ``dig``."""
    s_terms = terms(snn, chip, host or dig)
    e_snn = total(s_terms)
    a_terms = ann_terms(ann, dig)
    e_ann = total(a_terms)
    if e_ann <= 0:
        raise ReportError(
            f"profile {dig.name} prices the ANN at 0 pJ (every price it uses is 0), "
            "so the SNN/ANN ratio is undefined; give it non-zero prices"
        )
    cmp = Comparison(snn, ann, chip, host or dig, dig)
    where = placement(snn.net.sizes, chip)
    return {
        "snn_profile": chip.name,
        "host_profile": (host or dig).name,
        "ann": key,
        "ann_profile": dig.name,
        "snn_pj": e_snn,
        "ann_pj": e_ann,
        "ratio": e_snn / e_ann if e_ann else None,
        "memory": _memory(snn, ann, host or dig, dig),
        "placement": where.as_dict() if where else None,
        "static": cast(Static, cmp.with_static()),  # the record it writes
        "not_published": not_published(chip, host or dig, dig),
        "ann_success_rate": task["success_rate"] if task else None,
        "ann_success": _ann_success(task, float_task),
        "snn_per_episode_pj": e_snn * snn.steps_per_episode,
        "ann_per_episode_pj": e_ann * task["steps_per_episode"] if task else None,
        "snn_per_return_pj": _per_return(e_snn * snn.steps_per_episode, snn_return),
        "ann_per_return_pj": _per_return(e_ann * task["steps_per_episode"], task["mean_return"])
        if task
        else None,
        "snn_breakdown_pj": breakdown(s_terms),
        "ann_breakdown_pj": breakdown(a_terms),
        "snn_terms": _records(s_terms),
        "ann_terms": _records(a_terms),
        "break_even": break_even(cmp),
        "uncertainty": joint(s_terms, a_terms, (chip, host or dig, dig)),
    }


def _records(priced: Sequence[Term]) -> list[TermRecord]:
    """The terms as ``report.json`` lists them (:meth:`Term.as_dict` writes the record)."""
    return [t.as_dict() for t in priced]


def _memory(snn: SnnCounts, ann: AnnCounts, host: Profile, digital: Profile) -> Memory:
    """Each side's weight footprint and the memory array it is read from (its own row)."""
    snn_bytes = host.weight_bytes(snn.net.host_parameters)
    ann_bytes = digital.weight_bytes(ann.parameters)
    return {
        "snn_host_weight_bytes": snn_bytes,
        "snn_host_array": memory_row(snn_bytes),
        "ann_weight_bytes": ann_bytes,
        "ann_array": memory_row(ann_bytes),
    }


def _ann_success(task: Task | None, float_task: AnnRunTask | None) -> str:
    """Where the ANN's success on a profile comes from."""
    if task is None:
        return "not run"
    if task is not float_task:
        return "measured: the ANN quantised to int8, on the deployment's episodes"
    return "measured: the float ANN, on the deployment's episodes"


def _per_return(energy: float, mean_return: float) -> float | None:
    return energy / mean_return if mean_return > 0 else None


def sensitivity(
    snn: SnnCounts,
    ann: AnnCounts,
    chips: list[Profile],
    digital: list[Profile],
    host: Profile | None,
) -> list[Sensitivity]:
    """One price at a time, for each chip against the same-width ANN on each digital profile
    (the memory-inclusive first); :meth:`Comparison.sensitivity` writes the rows."""
    return [
        {
            "snn_profile": c.name,
            "ann_profile": d.name,
            "rows": cast(list[SensitivityRow], Comparison(snn, ann, c, host or d, d).sensitivity()),
        }
        for c in chips
        for d in memory_first(digital)
    ]
