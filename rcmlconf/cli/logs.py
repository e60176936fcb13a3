"""The reference implementations' logs (`serve -v`, `robot -v`) as lines on stdout."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager

from rcmlconf.cli.console import Output


class _LogLines(logging.Handler):
    """A reference implementation's log (one line per request, session or stream event),
    through `Output`."""

    def __init__(self, output: Output, name: str) -> None:
        super().__init__()
        self.output = output
        self.logger_name = name

    def emit(self, record: logging.LogRecord) -> None:
        try:
            stamp = time.strftime("%H:%M:%S", time.localtime(record.created))
            style = "bold red" if record.levelno >= logging.WARNING else ""
            self.output.live(
                [(f"{stamp}.{int(record.msecs):03d} ", "dim"), (record.getMessage(), style)]
            )
        except OSError:  # the reader went away (`| head`): the server goes on, unlogged
            logging.getLogger(self.logger_name).removeHandler(self)
        except Exception:  # logging's contract: a handler never raises into the code that logs
            self.handleError(record)


@contextmanager
def log_lines(output: Output, verbose: int, name: str) -> Iterator[None]:
    """-v: the INFO lines of logger `name` on stdout, -vv its DEBUG lines too; none otherwise."""
    if not verbose:
        yield
        return
    logger = logging.getLogger(name)
    handler = _LogLines(output, name)
    level, propagate = logger.level, logger.propagate
    logger.setLevel(logging.DEBUG if verbose > 1 else logging.INFO)
    logger.addHandler(handler)
    logger.propagate = False  # printed once, here, not again by a handler of the root logger
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
        logger.propagate = propagate
