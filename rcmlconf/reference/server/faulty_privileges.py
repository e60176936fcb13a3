"""The privilege table of a faulty reference server (`reference.faults`).

The rules of privileges live in the core's `Privileges`. The faults are not put there. A faulty
robot makes its table of this subclass instead (`FaultyRobot`). Each fault breaks one rule, in
the method where such a bug would sit.
"""

from __future__ import annotations

from rcmlconf.reference.faults import Fault
from rcmlconf.reference.server.privileges import Privileges


class FaultyPrivileges(Privileges):
    def __init__(self, faults: frozenset[Fault]) -> None:
        super().__init__()
        self.faults = faults

    def acquire(self, session: str, path: str) -> bool:
        if Fault.ACQUIRE_NOT_EXCLUSIVE in self.faults:  # fault: acquire-not-exclusive
            self._take(session, path)  # whoever holds an overlapping path
            return True
        return super().acquire(session, path)

    def release(self, session: str, path: str) -> bool:
        if Fault.RELEASE_UNHELD in self.faults and self._held.get(path) != session:
            return True  # fault: release-unheld
        return super().release(session, path)
