"""The documentation's tables come from committed JSON by code (scripts/render_docs.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _render_docs():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("render_docs", ROOT / "scripts/render_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_energy_page_is_rendered_from_its_committed_report() -> None:
    render = _render_docs()
    for page, source in render.blocks():
        for one in source.split(", "):  # a block may join several records
            assert (ROOT / one).is_file(), f"{one} is missing"
        assert (ROOT / page).read_text() == render.rendered(page, source), (
            f"{page} differs from what {source} renders: run scripts/render_docs.py"
        )


def test_a_page_without_its_markers_is_refused() -> None:
    import pytest

    from snnkart.report.docs_block import replace_block

    with pytest.raises(ValueError, match="no generated block"):
        replace_block("# Energy\n\nno markers here\n", "block")


def test_the_bc_scratch_arm_repeats_the_small_s_runs() -> None:
    """docs/results.md says so: same seeds and settings, deterministic training on the CPU."""
    from snnkart.report.study_record import StudyRecord

    def steps(path: str, variant: str) -> dict[tuple[str, int], tuple[int | None, int | None]]:
        record = StudyRecord.read(ROOT / path)
        return {(r.policy, r.seed): (r.first_finish_step, r.steps_to_finishes)
                for r in record.runs if r.env == "gazebo" and r.variant == variant}  # fmt: skip

    assert steps("docs/bc/gazebo.json", "scratch") == steps("docs/results/small_S.json", "")
    assert "repeats the small_S study's runs to the step" in (ROOT / "docs/results.md").read_text()
