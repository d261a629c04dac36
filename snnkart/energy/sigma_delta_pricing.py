"""A sigma-delta inference's schedule and update-rule what-ifs, and the message density at
which it meets an energy budget; it is priced as every family is (:func:`snnkart.energy.
pricing.terms`), with the graded prices of :mod:`snnkart.energy.graded`.
"""

from __future__ import annotations

from dataclasses import replace

from snnkart.contract.energy_record import BudgetBreakEven, ScheduleWhatIfs
from snnkart.energy.pricing import terms, total
from snnkart.energy.profiles import Profile, Rule
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts


def with_rule(chip: Profile, name: str, value: str, why: str) -> Profile:
    """``chip`` with one rule set (a what-if)."""
    return replace(chip, rules={**chip.rules, name: Rule(value, "assumed", why)})


def what_ifs(counts: SigmaDeltaCounts, chip: Profile, host: Profile) -> ScheduleWhatIfs:
    """The energy per inference (pJ) as priced, and under each other schedule and update rule:
    held (``rows`` Lava steps per env step) or one step per env step, clocked or active."""
    one = counts.one_step_schedule()
    clocked = with_rule(chip, "neuron_updates", "clocked", "what-if")
    active = with_rule(chip, "neuron_updates", "active", "what-if")
    return {
        "rule": chip.rule("neuron_updates").as_dict(),
        "rows": counts.rows,
        "as_priced_pj": total(terms(counts, chip, host)),
        "held_clocked_pj": total(terms(counts, clocked, host)),
        "held_active_pj": total(terms(counts, active, host)),
        "one_step_clocked_pj": total(terms(one, clocked, host)),
        "clocked_updates": {
            "held": sum(counts.updates_clocked[1:]),
            "one_step": sum(one.updates_clocked[1:]),
        },
        "note": "one step per env step: the action lags the observation by L + 1 env steps "
        "(docs/sigma-delta.md, the held-schedule decision); the same messages and synaptic events",
    }


def break_even_density(
    counts: SigmaDeltaCounts, chip: Profile, host: Profile, budget_pj: float
) -> BudgetBreakEven:
    """The message density (relative to today's) at which the inference costs ``budget_pj``:
    its energy is a fixed part (clocked updates, the link's readout, host work) plus a part
    proportional to the messages, so ``fixed + d x variable = budget``."""
    fixed = total(terms(counts.scaled(0.0), chip, host))
    variable = total(terms(counts, chip, host)) - fixed
    if fixed >= budget_pj:
        density = None
        reason = (
            "the parts that do not depend on the messages alone cost at least the budget: no "
            "sparsity reaches it"
        )
    elif variable <= 0:
        density = None
        reason = "the energy does not depend on the messages here, and it is within the budget"
    else:
        density = (budget_pj - fixed) / variable
        reason = (
            "below this density (messages relative to the deployment's) the inference costs "
            "less than the budget"
        )
    return BudgetBreakEven(
        budget_pj=budget_pj,
        fixed_pj=fixed,
        per_density_pj=variable,
        density=density,
        reason=reason,
    )
