"""The documents a reader follows hold together: README.md stays short, and every relative link,
image, `#anchor`, result path under ``benchmarks/results/`` and git tag that README.md,
``docs/**/*.md`` or ``benchmarks/README.md`` names exists, so the pages render on GitHub without
a dead link or a missing picture.

A tag is named as ``tag `NAME``` (or ``tags `A` and `B```); a result is named by its path
(``benchmarks/results/NAME``, globs and ``{a,b}`` allowed) or, in backticks, by its bare name
(``study-de61c27-small_S/``)."""

from __future__ import annotations

import functools
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

# scripts/docs_blocks: the documents' writers, not installed with snnkart
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from docs_blocks.docs_block import published_tags

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
README_MAX_LINES = 250

FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.S | re.M)
CODE_SPAN = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE = re.compile(r"^\s*\[[^\]]+\]:\s*<?(\S+?)>?(?:\s|$)", re.M)
HTML_SRC = re.compile(r"<(?:img|a)\b[^>]*?\b(?:src|href)=\"([^\"]+)\"", re.I)
HEADING = re.compile(r"^#{1,6}[ \t]+(.+?)[ \t#]*$", re.M)
RESULT_PATH = re.compile(r"benchmarks/results/([^\s`'\"()\[\]<>|]+)")
BARE_RESULT = re.compile(
    r"`((?:study|held-out|screen|every-seed|ablation|bench_[a-z_]+)-[^`\s/]+/?)`"
)
TAG = re.compile(r"\btag\s+(`[^`]+`)|\btags\s+((?:`[^`]+`(?:,\s*|,?\s+and\s+|,?\s+or\s+)?)+)")


def documents() -> list[Path]:
    """README.md, every Markdown page under docs/, and benchmarks/README.md."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return [*pages, ROOT / "benchmarks/README.md"]


def prose(text: str) -> str:
    """The text with fenced code blocks and inline code spans blanked out (links there are
    examples, not links)."""
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    return CODE_SPAN.sub("``", text)


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: the rendered text (no code ticks, link targets or
    emphasis), lowercase, punctuation but - and _ dropped, spaces to -."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"<[^>]+>", "", text).replace("`", "").lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading anchor of a Markdown page, numbered as GitHub numbers repeated ones."""
    seen: dict[str, int] = {}
    found = set()
    text = FENCE.sub("", page.read_text())
    for match in HEADING.finditer(text):
        base = slug(match.group(1))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def targets(text: str) -> Iterator[str]:
    """Every link and image target in a page's prose."""
    body = prose(text)
    for pattern in (LINK, REFERENCE, HTML_SRC):
        yield from (m.group(1) for m in pattern.finditer(body))


def link_problems(page: Path) -> Iterator[str]:
    """What is wrong with each relative link or image of a page: a missing file or an
    anchor that no heading of the target page makes."""
    name = page.relative_to(ROOT)
    for target in targets(page.read_text()):
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.I):  # http(s), mailto, ...
            continue
        path, _, anchor = target.split("?")[0].partition("#")
        base = ROOT if path.startswith("/") else page.parent
        file = (base / path.lstrip("/")).resolve() if path else page
        if not file.exists():
            yield f"{name}: link to {target}: {file} does not exist"
        elif anchor and file.suffix == ".md" and anchor.lower() not in anchors(file):
            yield f"{name}: link to {target}: no heading in {file.name} makes #{anchor}"


def expand(pattern: str) -> list[str]:
    """A ``{a,b}`` pattern as its alternatives: the catalogue script's own reading
    (``scripts/results_index.py``), so the two agree on what a document cites."""
    return _script().expand(pattern)  # type: ignore[no-any-return]


@functools.cache
def _script():  # type: ignore[no-untyped-def]
    from test_results_catalogue import _index_script

    return _index_script()


def result_exists(name: str) -> bool:
    """Whether a result path relative to benchmarks/results/ (globs allowed) names a file."""
    name = name.rstrip(".,:;")
    alternatives = expand(name.rstrip("/"))
    return all(any(RESULTS.glob(p)) if "*" in p else (RESULTS / p).exists() for p in alternatives)


def result_names(text: str) -> Iterator[str]:
    """Every result a page names: by path under benchmarks/results/, or by bare name."""
    text = TAG.sub("", text)  # a tag is not a result
    yield from (m.group(1) for m in RESULT_PATH.finditer(text))
    for match in BARE_RESULT.finditer(text):
        if not match.group(1).endswith((".toml", ".py")):
            yield match.group(1)


def tag_names(text: str) -> Iterator[str]:
    """Every git tag a page names as ``tag `NAME```."""
    for match in TAG.finditer(text):
        yield from re.findall(r"`([^`]+)`", match.group(1) or match.group(2))


def git_tags() -> dict[str, str]:
    """The tags git lists, with their commits (a clone without tags lists none)."""
    fmt = "--format=%(refname:short) %(objectname)%(*objectname)"  # an annotated tag's commit last
    out = subprocess.run(["git", "-C", str(ROOT), "tag", "--list", fmt], capture_output=True,
                         text=True, check=True)  # fmt: skip
    return {name: ref[-40:] for name, ref in (line.split() for line in out.stdout.splitlines())}


def test_the_readme_is_short() -> None:
    lines = (ROOT / "README.md").read_text().count("\n")
    assert lines <= README_MAX_LINES, (
        f"README.md has {lines} lines (at most {README_MAX_LINES}): move detail to docs/"
    )


@pytest.mark.parametrize("page", documents(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_link_and_image_resolves(page: Path) -> None:
    problems = list(link_problems(page))
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("page", documents(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_cited_result_exists(page: Path) -> None:
    missing = sorted({n for n in result_names(page.read_text()) if not result_exists(n)})
    assert not missing, (
        f"{page.relative_to(ROOT)} cites results not in benchmarks/results/: {missing}"
    )


def test_every_named_tag_exists() -> None:
    published = published_tags(ROOT)
    missing = [
        f"{page.relative_to(ROOT)}: tag `{tag}`"
        for page in documents()
        for tag in tag_names(page.read_text())
        if tag not in published
    ]
    assert not missing, f"tags that docs/tags.toml does not list: {missing}"
    moved = {t: c for t, c in git_tags().items() if t in published and published[t] != c}
    assert not moved, f"tags git points elsewhere than docs/tags.toml says: {moved}"


def test_the_checks_see_what_they_check() -> None:
    text = "See [a](#b) and ![c](d/e.png), `[x](y)` and tag `t1` or tag `t2`, `study-x/`."
    assert list(targets(text)) == ["#b", "d/e.png"]
    assert list(tag_names("tags `a`, `b` and `c`; at tag `d`, `e`")) == ["a", "b", "c", "d"]
    assert list(result_names(text)) == ["study-x/"]
    assert slug("Does a BC warm start help PPO? Yes, on `both` envs") == (
        "does-a-bc-warm-start-help-ppo-yes-on-both-envs"
    )
    assert expand("s-{ann,snn}/") == ["s-ann/", "s-snn/"]


def test_the_readme_names_the_extras_ci_installs() -> None:
    ci = re.search(r"SNNKART_EXTRAS=(\S+)", (ROOT / ".ci/run").read_text())
    assert ci is not None
    assert f"`SNNKART_EXTRAS={ci.group(1)}`" in (ROOT / "README.md").read_text()
