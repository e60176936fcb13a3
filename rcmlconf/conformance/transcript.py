"""What a case exchanged with the target, for the report of a failure (one line a message or
event, timed from the case's start), for --json and --html (`entries`: the same lines and the
payloads, as data) and for --capture (`capture`: the payloads with their endpoints).

Bounded, whatever the target sends (a flood of datagrams must not grow the harness without end):
of the lines, the first LINES and the last LINES are kept; of each flow (one way of a TCP
connection or of a UDP source and destination), the first KEPT payloads and the last KEPT, each
end at most KEPT_BYTES of them; of FLOWS flows at most. What lies between is counted, and said
once, where it was: a `LeftOut` among the entries and the lines, a `Gap` in the capture.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

from rcmlconf.conformance.kept import Kept
from rcmlconf.pcap.writer import Gap, Payload

Address = tuple[str, int]
#: Characters of a message shown in a line; the rest is elided (the capture has it all).
SHOWN = 160
#: Lines kept from the start of the exchange, and as many from its end.
LINES = 1000
#: Payloads (datagrams, TCP reads) of a flow kept from its start, and as many from its end.
KEPT = 1000
#: Bytes of payload each end of a flow keeps at most (one payload at least).
KEPT_BYTES = 256 * 1024
#: Flows whose payloads are kept; those of the flows past them are counted only.
FLOWS = 64
#: Characters of a line kept at most: a longer note is cut.
LINE_CHARS = 2000
#: What the line of a `LeftOut` says, after what it counts (the reports find it by this).
LEFT_OUT = " left out ("
#: A flow: its transport, source and destination.
Flow = tuple[str, Address, Address]


@dataclass(frozen=True, slots=True)
class LeftOut:
    """What the transcript left out in one place: `count` lines (`what` "lines"), or `count`
    payloads of `size` bytes of one flow (`what` its transport), or of the flows past FLOWS
    (`what` "flows", no endpoints); the first at `first` s from the case's start, the last at
    `last`."""

    what: str
    count: int
    size: int
    first: float
    last: float
    source: Address | None = None
    destination: Address | None = None

    @property
    def text(self) -> str:
        span = f"from {self.first:.3f} s to {self.last:.3f} s"
        if self.what == "lines":
            return f"... {self.count} lines of the exchange{LEFT_OUT}{span})"
        if self.source is None or self.destination is None:
            where = f"the flows past the first {FLOWS}"
        else:
            where = f"{self.what} {address_text(self.source)} -> {address_text(self.destination)}"
        what = "datagrams" if self.what == "udp" else "payloads"
        return f"... {self.count} {what} ({self.size} bytes) of {where}{LEFT_OUT}{span})"


@dataclass(frozen=True, slots=True)
class Entry:
    """A line of the exchange, a payload that crossed, or what was left out between them, `at`
    seconds from the case's start."""

    at: float
    text: str | None = None
    payload: Payload | None = None
    left_out: LeftOut | None = None


#: An entry and its place among all the case noted: odd for what was noted, even for a
#: `LeftOut` (just before the first entry kept after it).
_Placed = tuple[int, Entry]


def _size(placed: _Placed) -> int:
    payload = placed[1].payload
    return len(payload.data) if payload is not None else 0


def _left_out(kept: Kept[_Placed], what: str, flow: Flow | None = None) -> LeftOut:
    """What `kept` left out (of `what`: lines, or a flow's transport)."""
    assert kept.first_left_out is not None
    assert kept.last_left_out is not None
    first, last = kept.first_left_out[1].at, kept.last_left_out[1].at
    _, source, destination = flow or ("", None, None)
    return LeftOut(what, kept.left_out, kept.left_out_size, first, last, source, destination)


def _placed(kept: Kept[_Placed], what: str, flow: Flow | None = None) -> Iterator[_Placed]:
    """What `kept` kept, in order, and a `LeftOut` where the rest was."""
    yield from kept.head
    if kept.left_out:
        left_out = _left_out(kept, what, flow)
        yield kept.tail[0][0] - 1, Entry(left_out.last, left_out=left_out)
    yield from kept.tail


@dataclass
class Transcript:
    start: float = field(default_factory=time.monotonic)
    wall_start: float = field(default_factory=time.time)
    #: The nodes and devices the case's requests and packets named, in the order first named:
    #: which of the robot's a case chose decides what its check can show (`run -v`, --json).
    used: list[str] = field(default_factory=list)
    _labels: dict[str, int] = field(default_factory=dict)
    #: How many entries were noted: each one's place (odd: `_Placed`).
    _noted: int = 0
    _lines: Kept[_Placed] = field(default_factory=lambda: Kept(LINES, LINES))
    #: Each flow's payloads, and its endpoints (one copy for all its payloads).
    _flows: dict[Flow, tuple[Flow, Kept[_Placed]]] = field(default_factory=dict)
    #: The payloads of the flows past FLOWS: each left out, counted.
    _beyond: Kept[_Placed] = field(default_factory=lambda: Kept(0, 0, _size))

    def uses(self, *names: str) -> None:
        """The case named these nodes or devices (each kept once)."""
        self.used.extend(name for name in names if name not in self.used)

    def label(self, prefix: str) -> str:
        """`c1`, `c2`, ...: a name for the next connection (or flow) of `prefix` in this case."""
        self._labels[prefix] = self._labels.get(prefix, 0) + 1
        return f"{prefix}{self._labels[prefix]}"

    def _place(self) -> int:
        self._noted += 1
        return 2 * self._noted + 1

    def note(self, text: str) -> None:
        if len(text) > LINE_CHARS:
            text = f"{text[:LINE_CHARS]}... ({len(text)} characters)"
        self._lines.append((self._place(), Entry(time.monotonic() - self.start, text=text)))

    def notes(self, texts: list[str]) -> None:
        for text in texts:
            self.note(text)

    def sent(self, what: str, data: bytes) -> None:
        self.note(f"{_arrow(what, '->')} {show(data)}")

    def received(self, what: str, data: bytes) -> None:
        self.note(f"{_arrow(what, '<-')} {show(data)}")

    def packet(self, transport: str, source: Address, destination: Address, data: bytes) -> None:
        """A TCP payload or UDP datagram that crossed, from `source` to `destination`."""
        since = time.monotonic() - self.start
        flows = self._flows
        key = (transport, source, destination)
        found = flows.get(key)
        if found is None:
            if len(flows) >= FLOWS:
                found = (key, self._beyond)
            else:
                found = flows[key] = (key, Kept(KEPT, KEPT, _size, KEPT_BYTES))
        (_, source, destination), kept = found
        payload = Payload(self.wall_start + since, transport, source, destination, data)
        kept.append((self._place(), Entry(since, payload=payload)))

    def crossed(self, transport: str, port: int) -> tuple[bool, bool]:
        """Whether a payload of `transport` went to `port`, and whether one came from it (kept
        or left out: a flow past FLOWS counts as both)."""
        beyond = self._beyond.left_out > 0
        flows = [
            (source[1], destination[1]) for t, source, destination in self._flows if t == transport
        ]
        return (
            beyond or any(to == port for _, to in flows),
            beyond or any(source == port for source, _ in flows),
        )

    # -- what was kept -------------------------------------------------------------------------

    def _placed(self) -> list[_Placed]:
        placed = list(_placed(self._lines, "lines"))
        for flow, kept in self._flows.values():
            placed += _placed(kept, flow[0], flow)
        if self._beyond.left_out:  # at the end: they were of no flow kept
            left_out = _left_out(self._beyond, "flows")
            placed.append((2 * self._noted + 2, Entry(left_out.last, left_out=left_out)))
        placed.sort(key=lambda p: p[0])
        return placed

    @property
    def entries(self) -> list[Entry]:
        """The lines and payloads kept, as they came, and a `LeftOut` where any were left out:
        what the reports keep as data."""
        return [entry for _, entry in self._placed()]

    @property
    def lines(self) -> list[str]:
        """The lines kept, timed, and one that says how many were left out where they were."""
        return [
            f"{entry.at:7.3f}  {entry.text if entry.left_out is None else entry.left_out.text}"
            for _, entry in _placed(self._lines, "lines")
        ]

    @property
    def capture(self) -> list[Payload | Gap]:
        """The payloads kept, for --capture, and a `Gap` before the first payload of a flow kept
        after some of it was left out (or, for the flows past FLOWS, at the end)."""
        found: list[Payload | Gap] = []
        for _, entry in self._placed():
            if entry.payload is not None:
                found.append(entry.payload)
            elif entry.left_out is not None and entry.left_out.what != "lines":
                left = entry.left_out
                said = f"rcmlconf {left.text.removeprefix('... ')}"
                if left.source is not None:
                    said += ", before this packet"
                found.append(Gap(left.source, left.destination, left.what, said, left.size))
        return found


def _arrow(what: str, arrow: str) -> str:
    """`c1 ->`, or `->` alone: the name of the connection leads."""
    return f"{what} {arrow}" if what else arrow


def address_text(address: Address) -> str:
    """HOST:PORT, an IPv6 host in brackets."""
    host, port = address[:2]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def show(data: bytes) -> str:
    """Bytes as a readable one-liner: CRLF as ⏎, other controls escaped, elided past SHOWN."""
    text = data[:SHOWN].decode("latin-1").replace("\r\n", "⏎")
    text = "".join(c if c.isprintable() or c == "⏎" else f"\\x{ord(c):02x}" for c in text)
    return text + (f"… ({len(data)} bytes)" if len(data) > SHOWN else "")
