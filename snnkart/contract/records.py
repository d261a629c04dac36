"""Records: the JSON files one command writes and a later one reads (``deploy.json``,
``eval.json``, ``study.json``, ``launch.json``), as dataclasses, and the one rule for their
versions, written once here.

The rule, for every record kind (:class:`RecordKind`):

- a file carries its kind and version in ``"schema": "snnkart/<kind>/vN"``;
- a new field bumps N (and ``tests/golden`` is re-recorded in a commit of its own whose diff
  shows only the new keys);
- a file of an older version either loads, its missing fields taking their defaults (a field
  added later has one), or is refused with ``<path>: written by an older snnkart (<tag>); run
  `<command>` again``, the command being the kind's own (``snnkart deploy``, ...);
- a file of an unknown kind, or of a newer version than this snnkart writes, is refused.

A record converts to and from JSON through one generic path (:func:`to_data`,
:func:`from_data`) driven by its fields' types: nested dataclasses, ``list``/``tuple``,
``dict[str, X]``, ``X | None`` and JSON scalars. Field metadata: ``omit_none`` leaves a key
out of the file when it is None (as the files always did), ``omit_if`` a key only some records
carry, and ``key`` names a field whose JSON key is not a Python name. Keys come out in field
order, so a record written through its dataclass is byte for byte the file it replaced.
:func:`json_schema` gives the JSON Schema shipped beside each kind (``*.schema.json``).
"""

from __future__ import annotations

import dataclasses
import json
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from snnkart.errors import SnnkartError
from snnkart.io import write_json

R = TypeVar("R")

OMIT_NONE = {"omit_none": True}
"""Field metadata: leave the key out of the file when the value is None."""


def key(name: str, omit_none: bool = False) -> dict[str, object]:
    """Field metadata: the field's JSON key is ``name`` (e.g. ``return``, not a Python name)."""
    return {"key": name, "omit_none": omit_none}


def omit_if(test: typing.Callable[[Any], bool]) -> dict[str, object]:
    """Field metadata: leave the key out of the file when ``test(record)`` holds (a key only
    some records of a kind carry, e.g. only an SNN cell's comparison with its ANN)."""
    return {"omit_if": test}


class RecordError(SnnkartError, ValueError):
    """A record file is missing, malformed, of another kind, or of a version this snnkart does
    not read; the message names the file and what to do."""


@dataclass(frozen=True)
class RecordKind:
    """One kind of record file: its name, the version written now, the command that writes it
    (``rerun``, named in the error an old file gets), the oldest version that still loads, and
    (for a kind whose first files carried no tag) the version an untagged file is."""

    name: str
    version: int
    rerun: str
    loads_from: int = 1
    untagged: int | None = None

    @property
    def tag(self) -> str:
        """``snnkart/<name>/v<version>``: what this snnkart writes."""
        return self.tag_of(self.version)

    def tag_of(self, version: int) -> str:
        return f"snnkart/{self.name}/v{version}"

    def older(self, source: str, version: int) -> RecordError:
        """The one-line error for a file an older snnkart wrote that cannot load."""
        return RecordError(
            f"{source}: written by an older snnkart ({self.tag_of(version)}); "
            f"run `{self.rerun}` again"
        )

    def version_of(self, data: object, source: str) -> int:
        """The version of the record ``data`` (a file's parsed JSON), if this snnkart reads it."""
        if not isinstance(data, dict):
            raise RecordError(f"{source}: not a {self.name} record (a JSON {type(data).__name__})")
        tag = data.get("schema")
        if tag is None and self.untagged is not None:
            return self.untagged
        match = re.fullmatch(rf"snnkart/{re.escape(self.name)}/v([0-9]+)", str(tag))
        if match is None:
            raise RecordError(
                f"{source}: not a {self.name} record (schema {tag!r}, expected {self.tag!r})"
            )
        version = int(match[1])
        if version > self.version:
            raise RecordError(
                f"{source}: written by a newer snnkart ({tag}; this one reads up to "
                f"{self.tag}); upgrade snnkart to read it"
            )
        if version < self.loads_from:
            raise self.older(source, version)
        return version


def to_data(record: Any) -> Any:
    """A record (or any value inside one) as JSON-able data, keys in field order."""
    if dataclasses.is_dataclass(record) and not isinstance(record, type):
        out: dict[str, object] = {}
        for f in dataclasses.fields(record):
            value = getattr(record, f.name)
            test = f.metadata.get("omit_if")
            if (value is None and f.metadata.get("omit_none")) or (test and test(record)):
                continue
            out[f.metadata.get("key", f.name)] = to_data(value)
        return out
    if isinstance(record, (list, tuple)):
        return [to_data(v) for v in record]
    if isinstance(record, dict):
        return {k: to_data(v) for k, v in record.items()}
    return record


@dataclass(frozen=True)
class Reading:
    """Where a record is read from: its kind, its file (for errors) and its version."""

    kind: RecordKind
    source: str
    version: int

    def error(self, where: str, problem: str) -> RecordError:
        return RecordError(
            f"{self.source}: {where.rstrip('.') or 'the record'} {problem} in a "
            f"{self.kind.tag_of(self.version)} record"
        )


def from_data(cls: type[R], data: object, reading: Reading, where: str = "") -> R:
    """The record of type ``cls`` in ``data``. A missing field without a default means an older
    snnkart wrote the file (:meth:`RecordKind.older`); an unknown key or a wrong type is
    refused (a file this snnkart did not write)."""
    if not isinstance(data, dict):
        raise reading.error(where, "is not an object")
    hints = typing.get_type_hints(cls)
    fields = {f.metadata.get("key", f.name): f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = [k for k in data if k not in fields]
    if unknown:
        raise reading.error(f"{where}{unknown[0]}", "is an unknown key")
    values = {}
    for name, f in fields.items():
        if name in data:
            values[f.name] = _convert(hints[f.name], data[name], reading, f"{where}{name}.")
        elif f.metadata.get("omit_none") or f.metadata.get("omit_if"):
            values[f.name] = None  # a key left out when None (or for some records): None
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise reading.kind.older(reading.source, reading.version)
    return cls(**values)


def _convert(tp: Any, value: object, reading: Reading, where: str) -> Any:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any:
        return value
    if dataclasses.is_dataclass(tp):
        return from_data(tp, value, reading, where)  # type: ignore[arg-type]
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        rest = [a for a in args if a is not type(None)]
        for arg in rest[:-1]:
            try:
                return _convert(arg, value, reading, where)
            except RecordError:
                pass
        return _convert(rest[-1], value, reading, where)
    if origin in (list, tuple) and isinstance(value, list):
        items = [_convert(args[0], v, reading, f"{where}{i}.") for i, v in enumerate(value)]
        return items if origin is list else tuple(items)
    if origin is dict and isinstance(value, dict):
        return {k: _convert(args[1], v, reading, f"{where}{k}.") for k, v in value.items()}
    plain = {float: (int, float), int: (int,), str: (str,), bool: (bool,)}
    if tp in plain and isinstance(value, plain[tp]) and (tp is bool or not isinstance(value, bool)):
        return value
    raise reading.error(where, f"is {value!r:.40}, not {getattr(tp, '__name__', tp)},")


RecordT = TypeVar("RecordT", bound="Record")


class Record:
    """What every record class shares: ``KIND`` (a :class:`RecordKind`), conversion to and
    from JSON, and writing and reading a file. Subclasses are dataclasses whose first field is
    ``schema`` (unless the kind's first files were untagged: see :attr:`RecordKind.untagged`)."""

    KIND: typing.ClassVar[RecordKind]

    def to_json(self) -> str:
        return json.dumps(to_data(self), indent=2) + "\n"

    @classmethod
    def from_json(cls: type[RecordT], text: str, source: str = "record") -> RecordT:
        kind = cls.KIND
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise RecordError(
                f"{source}: not valid JSON ({exc}); run `{kind.rerun}` again"
            ) from exc
        return from_data(cls, data, Reading(kind, source, kind.version_of(data, source)))

    def write(self, path: Path) -> None:
        """Write the record to ``path`` atomically (as :func:`snnkart.io.write_json` does)."""
        write_json(path, to_data(self))

    @classmethod
    def read(cls: type[RecordT], path: Path) -> RecordT:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise RecordError(
                f"cannot read {path}: {exc.strerror or exc}; run `{cls.KIND.rerun}` first"
            ) from exc
        return cls.from_json(text, str(path))


def json_schema(cls: type, kind: RecordKind | None = None) -> dict[str, object]:
    """The JSON Schema (draft 2020-12) of a record class, as shipped in ``*.schema.json``."""
    body = _schema(cls)
    if kind is None:
        return body
    properties = body["properties"]
    if isinstance(properties, dict) and "schema" in properties:
        properties["schema"] = {"const": kind.tag}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": kind.tag,
        "title": f"snnkart {kind.name} record ({kind.name}.json)",
        **body,
    }


def _schema(tp: Any) -> dict[str, object]:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any:
        return {}
    if dataclasses.is_dataclass(tp):
        hints = typing.get_type_hints(tp)
        props, required = {}, []
        for f in dataclasses.fields(tp):
            name = f.metadata.get("key", f.name)
            props[name] = _schema(hints[f.name])
            no_default = (
                f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
            )
            if no_default and not (f.metadata.get("omit_none") or f.metadata.get("omit_if")):
                required.append(name)
        doc = " ".join((tp.__doc__ or "").split())
        auto = doc.startswith(f"{getattr(tp, '__name__', '')}(")  # dataclass's own
        described = {"description": doc} if doc and not auto else {}
        return {
            **described,
            "type": "object",
            "properties": props,
            "required": required,
            "additionalProperties": False,
        }
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [_schema(a) for a in args]}
    if origin in (list, tuple):
        return {"type": "array", "items": _schema(args[0])}
    if origin is dict:
        return {"type": "object", "additionalProperties": _schema(args[1])}
    simple = {float: "number", int: "integer", str: "string", bool: "boolean", type(None): "null"}
    return {"type": simple[tp]}
