"""The README's "Your own env" lines run as written (with a tiny budget added to train), on a
module of the user's own in the current directory that registers ``MyEnv-v0`` when imported."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from snnkart.cli.main import app

ROOT = Path(__file__).resolve().parents[1]
USER_MODULE = '''
import gymnasium as gym
import numpy as np
from gymnasium import spaces


class MyEnv(gym.Env):
    """Walk to the end of a corridor of ``size`` cells: left or right."""

    def __init__(self, size=4):
        self.size = size
        self.observation_space = spaces.Discrete(size)
        self.action_space = spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        self.cell = 0
        return self.cell, {}

    def step(self, action):
        self.cell = int(np.clip(self.cell + (1 if action == 1 else -1), 0, self.size - 1))
        done = self.cell == self.size - 1
        return self.cell, float(done) - 0.01, done, False, {}


gym.register(id="MyEnv-v0", entry_point=MyEnv, max_episode_steps=30)
'''
TINY = ["--steps", "256", "--set", "ppo.num_envs=2", "--set", "ppo.rollout_steps=64"]


def _commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    section = text.split("### Your own env", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, re.DOTALL)
    assert block is not None
    lines = []
    for line in block.group(1).splitlines():
        for command in line.split("&&"):
            words = shlex.split(command)
            assert words[0] == ".venv/bin/snnkart"
            lines.append(words[1:])
    return lines


@pytest.mark.timeout(600)
def test_the_readme_own_env_lines_run_as_written(tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("lava", reason="optional: lava-nc (the lava extra)")
    (tmp_path / "my_envs.py").write_text(USER_MODULE)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(__import__("sys").modules, "my_envs", raising=False)
    commands = _commands()
    assert [c[0] for c in commands] == ["train", "export", "eval", "deploy"]
    runner = CliRunner()
    for words in commands:
        args = [*words, *TINY] if words[0] == "train" else words
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (words, result.output)
    assert "0 of" in result.output and "env steps differ" in result.output  # deploy's parity
    assert (tmp_path / "runs/my-snn/policy.nir").is_file()
