"""Speed idioms for code that runs on every packet or every period, each named once.

Each helper does what a plain form does, only faster. The docstring or comment of each says
what it saves. Use them only where a bench shows the cost: `bench/rsp_codec_speed.py` and
`bench/rsp_pairs_scale.py` measure the RSP paths that use them.
"""

from __future__ import annotations

import enum
from typing import TypeVar

_E = TypeVar("_E", bound=enum.Enum)

#: `make_namedtuple(Item, (a, b, c))` is `Item(a, b, c)` without the class's Python `__new__`.
#: It costs less than half as much, but it fills no defaults and checks no field count.
make_namedtuple = tuple.__new__


def members(kind: type[_E], *names: str) -> tuple[_E, ...]:
    """The members of `kind` by name, to bind as module globals.

    A global is read in about a tenth of the time of `Kind.NAME`, a lookup on the enum's class.
    """
    return tuple(kind[name] for name in names)
