"""Seeded impairment of UDP flows: loss, bursts, delay, jitter, reordering, duplication, corruption.

- `spec`: `Impairment`, what happens to a direction's datagrams, and its text form
  (`parse_impairment("loss=5%,burst=3,delay=40ms")`).
- `channel`: `ImpairedChannel`, one direction without I/O (time passed in), deterministic for
  a seed.
- `proxy`: `ImpairProxy`, an asyncio UDP proxy that puts a pair of channels on every flow.
"""

from rcmlconf.impair.channel import Counts, ImpairedChannel, channel_pair, derive_seed
from rcmlconf.impair.spec import Impairment, ImpairmentError, parse_impairment

__all__ = [
    "Counts",
    "ImpairedChannel",
    "Impairment",
    "ImpairmentError",
    "channel_pair",
    "derive_seed",
    "parse_impairment",
]
