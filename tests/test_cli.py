"""The ``snnkart`` command line, run as the installed console script in subprocesses."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PYTHON = sys.executable
SNNKART = str(Path(sys.executable).with_name("snnkart"))
ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "COLUMNS": "200", "NO_COLOR": "1"}
HEAVY = ("torch", "pygame", "lava")


def run(
    *args: str, timeout: float = 60, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SNNKART, *args], capture_output=True, text=True, env=ENV, timeout=timeout, cwd=cwd
    )


def test_help_lists_the_commands() -> None:
    result = run("--help", timeout=30)
    assert result.returncode == 0, result.stderr
    for command in ("play", "train", "eval", "replay", "export", "deploy", "report", "demo"):
        assert f" {command} " in result.stdout, command


@pytest.mark.parametrize(
    "code",
    [
        "import snnkart.cli",
        "from snnkart.cli import app\ntry:\n    app(['--help'])\nexcept SystemExit as e:\n"
        "    assert e.code in (0, None), e.code",
        "from snnkart.cli import app\ntry:\n    app(['train', '--help'])\nexcept SystemExit:\n"
        "    pass",
    ],
    ids=["import", "help", "train-help"],
)
def test_cli_startup_does_not_import_heavy_packages(code: str) -> None:
    script = (
        "import contextlib, io, json, sys\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        + "".join(f"    {line}\n" for line in code.splitlines())
        + f"heavy = sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r})\n"
        "print(json.dumps(heavy))\n"
    )
    result = subprocess.run(
        [PYTHON, "-c", script], capture_output=True, text=True, env=ENV, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout.strip().splitlines()[-1]) == []


def test_play_headless_with_max_steps() -> None:
    result = run("play", "--env", "grid", "--track", "small_S", "--max-steps", "20", timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "grid on small_S" in result.stdout


def test_play_unknown_env_names_it() -> None:
    result = run("play", "--env", "nope", "--max-steps", "5", timeout=30)
    assert result.returncode != 0
    assert "unknown env 'nope'" in result.stderr
    assert "steer" in result.stderr
    assert "Traceback" not in result.stderr


def test_play_unknown_track_names_it(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.toml"
    result = run("play", "--track", str(missing), "--max-steps", "5", timeout=30)
    assert result.returncode != 0
    assert "nowhere.toml" in result.stderr
    assert "Traceback" not in result.stderr


def test_demo_scripted_gif(tmp_path: Path) -> None:
    out = tmp_path / "tmp.gif"
    result = run("demo", "--scripted-gif", str(out), timeout=120, cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert ": finished;" in result.stdout, result.stdout
    assert str(out) in result.stdout
    assert out.is_file() and out.stat().st_size > 0
    assert out.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert not list(tmp_path.glob(".tmp.gif*"))  # written atomically, no temp file left


def test_user_errors_are_messages_and_bugs_are_tracebacks(monkeypatch, tmp_path: Path) -> None:
    """A SnnkartError (bad input) prints ``error: ...`` and exits 2; anything else is a bug in
    snnkart and must surface with its traceback, not be dressed up as a user error."""
    from typer.testing import CliRunner

    import snnkart.app.train
    from snnkart.cli import app
    from snnkart.errors import RunError

    def user_error(*args: object, **kwargs: object) -> int:
        raise RunError("the run directory is in use")

    monkeypatch.setattr(snnkart.app.train, "run_training", user_error)
    result = CliRunner().invoke(app, ["train", "--out", str(tmp_path / "a")])
    assert result.exit_code == 2 and "error: the run directory is in use" in result.output

    def bug(*args: object, **kwargs: object) -> int:
        raise RuntimeError("an internal bug")

    monkeypatch.setattr(snnkart.app.train, "run_training", bug)
    result = CliRunner().invoke(app, ["train", "--out", str(tmp_path / "b")])
    assert isinstance(result.exception, RuntimeError) and "error:" not in result.output


def test_demo_exits_4_on_a_parity_mismatch(monkeypatch) -> None:
    from typer.testing import CliRunner

    import snnkart.app.pipeline
    from snnkart.cli import app
    from snnkart.errors import ParityError

    def mismatch(*args: object, **kwargs: object) -> None:
        raise ParityError("lava-sim differs from the fixed reference at env step 7", {})

    monkeypatch.setattr(snnkart.app.pipeline, "run_pipeline", mismatch)
    result = CliRunner().invoke(app, ["demo", "--steps", "10"])
    assert result.exit_code == 4, result.output
    assert "error: lava-sim differs" in result.output and result.exception is not None
    assert isinstance(result.exception, SystemExit)


def test_app_workflows_report_through_the_reporter_and_never_print(tmp_path: Path, capfd) -> None:
    """The app layer returns records and reports progress to its Reporter; it prints nothing
    (only the cli's ConsoleReporter writes to the terminal)."""
    from snnkart.app.evaluate import run_eval
    from snnkart.app.reporter import Silent

    fixture = Path(__file__).parent / "data" / "policies" / "grid-snn"
    reporter = Silent()
    record = run_eval(fixture, 1, 10_000, None, False, None, tmp_path / "eval.json", reporter)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert record.summary.episodes == 1 and (tmp_path / "eval.json").is_file()
    assert any("success" in m for m in reporter.messages)
    assert reporter.messages[-1] == f"results written to {tmp_path / 'eval.json'}"
