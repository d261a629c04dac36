"""The fault tests' shared-memory check (:class:`process_marks.ShmWatch`) on plain Python
processes: a segment the marked tree held and left is reported; a segment of another process
is not, whether it holds it, is unlinking it or has abandoned it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator

import pytest
from process_marks import SEGMENT_SCRIPT, ShmWatch, shm_segments


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


def _until_seen(watch: ShmWatch, name: str, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 10
    while name not in watch.seen:
        assert proc.poll() is None and time.monotonic() < deadline, "the watch never saw it"
        time.sleep(0.01)


@pytest.mark.parametrize("end", ["exit", "SIGKILL"])
def test_a_segment_the_marked_tree_left_is_reported(segments: list[str], end: str) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark).start()
    proc, name = _start(mark, "leak")
    segments.append(name)
    _until_seen(watch, name, proc)
    if end == "SIGKILL":
        proc.kill()
    proc.communicate("")
    watch.stop()
    assert watch.leaked(grace_s=0.2) == {name}


def test_a_segment_the_marked_tree_unlinks_late_is_not_reported(segments: list[str]) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark).start()
    proc, name = _start(mark, "hold", "0.3")  # unmapped, then unlinked 0.3 s later
    segments.append(name)
    _until_seen(watch, name, proc)
    assert proc.stdin is not None
    proc.stdin.close()
    try:
        assert watch.leaked(grace_s=0.0) == {name}  # while it is still there
        assert watch.leaked(grace_s=3.0) == set()
    finally:
        proc.wait()
        watch.stop()


@pytest.mark.parametrize("how", ["hold", "leak"])
def test_a_segment_of_another_process_is_not_reported(segments: list[str], how: str) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark).start()
    ours, our_name = _start(mark, "hold")  # held, then unlinked: no leak
    before = shm_segments()
    other, name = _start(None, how, "1.0")  # made while the watch runs, by another process
    segments += [our_name, name]
    _until_seen(watch, our_name, ours)
    ours.communicate("")
    assert other.stdin is not None
    try:
        assert watch.leaked(grace_s=0.0) == set()  # held by the other process
        other.stdin.close()  # then unmapped, and unlinked 1 s later, or left for good
        time.sleep(0.2)
        watch.stop()
        assert name in shm_segments() - before and our_name not in shm_segments()
        assert watch.leaked(grace_s=0.0) == set()
    finally:
        if not other.stdin.closed:
            other.stdin.close()
        other.wait()
        watch.stop()
