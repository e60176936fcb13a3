"""A session with an RSP robot packet by packet, as a case drives it (`RawSession`, made by
`hand_driven`): the core's `SessionWire` numbers, stamps and seals what the case builds, the case
may alter the bytes before they go, skip or rewind sequence numbers, and the BYE that ends the
case is numbered so that the robot takes it whatever the case did to the numbering."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import came
from rcmlconf.conformance.probes.rsp_datagram import (
    SEQUENCE_SPACE,
    SESSION_AT,
    Datagram,
    newer,
    sequence_of,
)
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.rsp_numbers import HELLO_INTERVAL
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.rsp.codec import (
    Bye,
    ByeReason,
    Encryption,
    Hello,
    Item,
    MapBody,
    PacketType,
    Refused,
    Welcome,
)
from rcmlconf.rsp.codec.bodies import Body
from rcmlconf.rsp.layout import MAC_SIZE, NONCE_SIZE
from rcmlconf.rsp.security import Direction
from rcmlconf.rsp.session.wire import SessionWire

#: What the robot's answer to a HELLO is due by, as `came`'s `expected` cites it.
BEFORE_REPEAT = (
    f"before the local system's first repeat of its HELLO (D-RSP-12: {HELLO_INTERVAL * 1000:g} ms)"
)


def hand_driven(
    probe: RspProbe,
    encryption: Encryption = Encryption.NONE,
    *,
    period_ms: int | None = None,
    nonce: bytes | None = None,
    psk: bytes | None = None,
) -> RawSession:
    """A session the case drives packet by packet on `probe`'s socket (`RawSession`)."""
    if encryption is not Encryption.NONE and (psk or probe.psk) is None:
        raise NotApplicable("the robot's pre-shared key is not known (ICS [rsp] psk-file)")
    raw = RawSession(probe, encryption, period_ms, nonce, psk or probe.psk)
    probe.adopt(raw)
    return raw


class RawSession:
    """A session packet by packet: the core's `SessionWire` numbers, stamps and seals what the
    case builds; the case may alter the bytes before they go (`send(..., mutate=...)`)."""

    def __init__(
        self,
        probe: RspProbe,
        encryption: Encryption,
        period_ms: int | None,
        nonce: bytes | None,
        psk: bytes | None,
    ) -> None:
        self.probe = probe
        self.wire = SessionWire(probe.codec, encryption, Direction.DOWNLINK)
        self.encryption = encryption
        self.period_ms = round(probe.model.period * 1000) if period_ms is None else period_ms
        self.nonce = os.urandom(NONCE_SIZE) if nonce is None else nonce
        self.psk = psk
        self.welcome: Datagram | None = None
        self.ended = False
        #: Items every `downlink` carries besides its own (the requests a local system repeats in
        #: every DOWNLINK, R-RSP-23): a device the call names itself is not added twice.
        self.standing: list[Item] = []
        #: The last packet `send` sent (as it went, altered or not).
        self.last = b""

    @property
    def session_id(self) -> int:
        return self.wire.session_id

    @property
    def period(self) -> float:
        """T in force, seconds: WELCOME's, else HELLO's."""
        if self.welcome is not None and isinstance(self.welcome.body, Welcome):
            return self.welcome.body.period_ms / 1000
        return self.period_ms / 1000

    @property
    def next_sequence(self) -> int:
        return self.wire.sent % SEQUENCE_SPACE

    def hello(self, *, psk: bytes | None = None) -> bytes:
        """Send HELLO (the next sequence number, this session's nonce); `psk` signs it instead
        of the robot's key (a wrong one, for the cases that want it refused)."""
        signed = self.encryption is not Encryption.NONE
        body = Hello(self.nonce, self.period_ms, bytes(MAC_SIZE) if signed else b"")
        data = self.wire.build(PacketType.HELLO, body, self.probe.now, 0, psk or self.psk)
        self.probe.send(data)
        self.last = data
        return data

    async def open(self) -> Datagram:
        """HELLO and the robot's WELCOME; Inconclusive when it refuses or does not answer."""
        answer = await self.probe.answer_to(
            self.hello,
            (PacketType.WELCOME, PacketType.REFUSED),
            where=lambda d: (
                d.type is PacketType.REFUSED
                or (isinstance(d.body, Welcome) and d.body.client_nonce == self.nonce)
            ),
        )
        if answer is None:
            raise Inconclusive(f"no answer to HELLO within {self.probe.wait:.2g} s")
        if isinstance(answer.body, Refused):
            raise Inconclusive(f"the robot refused the session: {answer.body.reason.name}")
        if self.welcome is None:
            self.accept(answer)
        return answer

    async def expect_welcome(
        self, ctx: Context, requirement: str, expected: str = "WELCOME"
    ) -> Datagram:
        """HELLO and the robot's answer, as `open`, for a case that checks the handshake itself:
        Failed (`requirement`, `expected`) when it refuses or does not answer (`came`), and any
        WELCOME taken (its nonce is the case's to check)."""
        answer = await came(
            ctx,
            self.probe,
            (PacketType.WELCOME, PacketType.REFUSED),
            f"{expected}, {BEFORE_REPEAT}",
            requirement,
            send=self.hello,
        )
        if isinstance(answer.body, Refused):
            raise Failed(requirement, expected, f"REFUSED {answer.body.reason.name}")
        if self.welcome is None:
            self.accept(answer)
        return answer

    def welcomed(self, found: Datagram) -> None:
        """A WELCOME the probe read: the session's, if it answers this session's HELLO first."""
        body = found.body
        if isinstance(body, Welcome) and body.client_nonce == self.nonce and not self.session_id:
            self.accept(found)

    def closing_bye(self) -> bytes | None:
        """The BYE that ends the session with the case (`last_bye`), if it is open."""
        return self.last_bye() if self.session_id and not self.ended else None

    def accept(self, welcome: Datagram) -> None:
        """The robot's WELCOME: the session's ID, and its keys (D-RSP-21)."""
        body = welcome.body
        assert isinstance(body, Welcome)
        self.welcome = welcome
        self.wire.session_id = welcome.header.session_id
        self.wire.tracker.see(welcome.header.sequence)
        self.wire.secure(self.psk or b"", self.nonce, body.robot_nonce)

    def build(self, kind: PacketType, body: Body, *, buffer: int = 0) -> bytes:
        """The next packet of the session (numbered, stamped, sealed)."""
        if kind is PacketType.BYE:
            self.ended = True
        return self.wire.build(kind, body, self.probe.now, buffer, self.psk)

    def send(
        self,
        kind: PacketType,
        body: Body,
        *,
        buffer: int = 0,
        mutate: Callable[[bytes], bytes] | None = None,
        what: str = "",
    ) -> bytes:
        """Build the next packet, alter it with `mutate`, send it; the bytes sent."""
        data = self.build(kind, body, buffer=buffer)
        if mutate is not None:
            data = mutate(data)
        self.probe.send(data, what)
        self.last = data
        return data

    def downlink(
        self,
        items: Iterable[Item] = (),
        *,
        buffer: int = 0,
        mutate: Callable[[bytes], bytes] | None = None,
        what: str = "",
    ) -> bytes:
        """A DOWNLINK of `items` and the standing ones (in any order: sorted into model order)."""
        given = {item.device: item for item in self.standing}
        given.update((item.device, item) for item in items)
        body = MapBody(tuple(given[device] for device in sorted(given)))
        return self.send(PacketType.DOWNLINK, body, buffer=buffer, mutate=mutate, what=what)

    def bye(self, reason: ByeReason = ByeReason.CLOSED) -> bytes:
        """BYE, sent again while the impairment spoils it (the robot answers none, and a case
        ending the session means it: the next one must not be refused as busy); the last sent."""
        self.probe.send_intact(lambda: self.send(PacketType.BYE, Bye(reason)))
        return self.last

    def last_bye(self) -> bytes:
        """The BYE that ends the case, numbered after the newest sequence number the robot can
        have taken: the last it reported (R-RSP-15), or one of ours newer than that. A case that
        skipped or rewound numbers, or lost some to the impairment, may have left the robot
        behind our own count, where a BYE would be dropped as stale (D-RSP-15) and the robot
        kept busy."""
        mine = [d for d in self.probe.received if d.header.session_id == self.session_id]
        newest = mine[-1].header.last_received if mine else 0
        for _, data in self.probe.sent:
            if int.from_bytes(data[SESSION_AT : SESSION_AT + 6]) == self.session_id:
                sequence = sequence_of(data)
                if newer(sequence, newest):
                    newest = sequence
        self.wire.sent = newest + 1
        return self.build(PacketType.BYE, Bye(ByeReason.CLOSED))

    def skip(self, packets: int) -> None:
        """Number the next packet `packets` further on, as if that many had been lost."""
        self.wire.sent += packets

    def rewind(self, sequence: int) -> None:
        """Number the next packet `sequence` (a late or repeated number, on purpose)."""
        self.wire.sent = sequence
