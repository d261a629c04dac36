"""``snnkart train --wandb``: the W&B logger gets the scalars TensorBoard gets, under the same
names (a real offline run in a temporary ``WANDB_DIR``); without the ``wandb`` extra the flag
fails with a one-line install hint before anything is written, and without the flag nothing
changes."""

from __future__ import annotations

import json
import struct
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from snnkart.cli import app
from snnkart.rl.wandb_log import INSTALL_HINT

TINY = ["--env", "grid", "--steps", "128", "--set", "ppo.num_envs=1",
        "--set", "ppo.rollout_steps=64", "--set", "ppo.update_epochs=1",
        "--set", "run.tensorboard=false"]  # fmt: skip


def test_without_the_extra_the_flag_gives_an_install_hint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "wandb", None)  # Python's way to make a module unimportable
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["train", *TINY, "--wandb", "--out", str(out)])
    assert result.exit_code == 2, result.output  # a usage error
    assert INSTALL_HINT in " ".join(result.output.split()), result.output
    assert not out.exists()  # refused before the run directory is written


@pytest.mark.timeout(300)
def test_offline_run_logs_the_tensorboard_names(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("wandb", reason="optional: the wandb extra is not installed")
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_DIR", str(tmp_path / "wb"))
    monkeypatch.setenv("WANDB_SILENT", "true")
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["train", *TINY, "--wandb", "--out", str(out)])
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    (run_file,) = (tmp_path / "wb").glob("wandb/offline-run-*/run-*.wandb")
    # W&B's service process may still be writing the file when finish() returns (1 of about
    # 20 runs on a loaded machine found no history yet), so wait for it, a while at most
    deadline = time.monotonic() + 30
    while len(history := _history(run_file)) < len(records) and time.monotonic() < deadline:
        time.sleep(0.5)
    assert len(history) == len(records) == 2, f"{run_file.stat().st_size} bytes, {history}"
    for logged, record in zip(history, records, strict=True):
        tensorboard = {k: v for k, v in record.items() if "/" in k and v is not None}
        assert logged.pop("_step") == record["global_step"]
        assert {k: v for k, v in logged.items() if not k.startswith("_")} == tensorboard


def _history(run_file: Path) -> list[dict[str, Any]]:
    """The history rows of an offline W&B run file: a LevelDB-style log (a 7-byte header,
    then records of crc32, length, type and a protobuf ``Record``, in 32 KiB blocks)."""
    from wandb.proto import wandb_internal_pb2

    data, rows, i = run_file.read_bytes(), [], 7
    while i + 7 <= len(data):
        if i % 32768 > 32768 - 7:  # a block's tail too short for a header is padding
            i = (i // 32768 + 1) * 32768
            continue
        _, n, kind = struct.unpack("<IHB", data[i : i + 7])
        if i + 7 + n > len(data):  # the record being written: read again later
            break
        chunk, i = data[i + 7 : i + 7 + n], i + 7 + n
        assert kind in (0, 1), "a record split across blocks: the run is longer than expected"
        record = wandb_internal_pb2.Record()
        record.ParseFromString(chunk)
        if n and record.WhichOneof("record_type") == "history":
            rows.append({_key(it): json.loads(it.value_json) for it in record.history.item})
    return rows


def test_without_the_flag_no_wandb_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "wandb", None)  # and it is never imported
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["train", *TINY, "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert (out / "metrics.jsonl").is_file() and not (out / "wandb").exists()


def _key(item: Any) -> str:
    return str(item.key or "/".join(item.nested_key))
