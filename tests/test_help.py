"""Help a user can act on: ``--version``, and ``train --help`` shows an example and the
defaults it trains with when nothing is given."""

from __future__ import annotations

from typer.testing import CliRunner

from snnkart import __version__
from snnkart.cli import app
from snnkart.rl.config import load_config


def test_version() -> None:
    result = CliRunner().invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"snnkart {__version__}"


def test_train_help_shows_an_example_and_the_defaults() -> None:
    result = CliRunner().invoke(app, ["train", "--help"], env={"COLUMNS": "100"})
    assert result.exit_code == 0
    text = " ".join(result.output.replace("│", " ").split())
    assert "Examples: snnkart train --env grid --policy snn" in text
    cfg = load_config()  # what training with no options uses: the help must say the same
    for option, default in (("--env", cfg.env), ("--track", cfg.track), ("--policy", cfg.policy),
                            ("--seed", cfg.seed), ("--action-mode", cfg.action_mode)):  # fmt: skip
        after = text[text.index(option) :]  # the first default after the option is its own
        own = after[after.index("[default:") :]
        assert own.startswith(f"[default: ({default})]"), (option, own[:80])
    assert f"{cfg.total_steps}" in text
