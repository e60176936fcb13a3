"""What a case exchanged with the target, for the report of a failure (one line a message or
event, timed from the case's start), for --json and --html (`entries`: the same lines and every
payload, as data) and for --capture (every payload with its endpoints)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from rcmlconf.pcap.writer import Payload

Address = tuple[str, int]
#: Characters of a message shown in a line; the rest is elided (the capture has it all).
SHOWN = 160


@dataclass(frozen=True, slots=True)
class Entry:
    """A line of the exchange or a payload that crossed, `at` seconds from the case's start."""

    at: float
    text: str | None = None
    payload: Payload | None = None


@dataclass
class Transcript:
    start: float = field(default_factory=time.monotonic)
    lines: list[str] = field(default_factory=list)
    #: Every TCP payload and UDP datagram sent and received, for --capture.
    packets: list[Payload] = field(default_factory=list)
    wall_start: float = field(default_factory=time.time)
    #: The nodes and devices the case's requests and packets named, in the order first named:
    #: which of the robot's a case chose decides what its check can show (`run -v`, --json).
    used: list[str] = field(default_factory=list)
    #: `lines` and `packets` as they came, in one list: what the reports keep as data.
    entries: list[Entry] = field(default_factory=list)
    _labels: dict[str, int] = field(default_factory=dict)

    def uses(self, *names: str) -> None:
        """The case named these nodes or devices (each kept once)."""
        self.used.extend(name for name in names if name not in self.used)

    def label(self, prefix: str) -> str:
        """`c1`, `c2`, ...: a name for the next connection (or flow) of `prefix` in this case."""
        self._labels[prefix] = self._labels.get(prefix, 0) + 1
        return f"{prefix}{self._labels[prefix]}"

    def note(self, text: str) -> None:
        at = time.monotonic() - self.start
        self.lines.append(f"{at:7.3f}  {text}")
        self.entries.append(Entry(at, text=text))

    def notes(self, texts: list[str]) -> None:
        for text in texts:
            self.note(text)

    def sent(self, what: str, data: bytes) -> None:
        self.note(f"{_arrow(what, '->')} {show(data)}")

    def received(self, what: str, data: bytes) -> None:
        self.note(f"{_arrow(what, '<-')} {show(data)}")

    def packet(self, transport: str, source: Address, destination: Address, data: bytes) -> None:
        since = time.monotonic() - self.start
        payload = Payload(self.wall_start + since, transport, source, destination, data)
        self.packets.append(payload)
        self.entries.append(Entry(since, payload=payload))


def _arrow(what: str, arrow: str) -> str:
    """`c1 ->`, or `->` alone: the name of the connection leads."""
    return f"{what} {arrow}" if what else arrow


def show(data: bytes) -> str:
    """Bytes as a readable one-liner: CRLF as ⏎, other controls escaped, elided past SHOWN."""
    text = data[:SHOWN].decode("latin-1").replace("\r\n", "⏎")
    text = "".join(c if c.isprintable() or c == "⏎" else f"\\x{ord(c):02x}" for c in text)
    return text + (f"… ({len(data)} bytes)" if len(data) > SHOWN else "")
