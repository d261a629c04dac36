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

    render = _render_docs()
    with pytest.raises(ValueError, match="no generated block"):
        render.replace_block("# Energy\n\nno markers here\n", "block")


def test_the_bc_scratch_arm_repeats_the_small_s_runs() -> None:
    """docs/results.md says so: same seeds and settings, deterministic training on the CPU."""
    from snnkart.report.study_record import StudyRecord

    def steps(path: str, variant: str) -> dict[tuple[str, int], tuple[int | None, int | None]]:
        record = StudyRecord.read(ROOT / path)
        return {(r.policy, r.seed): (r.first_finish_step, r.steps_to_finishes)
                for r in record.runs if r.env == "gazebo" and r.variant == variant}  # fmt: skip

    assert steps("docs/bc/gazebo.json", "scratch") == steps("docs/results/small_S.json", "")
    assert "repeats the small_S study's runs to the step" in (ROOT / "docs/results.md").read_text()


def test_every_published_record_is_what_its_config_runs() -> None:
    """Each published study record names the settings of the committed config that makes it
    again (a config changed after its results were published fails here), and every
    reporting config is published."""
    from snnkart.app.study_run import load_study
    from snnkart.report.study_record import StudyRecord

    render = _render_docs()
    for source, config in render.PUBLISHED.items():
        study, record = load_study(ROOT / config), StudyRecord.read(ROOT / source).study
        for key in ("name", "data", "tracks", "envs", "policies", "seeds", "steps", "finishes",
                    "eval_episodes", "sets", "variants", "eval_tracks"):  # fmt: skip
            assert getattr(study, key) == getattr(record, key), f"{config} vs {source}: {key}"
    reporting = {f"studies/{p.name}" for p in (ROOT / "studies").glob("*.toml")
                 if load_study(p).data == "reporting"}  # fmt: skip
    assert reporting == set(render.PUBLISHED.values())


def test_the_frontier_page_refuses_a_tuning_record(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The frontier's blocks, like the study tables, publish reporting data only."""
    import dataclasses

    import pytest

    from snnkart.errors import ReportError
    from snnkart.report.study_record import StudyRecord

    render = _render_docs()
    record = StudyRecord.read(ROOT / render.FRONTIER)
    tuning = dataclasses.replace(record, study=dataclasses.replace(record.study, data="tuning"))
    monkeypatch.setattr(render.StudyRecord, "read", lambda path: tuning)
    for page in ("docs/frontier.md", "README.md"):
        with pytest.raises(ReportError, match="tuning data cannot fill a published table"):
            render.block(page, render.FRONTIER)
