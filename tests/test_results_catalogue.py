"""benchmarks/results/ is a catalogue: every entry indexed and cited by a document, the index
written by scripts/results_index.py; the code names no result file or commit, and points to
docs/decisions.md for why a default is what it is."""

from __future__ import annotations

import hashlib
import importlib.util
import io
import re
import sys
import tokenize
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEX = re.compile(
    r"(?<![0-9A-Za-z_])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![0-9A-Za-z_])"
)
"""A commit hash, short or full: 7-40 hex digits with a letter and a digit in them (a sha256
digest, 64 digits, is not one)."""
COMMIT_NAMED = re.compile(
    r"(?:bench_[a-z_]+|study|screen|held-out|every-seed|ablation)-[0-9a-f]{7}"
)
ALLOWED_HEX: dict[tuple[str, str], str] = {}
"""(module, hex) pairs that must stay in the code, each with its reason; none today."""
POINTER = re.compile(r"docs/decisions\.md#([A-Za-z0-9_-]+)")


def _index_script():  # type: ignore[no-untyped-def]
    path = ROOT / "scripts/results_index.py"
    spec = importlib.util.spec_from_file_location("results_index", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


def _entries_on_disk() -> set[str]:
    results = ROOT / "benchmarks/results"
    return {p.name + ("/" if p.is_dir() else "") for p in results.iterdir()} - {"README.md"}


def test_the_index_lists_every_entry_and_nothing_else() -> None:
    rows = (ROOT / "benchmarks/results/README.md").read_text().splitlines()
    indexed = {m.group(1) for r in rows if (m := re.match(r"\| `([^`]+)` \|", r))}
    on_disk = _entries_on_disk()
    assert not on_disk - indexed, f"not in the index: {sorted(on_disk - indexed)}"
    assert not indexed - on_disk, f"the index names what is not there: {sorted(indexed - on_disk)}"


def test_the_committed_index_is_what_the_script_writes() -> None:
    script = _index_script()
    assert (ROOT / script.INDEX).read_text() == script.index(script.entries()), (
        f"{script.INDEX} is out of date: run scripts/results_index.py"
    )


def test_every_entry_is_cited_by_a_document() -> None:
    uncited = [e.name for e in _index_script().entries() if not e.cited_by]
    assert not uncited, (
        f"no document cites {uncited}: cite each in README.md or docs/, or git rm it"
    )


def test_citations_are_read_as_documents_write_them() -> None:
    script = _index_script()
    names = ["bench_train-aaaaaa1-run1.json", "bench_train-aaaaaa1-run2.json",
             "bench_learning-aaaaaa1.json", "study-bbbbbb2-x-ann/", "study-bbbbbb2-x-snn/",
             "screen-ccccc3d-grid/", "screen-ccccc3d-grid-2/"]  # fmt: skip
    cite = script.citations
    assert cite("`study-bbbbbb2-x-{ann,snn}/`", names) == {"study-bbbbbb2-x-ann/",
                                                          "study-bbbbbb2-x-snn/"}  # fmt: skip
    assert cite("(`bench_train-aaaaaa1-run1.json`, `-run2.json`)", names) == {
        "bench_train-aaaaaa1-run1.json", "bench_train-aaaaaa1-run2.json"}  # fmt: skip
    assert cite("`screen-ccccc3d-grid/`, `-2/`", names) == {
        "screen-ccccc3d-grid/", "screen-ccccc3d-grid-2/"}  # fmt: skip
    assert cite("earlier ones are in `bench_learning-*.json`", names) == set()
    assert cite("`bench_train-aaaaaa1-run*.json`", names) == set(names[:2])
    # a suffix belongs to the full name before it in the same paragraph only
    assert cite("`screen-ccccc3d-grid/`\n\n`-2/`", names) == {"screen-ccccc3d-grid/"}


def test_no_results_folder_holds_another_folders_file() -> None:
    """A study folder's plots are its own: the same bytes twice is a copy left behind."""
    by_hash: dict[str, list[str]] = defaultdict(list)
    for path in sorted((ROOT / "benchmarks/results").glob("*/plots/*")):
        by_hash[hashlib.sha256(path.read_bytes()).hexdigest()].append(path.parent.parent.name)
    copies = [folders for folders in by_hash.values() if len(folders) > 1]
    assert not copies, f"the same plot in several folders: {copies}"


def _comments_and_strings(path: Path) -> list[tuple[int, str]]:
    tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    return [(t.start[0], t.string) for t in tokens if t.type in (tokenize.COMMENT, tokenize.STRING)]


def test_no_module_names_a_result_file_or_a_commit() -> None:
    """Why a default is what it is lives in docs/decisions.md, with its result file; the code
    points there instead of naming commit-named files or commits."""
    entries = {n.rstrip("/").removesuffix(".json") for n in _entries_on_disk()}
    found, used = [], set()
    for path in sorted((ROOT / "snnkart").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        for line, text in _comments_and_strings(path):
            for match in [*HEX.finditer(text), *COMMIT_NAMED.finditer(text)]:
                if (rel, match.group(0)) in ALLOWED_HEX:
                    used.add((rel, match.group(0)))
                else:
                    found.append(f"{rel}:{line}: {match.group(0)}")
            found += [f"{rel}:{line}: {e}" for e in entries if e in text]
    assert not found, "point to docs/decisions.md#<heading> instead:\n" + "\n".join(found)
    assert used == set(ALLOWED_HEX), f"stale allow-list entries: {set(ALLOWED_HEX) - used}"


def _anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def test_every_decisions_pointer_names_a_heading() -> None:
    page = (ROOT / "docs/decisions.md").read_text()
    anchors = {_anchor(m.group(1)) for m in re.finditer(r"^#+ (.+)$", page, re.MULTILINE)}
    code = [*(ROOT / "snnkart").rglob("*.py"), *(ROOT / "scripts").glob("*.py"),
            *(ROOT / "benchmarks").glob("*.py")]  # fmt: skip
    pointers = {
        (p.relative_to(ROOT).as_posix(), m.group(1))
        for p in sorted(code)
        for m in POINTER.finditer(p.read_text())
    }
    assert len(pointers) >= 10, f"the defaults' pointers are gone: {sorted(pointers)}"
    broken = sorted(f"{path}: #{anchor}" for path, anchor in pointers if anchor not in anchors)
    assert not broken, f"no such heading in docs/decisions.md: {broken}"
