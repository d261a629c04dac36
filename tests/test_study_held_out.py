"""A study's held-out tracks (``eval_tracks``): every run, trained on random tracks or on one,
is also evaluated on tracks it never trained on (a folder of generated tracks as one column,
the built-in big_S as another), on its own evaluation backend, and ``study.md`` sets the
results beside its own evaluation."""

from __future__ import annotations

import json
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

import pytest

from snnkart.app.study_run import load_study
from snnkart.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ROOT / "benchmarks/tracks/generated"
TINY = ["ppo.num_envs=2", "ppo.rollout_steps=64", "ppo.update_epochs=1", "ppo.num_minibatches=2",
        "snn.num_steps=2"]  # fmt: skip


def _config(tmp_path: Path, eval_tracks: list[str], data: str = "reporting") -> Path:
    path = tmp_path / "study.toml"
    path.write_text(f"""
schema = "snnkart/study-config/v1"
data = "{data}"
tracks = ["random", "small_S"]
envs = ["steer"]
policies = ["ann", "snn"]
seeds = [101]
steps = 128
finishes = 1
eval_episodes = 2
deploy_episodes = 0
eval_tracks = {json.dumps(eval_tracks)}
eval_track_episodes = 2
sets = {json.dumps(TINY)}
""")
    return path


@pytest.mark.timeout(600)
def test_every_run_is_evaluated_on_the_held_out_tracks(tmp_path: Path) -> None:
    folder = tmp_path / "generated"
    folder.mkdir()
    for track in sorted(GENERATED.glob("*.toml"))[:2]:  # two reporting tracks
        shutil.copy(track, folder)
    out = tmp_path / "study"
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "study", str(_config(tmp_path, [str(folder), "big_S"])),
         "--out", str(out), "--jobs", "2"],
        cwd=ROOT, capture_output=True, text=True, timeout=500,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((out / "study.json").read_text())
    assert record["schema"] == "snnkart/study/v4" and record["study"]["eval_track_episodes"] == 2
    stems = [p.stem for p in sorted(folder.glob("*.toml"))]
    assert len(record["runs"]) == 4
    for run in record["runs"]:
        held = run["held_out"]
        assert [h["track"] for h in held] == [*stems, "big_S"]
        assert [h["tuning_track"] for h in held] == [False, False, True]
        for h in held:  # each number is the evaluation file's, on that track and backend
            where = out / "runs" / run["name"] / "study-held-out"
            if run["policy"] == "snn":
                file = json.loads((where / h["track"] / "deploy.json").read_text())
                assert (file["backend"], file["precision"]) == ("nir-ref", "fixed")
                assert file["env"]["track"] == h["track"]
            else:
                file = json.loads((where / f"{h['track']}.json").read_text())
                assert file["track"] == h["track"]
            assert file["summary"]["episodes"] == 2 == h["episodes"]
            assert file["summary"]["success_rate"] == h["success_rate"]
    text = (out / "study.md").read_text()
    assert "## Held-out tracks" in text and "| own track | generated (2 tracks) | big_S † |" in text
    run = next(r for r in record["runs"] if r["name"] == "random-steer-snn-s101")
    folder_mean = statistics.mean(h["success_rate"] for h in run["held_out"][:2])
    big = run["held_out"][2]["success_rate"]
    own = run["eval_success_rate"]
    assert (
        f"| random | steer | snn | {own:.0%} | {folder_mean:.0%} | {big:.0%} |".replace("%", " %")
        in text
    )


def test_held_out_tracks_follow_the_protocol_and_must_exist(tmp_path: Path) -> None:
    assert load_study(_config(tmp_path, ["benchmarks/tracks/zigzag.toml", "small_S"])).eval_tracks
    with pytest.raises(UsageError, match=r"track .benchmarks/tracks/ring\.toml. is not reporting"):
        load_study(_config(tmp_path, ["benchmarks/tracks/ring.toml"]))
    with pytest.raises(UsageError, match=r"eval_tracks: track .nowhere\.toml. is neither"):
        load_study(_config(tmp_path, ["nowhere.toml"]))
    (tmp_path / "empty").mkdir()
    with pytest.raises(UsageError, match=r"holds no \*\.toml track file"):
        load_study(_config(tmp_path, [str(tmp_path / "empty")]))
    with pytest.raises(UsageError, match="is not tuning data"):
        load_study(_config(tmp_path, [str(GENERATED)], data="tuning"))
