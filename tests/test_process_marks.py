"""The fault tests' shared-memory check (:class:`process_marks.ShmCheck`) on plain Python
processes: a segment the marked tree leaves is reported; a segment another process holds, or
is just unlinking, is not."""

from __future__ import annotations

import os
import subprocess
import sys
import uuid
from collections.abc import Iterator

import pytest
from process_marks import SEGMENT_SCRIPT, ShmCheck, shm_segments


@pytest.fixture
def segments() -> Iterator[list[str]]:
    """Names the test made; whatever of them is left is unlinked afterwards."""
    made: list[str] = []
    yield made
    for name in made:
        if name in shm_segments():
            os.unlink(f"/dev/shm/{name}")


def _start(mark: str | None, *args: str) -> tuple[subprocess.Popen[str], str]:
    env = {**os.environ, **({"SNNKART_TEST_MARK": mark} if mark else {})}
    proc = subprocess.Popen([sys.executable, "-c", SEGMENT_SCRIPT, *args], env=env, text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE)  # fmt: skip
    assert proc.stdout is not None
    return proc, proc.stdout.readline().strip()


@pytest.mark.parametrize("end", ["exit", "SIGKILL"])
def test_a_segment_the_marked_tree_left_is_reported(segments: list[str], end: str) -> None:
    mark = uuid.uuid4().hex
    check = ShmCheck(mark)
    proc, name = _start(mark, "leak")
    segments.append(name)
    if end == "SIGKILL":
        proc.kill()
    proc.communicate("")
    assert check.leaked(grace_s=0.2) == {name}


def test_a_segment_a_live_marked_process_holds_is_reported(segments: list[str]) -> None:
    mark = uuid.uuid4().hex
    check = ShmCheck(mark)
    proc, name = _start(mark, "hold")
    segments.append(name)
    try:
        assert check.leaked(grace_s=0.2) == {name}
    finally:
        proc.communicate("")
    assert check.leaked(grace_s=0.2) == set()  # unlinked when it ended


def test_a_segment_another_process_holds_or_is_unlinking_is_not_reported(
    segments: list[str],
) -> None:
    mark = uuid.uuid4().hex
    check = ShmCheck(mark)
    ours, our_name = _start(mark, "hold")  # held, then unlinked: no leak
    other, name = _start(None, "hold", "0.5")  # made while the check runs, by another process
    segments += [our_name, name]
    ours.communicate("")
    assert other.stdin is not None and other.stdout is not None
    try:
        assert name in shm_segments() - check.before
        assert check.leaked(grace_s=0.2) == set()  # held by the other process
        other.stdin.close()
        assert check.leaked(grace_s=2.0) == set()  # unmapped, then unlinked 0.5 s later
    finally:
        if not other.stdin.closed:
            other.stdin.close()
        other.wait()
        other.stdout.close()
    assert name not in shm_segments()
