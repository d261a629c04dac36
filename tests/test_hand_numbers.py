"""Result numbers in the documents' results sections sit in generated blocks, rendered from a
study's record by code (scripts/render_docs.py); a percentage or a step count typed by hand
outside a block in such a section fails here (issue 36). A section joins
:data:`RESULTS_SECTIONS` once its numbers are rendered."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS_SECTIONS = {
    "README.md": ["Results: small_S compared with the original"],
    "docs/results.md": [
        "small_S: compared with the original",
        "big_S",
        "The gazebo SNN on reporting seeds",
        "The SNN design ablation",
        "Making every result again",
        "Does every seed learn?",
    ],
    "docs/training.md": ["Does a BC warm start help PPO? Yes, on both envs"],
    "docs/tracks.md": ["Does a policy carry to tracks it never trained on?"],
}
"""The results sections whose numbers are all rendered: page -> headings."""
BLOCK = re.compile(r"<!-- generated from .*?<!-- end of generated block -->", re.S)
NUMBER = re.compile(
    r"\b\d+(?:\.\d+)?\s?%"  # a percentage
    r"|\b\d+(?:\.\d+)?\s?[kM]\b"  # a step count in thousands or millions
    r"|\b\d{1,3}(?:,\d{3})+\b"  # a count with thousands separators
    r"|\b\d+\s+(?:env\s+)?steps\b"  # "5000 steps"
)


def section(page: str, heading: str) -> str:
    """The text under ``heading`` up to the next heading of the same or a higher level."""
    match = re.search(rf"^(#+) {re.escape(heading)}\n", page, re.M)
    if match is None:
        raise AssertionError(f"no heading {heading!r}")
    level = len(match.group(1))
    rest = page[match.end() :]
    end = re.search(rf"^#{{1,{level}}} ", rest, re.M)
    return rest[: end.start()] if end else rest


def typed_numbers(text: str) -> list[str]:
    """The percentages and step counts of ``text`` outside generated blocks."""
    return NUMBER.findall(BLOCK.sub("", text))


@pytest.mark.parametrize(
    ("page", "heading"),
    [(page, h) for page, headings in RESULTS_SECTIONS.items() for h in headings],
)
def test_results_sections_hold_no_number_typed_by_hand(page: str, heading: str) -> None:
    text = section((ROOT / page).read_text(), heading)
    assert BLOCK.search(text), f"{page} § {heading}: no generated block"
    found = typed_numbers(text)
    assert not found, f"{page} § {heading}: numbers typed by hand outside a block: {found}"


def test_what_counts_as_a_number_typed_by_hand() -> None:
    text = (
        "## R\n\nsuccess 84 % and 3.5% of 15,613 steps, first finish at 83k, 600k env steps, "
        "5000 steps, 1.2M.\n<!-- generated from x by y -->\n99 % 12k\n"
        "<!-- end of generated block -->\nseed 104, 20 episodes, issue 36, T = 4.\n## Next\n42 %\n"
    )
    assert typed_numbers(section(text, "R")) == [
        "84 %", "3.5%", "15,613", "83k", "600k", "5000 steps", "1.2M"]  # fmt: skip
