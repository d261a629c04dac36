"""The main job's numbers in the documentation (``docs/deployment.md``): rendered from the
committed record of ``python -m benchmarks.bench_main_job`` (which runs ``snnkart demo`` as a
user does), never typed by hand. A record made at a commit with uncommitted changes is
refused."""

from __future__ import annotations

from typing import Any

from snnkart.errors import ReportError


def bench_commit(bench: dict[str, Any], source: str) -> str:
    """The main-job record's commit, if it may be published; else a one-line refusal."""
    commit = str(bench.get("machine", {}).get("commit", "unknown"))
    if commit.endswith("-dirty") or commit == "unknown":
        raise ReportError(f"{source}: made at commit {commit}; run the benchmark at a clean commit")
    return commit


def main_job_block(bench: dict[str, Any], source: str, seed: int, begin: str, end: str) -> str:
    """The block: training, the quantisation's effect, Lava's parity and speed, and the counts
    per inference; ``seed`` is the demo's training seed (the record does not carry it)."""
    commit = bench_commit(bench, source)
    t, q, report = bench["training"], bench["torch_vs_fixed_point"], bench["report"]
    fixed, flt = bench["lava"]["fixed"], bench["lava"]["float"]
    first = t["first_finish_step"]
    text = (
        f"Measured on the main job (`python -m benchmarks.bench_main_job` at commit {commit}, "
        f"`{source}`, {bench['wall_s']:.0f} s in all): grid/small_S SNN, seed {seed}, "
        f"{t['global_step']:,} steps, first finish at "
        + ("no step" if first is None else f"{first:,} steps")
        + f", {t['steps_per_s']:,.0f} training steps/s; success on the same {q['episodes']} "
        f"seeded episodes: torch {100 * q['torch_success_rate']:.0f} %, fixed point "
        f"{100 * q['fixed_point_success_rate']:.0f} %; Lava fixed and float differ from the "
        f"reference in {fixed['mismatched_windows']} of {fixed['env_steps']:,} and "
        f"{flt['mismatched_windows']} of {flt['env_steps']:,} env steps; Lava fixed agrees with "
        "the float32 policy on "
        f"{100 * fixed['float32_identical_action_fraction']:.1f} % of actions; Lava "
        f"{round(fixed['success_rate'] * fixed['episodes'])}/{fixed['episodes']} (fixed) and "
        f"{round(flt['success_rate'] * flt['episodes'])}/{flt['episodes']} (float) episodes, "
        f"{fixed['ms_per_env_step']:.1f} and {flt['ms_per_env_step']:.1f} ms per env step; "
        f"{report['spikes_per_inference']:.0f} spikes and {report['synops_per_inference']:.0f} "
        "synaptic operations per inference."
    )
    return "\n\n".join([begin.format(source=source), text, end])
