"""An --out directory that holds other files is refused (one line, exit 2, naming --force)
unless --force, which deletes nothing; a command's own files (the demo's layout, a deployment
beside its report) and --resume are not "other". And ``eval`` pointed at the main job's folder
names the main job's policy, from the demo's own layout."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from snnkart.app.pipeline import ANN_RUN, POLICY_FILE, SNN_RUN, main_job_files
from snnkart.cli import app

ROOT = Path(__file__).resolve().parents[1]
NIR = ROOT / "tests/data/policies/grid-snn-nir-8ddd6dd/policy.nir"
TINY = ["--steps", "64", "--set", "ppo.num_envs=1", "--set", "ppo.rollout_steps=64",
        "--set", "ppo.update_epochs=1", "--set", "run.tensorboard=false"]  # fmt: skip


def _invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.output


def _foreign(out: Path) -> Path:
    out.mkdir()
    notes = out / "notes.txt"
    notes.write_text("mine")
    return notes


@pytest.mark.parametrize(
    "command",
    [
        ["train", "--env", "grid", *TINY, "--out"],
        ["deploy", str(NIR), "--backend", "nir-ref", "--episodes", "1", "--out"],
        ["report", str(ROOT / "tests/data"), "--out"],
        ["demo", "--steps", "10", "--out"],
    ],
    ids=lambda c: c[0],
)
def test_an_out_with_other_files_is_refused_naming_force(
    tmp_path: Path, command: list[str]
) -> None:
    notes = _foreign(tmp_path / "out")
    code, output = _invoke(*command, str(tmp_path / "out"))
    assert code == 2, output
    lines = output.strip().splitlines()
    assert len(lines) == 1 and "already holds other files (notes.txt)" in lines[0]
    assert "--force" in lines[0] and notes.read_text() == "mine"
    assert sorted(p.name for p in notes.parent.iterdir()) == ["notes.txt"]  # nothing written


@pytest.mark.parametrize(
    "command",
    [
        ["train", "--env", "grid", *TINY, "--out"],
        ["deploy", str(NIR), "--backend", "nir-ref", "--episodes", "1", "--out"],
    ],
    ids=lambda c: c[0],
)
def test_force_writes_beside_the_other_files(tmp_path: Path, command: list[str]) -> None:
    notes = _foreign(tmp_path / "out")
    code, output = _invoke(*command, str(tmp_path / "out"), "--force")
    assert code == 0, output
    assert notes.read_text() == "mine" and len(list(notes.parent.iterdir())) > 1


def test_resume_and_the_demos_own_files_are_not_other_files(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _invoke("train", "--env", "grid", *TINY, "--out", str(out))[0] == 0
    code, output = _invoke("train", "--resume", "--steps", "128", "--out", str(out))
    assert code == 0, output
    # what the demo writes is its own: a second `snnkart demo` resumes in it
    assert {SNN_RUN, ANN_RUN, POLICY_FILE, "report", "deploy-lava-sim-fixed"} <= main_job_files()


def test_eval_on_the_main_jobs_folder_suggests_its_policy(tmp_path: Path) -> None:
    demo = tmp_path / "demo"
    assert _invoke("train", "--env", "grid", *TINY, "--out", str(demo / SNN_RUN))[0] == 0
    code, output = _invoke("eval", str(demo), "--episodes", "1")
    assert code == 2, output
    assert f"did you mean {demo / SNN_RUN}" in " ".join(output.split())
    (demo / POLICY_FILE).write_bytes(b"")  # a NIR backend is pointed at the exported policy
    code, output = _invoke("eval", str(demo), "--backend", "nir-ref")
    assert code == 2 and f"did you mean {demo / POLICY_FILE}" in " ".join(output.split())
