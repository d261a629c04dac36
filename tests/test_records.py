"""The record files (``deploy.json``, ``eval.json``, ``study.json``, ``launch.json``) as typed
records: files written by today's snnkart load and write back byte for byte, round-trip
through a file with every field equal, validate against the schema shipped in the package,
and follow the one versioning rule of :mod:`snnkart.contract.records`.

``tests/data/records/`` holds files written by the snnkart before the records were typed
(commit c415580): ``snnkart deploy`` of the committed NIR export on nir-ref (fixed, 2 episodes;
float32, 1 episode) and on lava-sim fixed on another track (big_S, 1 episode), and
``snnkart eval`` of the committed grid SNN (2 episodes), and ``snnkart study`` of a tiny
study (grid, ANN and SNN, seeds 1 and 2, 384 steps, 1 episode on Lava: its ``study.json``,
``study.md`` and ``runs/launch.json``); absolute paths were made relative.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from snnkart.app import launch
from snnkart.app.launch import LaunchRecord
from snnkart.contract import deploy_record, eval_record
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord
from snnkart.contract.records import Record, RecordError, RecordKind, json_schema, to_data
from snnkart.report import study_record
from snnkart.report.study_record import StudyRecord

DATA = Path(__file__).parent / "data" / "records"
FILES = [
    (DeployRecord, DATA / "deploy-nir-ref-fixed.json"),
    (DeployRecord, DATA / "deploy-nir-ref-float32.json"),
    (DeployRecord, DATA / "deploy-lava-sim-fixed-big_S.json"),
    (EvalRecord, DATA / "eval.json"),
    (StudyRecord, DATA / "study.json"),
    (LaunchRecord, DATA / "launch.json"),
]
TAGGED = [(cls, path) for cls, path in dict(FILES).items() if cls.KIND.untagged is None]
"""A file of each kind with a ``schema`` tag (``launch.json`` v1 has none)."""
WRONG_TYPE = {  # a field of each kind, and a value of the wrong type for it
    DeployRecord: ("summary", "episodes", "two"),
    EvalRecord: ("summary", "crashes", 1.5),
    StudyRecord: ("wall_clock", "runs", None),
    LaunchRecord: ("runs", 0, {"name": 1}),
}
SCHEMA_FILES: dict[type[Record], Path] = {
    DeployRecord: deploy_record.SCHEMA_FILE,
    EvalRecord: eval_record.SCHEMA_FILE,
    StudyRecord: study_record.SCHEMA_FILE,
    LaunchRecord: launch.SCHEMA_FILE,
}
KINDS = list(SCHEMA_FILES)


def _id(case: Any) -> str:
    return case.name if isinstance(case, Path) else case.__name__


def assert_same_fields(a: Any, b: Any, where: str = "") -> None:
    """Every field of two records equal, naming the first that is not."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_same_fields(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), f"{where}: {len(a)} != {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same_fields(x, y, f"{where}[{i}]")
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


@pytest.mark.parametrize(("cls", "path"), FILES, ids=_id)
def test_a_file_of_today_loads_and_writes_back_byte_for_byte(cls: type[Record], path: Path,
                                                              tmp_path: Path) -> None:  # fmt: skip
    text = path.read_text()
    record = cls.read(path)
    assert record.to_json() == text
    record.write(tmp_path / path.name)  # the round trip through a file: every field equal
    assert (tmp_path / path.name).read_text() == text
    assert_same_fields(cls.read(tmp_path / path.name), record)


@pytest.mark.parametrize(("cls", "path"), FILES, ids=_id)
def test_a_file_of_today_validates_against_the_shipped_schema(cls: type[Record],
                                                              path: Path) -> None:  # fmt: skip
    schema = _schema(cls)
    data = json.loads(path.read_text())
    jsonschema.validate(data, schema)
    first = schema["required"][-1]
    for name, broken in {
        "newer": {**data, "schema": cls.KIND.tag_of(cls.KIND.version + 1)},
        "wrong type": _wrong_type(cls, data),
        "missing": {k: v for k, v in data.items() if k != first},
        "unknown key": {**data, "extra": 1},
    }.items():
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, schema)
            pytest.fail(f"{name}: valid")


def _wrong_type(cls: type[Record], data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with one nested value of the wrong type (:data:`WRONG_TYPE`)."""
    outer, inner, value = WRONG_TYPE[cls]
    broken = json.loads(json.dumps(data))
    broken[outer][inner] = value
    return broken  # type: ignore[no-any-return]


def _schema(cls: type[Record]) -> dict[str, Any]:
    return json.loads(SCHEMA_FILES[cls].read_text())  # type: ignore[no-any-return]


@pytest.mark.parametrize("cls", KINDS, ids=_id)
def test_the_shipped_schema_is_the_records(cls: type[Record]) -> None:
    assert _schema(cls) == json_schema(cls, cls.KIND), (
        "run scripts/record_schemas.py to write the schema of the changed record"
    )


@pytest.mark.parametrize(("cls", "path"), TAGGED, ids=_id)
def test_a_file_of_another_kind_or_a_newer_version_is_refused(cls: type[Record], path: Path,
                                                              tmp_path: Path) -> None:  # fmt: skip
    data = json.loads(path.read_text())
    kind = cls.KIND
    cases = {
        "newer": ({**data, "schema": kind.tag_of(kind.version + 1)},
                  f"written by a newer snnkart ({kind.tag_of(kind.version + 1)}; this one reads "
                  f"up to {kind.tag}); upgrade snnkart to read it"),
        "other": ({**data, "schema": "snnkart/other/v1"},
                  f"not a {kind.name} record (schema 'snnkart/other/v1', expected {kind.tag!r})"),
        "untagged": ({k: v for k, v in data.items() if k != "schema"},
                     f"not a {kind.name} record (schema None"),
        "unknown key": ({**data, "extra": 1}, f"extra is an unknown key in a {data['schema']} record"),
        "wrong type": (_wrong_type(cls, data), f"{WRONG_TYPE[cls][0]}.{WRONG_TYPE[cls][1]} is "
                       f"{WRONG_TYPE[cls][2]!r}, not "),
    }  # fmt: skip
    for name, (broken, message) in cases.items():
        bad = tmp_path / f"{name}.json"
        bad.write_text(json.dumps(broken))
        with pytest.raises(RecordError) as caught:
            cls.read(bad)
        assert str(caught.value).startswith(f"{bad}: "), name
        assert message in str(caught.value), (name, str(caught.value))


def test_an_older_deploy_file_without_a_field_it_needs_is_refused_in_one_line(
    tmp_path: Path,
) -> None:
    data = json.loads(FILES[0][1].read_text())
    del data["network"]  # deployments before the network description was recorded
    data["schema"] = "snnkart/deploy/v1"
    old = tmp_path / "deploy.json"
    old.write_text(json.dumps(data))
    with pytest.raises(RecordError) as caught:
        DeployRecord.read(old)
    assert str(caught.value) == (
        f"{old}: written by an older snnkart (snnkart/deploy/v1); run `snnkart deploy` again"
    )
    data = json.loads((DATA / "eval.json").read_text())
    del data["first_seed"]
    old.write_text(json.dumps(data))
    with pytest.raises(RecordError, match=r"run `snnkart eval` again$"):
        EvalRecord.read(old)


def test_an_older_deploy_file_without_later_fields_loads_with_their_defaults(
    tmp_path: Path,
) -> None:
    """Early v1 deployments named only the env and track, had no population, readout flags,
    pipeline counts or per-episode list: the energy report read them, so they still load."""
    data = json.loads(FILES[0][1].read_text())
    data["env"] = {"env": "grid", "track": "small_S"}
    del data["manifest"]["population"], data["network"]["readout"], data["episodes"]
    del data["counts"]["pipeline_overhead"], data["parity"]["float32_spike_flips"]
    old = tmp_path / "deploy.json"
    old.write_text(json.dumps(data))
    record = DeployRecord.read(old)
    assert record.env.track_label is None and record.env.track_override is None
    assert record.manifest.population is None and record.network.readout is True
    assert record.episodes == [] and record.counts.pipeline_overhead is None
    assert record.parity.float32_spike_flips is None
    record.write(tmp_path / "again.json")  # written again: with the defaults, and equal
    assert_same_fields(DeployRecord.read(tmp_path / "again.json"), record)


# The rule on a kind of its own: v1 had one field, v2 added ``speed`` with a default.
TOY = RecordKind("toy", 2, rerun="snnkart toy")


@dataclass(frozen=True)
class Toy(Record):
    KIND = TOY

    schema: str
    name: str
    speed: float = 1.0
    tags: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class StrictToy(Toy):
    KIND = dataclasses.replace(TOY, loads_from=2)


def test_the_versioning_rule_on_a_kind_of_its_own(tmp_path: Path) -> None:
    v1 = tmp_path / "toy.json"
    v1.write_text(json.dumps({"schema": "snnkart/toy/v1", "name": "a"}))
    assert Toy.read(v1) == Toy("snnkart/toy/v1", "a", 1.0, [])  # an older file: defaults
    with pytest.raises(RecordError) as caught:  # a kind that no longer loads v1
        StrictToy.read(v1)
    assert str(caught.value) == (
        f"{v1}: written by an older snnkart (snnkart/toy/v1); run `snnkart toy` again"
    )
    v3 = tmp_path / "toy3.json"
    v3.write_text(json.dumps({"schema": "snnkart/toy/v3", "name": "a"}))
    with pytest.raises(RecordError, match="written by a newer snnkart"):
        Toy.read(v3)
    now = Toy(TOY.tag, "b", 2.5, ["x"])
    now.write(tmp_path / "now.json")
    assert Toy.read(tmp_path / "now.json") == now
    assert to_data(now) == {"schema": "snnkart/toy/v2", "name": "b", "speed": 2.5, "tags": ["x"]}
    with pytest.raises(RecordError, match="not valid JSON"):
        (tmp_path / "bad.json").write_text("{")
        Toy.read(tmp_path / "bad.json")
    with pytest.raises(RecordError, match="cannot read"):
        Toy.read(tmp_path / "missing.json")


SUMMARY_LINES = {
    "deploy-nir-ref-fixed.json": [
        "nir-ref (fixed) on grid/small_S, 2 episodes: success 100%, return 20.15, crashes 0, "
        "time-outs 0",
        "agreement with the float32 policy (torch order): 99.43% identical actions, 2932 spike "
        "flips per million neuron-steps",
        "per env step (policy): spikes layer 1: 142.3, layer 2: 167.8; synops layer 1: 9109, layer 2: 839",
        "pipeline overhead per env step (fill/drain, not the policy): spikes layer 1: 0.00, layer 2: 0.54; "
        "neuron updates layer 1: 64, layer 2: 64",
        "0.7 ms per env step, start-up 0.0 s",
    ],
    "deploy-lava-sim-fixed-big_S.json": [
        "lava-sim (fixed) on grid/big_S, 1 episodes: success 0%, return -0.99, crashes 1, "
        "time-outs 0",
        "note: track big_S is not the track the policy was trained on (small_S)",
        "parity vs numpy reference (fixed, same arithmetic): 0 of 34 env steps differ (spike "
        "rasters), 0 actions differ",
        "agreement with the float32 policy (torch order): 100.00% identical actions, 2729 spike "
        "flips per million neuron-steps",
        "per env step (policy): spikes layer 1: 187.9, layer 2: 187.6; synops layer 1: 12028, layer 2: 938",
        "pipeline overhead per env step (fill/drain, not the policy): spikes layer 1: 0.00, layer 2: 0.44; "
        "neuron updates layer 1: 64, layer 2: 64",
        "7.5 ms per env step, start-up 1.1 s",
    ],
}


@pytest.mark.parametrize("name", list(SUMMARY_LINES))
def test_deploy_prints_what_it_printed_from_a_dict(name: str) -> None:
    """The lines ``snnkart deploy`` prints, from the typed record, are what the code before it
    printed from the same file (recorded with that code)."""
    from snnkart.eval.closed_loop import summary_lines

    assert summary_lines(DeployRecord.read(DATA / name)) == SUMMARY_LINES[name]


def test_an_untagged_launch_file_is_v1_and_a_tagged_newer_one_is_refused(tmp_path: Path) -> None:
    data = json.loads((DATA / "launch.json").read_text())
    assert "schema" not in data and LaunchRecord.KIND.untagged == 1
    assert [r.name for r in LaunchRecord.read(DATA / "launch.json").runs] == [
        "small_S-grid-ann-s1", "small_S-grid-ann-s2", "small_S-grid-snn-s1", "small_S-grid-snn-s2"]  # fmt: skip
    newer = tmp_path / "launch.json"
    newer.write_text(json.dumps({"schema": "snnkart/launch/v2", **data}))
    with pytest.raises(RecordError, match=r"written by a newer snnkart \(snnkart/launch/v2"):
        LaunchRecord.read(newer)
    ray = LaunchRecord(backend="ray", interrupted=True, runs=[])
    assert ray.to_json() == '{\n  "backend": "ray",\n  "interrupted": true,\n  "runs": []\n}\n'


def test_study_md_from_the_typed_record_is_what_it_was() -> None:
    """``study.md`` rendered from the typed record equals the one the code before it wrote
    from the same study (recorded with that code)."""
    from snnkart.app.study_summary import ORIGINAL
    from snnkart.report.study_document import markdown

    record = StudyRecord.read(DATA / "study.json")
    assert markdown(record, ORIGINAL) == (DATA / "study.md").read_text()
    assert len(record.deployed) == 1 and {c.policy for c in record.cells} == {"ann", "snn"}


def test_dict_annotations_are_counted_with_aliases_resolved(tmp_path: Path) -> None:
    """``scripts/dict_annotations.py``: str-to-Any mappings in parameters, returns, variables
    and fields, through module-level aliases (also aliases of aliases) and string annotations;
    other mappings are not counted."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "dict_annotations", Path(__file__).parents[1] / "scripts" / "dict_annotations.py"
    )
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import Any, Dict, Mapping, TypeAlias\n"
        "import typing\n"
        "Record = dict[str, Any]\n"
        "Again: TypeAlias = 'Record'\n"
        "Counts = dict[str, int]\n"
        "def f(a: Record, b: Counts, c: 'Mapping[str, Any]') -> list[Again] | None: ...\n"
        "def g(d: typing.Dict[str, typing.Any], e: dict[str, list[Any]]) -> Dict[int, Any]: ...\n"
        "class C:\n"
        "    x: dict[str, Any] | None = None\n"
        "    y: Mapping[str, str] = {}\n"
        "    z: list['dict[str, Any]'] = []\n"
    )  # counted: a, c, f's return, d, x, z (not b, e, g's return, y)
    assert script.count(module) == 6


def test_a_v1_study_loads_without_the_v2_keys() -> None:
    """``study.json`` v1 (before the data kind and the counts per env step) still loads, the
    new keys taking their defaults; v2 added exactly those keys to a run."""
    old = DATA / "study-v1.json"
    record = StudyRecord.read(old)
    assert json.loads(old.read_text())["schema"] == "snnkart/study/v1"
    assert record.study.data is None
    assert all(r.eval_counts_per_step is None and r.eval_mean_lap_time is None
               for r in record.runs)  # fmt: skip
    assert all(c.eval_synops_per_step is None for c in record.cells)
    current = json.loads((DATA / "study.json").read_text())
    assert current["schema"] == "snnkart/study/v4"  # what today's snnkart writes
    assert set(current["runs"][0]) - set(json.loads(old.read_text())["runs"][0]) == {
        "eval_mean_lap_time", "eval_counts_per_step"}  # fmt: skip


def test_a_v2_study_loads_without_sigma_delta_counts() -> None:
    """``study.json`` v2 (before sigma-delta runs) still loads, every run without
    ``sigma_delta_counts``; v3 writes that key only for a run that has it."""
    old = DATA / "study-v2.json"
    assert json.loads(old.read_text())["schema"] == "snnkart/study/v2"
    record = StudyRecord.read(old)
    assert record.runs and all(r.sigma_delta_counts is None for r in record.runs)
    assert "sigma_delta_counts" not in to_data(record)["runs"][0]


def test_a_v3_study_loads_without_held_out_tracks() -> None:
    """``study.json`` v3 (before held-out tracks) still loads: no ``eval_tracks``, no run
    ``held_out``; v4 added exactly the two study keys (a run's ``held_out`` is written only
    when the study has held-out tracks)."""
    old = DATA / "study-v3.json"
    assert json.loads(old.read_text())["schema"] == "snnkart/study/v3"
    record = StudyRecord.read(old)
    assert record.study.eval_tracks == [] and all(r.held_out is None for r in record.runs)
    current = json.loads((DATA / "study.json").read_text())
    assert set(current["study"]) - set(json.loads(old.read_text())["study"]) == {
        "eval_tracks", "eval_track_episodes"}  # fmt: skip
    assert "held_out" not in to_data(record)["runs"][0]
