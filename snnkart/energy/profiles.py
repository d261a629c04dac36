"""Hardware profiles: per-operation energy prices, each with its source, a low-high range and a
tag saying what kind of number it is.

A profile is a TOML file (the built-in ones are package data in ``snnkart/energy/builtin/``,
linked from the repository's ``hardware/``; a user passes their own by path)::

    schema = "snnkart.hardware/1"
    name = "loihi1"
    title = "Intel Loihi 1 (Davies et al. 2018)"
    kind = "neuromorphic"            # prices synaptic_op, neuron_update, spike
    technology = "Intel 14 nm FinFET, 0.75 V"
    notes = "what the figures include and leave out"

    [prices.synaptic_op]
    value = 23.6                     # the central value
    low = 23.6                       # the range the sensitivity analysis moves it across
    high = 27.1
    unit = "pJ"                      # fJ, pJ, nJ or uJ
    tag = "pre-silicon"              # measured, pre-silicon, derived or assumed
    source = "Davies et al. 2018, Table 2 ..."

A ``digital`` profile prices ``mac``, ``add``, ``mult`` and ``weight_read`` (one read of one
weight from memory; 0 in compute-only profiles).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from snnkart.errors import ProfileError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PROFILE_SCHEMA = "snnkart.hardware/1"
UNITS = {"fJ": 1e-3, "pJ": 1.0, "nJ": 1e3, "uJ": 1e6}
"""Energy units a profile may use, in pJ."""
TAGS = ("measured", "pre-silicon", "derived", "assumed")
PRICES = {
    "neuromorphic": ("synaptic_op", "neuron_update", "spike"),
    "digital": ("mac", "add", "mult", "weight_read"),
}
"""The operations each kind of profile prices."""
BUILTIN = (
    "loihi1", "loihi2", "spinnaker2", "spinnaker1", "truenorth",
    "horowitz45_fp32", "horowitz45_int8", "horowitz45_fp32_sram",
)  # fmt: skip
DEFAULT_CHIPS = ("loihi1", "loihi2", "spinnaker2", "spinnaker1", "truenorth")
DEFAULT_DIGITAL = ("horowitz45_fp32", "horowitz45_int8", "horowitz45_fp32_sram")
DEFAULT_HOST = "horowitz45_fp32"
"""The digital profile that prices the SNN's host-side work unless another is chosen."""

_TOP_KEYS = {"schema", "name", "title", "kind", "technology", "notes", "prices"}
_PRICE_KEYS = {"value", "low", "high", "unit", "tag", "source"}


@dataclass(frozen=True)
class Price:
    """One operation's energy in pJ (converted from the file's unit), with its range and
    provenance."""

    value: float
    low: float
    high: float
    unit: str  # as written in the file
    tag: str
    source: str

    def as_dict(self) -> dict[str, Any]:
        return {"pj": self.value, "low_pj": self.low, "high_pj": self.high,
                "unit_in_file": self.unit, "tag": self.tag, "source": self.source}  # fmt: skip


@dataclass(frozen=True)
class Profile:
    name: str
    title: str
    kind: str
    technology: str
    notes: str
    prices: dict[str, Price]
    path: str  # where it was read from

    def __getitem__(self, op: str) -> float:
        return self.prices[op].value

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name, "title": self.title, "kind": self.kind,
            "technology": self.technology, "notes": self.notes, "file": self.path,
            "prices": {op: p.as_dict() for op, p in self.prices.items()},
        }  # fmt: skip


def load_profile(name_or_path: str | Path) -> Profile:
    """A built-in profile by name, or a profile file by path."""
    text = str(name_or_path)
    if text in BUILTIN:
        ref = resources.files("snnkart.energy.builtin").joinpath(f"{text}.toml")
        return parse_profile(ref.read_text("utf-8"), f"built-in profile {text!r}")
    path = Path(text).expanduser()
    if not path.is_file():
        raise ProfileError(
            f"profile {text!r} is neither a built-in profile ({', '.join(BUILTIN)}) nor an "
            "existing file; check the name or the path"
        )
    return parse_profile(path.read_text("utf-8"), str(path))


def parse_profile(text: str, source: str) -> Profile:
    """Parse and check a profile's TOML; every problem names the file, the key and the fix."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{source}: not valid TOML: {exc}") from exc
    unknown = sorted(set(raw) - _TOP_KEYS)
    if unknown:
        raise ProfileError(
            f"{source}: unknown key {unknown[0]!r}; a profile has {', '.join(sorted(_TOP_KEYS))}"
        )
    if raw.get("schema") != PROFILE_SCHEMA:
        raise ProfileError(
            f"{source}: schema must be {PROFILE_SCHEMA!r}, got {raw.get('schema')!r}"
        )
    for key in ("name", "title", "kind"):
        if not isinstance(raw.get(key), str) or not raw[key]:
            raise ProfileError(f'{source}: {key}: missing; add {key} = "..."')
    kind = raw["kind"]
    if kind not in PRICES:
        raise ProfileError(f"{source}: kind: {kind!r} is not one of {', '.join(PRICES)}")
    table = raw.get("prices")
    if not isinstance(table, dict):
        raise ProfileError(
            f"{source}: prices: missing; add a [prices.<operation>] table per operation"
        )
    prices = {op: _price(table.get(op), f"{source}: prices.{op}") for op in PRICES[kind]}
    extra = sorted(set(table) - set(PRICES[kind]))
    if extra:
        raise ProfileError(
            f"{source}: prices.{extra[0]}: unknown operation for a {kind} profile; it prices "
            f"{', '.join(PRICES[kind])}"
        )
    return Profile(
        name=raw["name"], title=raw["title"], kind=kind,
        technology=str(raw.get("technology", "")), notes=str(raw.get("notes", "")).strip(),
        prices=prices, path=source,
    )  # fmt: skip


def _price(raw: Any, where: str) -> Price:
    if not isinstance(raw, dict):
        raise ProfileError(f"{where}: missing; add the table with {', '.join(sorted(_PRICE_KEYS))}")
    unknown = sorted(set(raw) - _PRICE_KEYS)
    if unknown:
        raise ProfileError(
            f"{where}.{unknown[0]}: unknown key; a price has {', '.join(sorted(_PRICE_KEYS))}"
        )
    missing = sorted(_PRICE_KEYS - set(raw))
    if missing:
        raise ProfileError(f"{where}.{missing[0]}: missing; add it")
    unit = raw["unit"]
    if unit not in UNITS:
        raise ProfileError(f"{where}.unit: unknown unit {unit!r}; use one of {', '.join(UNITS)}")
    if raw["tag"] not in TAGS:
        raise ProfileError(f"{where}.tag: {raw['tag']!r} is not one of {', '.join(TAGS)}")
    values = {}
    for key in ("value", "low", "high"):
        v = raw[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or v != v:
            raise ProfileError(f"{where}.{key}: must be a number, got {v!r}")
        if v < 0:
            raise ProfileError(f"{where}.{key}: an energy cannot be negative, got {v}")
        values[key] = float(v) * UNITS[unit]
    if not values["low"] <= values["value"] <= values["high"]:
        raise ProfileError(
            f"{where}: need low <= value <= high, got {raw['low']}, {raw['value']}, {raw['high']}"
        )
    if not isinstance(raw["source"], str) or not raw["source"].strip():
        raise ProfileError(f"{where}.source: say where the number comes from")
    return Price(values["value"], values["low"], values["high"], unit, raw["tag"], raw["source"])
