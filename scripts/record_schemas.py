"""Write the JSON Schema of every record kind beside its module (``*.schema.json``, shipped in
the package), from the record dataclasses (:func:`snnkart.contract.records.json_schema`).

Run after changing a record (and bump its version: see :mod:`snnkart.contract.records`);
``tests/test_records.py`` fails while a shipped schema differs from its record.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from snnkart.app import launch
from snnkart.contract import deploy_record, eval_record
from snnkart.contract.records import json_schema
from snnkart.report import study_record

RECORDS = [
    (deploy_record.DeployRecord, deploy_record.SCHEMA_FILE),
    (eval_record.EvalRecord, eval_record.SCHEMA_FILE),
    (study_record.StudyRecord, study_record.SCHEMA_FILE),
    (launch.LaunchRecord, launch.SCHEMA_FILE),
]
"""Every record kind and its shipped schema (``tests/test_records.py`` lists them too)."""


def schema_text(record: type) -> str:
    return json.dumps(json_schema(record, record.KIND), indent=2) + "\n"  # type: ignore[attr-defined]


def main() -> int:
    for record, path in RECORDS:
        path.write_text(schema_text(record))
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
