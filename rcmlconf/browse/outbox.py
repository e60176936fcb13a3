"""What the bridge has for its page, waiting until the WebSocket takes it.

Values are the robot's state, not its history (D-RCTP-20): while the page is slower than the
robot, a node's newer value replaces the one waiting, as rosbridge's throttle and queue options
do, so nothing grows and the page always gets the latest. Other messages (states, refusals) keep
their order, at most MAX_NOTES of them; beyond that the oldest go and the page is told how many.
"""

from __future__ import annotations

import asyncio
from collections import deque

from rcmlconf.browse.messages import message

MAX_NOTES = 256


class Outbox:
    def __init__(self) -> None:
        #: Robot href -> node path -> its newest text not yet sent.
        self._values: dict[str, dict[str, str]] = {}
        #: Robot href -> when the robot sent the newest stream values waiting (Unix seconds).
        self._sent: dict[str, float] = {}
        self._notes: deque[dict[str, object]] = deque()
        self._dropped = 0
        self._ready = asyncio.Event()

    def values(self, robot: str, values: dict[str, str], sent: float | None = None) -> None:
        """`sent`: the robot's time of sending, for stream values (the page may show their age)."""
        self._values.setdefault(robot, {}).update(values)
        if sent is not None:
            self._sent[robot] = max(sent, self._sent.get(robot, sent))
        self._ready.set()

    def note(self, kind: str, **fields: object) -> None:
        if len(self._notes) >= MAX_NOTES:
            self._notes.popleft()
            self._dropped += 1
        self._notes.append(message(kind, **fields))
        self._ready.set()

    async def take(self) -> list[dict[str, object]]:
        """Everything waiting, notes first, once there is something."""
        while not self._notes and not self._values:
            self._ready.clear()
            await self._ready.wait()
        taken = list(self._notes)
        if self._dropped:
            taken.append(message("dropped", count=self._dropped))
        for robot, values in self._values.items():
            sent = self._sent.get(robot)
            extra = {} if sent is None else {"sent": sent}
            taken.append(message("values", robot=robot, values=values, **extra))
        self._notes.clear()
        self._values = {}
        self._sent = {}
        self._dropped = 0
        return taken
