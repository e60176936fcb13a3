"""The access privilege of a robot (D-RCTP-16): which session may write which subtree.

A robot has one table, shared by all its sessions. A session holds a path and everything below
it. No two sessions hold overlapping paths (R-RCTP-37). One request at a time changes the table,
so the second of two close ACQUIREs sees the first.
"""

from __future__ import annotations

from collections.abc import Iterator

from rcmlconf.rcml.paths import is_within
from rcmlconf.rctp.targets import ROOT


def _ancestors(path: str) -> Iterator[str]:
    """The path itself and every path above it, up to `/`."""
    while path != ROOT:
        yield path
        path = path.rsplit("/", 1)[0] or ROOT
    yield ROOT


class Privileges:
    def __init__(self) -> None:
        #: Held path -> the session holding it.
        self._held: dict[str, str] = {}

    def holder(self, path: str) -> str | None:
        """The session whose privilege covers `path` (it holds the path or a path above)."""
        for above in _ancestors(path):
            session = self._held.get(above)
            if session is not None:
                return session
        return None

    def covers(self, session: str, path: str) -> bool:
        return self.holder(path) == session

    def conflict(self, session: str, path: str) -> str | None:
        """Another session holding the path, a path above it or a path below it (R-RCTP-33)."""
        holder = self.holder(path)
        if holder is not None and holder != session:
            return holder
        return next(
            (s for held, s in self._held.items() if s != session and is_within(held, path)), None
        )

    def acquire(self, session: str, path: str) -> bool:
        """Take `path` for `session`; False when another session holds an overlapping path.
        Acquiring what the session holds already, or a path below it, changes nothing."""
        if self.conflict(session, path) is not None:
            return False
        self._take(session, path)
        return True

    def _take(self, session: str, path: str) -> None:
        """Give `path` to `session`, whatever other sessions hold."""
        if self.covers(session, path):
            return
        # What the session held below the new path is now part of it.
        for held in [h for h, s in self._held.items() if s == session and is_within(h, path)]:
            del self._held[held]
        self._held[path] = session

    def release(self, session: str, path: str) -> bool:
        """Give back a path the session acquired; False when it does not hold exactly that."""
        if self._held.get(path) != session:
            return False
        del self._held[path]
        return True

    def release_all(self, session: str) -> tuple[str, ...]:
        """Everything the session holds (RELEASE *, or the session's end, R-RCTP-36)."""
        paths = tuple(h for h, s in self._held.items() if s == session)
        for path in paths:
            del self._held[path]
        return paths

    def held_by(self, session: str) -> tuple[str, ...]:
        return tuple(sorted(h for h, s in self._held.items() if s == session))
