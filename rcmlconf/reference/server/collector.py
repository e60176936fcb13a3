"""The garbage collector of a process that serves (`rcmlconf serve`): fewer pauses under load.

Python's cyclic collector stops the process while it runs, and a collection of its oldest
generation traverses every object alive. With a thousand connections open (a flood, D-RCTP-32),
each such collection took 40 to 60 ms of CPU and came every 2 to 3 s (bench/hostile_load.py): a
request that arrived meanwhile waited for it, and under the mix of attacks the READ prober's 99th
percentile was 33 ms, against a goal of 20. So a serving process freezes what it holds once
listening (its modules and the robot's model, alive until it exits: never traversed again), and
collects its youngest generation every 10,000 allocations rather than 700, so that the oldest
generation's collections come about fourteen times less often (measured: READ p99 20 ms, stream
gap max 77 ms against 108). The setting is the process's, not the server's: an application that
embeds the server among other work chooses its own.
"""

from __future__ import annotations

import gc

#: Allocations (less deallocations) between two collections of the youngest generation.
YOUNG_THRESHOLD = 10_000


def settle() -> None:
    """Once listening: freeze what the process holds, and collect less often."""
    gc.freeze()
    _young, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_THRESHOLD, middle, old)
