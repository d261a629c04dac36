"""Hardware profiles: per-operation energy prices, each with its source, a low-high range and a
tag saying what kind of number it is.

A profile is a TOML file (the built-in ones are package data in ``snnkart/energy/builtin/``,
linked from the repository's ``hardware/``; a user passes their own by path)::

    schema = "snnkart.hardware/2"
    name = "loihi1"
    title = "Intel Loihi 1 (Davies et al. 2018)"
    kind = "neuromorphic"            # prices synaptic_op, neuron_update, spike (+ optional ones)
    technology = "Intel 14 nm FinFET, 0.75 V"
    notes = "what the figures include and leave out"
    neurons_per_core = 1024          # the placement that routing (hop) is priced on
    cores_per_tile = 4

    [prices.synaptic_op]
    value = 23.6                     # the central value
    low = 23.6                       # the range the uncertainty analysis moves it across
    high = 35.5
    unit = "pJ"                      # fJ, pJ, nJ or uJ; static_power: uW, mW or W
    tag = "pre-silicon"              # measured, pre-silicon, derived or assumed
    source = "Davies et al. 2018, Table 2 ..."

    [not_published]                  # an optional price with no published figure, and why
    static_power = "no idle power published for ..."

A ``neuromorphic`` profile may also state two facts of the chip that decide what a
sigma-delta network's counts cost (:mod:`snnkart.energy.sigma_delta`), each with its
evidence; a profile that does not is read with the costlier default (``assumed``)::

    [rules.neuron_updates]
    value = "clocked"                # clocked: every neuron is updated at every time step
    tag = "pre-silicon"              #   (an idle one too); active: only one with input or
    source = "Davies et al. 2018 ..."  # a message to send
    [rules.messages]
    value = "binary"                 # graded: a message carries an integer payload natively;
    tag = "derived"                  #   binary: one bit (a graded message is emulated)
    source = "..."

A ``digital`` profile prices ``mac``, ``add``, ``mult`` and one 64-bit memory read per array
size (``sram_read_8kb``, ``sram_read_32kb``, ``sram_read_1mb``, ``dram_read``; 0 in a
compute-only profile), and says its ``weight_bits``: each side's weights are read from the
smallest array that holds them (:func:`memory_row`). Optional prices (``OPTIONAL``): the
chip's ``hop`` (one spike crossing one tile boundary), ``io_bit`` (one bit over the host<->chip
link) and ``static_power`` (drawn whether or not the network computes); each optional price is
either given or named in ``[not_published]`` with the reason.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from snnkart.contract.energy_record import PriceRecord, ProfileRecord
from snnkart.errors import ProfileError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PROFILE_SCHEMA = "snnkart.hardware/2"
UNITS = {"fJ": 1e-3, "pJ": 1.0, "nJ": 1e3, "uJ": 1e6}
"""Energy units a profile may use, in pJ."""
POWER_UNITS = {"uW": 1e6, "mW": 1e9, "W": 1e12}
"""Power units (``static_power``), in pJ per second: a static term is seconds x this price."""
TAGS = ("measured", "pre-silicon", "derived", "assumed")
PRICES = {
    "neuromorphic": ("synaptic_op", "neuron_update", "spike"),
    "digital": (
        "mac",
        "add",
        "mult",
        "sram_read_8kb",
        "sram_read_32kb",
        "sram_read_1mb",
        "dram_read",
    ),
}
"""The operations each kind of profile must price."""
OPTIONAL = {
    "neuromorphic": ("hop", "io_bit", "static_power"),
    "digital": ("static_power",),
}
"""The operations a profile prices or names in ``[not_published]``."""
MEMORY_ROWS = (
    (8 * 1024, "sram_read_8kb"),
    (32 * 1024, "sram_read_32kb"),
    (1024 * 1024, "sram_read_1mb"),
    (None, "dram_read"),
)
"""Horowitz's rows (ISSCC 2014): the largest footprint in bytes each array holds, smallest first."""
BUILTIN = (
    "loihi1",
    "loihi2",
    "spinnaker2",
    "spinnaker1",
    "truenorth",
    "horowitz45_fp32",
    "horowitz45_int8",
    "horowitz45_fp32_sram",
    "arm_degnan2015",
)
DEFAULT_CHIPS = ("loihi1", "loihi2", "spinnaker2", "spinnaker1", "truenorth")
DEFAULT_DIGITAL = ("horowitz45_fp32_sram", "horowitz45_int8", "arm_degnan2015")
"""The realistic digital targets (memory priced, or an all-in per-op figure); the compute-only
``horowitz45_fp32``, the SNN papers' usual baseline, is built in but not a default."""

RULES = {"neuron_updates": ("clocked", "active"), "messages": ("binary", "graded")}
"""A neuromorphic profile's rules (``[rules.<name>]``) and the values each may take, the
default (costlier) first."""

_TOP_KEYS = {
    "schema",
    "name",
    "title",
    "kind",
    "technology",
    "notes",
    "prices",
    "not_published",
    "weight_bits",
    "neurons_per_core",
    "cores_per_tile",
    "rules",
}
_PRICE_KEYS = {"value", "low", "high", "unit", "tag", "source"}
_RULE_KEYS = {"value", "tag", "source"}


def memory_row(nbytes: float) -> str:
    """The memory read that prices weights whose footprint is ``nbytes``: the smallest of
    Horowitz's arrays (8 KB, 32 KB, 1 MB SRAM; DRAM beyond) that holds them all."""
    for limit, op in MEMORY_ROWS:
        if limit is None or nbytes <= limit:
            return op
    raise AssertionError("unreachable: the last row holds any footprint")


@dataclass(frozen=True)
class Price:
    """One operation's energy in pJ (``static_power``: pJ per second), converted from the
    file's unit, with its range and provenance."""

    value: float
    low: float
    high: float
    unit: str  # as written in the file
    tag: str
    source: str

    def as_dict(self) -> PriceRecord:
        return {
            "pj": self.value,
            "low_pj": self.low,
            "high_pj": self.high,
            "per": "second" if self.unit in POWER_UNITS else "operation",
            "unit_in_file": self.unit,
            "tag": self.tag,
            "source": self.source,
        }


@dataclass(frozen=True)
class Rule:
    """A fact about how a chip computes (one of :data:`RULES`), with its evidence."""

    value: str
    tag: str
    source: str

    def as_dict(self) -> dict[str, str]:
        return {"value": self.value, "tag": self.tag, "source": self.source}


def default_rule(name: str) -> Rule:
    """The rule a profile that states none is read with: the costlier value, ``assumed``."""
    return Rule(
        RULES[name][0],
        "assumed",
        f"not stated by the profile: snnkart assumes the costlier rule ({RULES[name][0]})",
    )


@dataclass(frozen=True)
class Profile:
    name: str
    title: str
    kind: str
    technology: str
    notes: str
    prices: dict[str, Price]
    path: str  # where it was read from
    not_published: dict[str, str] = field(default_factory=dict)
    """Optional operations with no published figure: operation -> why."""
    weight_bits: int = 32  # digital: bits of one stored weight
    neurons_per_core: int = 0  # neuromorphic: the placement routing is priced on (0: none)
    cores_per_tile: int = 1
    rules: dict[str, Rule] = field(default_factory=dict)
    """Neuromorphic: the rules the profile states (:data:`RULES`); see :meth:`rule`."""

    def rule(self, name: str) -> Rule:
        """The profile's ``name`` rule, or :func:`default_rule` where it states none."""
        return self.rules.get(name) or default_rule(name)

    def weight_bytes(self, parameters: float) -> float:
        """The footprint of ``parameters`` weights stored at this profile's ``weight_bits``
        (what :func:`memory_row` sizes the array by)."""
        return parameters * self.weight_bits / 8

    def __getitem__(self, op: str) -> float:
        return self.prices[op].value

    @property
    def prices_memory(self) -> bool:
        """Whether weight reads cost anything here (not a compute-only profile)."""
        return any(self[op] > 0 for _, op in MEMORY_ROWS)

    def describe(self) -> ProfileRecord:
        return {
            "name": self.name,
            "title": self.title,
            "kind": self.kind,
            "technology": self.technology,
            "notes": self.notes,
            "file": self.path,
            "prices": {op: p.as_dict() for op, p in self.prices.items()},
            "not_published": dict(self.not_published),
            "weight_bits": self.weight_bits,
            "neurons_per_core": self.neurons_per_core,
            "cores_per_tile": self.cores_per_tile,
        }


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
    if raw.get("schema") == "snnkart.hardware/1":
        raise ProfileError(
            f"{source}: written for snnkart.hardware/1; in /2 a digital profile prices "
            "sram_read_8kb, sram_read_32kb, sram_read_1mb and dram_read (64-bit reads) instead "
            "of weight_read and says weight_bits; see snnkart/energy/profiles.py"
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
    prices, not_published = _prices(raw, kind, source)
    ints = {
        k: _count(raw, k, d, source)
        for k, d in (("weight_bits", 32), ("neurons_per_core", 0), ("cores_per_tile", 1))
    }
    if "hop" in prices and ints["neurons_per_core"] < 1:
        raise ProfileError(
            f"{source}: neurons_per_core: missing; a profile that prices hop places the "
            "layers on cores: add neurons_per_core = N (and cores_per_tile)"
        )
    return Profile(
        name=raw["name"],
        title=raw["title"],
        kind=kind,
        technology=str(raw.get("technology", "")),
        notes=str(raw.get("notes", "")).strip(),
        prices=prices,
        path=source,
        not_published=not_published,
        rules=_rules(raw.get("rules", {}), kind, source),
        **ints,
    )


def _rules(raw: Any, kind: str, source: str) -> dict[str, Rule]:
    """The ``[rules.<name>]`` tables (neuromorphic profiles only), each checked."""
    if raw and kind != "neuromorphic":
        raise ProfileError(f"{source}: rules: only a neuromorphic profile states rules; remove it")
    if not isinstance(raw, dict):
        raise ProfileError(f"{source}: rules: a table of [rules.<name>] tables")
    out = {}
    for name, table in raw.items():
        where = f"{source}: rules.{name}"
        if name not in RULES:
            raise ProfileError(f"{where}: unknown rule; a profile states {', '.join(RULES)}")
        keys = set(table) if isinstance(table, dict) else set()
        if keys != _RULE_KEYS:
            raise ProfileError(f"{where}: give exactly {', '.join(sorted(_RULE_KEYS))}")
        if table["value"] not in RULES[name]:
            raise ProfileError(
                f"{where}.value: {table['value']!r} is not one of {', '.join(RULES[name])}"
            )
        if table["tag"] not in TAGS:
            raise ProfileError(f"{where}.tag: {table['tag']!r} is not one of {', '.join(TAGS)}")
        if not isinstance(table["source"], str) or not table["source"].strip():
            raise ProfileError(f"{where}.source: say where the rule comes from")
        out[name] = Rule(table["value"], table["tag"], table["source"])
    return out


def _prices(
    raw: Mapping[str, object], kind: str, source: str
) -> tuple[dict[str, Price], dict[str, str]]:
    table = raw.get("prices")
    if not isinstance(table, dict):
        raise ProfileError(
            f"{source}: prices: missing; add a [prices.<operation>] table per operation"
        )
    prices = {op: _price(table.get(op), f"{source}: prices.{op}", op) for op in PRICES[kind]}
    extra = sorted(set(table) - set(PRICES[kind]) - set(OPTIONAL[kind]))
    if extra:
        raise ProfileError(
            f"{source}: prices.{extra[0]}: unknown operation for a {kind} profile; it prices "
            f"{', '.join(PRICES[kind] + OPTIONAL[kind])}"
        )
    not_published = raw.get("not_published", {})
    if not isinstance(not_published, dict) or not all(
        isinstance(v, str) and v.strip() for v in not_published.values()
    ):
        raise ProfileError(f'{source}: not_published: a table of operation = "why no figure"')
    for op in OPTIONAL[kind]:
        if (op in table) == (op in not_published):
            raise ProfileError(
                f"{source}: {op}: give [prices.{op}] or, where no figure is published, "
                f'not_published.{op} = "why" (exactly one of the two)'
            )
        if op in table:
            prices[op] = _price(table[op], f"{source}: prices.{op}", op)
    unknown = sorted(set(not_published) - set(OPTIONAL[kind]))
    if unknown:
        raise ProfileError(
            f"{source}: not_published.{unknown[0]}: only {', '.join(OPTIONAL[kind])} may be "
            "left unpublished"
        )
    return prices, dict(not_published)


def _count(raw: Mapping[str, object], key: str, default: int, source: str) -> int:
    v = raw.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ProfileError(f"{source}: {key}: must be a whole number >= 0, got {v!r}")
    return v


def _price(raw: Any, where: str, op: str) -> Price:
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
    units = POWER_UNITS if op == "static_power" else UNITS
    if unit not in units:
        raise ProfileError(f"{where}.unit: unknown unit {unit!r}; use one of {', '.join(units)}")
    if raw["tag"] not in TAGS:
        raise ProfileError(f"{where}.tag: {raw['tag']!r} is not one of {', '.join(TAGS)}")
    values = {}
    for key in ("value", "low", "high"):
        v = raw[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or v != v:
            raise ProfileError(f"{where}.{key}: must be a number, got {v!r}")
        if v < 0:
            raise ProfileError(f"{where}.{key}: an energy cannot be negative, got {v}")
        values[key] = float(v) * units[unit]
    if not values["low"] <= values["value"] <= values["high"]:
        raise ProfileError(
            f"{where}: need low <= value <= high, got {raw['low']}, {raw['value']}, {raw['high']}"
        )
    if not isinstance(raw["source"], str) or not raw["source"].strip():
        raise ProfileError(f"{where}.source: say where the number comes from")
    return Price(values["value"], values["low"], values["high"], unit, raw["tag"], raw["source"])
