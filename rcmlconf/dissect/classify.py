"""Which of our protocols a flow carries: the one rule of `rcmlconf dissect` and of the scapy
layers (`rcmlconf dissect -V`, `rcmlconf sniff`), importable without scapy.

A UDP flow (one direction: source and destination address and port) is classified by its first
datagram: `--decode-as` ports first, then the data-stream endpoints SETUP's answers named
(D-RCTP-18, as Wireshark follows RTSP's SETUP to its RTP ports), then the default ports (UDP 7340
RSP, D-RSP-9; UDP 7330 the data stream, which the reference server serves on its TCP port's
number, D-RCTP-28 leaving it to the server), then, with heuristics on, the datagram itself: a
data-stream packet the core reads (D-RCTP-19) or a header the core's RSP rules take for any model
(D-RSP-10). A TCP connection is RCTP when either port is 7330 (D-RCTP-2) or a `--decode-as` port,
or when it is to a server endpoint already seen speaking RCTP; with heuristics on, one on other
ports is held (`Pending`) until its first bytes are an RCTP start line, or cannot be one.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Generic, TypeVar

from rcmlconf.dissect.records import PROTOCOLS, RCTP, RCTP_DATA, RSP
from rcmlconf.errors import ProtocolError
from rcmlconf.rctp.datastream.packets import VERSION as DATA_VERSION
from rcmlconf.rctp.datastream.packets import pull_packet
from rcmlconf.rctp.messages import METHODS
from rcmlconf.rsp.codec.header import ANY
from rcmlconf.rsp.codec.header import VERSION as RSP_VERSION

#: D-RCTP-2: RCTP's TCP port; D-RSP-9: RSP's UDP port; the reference server's data stream uses
#: its TCP port's number.
DEFAULT_TCP = {7330: RCTP}
DEFAULT_UDP = {7340: RSP, 7330: RCTP_DATA}
#: The start of an RCTP message (D-RCTP-4): a status line, a request line of one of the ten
#: methods (D-RCTP-12), or of another token (a method the peer does not know is still RCTP).
START = re.compile(
    rb"RCTP/[0-9]|(?:" + b"|".join(m.encode() for m in METHODS) + rb") |"
    rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+ [!-~]+ (?i:RCTP)/[0-9]"  # rctp/2.0: another version, 505
)
#: Bytes of each direction looked at, and segments held, before a connection is taken as not RCTP.
LOOK = 16
HELD = 32

#: (source address, source port, destination address, destination port): one direction.
FlowKey = tuple[bytes, int, bytes, int]
Endpoint = tuple[bytes, int]
#: What a caller keeps of each segment of a connection held by `Pending`.
Segment = TypeVar("Segment")


def parse_decode_as(text: str) -> tuple[str, int]:
    """`PROTO=PORT` (`rctp=8000`, `rctp-data=41000`, `rsp=9000`); ValueError for anything else."""
    proto, equals, port = text.partition("=")
    proto = proto.strip().lower()
    if (
        not equals
        or proto not in PROTOCOLS
        or not port.strip().isdigit()
        or not 0 < int(port) < 65536
    ):
        raise ValueError(
            f"{text!r}: give PROTO=PORT with PROTO one of {', '.join(PROTOCOLS)} and a PORT"
            " from 1 to 65535"
        )
    return proto, int(port)


def reverse(key: FlowKey) -> FlowKey:
    return key[2], key[3], key[0], key[1]


class Pending(Generic[Segment]):
    """A TCP connection on ports not known to be RCTP's, held until its first bytes tell: the
    segments meanwhile, in the form the caller replays them, and each direction's first bytes
    (`looked[0]` from the side that sent the first segment seen, `first`)."""

    __slots__ = ("first", "looked", "segments")

    def __init__(self, first: FlowKey) -> None:
        self.first = first
        self.looked = [b"", b""]
        self.segments: list[Segment] = []


class Classifier:
    """The protocol of each flow, by the rules above; it learns as the capture goes on: the
    server endpoints that spoke RCTP and the data-stream endpoints SETUP's answers named."""

    __slots__ = (
        "_decode_as_udp",
        "_udp_ports",
        "data_endpoints",
        "heuristics",
        "servers",
        "tcp_ports",
    )

    def __init__(self, decode_as: Iterable[tuple[str, int]] = (), heuristics: bool = True) -> None:
        self.heuristics = heuristics
        tcp_ports = set(DEFAULT_TCP)
        self._decode_as_udp: dict[int, str] = {}
        for protocol, port in decode_as:
            if protocol == RCTP:
                tcp_ports.add(port)
            else:
                self._decode_as_udp[port] = protocol
        #: RCTP's ports: either end of a connection on one of them is taken as its server.
        self.tcp_ports = frozenset(tcp_ports)
        self._udp_ports = dict(DEFAULT_UDP)
        #: The data stream's endpoints SETUP's answers named (D-RCTP-18).
        self.data_endpoints: set[Endpoint] = set()
        #: Server endpoints seen speaking RCTP: later connections to them are RCTP too.
        self.servers: set[Endpoint] = set()

    # -- UDP -------------------------------------------------------------------------------------

    def udp(self, key: FlowKey, payload: bytes) -> str | None:
        """The protocol of a UDP flow whose first datagram (seen since the last `learn` that
        named new endpoints) is `payload`; None for none of ours."""
        source, sport, destination, dport = key
        chosen = self._decode_as_udp
        if dport in chosen:
            return chosen[dport]
        if sport in chosen:
            return chosen[sport]
        endpoints = self.data_endpoints
        if (destination, dport) in endpoints or (source, sport) in endpoints:
            return RCTP_DATA
        ports = self._udp_ports
        if dport in ports:
            return ports[dport]
        if sport in ports:
            return ports[sport]
        if not self.heuristics or not payload:
            return None
        # The version byte tells which of the two to try: 2 the data stream's, 1 RSP's.
        try:
            if payload[0] == DATA_VERSION:
                pull_packet(payload)
                return RCTP_DATA
            if payload[0] == RSP_VERSION:
                ANY.pull(payload)
                return RSP
        except ProtocolError:
            pass
        return None

    def learn(self, *endpoints: tuple[bytes, int | None]) -> bool:
        """D-RCTP-18: a SETUP's answer named the data stream's endpoints (a port None: not
        named). True when one is new: the UDP flows taken for none of ours are then to be
        classified again, by their next datagram."""
        named = {(address, port) for address, port in endpoints if port is not None}
        fresh = named - self.data_endpoints
        self.data_endpoints |= fresh
        return bool(fresh)

    # -- TCP -------------------------------------------------------------------------------------

    def tcp(self, key: FlowKey) -> bool | None:
        """Whether a connection whose first segment seen went `key`'s way is RCTP by its ports or
        its server (True; a server on an RCTP port is noted), or is not (False); None when its
        first bytes are to tell (heuristics on): hold it in a `Pending`, see `look`."""
        source, sport, destination, dport = key
        ports = self.tcp_ports
        if dport in ports:
            self.servers.add((destination, dport))
            return True
        if sport in ports:
            self.servers.add((source, sport))
            return True
        servers = self.servers
        if (destination, dport) in servers or (source, sport) in servers:
            return True
        return None if self.heuristics else False

    def look(
        self, pending: Pending[Segment], side: int, segment: Segment, payload: bytes
    ) -> bool | None:
        """Hold a segment of a connection from `side` (0: `pending.first`'s), its `payload` added
        to what the side sent first: whether the connection is RCTP, None to wait for more. The
        side of an RCTP one that sent a request line is a client: its peer is noted as a server."""
        pending.segments.append(segment)
        looked = pending.looked
        looked[side] += payload
        if any(START.match(data) for data in looked):
            first = pending.first
            for index, data in enumerate(looked):
                if START.match(data) and not data.startswith(b"RCTP/"):
                    server = first[2:] if index == 0 else first[:2]
                    self.servers.add((server[0], server[1]))
            return True
        if any(len(data) >= LOOK or b"\n" in data for data in looked):
            return False
        return None if len(pending.segments) <= HELD else False
