"""Write the catalogue of ``benchmarks/results/``: ``benchmarks/results/README.md``.

    .venv/bin/python scripts/results_index.py           # write the index
    .venv/bin/python scripts/results_index.py --check   # exit 1 if the committed one differs

One row per entry of ``benchmarks/results/`` (a result file or a study's folder), read from the
entry itself: what it is, which documents cite it, the commit it was made at and the data it
used under the results protocol of ``docs/results.md``.

- **cited by**: ``README.md``, ``benchmarks/README.md`` and ``docs/*.md`` that name the entry:
  its full name (``study-43bb29c-small_S-stall0.01/``), a brace list
  (``study-7028a5d-steer-stall0.01-standstill2-{ann,snn}/``), a glob that names more than the
  family (``bench_train-07dea46-run*.json``; ``bench_learning-*.json`` names every learning
  record and so cites none), or a suffix right after a full name in the same paragraph
  (``bench_train-23b812a-run1.json``, ``-run2.json``).
- **commit**: the record's own (``machine.commit``, or ``commit``), else the one its name
  carries; ``-dirty`` means the working tree had uncommitted changes.
- **data**: the kind its study config declares, else judged from the training seeds and tracks
  the record names: ``reporting`` when every seed is 101 or above and every track a reporting
  track or one of the original's two; ``tuning`` when any seed is 1-100 or any track a tuning
  track; ``before the protocol`` when the record names no training seed or track (throughput
  and latency measurements). Evaluation seeds (10,000 and up) are not training seeds.
"""

from __future__ import annotations

import fnmatch
import json
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # docs_blocks/, beside this script

from docs_blocks.docs_block import RESULTS_TAG, published_tags

from snnkart.app.pipeline import DEMO_SEED, DEMO_TRACK
from snnkart.app.protocol import FIRST_REPORTING_SEED, data_problem, is_tuning_track

ROOT = Path(__file__).resolve().parents[1]
RESULTS = "benchmarks/results"
INDEX = f"{RESULTS}/README.md"
EVAL_SEEDS_FROM = 10_000
"""Seeds from here up seed evaluation episodes (``eval_seed``), not training."""

FAMILIES = {
    "bench_deploy": "ms per env step: torch, the NIR reference, Lava float and fixed",
    "bench_env": "env steps/s, single and vectorised; compiled against per-ray LIDAR",
    "bench_learning": "learning runs (first finish, evaluation success)",
    "bench_main_job": "the main job (snnkart demo): training, quantisation, Lava, report",
    "bench_ros": "ROS bridge latency per backend",
    "bench_sim2real": "evaluation under LIDAR noise, beam dropout and actuation delay",
    "bench_sparsity": "success against synaptic operations (T, width, rate penalty)",
    "bench_train": "training steps/s: snnkart ANN and SNN against Stable-Baselines3",
    "ablation": "ablation study",
    "every-seed": "every-seed study",
    "held-out": "held-out-track study",
    "screen": "screen of a candidate setting",
    "study": "study",
}
HASH = re.compile(r"(?<![0-9a-z])[0-9a-f]{7}(?:-dirty)?(?![0-9a-z])")
CITED_NAME = re.compile(
    r"(?:bench_[a-z0-9_]+|study|screen|held-out|every-seed|ablation)-[A-Za-z0-9_.*{},-]+"
)
SUFFIX = re.compile(r"`(-[A-Za-z0-9_.]+)/?`")


@dataclass(frozen=True)
class Entry:
    """One row of the catalogue."""

    name: str
    what: str
    cited_by: tuple[str, ...]
    commit: str
    data: str


def documents(root: Path = ROOT) -> list[Path]:
    """The documents whose citations keep a result in the tree."""
    found = [root / "README.md", root / "benchmarks/README.md", *sorted(root.glob("docs/*.md"))]
    return [p for p in found if p.is_file()]


def expand(pattern: str) -> list[str]:
    """``a-{x,y}-b`` as ``a-x-b`` and ``a-y-b``."""
    match = re.search(r"\{([^{}]*)\}", pattern)
    if match is None:
        return [pattern]
    head, tail = pattern[: match.start()], pattern[match.end() :]
    return [n for part in match.group(1).split(",") for n in expand(head + part + tail)]


def _stem(name: str) -> str:
    return name.removesuffix("/").removesuffix(".json")


def _family(name: str) -> str:
    return next(f for f in sorted(FAMILIES, key=len, reverse=True) if name.startswith(f + "-"))


def _matches(pattern: str, names: list[str]) -> list[str]:
    """The entries ``pattern`` names; a glob that names only a family names none."""
    pattern = _stem(pattern.rstrip(".,;:)"))
    if "*" in pattern:
        rest = pattern.removeprefix(_family(pattern) + "-") if "-" in pattern else pattern
        if not rest.strip("*-."):
            return []
    return [n for n in names if fnmatch.fnmatchcase(_stem(n), pattern)]


def citations(text: str, names: list[str]) -> set[str]:
    """The entries of ``names`` that ``text`` cites (see the module docstring)."""
    cited: set[str] = set()
    for paragraph in re.split(r"\n\s*\n", text):
        last: list[str] = []
        for match in re.finditer(f"{CITED_NAME.pattern}|{SUFFIX.pattern}", paragraph):
            if match.group(1) is None:
                found = [n for p in expand(match.group(0)) for n in _matches(p, names)]
                cited.update(found)
                last = found or last
                continue
            suffix = _stem(match.group(1))
            for full in last:
                base = _stem(full)
                for candidate in (base + suffix, base.rsplit("-", 1)[0] + suffix):
                    cited.update(n for n in names if _stem(n) == candidate)
    return cited


def _load(path: Path) -> dict[str, Any]:
    record = path / "study.json" if path.is_dir() else path
    data = json.loads(record.read_text())
    return data if isinstance(data, dict) else {}


def _what(name: str, record: dict[str, Any]) -> str:
    study = record.get("study")
    if isinstance(study, dict):
        only = record.get("only")
        where = f", runs {', '.join(only)}" if only else ""
        return f'{FAMILIES[_family(name)]} "{study.get("name", "")}"{where}'
    own = record.get("what")
    if isinstance(own, str):
        return own.split(";")[0].split(". ")[0].strip()
    family = _family(name)
    label = HASH.sub("", _stem(name).removeprefix(family)).replace("--", "-").strip("-")
    return FAMILIES[family] + (f" ({label})" if label else "")


def _commit(name: str, record: dict[str, Any]) -> str:
    machine = record.get("machine")
    own = machine.get("commit") if isinstance(machine, dict) else None
    own = own or record.get("commit")
    named = HASH.search(_stem(name))
    if not own:
        return f"{named.group(0)} (from the name)" if named else "not recorded"
    if named and not str(own).startswith(named.group(0).removesuffix("-dirty")):
        return f"{own} (named {named.group(0)})"
    return str(own)


def _seeds_and_tracks(record: dict[str, Any]) -> tuple[set[int], set[str]]:
    """The training seeds and tracks the record names, anywhere in it."""
    seeds: set[int] = set()
    tracks: set[str] = set()
    stack: list[Any] = [record.get("runs", record) if "study" in record else record]
    while stack:
        item = stack.pop()
        if isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, dict):
            for key, value in item.items():
                values = value if isinstance(value, list) else [value]
                if key in ("seed", "seeds"):
                    seeds.update(v for v in values if isinstance(v, int) and v < EVAL_SEEDS_FROM)
                elif key in ("track", "tracks"):
                    tracks.update(v for v in values if isinstance(v, str))
                else:
                    stack.append(value)
    command = record.get("command")
    if isinstance(command, list) and command[1:2] == ["demo"]:
        seeds.add(_demo_seed(record))
        tracks.add(DEMO_TRACK)
    return seeds, tracks


def _demo_seed(record: dict[str, Any]) -> int:
    """The main job's training seed: DEMO_SEED (101) from tag results-1 on; 1 before it (those
    records name no seed)."""
    commit = str((record.get("machine") or {}).get("commit", "")).removesuffix("-dirty")
    tag = published_tags(ROOT)[RESULTS_TAG]
    since = subprocess.run(["git", "merge-base", "--is-ancestor", tag, commit],
                           cwd=ROOT, capture_output=True).returncode == 0  # fmt: skip
    return DEMO_SEED if since else 1


def _data(record: dict[str, Any]) -> str:
    study = record.get("study")
    if isinstance(study, dict) and study.get("data"):
        return str(study["data"])
    seeds, tracks = _seeds_and_tracks(record)
    if not seeds and not tracks:
        return "before the protocol"
    if data_problem("reporting", sorted(seeds), sorted(tracks)) is None and seeds:
        return "reporting"
    if any(s < FIRST_REPORTING_SEED for s in seeds) or any(map(is_tuning_track, tracks)):
        return "tuning"
    return "before the protocol"


def entries(root: Path = ROOT) -> list[Entry]:
    """Every entry of ``benchmarks/results/`` but the index, with what the catalogue says."""
    paths = sorted(p for p in (root / RESULTS).iterdir() if p.name != "README.md")
    names = [p.name + ("/" if p.is_dir() else "") for p in paths]
    cited: dict[str, list[str]] = {n: [] for n in names}
    for doc in documents(root):
        for name in citations(doc.read_text(), names):
            cited[name].append(doc.relative_to(root).as_posix())
    rows = []
    for path, name in zip(paths, names, strict=True):
        record = _load(path)
        rows.append(Entry(name, _what(name, record), tuple(cited[name]), _commit(name, record),
                          _data(record)))  # fmt: skip
    return rows


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def index(rows: list[Entry]) -> str:
    """The catalogue's Markdown."""
    lines = [
        "# benchmarks/results",
        "",
        "<!-- generated by scripts/results_index.py from the files themselves: do not edit -->",
        "",
        "Every result file and study folder here, what it is, which document cites it, the "
        "commit it was made at (`-dirty`: with uncommitted changes) and the data it used under "
        "the results protocol ([docs/results.md](../../docs/results.md)): `tuning`, "
        "`reporting`, or `before the protocol` for a record that names no training seed or "
        "track. How each column is read: `scripts/results_index.py`. A result no document "
        "cites leaves the tree (git keeps it); `tests/test_results_catalogue.py` checks both.",
        "",
        "| entry | what it is | cited by | commit | data |",
        "|---|---|---|---|---|",
    ]
    for row in rows:
        cited = ", ".join(row.cited_by) or "nothing"
        lines.append(
            f"| `{row.name}` | {_cell(row.what)} | {cited} | `{row.commit}` | {row.data} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    text = index(entries())
    target = ROOT / INDEX
    if "--check" in argv:
        if not target.is_file() or target.read_text() != text:
            print(f"{INDEX} is out of date: run scripts/results_index.py", file=sys.stderr)
            return 1
        return 0
    target.write_text(text)
    print(f"wrote {INDEX} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
