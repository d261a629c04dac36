"""Record the golden outputs (``tests/golden/expected.json``) that ``tests/test_golden.py``
holds every later change to.

    .venv/bin/python scripts/record_golden.py

Re-record only in a commit of its own, for a change that must move the values (a faster
optimiser, new dependency versions), with the evidence that learning is unchanged.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from golden.harness import EXPECTED, produce  # noqa: E402


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="golden-") as tmp:
        values = produce(Path(tmp))
    EXPECTED.write_text(json.dumps(values, indent=1, sort_keys=True) + "\n")
    print(f"golden values written to {EXPECTED.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
