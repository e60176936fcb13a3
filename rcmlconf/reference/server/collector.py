"""The garbage collector of a process that serves (`rcmlconf serve`): short pauses under load.

Python's cyclic collector stops the process while it runs, and a pass over a generation takes
time in proportion to the objects in it. A serving process under a flood (D-RCTP-32) makes many
short-lived objects that survive a pass or two, and with a thousand connections open a pass over
the oldest generation walks every one of them. The CPU each pass took under the mix of
bench/hostile_load.py (--turns, 30 s, two runs each):

- Python's thresholds (700, 10, 10): the youngest's at most 2.6 to 3.7 ms, the middle's 4.7 to
  6.2, the oldest's 14 to 25 ms, four or five times in 30 s;
- the youngest's every 10,000 allocations (this module's earlier choice, to make the oldest's
  rare): the youngest's 4.5 to 7 ms at the median and up to 16, the middle's 22 to 34 ms;
- Python's, the oldest's every 100 middle passes rather than 10: at most 2.1 and 4.7 ms, and no
  pass of the oldest in 30 s, the RSS's growth the same (28 to 38 MiB).

A request that comes during a pass waits for it: so the youngest and middle generations are
collected as often as Python would, in passes of a few milliseconds, and the oldest ten times less
often; it has little to free (the adapter breaks the cycle of each closed transport of asyncio's:
the passes then freed 5,000 objects in 30 s rather than 250,000, and a 60 s mix saw no pass of the
oldest). The process also freezes what it holds once listening
(its modules and the robot's model, alive until it exits: never walked again). The setting is the
process's, not the server's: an application that embeds the server among other work chooses its
own.
"""

from __future__ import annotations

import gc

#: Middle generation passes between two of the oldest (Python's: 10).
OLD_THRESHOLD = 100


def settle() -> None:
    """Once listening: freeze what the process holds, and collect the oldest generation less
    often."""
    gc.freeze()
    young, middle, _old = gc.get_threshold()
    gc.set_threshold(young, middle, OLD_THRESHOLD)
