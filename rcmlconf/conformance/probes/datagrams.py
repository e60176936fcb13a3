"""What the RSP probes share, whichever side the harness plays (`rsp_probe.RspProbe` the local
system, `local_probe.LocalProbe` the robot): the datagrams received so far, in order, decoded (the
first FIRST and the last LAST of them: a peer sends more only in a flood, and the rest are
counted), and bounded waits for the next one of some types; `answer_to` sends again what the
case's impairment spoiled."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Iterable

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where
from rcmlconf.conformance.transcript import Transcript
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.errors import ProtocolError
from rcmlconf.rsp.codec import PacketType

#: Packets `answer_to` sends at most while the impairment spoils them. They go at once, one
#: after the other, so a loss burst (`burst`, counted in datagrams) takes several in a row: with
#: a mean burst of 3, all twelve are lost about once in a hundred bursts; at 20 % independent
#: loss, never.
ANSWER_TRIES = 12
#: Datagrams a probe keeps of those it received, from the first and from the last: more than a
#: session of the longest case sends at the shortest period (D-RSP-13).
FIRST, LAST = 1000, 4000


def kept_log() -> Kept[Datagram]:
    """What a probe keeps of what it received (`DatagramLog.received`)."""
    return Kept(FIRST, LAST)


class DatagramLog:
    """Mixed into a probe that keeps `received` (decoded, in arrival order), sets `_arrival` on
    each, keeps the first undecodable datagram's failure in `fault` (`_fail`), has `wait`, `now`
    and a `transcript`, and counts in `spoiled` the datagrams it sent of which its impairment let
    no intact copy through."""

    received: Kept[Datagram]
    fault: Failed | None
    wait: float
    spoiled: int
    transcript: Transcript
    _arrival: asyncio.Event

    @property
    def now(self) -> float:
        raise NotImplementedError

    @property
    def _who(self) -> str:
        """What marks the probe's lines in the transcript (nothing by default)."""
        return ""

    def _fail(self, rule: str, expected: str, data: bytes, error: ProtocolError) -> None:
        """A datagram the codec refuses: noted, and the first one's failure kept for `check`."""
        actual = f"{error.reason} at byte {error.offset} of {data[:32].hex()}"
        self.transcript.note(f"{self._who}<- {len(data)} bytes the codec refuses: {actual}")
        if self.fault is None:
            self.fault = Failed(rule, expected, actual)

    def keep(self, found: Datagram) -> None:
        """`found` into `received`; the first time that leaves one out, the transcript says so."""
        self.received.append(found)
        if self.received.left_out == 1:
            self.transcript.note(
                f"{self._who}the probe keeps the first {FIRST} and the last {LAST} datagrams it"
                " receives: it leaves out the rest (counted when it closes)"
            )

    def noted_left_out(self) -> None:
        """When the probe closes: how many of what it received it left out, if any."""
        if self.received.left_out:
            self.transcript.note(
                f"{self._who}the probe left out {self.received.left_out} of the"
                f" {len(self.received)} datagrams it received"
            )

    def check(self) -> None:
        """Fail the case if the peer sent a datagram the codec could not read."""
        if self.fault is not None:
            raise self.fault

    def mark(self) -> int:
        """A place in `received`: `packets(after=...)` and `next(after=...)` start there."""
        return len(self.received)

    def packets(
        self, kinds: Iterable[PacketType] | PacketType | None = None, *, after: int = 0
    ) -> list[Datagram]:
        wanted = _kinds(kinds)
        return [d for d in self.received[after:] if wanted is None or d.type in wanted]

    async def next(
        self,
        kinds: Iterable[PacketType] | PacketType | None = None,
        *,
        after: int | None = None,
        wait: float | None = None,
        where: Where | None = None,
    ) -> Datagram | None:
        """The first datagram from `after` (by default: from now) of one of `kinds` for which
        `where` holds; None if none came within `wait`."""
        wanted = _kinds(kinds)
        start = self.mark() if after is None else after
        deadline = self.now + (self.wait if wait is None else wait)
        while True:
            self.check()
            for found in self.received[start:]:
                if (wanted is None or found.type in wanted) and (where is None or where(found)):
                    return found
            start = len(self.received)
            remaining = deadline - self.now
            if remaining <= 0:
                return None
            self._arrival.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._arrival.wait(), remaining)

    async def expect(
        self,
        kinds: Iterable[PacketType] | PacketType,
        requirement: str,
        *,
        after: int | None = None,
        wait: float | None = None,
        where: Where | None = None,
        expected: str = "",
    ) -> Datagram:
        """As `next`, but Failed (`requirement`) when nothing comes."""
        found = await self.next(kinds, after=after, wait=wait, where=where)
        if found is None:
            raise self._nothing(kinds, requirement, wait, expected)
        return found

    async def answer_to(
        self,
        send: Callable[[], object],
        kinds: Iterable[PacketType] | PacketType,
        *,
        where: Where | None = None,
        wait: float | None = None,
    ) -> Datagram | None:
        """Call `send` (it sends one new packet) and return the first answer of `kinds` for which
        `where` holds, or None if none came within `wait`. While the case's impairment spoils
        what `send` sent, `send` is called again at once, as a local system repeats a HELLO or
        a reliable item that went unanswered (D-RSP-12, D-RSP-16), up to ANSWER_TRIES times in
        all; Inconclusive if it spoiled them all. Without an impairment: one packet, one wait."""
        start = self.mark()
        if not self.send_intact(send):
            raise Inconclusive(f"the impairment lost or corrupted all {ANSWER_TRIES} packets sent")
        return await self.next(kinds, after=start, where=where, wait=wait)

    def send_intact(self, send: Callable[[], object]) -> bool:
        """Call `send` (it sends one new packet), and again at once while the case's impairment
        spoils what it sent, up to ANSWER_TRIES times in all; False if it spoiled them all."""
        for _ in range(ANSWER_TRIES):
            spoiled = self.spoiled
            send()
            if self.spoiled == spoiled:
                return True
        return False

    async def expect_answer_to(
        self,
        send: Callable[[], object],
        kinds: Iterable[PacketType] | PacketType,
        requirement: str,
        *,
        where: Where | None = None,
        wait: float | None = None,
        expected: str = "",
    ) -> Datagram:
        """As `answer_to`, but Failed (`requirement`) when no answer comes."""
        found = await self.answer_to(send, kinds, where=where, wait=wait)
        if found is None:
            raise self._nothing(kinds, requirement, wait, expected)
        return found

    def _nothing(
        self,
        kinds: Iterable[PacketType] | PacketType,
        requirement: str,
        wait: float | None,
        expected: str,
    ) -> Failed:
        names = "/".join(k.name for k in sorted(_kinds(kinds) or ()))
        seconds = self.wait if wait is None else wait
        return Failed(requirement, expected or names, f"nothing within {seconds:.2g} s")

    async def listen(self, seconds: float) -> None:
        """Let `seconds` pass (the probe keeps receiving, and answering what it answers)."""
        await asyncio.sleep(max(seconds, 0.0))
        self.check()

    async def received_within(
        self,
        seconds: float,
        kinds: Iterable[PacketType] | PacketType | None = None,
        *,
        session: int | None = None,
    ) -> list[Datagram]:
        """Let `seconds` pass (as `listen`) and return the datagrams of `kinds` that came (of
        `session` alone, if given: another session's are no packets of it)."""
        start = self.mark()
        await self.listen(seconds)
        found = self.packets(kinds, after=start)
        return [d for d in found if session is None or d.header.session_id == session]


def _kinds(kinds: Iterable[PacketType] | PacketType | None) -> frozenset[PacketType] | None:
    if kinds is None:
        return None
    if isinstance(kinds, PacketType):
        return frozenset({kinds})
    return frozenset(kinds)
