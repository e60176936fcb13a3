"""A serving process's collector (`collector.settle`), in a process of its own: the setting is
the process's, and must not reach the tests'."""

from __future__ import annotations

import subprocess
import sys

from rcmlconf.reference.server.collector import YOUNG_THRESHOLD

_CHECK = """
import gc
from rcmlconf.reference.server.collector import settle
before = gc.get_threshold()
settle()
after = gc.get_threshold()
print(before[0], after[0], before[1:] == after[1:], gc.get_freeze_count() > 0)
"""


def test_settle_freezes_the_heap_and_collects_the_young_generation_less_often() -> None:
    done = subprocess.run(
        [sys.executable, "-c", _CHECK], capture_output=True, text=True, timeout=60, check=True
    )
    before, after, older_kept, frozen = done.stdout.split()
    assert int(before) < YOUNG_THRESHOLD
    assert int(after) == YOUNG_THRESHOLD
    assert older_kept == "True"
    assert frozen == "True"
