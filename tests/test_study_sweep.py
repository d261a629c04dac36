"""A study with variants (what ``studies/sparsity.toml`` is, at a tiny budget): every variant
trained, evaluated on the fixed-point reference with its counts per env step in ``study.json``,
and ``snnkart report --sweep`` pricing those counts as the report prices a deployment."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from snnkart.app.report import build_report
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.counts import SnnCounts
from snnkart.energy.pricing import terms, total
from snnkart.energy.profiles import load_profile
from snnkart.errors import ReportError

pytestmark = pytest.mark.xdist_group("study_sweep")  # one worker builds the module's fixtures once

ROOT = Path(__file__).resolve().parents[1]
SNNKART = [sys.executable, "-m", "snnkart.cli"]
OLD_STUDY = Path(__file__).parent / "data" / "records" / "study-v1.json"
TINY = ["ppo.num_envs=2", "ppo.rollout_steps=64", "ppo.update_epochs=1", "ppo.num_minibatches=2"]
EVAL = "study-eval-nir-ref-fixed"


def _cli(*args: str, timeout: float = 400) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*SNNKART, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)  # fmt: skip


@pytest.fixture(scope="session")  # built once per worker, whatever runs between its tests
def sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two variants of a grid SNN (T = 2; T = 4 with a rate penalty), one seed, one iteration."""
    tmp = tmp_path_factory.mktemp("sweep")
    (tmp / "sweep.toml").write_text(f"""
schema = "snnkart/study-config/v1"
data = "tuning"
envs = ["grid"]
policies = ["snn"]
seeds = [1]
steps = 128
finishes = 1
eval_episodes = 2
deploy_episodes = 0
sets = {json.dumps(TINY)}
[variants]
T2 = ["snn.num_steps=2"]
"T4_r0.05" = ["snn.num_steps=4", "snn.rate_reg=0.05"]
""")
    result = _cli("study", str(tmp / "sweep.toml"), "--out", str(tmp / "study"), "--jobs", "2")
    assert result.returncode == 0, result.stderr[-3000:]
    return tmp / "study"


@pytest.mark.timeout(600)
def test_a_variant_study_records_each_runs_counts_per_env_step(sweep: Path) -> None:
    record = json.loads((sweep / "study.json").read_text())
    assert [r["name"] for r in record["runs"]] == [
        "small_S-grid-snn-T2-s1", "small_S-grid-snn-T4_r0.05-s1"]  # fmt: skip
    assert [c["variant"] for c in record["cells"]] == ["T2", "T4_r0.05"]
    assert "Data: tuning (the results protocol" in (sweep / "study.md").read_text()
    for run, num_steps in zip(record["runs"], (2, 4), strict=True):
        deploy = json.loads((sweep / "runs" / run["name"] / EVAL / "deploy.json").read_text())
        counts, n = deploy["counts"], deploy["counts"]["env_steps"]
        per_step = run["eval_counts_per_step"]
        assert per_step["num_steps"] == num_steps == deploy["manifest"]["num_steps"]
        assert per_step["env_steps"] == n > 0 and per_step["sizes"] == [64, 64]
        for key in ("spikes", "synops", "neuron_updates"):
            assert per_step[f"{key}_per_step"] == [c / n for c in counts[key]], key
            overhead = counts["pipeline_overhead"][key]
            assert per_step[f"overhead_{key}_per_step"] == [c / n for c in overhead], key
        assert run["eval_success_rate"] == deploy["summary"]["success_rate"]
        assert run["eval_mean_lap_time"] == deploy["summary"]["mean_lap_time"]
        cell = next(c for c in record["cells"] if c["variant"] == run["variant"])
        chip = sum(counts["synops"][:-1]) / n  # the last layer's fan-out is the host's readout
        assert cell["eval_synops_per_step"]["median"] == pytest.approx(chip, rel=1e-12)


@pytest.mark.timeout(600)
def test_report_sweep_prices_each_run_of_a_study_as_its_deployment(
    sweep: Path, tmp_path: Path
) -> None:
    """Each run's energy from the study's counts per env step equals the energy of that run's
    own evaluation record priced the way the report prices a deployment."""
    deployment = sweep / "runs" / "small_S-grid-snn-T2-s1" / EVAL
    result = _cli("report", str(deployment), "--sweep", str(sweep / "study.json"),
                  "--out", str(tmp_path))  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "tradeoff.png").is_file()
    section = json.loads((tmp_path / "report.json").read_text())["sweep"]
    chip, host = load_profile(section["profile"]), load_profile(section["host_profile"])
    assert [(p["point"], p["seed"], p["num_steps"]) for p in section["points"]] == [
        ("T2", 1, 2), ("T4_r0.05", 1, 4)]  # fmt: skip
    for point in section["points"]:
        run_dir = sweep / "runs" / f"small_S-grid-snn-{point['point']}-s1"
        deploy = DeployRecord.read(run_dir / EVAL / "deploy.json")
        expected = total(terms(SnnCounts.of_deploy(deploy), chip, host))
        assert point["energy_pj"] == pytest.approx(expected, rel=1e-12)
        assert point["success_rate"] == deploy.summary.success_rate


@pytest.mark.timeout(600)
def test_report_sweep_refuses_an_old_or_foreign_file_in_one_line(
    sweep: Path, tmp_path: Path
) -> None:
    deployment = sweep / "runs" / "small_S-grid-snn-T2-s1" / EVAL
    old = tmp_path / "bench_sparsity-grid.json"
    old.write_text(json.dumps({"benchmark": "bench_sparsity", "env": "grid", "runs": []}))
    out = tmp_path / "report"  # the sweep file beside it would be "other files" in --out
    result = _cli("report", str(deployment), "--sweep", str(old), "--out", str(out))
    assert result.returncode != 0
    assert ("written by bench_sparsity, an older snnkart; run `snnkart study "
            "studies/sparsity.toml` again") in result.stderr  # fmt: skip
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    current = json.loads((sweep / "study.json").read_text())
    no_counts = {**current, "runs": [{**r, "eval_counts_per_step": None} for r in current["runs"]]}
    cases = [
        ({"schema": "snnkart/deploy/v1"}, "not a study.json (schema 'snnkart/deploy/v1')"),
        ([1, 2], "not a study.json"),
        (no_counts, "no run of this study has counts"),
        (json.loads(OLD_STUDY.read_text()),  # v1, written before the counts per env step
         "written by an older snnkart (no counts per env step); run `snnkart study`"),
    ]  # fmt: skip
    for data, refusal in cases:
        old.write_text(json.dumps(data))
        with pytest.raises(ReportError) as info:
            build_report(deployment, None, None, sweep=old)
        assert str(info.value).startswith(f"--sweep {old}: ") and refusal in str(info.value)
