"""The Python API: ``import snnkart`` imports no torch, its functions are typed and listed in
``__all__``, and the README's example runs exactly as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARKER = "<!-- python-api-example"


def readme_example() -> str:
    text = (ROOT / "README.md").read_text()
    after = text[text.index(MARKER) :]
    match = re.search(r"```python\n(.*?)```", after, re.S)
    assert match is not None, "no python block after the API example marker"
    return match.group(1)


def test_importing_snnkart_imports_no_torch_until_a_function_runs() -> None:
    code = (
        "import sys, snnkart\n"
        "assert 'torch' not in sys.modules\n"
        "f = snnkart.load_policy, snnkart.train, snnkart.evaluate\n"
        "assert 'torch' not in sys.modules, 'looking a function up imported torch'\n"
        "assert set(snnkart.__all__) >= {'load_policy', 'train', 'evaluate', 'make'}\n"
        "assert snnkart.load_policy.__doc__ and snnkart.load_policy.__annotations__\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)  # fmt: skip
    assert result.returncode == 0, result.stderr


def test_an_unknown_name_is_an_attribute_error() -> None:
    import snnkart

    with pytest.raises(AttributeError, match="no attribute 'load_polcy'"):
        snnkart.load_polcy  # noqa: B018


def test_bad_input_is_one_clear_error(tmp_path: Path) -> None:
    import snnkart
    from snnkart.errors import UsageError

    with pytest.raises(UsageError, match="does not exist"):
        snnkart.load_policy(tmp_path / "nothing")
    with pytest.raises(UsageError, match="unknown backend 'loihi'"):
        snnkart.load_policy(tmp_path, backend="loihi")


@pytest.mark.timeout(300)
def test_the_readme_example_runs_as_written(tmp_path: Path) -> None:
    script = tmp_path / "example.py"
    script.write_text(readme_example())
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                            text=True, timeout=280)  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    assert re.fullmatch(r"torch policy: success \d+%\n", result.stdout), result.stdout
    assert (tmp_path / "runs/api-grid-snn/checkpoint.pt").is_file()
