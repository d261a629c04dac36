"""The fault tests' shared-memory check (:class:`process_marks.ShmWatch`) on plain Python
processes: a segment the marked tree leaves is reported, whether it was seen held or made and
abandoned between two looks; a segment another process holds is not."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator

import pytest
from process_marks import ShmWatch, shm_segments

SEGMENT = """
import sys
from multiprocessing import resource_tracker
from multiprocessing.shared_memory import SharedMemory
shm = SharedMemory(create=True, size=4096)
if sys.argv[1] == "leak":  # nothing will unlink it: a leak as a killed process tree leaves
    resource_tracker.unregister(shm._name, "shared_memory")
print(shm.name.lstrip("/"), flush=True)
sys.stdin.read()  # held until the test closes its end
if sys.argv[1] == "hold":
    shm.close()
    shm.unlink()
"""


@pytest.fixture
def segments() -> Iterator[list[str]]:
    """Names the test made; whatever of them is left is unlinked afterwards."""
    made: list[str] = []
    yield made
    for name in made:
        if name in shm_segments():
            os.unlink(f"/dev/shm/{name}")


def _start(how: str, mark: str | None) -> tuple[subprocess.Popen[str], str]:
    env = {**os.environ, **({"SNNKART_TEST_MARK": mark} if mark else {})}
    proc = subprocess.Popen([sys.executable, "-c", SEGMENT, how], env=env, text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE)  # fmt: skip
    assert proc.stdout is not None
    return proc, proc.stdout.readline().strip()


def _until_seen(watch: ShmWatch, name: str, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 10
    while name not in watch.seen:
        assert proc.poll() is None and time.monotonic() < deadline, "the watch never saw it"
        time.sleep(0.01)


def test_a_segment_the_marked_tree_held_and_left_is_reported(segments: list[str]) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark).start()
    proc, name = _start("leak", mark)
    segments.append(name)
    _until_seen(watch, name, proc)
    proc.kill()
    proc.wait()
    watch.stop()
    assert watch.leaked(grace_s=0.2) == {name}


def test_a_segment_made_and_abandoned_between_two_looks_is_reported(segments: list[str]) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark, every_s=3600).start()  # no look while the process lives
    proc, name = _start("leak", mark)
    segments.append(name)
    proc.communicate("")
    watch.stop()
    assert name not in watch.seen
    assert watch.leaked(grace_s=0.2) == {name}


def test_a_segment_another_process_holds_is_not_reported(segments: list[str]) -> None:
    mark = uuid.uuid4().hex
    watch = ShmWatch(mark).start()
    ours, our_name = _start("hold", mark)  # held, then unlinked: no leak
    other, name = _start("hold", None)  # made while the watch runs, by an unmarked process
    segments += [our_name, name]
    _until_seen(watch, our_name, ours)
    ours.communicate("")
    watch.stop()
    try:
        assert name in shm_segments() - watch.before
        assert watch.leaked(grace_s=0.2) == set()
    finally:
        other.communicate("")
    assert name not in shm_segments()
