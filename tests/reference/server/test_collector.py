"""A serving process's collector (`collector.settle`), in a process of its own: the setting is
the process's, and must not reach the tests'."""

from __future__ import annotations

import subprocess
import sys

from rcmlconf.reference.server.collector import OLD_THRESHOLD

_CHECK = """
import gc
from rcmlconf.reference.server.collector import settle
before = gc.get_threshold()
settle()
after = gc.get_threshold()
print(before[2], after[2], before[:2] == after[:2], gc.get_freeze_count() > 0)
"""


def test_settle_freezes_the_heap_and_collects_the_oldest_generation_less_often() -> None:
    done = subprocess.run(
        [sys.executable, "-c", _CHECK], capture_output=True, text=True, timeout=60, check=True
    )
    before, after, younger_kept, frozen = done.stdout.split()
    assert int(before) < OLD_THRESHOLD
    assert int(after) == OLD_THRESHOLD
    assert younger_kept == "True"
    assert frozen == "True"
