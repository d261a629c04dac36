"""The suite's ``--dist loadgroup`` keeps each ``xdist_group`` on one worker (tests/conftest.py
sets the group where pytest 9 reads a node's id): the costly module fixtures of the energy,
study-sweep and Ray modules are built once, not on every worker."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

CONFTEST = Path(__file__).with_name("conftest.py")


@pytest.mark.timeout(120)
def test_a_group_runs_on_one_worker(tmp_path: Path) -> None:
    shutil.copy(CONFTEST, tmp_path / "conftest.py")
    (tmp_path / "test_grouped.py").write_text(
        "import os, pytest\n"
        'pytestmark = pytest.mark.xdist_group("g")\n'
        '@pytest.mark.parametrize("i", range(8))\n'
        "def test_it(i, request):\n"
        '    with open(os.path.join(os.path.dirname(__file__), "who.txt"), "a") as f:\n'
        "        f.write(os.environ['PYTEST_XDIST_WORKER'] + ' ' + request.node.nodeid + '\\n')\n"
    )
    (tmp_path / "test_free.py").write_text("def test_a():\n    pass\n\ndef test_b():\n    pass\n")
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2", "--dist",
         "loadgroup", str(tmp_path)],
        cwd=tmp_path, capture_output=True, text=True, timeout=100,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    rows = [line.split() for line in (tmp_path / "who.txt").read_text().splitlines()]
    assert len(rows) == 8 and all(nodeid.endswith("@g") for _, nodeid in rows), rows
    assert len({worker for worker, _ in rows}) == 1, rows
