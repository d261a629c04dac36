"""``snnkart report`` on a sigma-delta deployment (a nir-ref fixed deployment of the test
policy of :mod:`sigma_delta_policy`): report.json prices its counts with ``terms`` on every
chip and holds the goal's decision, equal to calling them directly; the first screen answers
first; an old report.json is refused with the fix; ``--sweep`` prices a study's sigma-delta
runs and draws them as their own kind."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from sigma_delta_policy import write_sigma_delta_policy

from snnkart.app.report import build_report
from snnkart.app.report_sigma_delta import stateful_note
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy import goal
from snnkart.energy.counts import AnnCounts
from snnkart.energy.pricing import terms as price_terms
from snnkart.energy.pricing import total
from snnkart.energy.profiles import DEFAULT_CHIPS, load_profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.energy.sigma_delta_pricing import what_ifs
from snnkart.errors import ReportError

# scripts/docs_blocks: the documents' writers, not installed with snnkart
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from docs_blocks.docs_block import energy_block

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data" / "records"
SNNKART = [sys.executable, "-m", "snnkart.cli"]


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*SNNKART, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, env={"COLUMNS": "200", **__import__("os").environ})  # fmt: skip


@pytest.fixture(scope="module")
def deployed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sigma-delta deployment (2 episodes on the numpy reference, fixed point) and its report."""
    base = tmp_path_factory.mktemp("report-sd")
    nir = write_sigma_delta_policy(base / "policy", vth=4, vth_in=2)
    out = base / "deploy"
    run = _cli("deploy", str(nir), "--backend", "nir-ref", "--precision", "fixed",
               "--episodes", "2", "--out", str(out))  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    report = _cli("report", str(out))
    assert report.returncode == 0, report.stderr[-2000:]
    (out / "stdout.txt").write_text(report.stdout)
    return out


def _json(x: Any) -> Any:
    return json.loads(json.dumps(x))


def test_the_report_prices_the_counts_with_sd_terms_and_decides_the_goal(deployed: Path) -> None:
    report = json.loads((deployed / "report.json").read_text())
    record = DeployRecord.read(deployed / "deploy.json")
    counts = SigmaDeltaCounts.of_deploy(record)
    sd = record.counts.sigma_delta
    assert sd is not None and counts.env_steps == record.counts.env_steps > 0
    assert counts.messages == tuple(m / counts.env_steps for m in sd.messages)
    assert report["schema"] == "snnkart/report/v4" and report["kind"] == "sigma-delta"
    assert report["sigma_delta"]["per_env_step"] == _json(dataclasses.asdict(counts))
    fp32, int8 = load_profile(goal.FP32), load_profile(goal.INT8)
    assert [p["chip"] for p in report["pricing"]] == list(DEFAULT_CHIPS)
    for priced in report["pricing"]:
        chip = load_profile(priced["chip"])
        terms = price_terms(counts, chip, fp32)  # host work on the first fair baseline
        assert priced["terms"] == _json([t.as_dict() for t in terms])
        assert priced["snn_pj"] == pytest.approx(total(terms), rel=1e-12)
        assert priced["what_ifs"] == _json(what_ifs(counts, chip, fp32))
    ann = AnnCounts((counts.n_in, *counts.sizes, counts.n_out), counts.action_mode)
    direct = goal.decide([goal.priced_policy(counts, load_profile(c), b, ann)
                          for c in ("loihi2", "loihi1") for b in (fp32, int8)])  # fmt: skip
    assert report["goal"] == _json(direct)
    loihi2 = next(p for p in report["pricing"] if p["chip"] == "loihi2")
    assert [c["ratio"] for c in loihi2["intervals"]] == [
        c["ratio"] for c in report["goal"]["primary"]["checks"]]  # fmt: skip


def test_a_lif_deployment_has_no_sigma_delta_counts() -> None:
    record = DeployRecord.read(DATA / "deploy-nir-ref-fixed.json")
    with pytest.raises(ReportError, match="a LIF deployment has no sigma-delta counts"):
        SigmaDeltaCounts.of_deploy(record)


def test_the_first_screen_answers_first_then_the_term_in_the_way(deployed: Path) -> None:
    report = json.loads((deployed / "report.json").read_text())
    g = report["goal"]
    answer = "Yes: " if g["holds"] else "No: "
    md = (deployed / "report.md").read_text().split("\n\n")
    first = next(p for p in md[1:] if not p.startswith("**WARNING"))
    assert first.startswith(answer + "the sigma-delta policy")
    assert f"the energy goal on {g['primary']['chip']}" in first
    if g["primary"]["in_the_way"]:
        assert f"{g['primary']['in_the_way']['part']} is in the way" in first
    assert f'<p id="verdict">{answer}' in (deployed / "report.html").read_text()
    assert answer + "the sigma-delta policy" in (deployed / "stdout.txt").read_text()
    page = (deployed / "report.md").read_text()
    for column in ("messages", "payload bits", "synaptic events", "updates clocked",
                   "updates active", "held, active", "one step, clocked"):  # fmt: skip
        assert f" {column} |" in page, column


def test_an_old_report_json_is_refused_with_the_fix_and_v2_still_renders(deployed: Path) -> None:
    old = json.loads((DATA / "report-v2.json").read_text())
    assert old["schema"] == "snnkart/report/v2"
    assert "Deployment: `" in energy_block(old, "report-v2.json")
    with pytest.raises(ReportError, match=r"written by an older snnkart; run `snnkart report"):
        energy_block({**old, "schema": "snnkart/report/v1"}, "old/report.json")
    sd = json.loads((deployed / "report.json").read_text())
    assert sd["goal"]["verdict"] in energy_block(sd, "report.json")


def test_a_stateful_lif_deployment_says_its_membranes_persist(tmp_path: Path) -> None:
    record = DeployRecord.read(DATA / "deploy-nir-ref-fixed.json")
    manifest = json.loads(
        (ROOT / "tests/data/policies/grid-snn-nir-8ddd6dd/policy.manifest.json").read_text()
    )
    for persists in (False, True):
        nir = tmp_path / f"p{int(persists)}" / "policy.nir"
        nir.parent.mkdir()
        (nir.parent / "policy.manifest.json").write_text(
            json.dumps({**manifest, "state_persists": persists}))  # fmt: skip
        note = stateful_note(dataclasses.replace(record, nir_file=str(nir)))
        if persists:
            assert note is not None and note["rows_per_env_step"] == "T + L"
            assert "membranes persist" in note["note"] and "fill/drain" in note["note"]
        else:
            assert note is None


def _study_with_an_sd_run(deployed: Path, out: Path) -> tuple[Path, dict[str, Any]]:
    """The committed tiny study (LIF runs) and one sigma-delta run whose counts are the
    deployment's, as the study's evaluation will record them."""
    study = json.loads((DATA / "study.json").read_text())
    counts = dataclasses.asdict(
        SigmaDeltaCounts.of_deploy(DeployRecord.read(deployed / "deploy.json"))
    )
    sd_run = {**study["runs"][-1], "name": "small_S-grid-sdnn-s1", "policy": "sdnn",
              "eval_counts_per_step": None, "sigma_delta_counts": _json(counts)}  # fmt: skip
    study["runs"].append(sd_run)
    path = out / "study.json"
    path.write_text(json.dumps(study))
    return path, counts


def test_the_sweep_prices_sigma_delta_runs_as_their_own_kind(
    deployed: Path, tmp_path: Path
) -> None:
    path, counts = _study_with_an_sd_run(deployed, tmp_path)
    report = build_report(deployed, None, None, sweep=path)
    points = report["sweep"]["points"]
    sd = [p for p in points if p["kind"] == "sigma-delta trained"]
    assert len(sd) == 1 and {p["kind"] for p in points} == {"dense LIF", "sigma-delta trained"}
    expected = total(price_terms(SigmaDeltaCounts.from_dict(counts), load_profile("loihi1"),
                              load_profile(goal.FP32)))  # fmt: skip
    assert sd[0]["energy_pj"] == pytest.approx(expected, rel=1e-12)
    from snnkart.report.document import write_report

    write_report(report, tmp_path)
    assert (tmp_path / "tradeoff.png").stat().st_size > 10_000


def test_the_report_validates_against_its_schema(deployed: Path) -> None:
    import jsonschema

    schema = json.loads((ROOT / "snnkart/report/report.schema.json").read_text())
    report = json.loads((deployed / "report.json").read_text())
    jsonschema.validate(report, schema)
    with pytest.raises(jsonschema.ValidationError, match="'goal' is a required property"):
        jsonschema.validate({k: v for k, v in report.items() if k != "goal"}, schema)


def test_sanafe_checks_the_goal_with_its_chip_energy_plus_host_and_link(deployed: Path) -> None:
    from snnkart.energy.sanafe_model import sanafe_python

    if sanafe_python() is None:
        pytest.skip("optional: SANA-FE is not installed (pip install 'snnkart[sanafe]')")
    report = build_report(deployed, None, None, sanafe=True)
    section = report["sanafe"]
    counts = SigmaDeltaCounts.of_deploy(DeployRecord.read(deployed / "deploy.json"))
    replay = section["per_inference"]["counts"]
    assert replay["synaptic_events"] == pytest.approx(sum(counts.synaptic_events[:-1]), rel=1e-9)
    assert replay["packets"] == pytest.approx(sum(counts.messages[:-1]), rel=1e-9)
    loihi1 = load_profile("loihi1")
    energy = {}
    for b in (goal.FP32, goal.INT8):
        off = [t for t in price_terms(counts, loihi1, load_profile(b))
               if t.part in ("host link", "host compute", "memory")]  # fmt: skip
        energy[b] = section["per_inference"]["chip_pj"] + total(off)
    assert section["energy_pj"] == pytest.approx(energy, rel=1e-12)
    ann = AnnCounts((counts.n_in, *counts.sizes, counts.n_out), counts.action_mode)
    fp32, int8 = load_profile(goal.FP32), load_profile(goal.INT8)
    direct = goal.decide([goal.priced_policy(counts, load_profile(c), b, ann)
                          for c in ("loihi2", "loihi1") for b in (fp32, int8)], energy)  # fmt: skip
    assert report["goal"]["sanafe"] == _json(direct["sanafe"])
    assert report["goal"]["verdict"] == direct["verdict"]


def test_a_stateful_lif_report_page_says_so() -> None:
    from snnkart.app.report_sigma_delta import STATEFUL
    from snnkart.report.document import markdown

    report = json.loads((ROOT / "docs/energy/report.json").read_text())
    assert "membranes persist" not in markdown(report, [])
    page = markdown({**report, "state": {"state_persists": True, "note": STATEFUL}}, [])
    assert f"Stateful: {STATEFUL}." in page


def test_a_stateful_lif_deployments_report_json_has_the_state(tmp_path: Path) -> None:
    """The committed LIF deployment, its manifest marked stateful: report.json gains ``state``;
    unmarked it has none (a LIF report as before)."""
    src = ROOT / "tests/data/policies/grid-snn-nir-8ddd6dd"
    for persists in (False, True):
        where = tmp_path / f"p{int(persists)}"
        (where / "deploy").mkdir(parents=True)
        manifest = json.loads((src / "policy.manifest.json").read_text())
        (where / "policy.manifest.json").write_text(
            json.dumps({**manifest, "state_persists": persists}))  # fmt: skip
        deploy = json.loads((DATA / "deploy-nir-ref-fixed.json").read_text())
        deploy["nir_file"] = str(where / "policy.nir")
        (where / "deploy" / "deploy.json").write_text(json.dumps(deploy))
        report = build_report(where / "deploy", None, ["loihi1", goal.FP32])
        assert ("state" in report) == persists
        if persists:
            assert "membranes persist" in report["state"]["note"]


def test_a_runs_kind_comes_from_its_settings_and_each_has_its_own_marker() -> None:
    from snnkart.report.plots import MARKERS
    from snnkart.report.study_record import StudySettings

    study = StudySettings(
        schema="snnkart/study-config/v1", name="t", tracks=["small_S"], envs=["grid"],
        policies=["snn", "rsnn", "sdnn", "ann-sd"], seeds=[1], steps=1, finishes=1,
        eval_episodes=1, sets=["snn.num_steps=4"],
        cells={"grid-snn": ["snn.rate_reg=0.0"]},
        variants={"snn:stateful_named": [], "snn:t4_r0.05": ["snn.rate_reg=0.05"],
                  "snn:carried": ["snn.stateful=true", "snn.num_steps=1"], "plain": []},
    )  # fmt: skip
    runs = [("snn", "stateful_named"), ("snn", "t4_r0.05"), ("snn", "carried"),
            ("rsnn", "plain"), ("sdnn", "plain"), ("ann-sd", "plain")]  # fmt: skip
    labels = [study.run_label("small_S", "grid", p, v) for p, v in runs]
    assert labels == ["dense LIF", "sparse LIF", "stateful LIF", "recurrent LIF",
                      "sigma-delta trained", "ANN converted"]  # fmt: skip
    drawn = set(labels)
    assert drawn <= set(MARKERS) and len({MARKERS[k] for k in drawn}) == len(drawn)
