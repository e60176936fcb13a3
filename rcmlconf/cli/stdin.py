"""Standard input, for the commands that read a file named `-` from it."""

from __future__ import annotations

import errno
import sys
from typing import BinaryIO


def standard_input() -> BinaryIO:
    """Standard input's bytes; OSError when the process was started with it closed (`<&-`),
    which a command reports as it reports any file it cannot read."""
    if sys.stdin is None:
        raise OSError(errno.EBADF, "standard input is closed")
    return sys.stdin.buffer
