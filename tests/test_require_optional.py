"""``SNNKART_REQUIRE_OPTIONAL=1`` turns a skip for a missing optional part into a failure,
whether the test skips while it runs or its module skips at collection (as
``tests/test_launch_ray.py`` does without Ray): a small test directory with the suite's real
``conftest.py``, run by pytest in a subprocess."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
AT_COLLECTION = """
import pytest
pytest.importorskip("snnkart_no_such_module", reason="optional: the test extra is missing")

def test_never_collected():
    pass
"""
AT_RUN = """
import pytest

def test_skips_for_an_optional_part():
    pytest.skip("optional: the tool is missing")

def test_skips_for_another_reason():
    pytest.skip("not on this platform")

def test_runs():
    pass
"""


def _pytest(tmp_path: Path, require: str, *options: str) -> subprocess.CompletedProcess[str]:
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_at_collection.py").write_text(AT_COLLECTION)
    (tmp_path / "test_at_run.py").write_text(AT_RUN)
    env = {**os.environ, "SNNKART_REQUIRE_OPTIONAL": require}
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-rA", "-p", "no:cacheprovider", *options, str(tmp_path)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@pytest.mark.parametrize("require", ["0", ""])
def test_without_it_optional_parts_skip(tmp_path: Path, require: str) -> None:
    result = _pytest(tmp_path, require)
    assert result.returncode == 0, result.stdout
    assert "1 passed, 3 skipped" in result.stdout, result.stdout


def test_with_it_a_module_skipping_at_collection_fails(tmp_path: Path) -> None:
    result = _pytest(tmp_path, "1")
    assert result.returncode != 0, result.stdout
    assert "ERROR test_at_collection.py" in result.stdout, result.stdout
    assert (
        "SNNKART_REQUIRE_OPTIONAL=1 and test_at_collection.py skips at collection for a missing "
        "optional part: Skipped: optional: the test extra is missing"
    ) in result.stdout, result.stdout


def test_with_it_a_test_skipping_for_an_optional_part_fails(tmp_path: Path) -> None:
    result = _pytest(tmp_path, "1", "--continue-on-collection-errors")
    assert result.returncode == 1, result.stdout
    assert "1 failed, 1 passed, 1 skipped, 1 error" in result.stdout, result.stdout
    assert "FAILED test_at_run.py::test_skips_for_an_optional_part" in result.stdout
    assert (
        "SNNKART_REQUIRE_OPTIONAL=1 and a missing optional part: Skipped: optional: the tool is "
        "missing"
    ) in result.stdout, result.stdout
    assert "SKIPPED [1] test_at_run.py:8: not on this platform" in result.stdout, result.stdout
