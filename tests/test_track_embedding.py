"""A policy trained on a track file of the user's own carries the track in its checkpoint and
its NIR manifest: after the file is deleted, ``deploy`` (nir-ref and lava-sim), ``eval`` of the
NIR file and of the run directory, ``replay`` and ``train --resume`` still run on it; another
``--track`` is allowed and recorded; manifests and checkpoints written before tracks were
embedded still load."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import json
import shutil
from pathlib import Path

import pytest
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.cli import app
from snnkart.contract.manifest import manifest_path
from snnkart.envs.tracks import embed_track, embedded_track, load_track, parse_track, track_sha256
from snnkart.export.nir_export import export_nir
from snnkart.rl.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from snnkart.rl.trained import load_run

RING = "ring"


def _ring_toml() -> str:
    """small_S under another name and a longer time limit: a different track file (hash)."""
    text = load_track("small_S").to_toml()
    return text.replace('name = "small_S"', f'name = "{RING}"').replace(
        "time_limit_s = ", "time_limit_s = 1"
    )


@pytest.fixture(scope="module")
def moved(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A tiny steer SNN trained on ``tracks/ring.toml`` (given as a relative path, as a user
    would), exported, and the track file then deleted."""
    base = tmp_path_factory.mktemp("own-track")
    cwd = Path.cwd()
    os.chdir(base)
    try:
        Path("tracks").mkdir()
        Path("tracks/ring.toml").write_text(_ring_toml())
        run = train_tiny(base / "run", "steer", "snn", track="tracks/ring.toml")
        nir_path, _ = export_nir(load_run(run), base / "export" / "policy.nir")
    finally:
        os.chdir(cwd)
    shutil.rmtree(base / "tracks")
    return {"run": run, "nir": nir_path, "base": base}


def _invoke(*args: str) -> str:
    result = CliRunner().invoke(app, list(args))
    assert result.exit_code == 0, result.output
    return result.output


def test_embedded_track_round_trips_exactly() -> None:
    for name in ("small_S", "big_S"):
        track = load_track(name)
        record = embed_track(track, name)
        again = embedded_track(record, "a test")
        assert track_sha256(again) == record["sha256"] == track_sha256(track)
        assert again.to_toml() == track.to_toml() and again.name == name
    record = embed_track(load_track("small_S"), "small_S")
    record["toml"] = record["toml"].replace('description = "', 'description = "edited ')
    with pytest.raises(ValueError, match="does not match its hash"):
        embedded_track(record, "a test")


def test_checkpoint_and_manifest_embed_the_track(moved: dict[str, Path]) -> None:
    _, meta = load_checkpoint(moved["run"] / "checkpoint.pt")
    assert meta["track"]["name"] == RING
    assert meta["track"]["given"] == "tracks/ring.toml"  # the path as the user gave it
    assert parse_track(meta["track"]["toml"]).to_toml() == _ring_toml()
    manifest = json.loads(manifest_path(moved["nir"]).read_text())
    assert manifest["schema"] == "snnkart/manifest/v4"
    assert manifest["track"] == meta["track"]
    assert manifest["env"]["track_sha256"] == meta["track"]["sha256"]
    assert manifest["env"]["env_config"] == meta["env_spec"]["env_config"]


def test_deploy_reference_without_the_track_file(moved: dict[str, Path], tmp_path: Path) -> None:
    out = _invoke("deploy", str(moved["nir"]), "--backend", "nir-ref", "--episodes", "2",
                  "--out", str(tmp_path))  # fmt: skip
    assert "steer/ring (tracks/ring.toml, embedded), 2 episodes" in out
    assert "steer//" not in out and "note:" not in out
    env = json.loads((tmp_path / "deploy.json").read_text())["env"]
    assert env["track"] == RING and env["track_source"] == "embedded"
    assert env["track_given"] == "tracks/ring.toml" and env["track_override"] is False


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_deploy_on_lava_without_the_track_file(moved: dict[str, Path], tmp_path: Path) -> None:
    out = _invoke("deploy", str(moved["nir"]), "--backend", "lava-sim", "--episodes", "1",
                  "--out", str(tmp_path))  # fmt: skip
    assert "lava-sim (fixed) on steer/ring (tracks/ring.toml, embedded)" in out
    record = json.loads((tmp_path / "deploy.json").read_text())
    assert record["env"]["track"] == RING
    assert record["parity"]["same_arithmetic_mismatched_windows"] == 0


def test_eval_of_the_nir_file_and_of_the_run_without_the_track_file(
    moved: dict[str, Path], tmp_path: Path
) -> None:
    out = _invoke("eval", str(moved["nir"]), "--backend", "nir-ref", "--episodes", "2",
                  "--out", str(tmp_path / "nir"))  # fmt: skip
    assert "steer/ring (tracks/ring.toml, embedded)" in out
    out = _invoke("eval", str(moved["run"]), "--episodes", "2", "--out", str(tmp_path / "e.json"))
    assert "SNN steer/ring (tracks/ring.toml)" in out and "note:" not in out
    record = json.loads((tmp_path / "e.json").read_text())
    assert record["track"] == RING and record["track_override"] is False
    assert record["track_source"] == "run"
    # a run directory on another backend goes through the export
    _invoke("eval", str(moved["run"]), "--backend", "nir-ref", "--episodes", "1",
            "--out", str(tmp_path / "run-nir"))  # fmt: skip


def test_another_track_is_allowed_and_recorded(moved: dict[str, Path], tmp_path: Path) -> None:
    out = _invoke("deploy", str(moved["nir"]), "--backend", "nir-ref", "--episodes", "1",
                  "--track", "small_S", "--out", str(tmp_path / "d"))  # fmt: skip
    assert "steer/small_S, 1 episodes" in out
    assert "note: track small_S is not the track the policy was trained on (ring " in out
    env = json.loads((tmp_path / "d" / "deploy.json").read_text())["env"]
    assert env["track"] == "small_S" and env["track_source"] == "--track"
    assert env["track_override"] is True and env["trained_track"]["name"] == RING
    out = _invoke("eval", str(moved["run"]), "--episodes", "1", "--track", "small_S",
                  "--out", str(tmp_path / "e.json"))  # fmt: skip
    assert "note: track small_S is not the track the policy was trained on" in out
    record = json.loads((tmp_path / "e.json").read_text())
    assert record["track"] == "small_S" and record["track_override"] is True
    assert record["track_source"] == "--track"
    out = _invoke("eval", str(moved["nir"]), "--backend", "nir-ref", "--episodes", "1",
                  "--env", "steer", "--track", "small_S", "--out", str(tmp_path / "n"))  # fmt: skip
    assert "note: track small_S" in out


def test_resume_and_replay_after_the_track_file_moved(
    moved: dict[str, Path], tmp_path: Path
) -> None:
    run = tmp_path / "run"
    shutil.copytree(moved["run"], run)
    step = load_checkpoint(run / "checkpoint.pt")[1]["global_step"]
    result = CliRunner().invoke(app, ["train", "--resume", "--out", str(run),
                                      "--steps", str(step + 256)])  # fmt: skip
    assert result.exit_code == 0, result.output
    _, meta = load_checkpoint(run / "checkpoint.pt")
    assert meta["global_step"] == step + 256 and meta["track"]["name"] == RING
    _invoke("replay", str(run), "--out", str(tmp_path / "replay.gif"), "--every", "8")


def _as_v1(nir: Path, dst: Path) -> Path:
    """A copy of an export whose manifest is as snnkart wrote it before tracks were embedded."""
    dst.mkdir(parents=True)
    out = dst / "policy.nir"
    shutil.copyfile(nir, out)
    manifest = json.loads(manifest_path(nir).read_text())
    manifest["schema"] = "snnkart/manifest/v1"
    del manifest["track"]
    manifest_path(out).write_text(json.dumps(manifest))
    return out


def test_manifest_written_before_embedding_still_loads(
    moved: dict[str, Path], tmp_path: Path
) -> None:
    old = _as_v1(moved["nir"], tmp_path / "v1")
    result = CliRunner().invoke(app, ["deploy", str(old), "--backend", "nir-ref",
                                      "--episodes", "1", "--out", str(tmp_path / "a")])  # fmt: skip
    assert result.exit_code == 2
    assert "written before tracks were embedded" in result.output and "--track" in result.output
    (tmp_path / "ring.toml").write_text(_ring_toml())
    out = _invoke("deploy", str(old), "--backend", "nir-ref", "--episodes", "1",
                  "--track", str(tmp_path / "ring.toml"), "--out", str(tmp_path / "b"))  # fmt: skip
    assert "note:" not in out  # the same track, found by its hash
    env = json.loads((tmp_path / "b" / "deploy.json").read_text())["env"]
    assert env["track_override"] is False and env["track"] == RING


def test_checkpoint_written_before_embedding_still_loads(
    moved: dict[str, Path], tmp_path: Path
) -> None:
    run = tmp_path / "run"
    shutil.copytree(moved["run"], run)
    state, meta = load_checkpoint(run / "checkpoint.pt")
    del meta["track"]
    save_checkpoint(run / "checkpoint.pt", state, meta)
    with pytest.raises(CheckpointError, match="predates embedded tracks"):
        load_run(run)  # its config names tracks/ring.toml, which is gone
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        Path("tracks").mkdir()
        Path("tracks/ring.toml").write_text(_ring_toml())
        assert load_run(run).track.name == RING  # where it was trained: works as before
    finally:
        os.chdir(cwd)
