"""A case's exchange as data, for --json and --html: an entry for each line of the transcript
(when, which way, on which connection, what it said) holding the bytes of the payload it tells
of, one for each payload no line tells of (a TCP read that held part of a message, or several;
a datagram the impairment held back), and a note where the transcript left lines or payloads
out (`left_out_json`: how many)."""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from rcmlconf.conformance.transcript import Address, Entry, LeftOut, address_text
from rcmlconf.pcap.writer import Payload

#: The arrows of the transcript's lines (`Transcript.sent`, the probes' notes).
DIRECTIONS = {"->": "sent", "<-": "received", "-x": "withheld"}
#: `c1 -> ...`, `[robot 2] <- ...`, `-> ...`, `h1 connected to ...`: a connection's or a
#: flow's label first, if any, then an arrow, if any.
_LINE = re.compile(
    r"(?:\[(?P<who>[^\]]*)\] |(?P<label>[a-z]\d+) )?(?:(?P<arrow>->|<-|-x) )?(?P<said>.*)",
    re.DOTALL,
)
#: A payload noted this close to the line beside it is the one the line tells of: the probes
#: note both in one step, with no wait between.
_SAME = 0.001


def exchange_json(entries: Sequence[Entry]) -> list[dict[str, Any]]:
    """The entries as JSON objects (the run report's schema, `exchange`), in their order."""
    found = [_entry(e) for e in entries]
    taken = [False] * len(found)
    ours: set[str] = set()
    for index, item in enumerate(found):
        if item["direction"] is not None or taken[index]:  # a line, or a payload told of
            continue
        line = _told(found, taken, index)
        if line is not None:
            line.update({k: item[k] for k in ("transport", "source", "destination", "bytes")})
            taken[index] = True
            ours.add(item["source"] if line["direction"] == "sent" else item["destination"])
    for index, item in enumerate(found):
        if item["direction"] is None and not taken[index]:
            item["direction"] = _way(item, ours)
    return [item for index, item in enumerate(found) if not taken[index]]


def _told(found: list[dict[str, Any]], taken: list[bool], index: int) -> dict[str, Any] | None:
    """The line beside the payload at `index` that tells of it, if any: the one before first."""
    for other in (index - 1, index + 1):
        if not 0 <= other < len(found) or taken[other]:
            continue
        line = found[other]
        told = line["direction"] in ("sent", "received") and line["bytes"] is None
        if told and abs(line["time"] - found[index]["time"]) <= _SAME:
            return line
    return None


def _way(item: dict[str, Any], ours: set[str]) -> str:
    """A payload no line tells of: sent if it left an address of the harness's, received if it
    came to one (as the lines beside the other payloads showed them)."""
    if item["source"] in ours:
        return "sent"
    if item["destination"] in ours:
        return "received"
    return "unknown"


def left_out_json(entries: Sequence[Entry]) -> list[dict[str, Any]]:
    """What the transcript left out, place by place (the run report's schema, `left_out`)."""
    return [
        {
            "what": e.left_out.what,
            "count": e.left_out.count,
            "bytes": e.left_out.size,
            "first": round(e.left_out.first, 6),
            "last": round(e.left_out.last, 6),
            "source": _address(e.left_out.source),
            "destination": _address(e.left_out.destination),
        }
        for e in entries
        if e.left_out is not None
    ]


def _entry(entry: Entry) -> dict[str, Any]:
    if entry.payload is not None:
        return _payload(entry.at, entry.payload)
    if entry.left_out is not None:
        return _left_out(entry.at, entry.left_out)
    return _line(entry.at, entry.text or "")


def _left_out(at: float, left_out: LeftOut) -> dict[str, Any]:
    """A note where lines or payloads were left out, with the flow's endpoints if of one."""
    flow = left_out.what in ("tcp", "udp")
    return {
        "time": round(at, 6),
        "direction": "note",
        "channel": None,
        "summary": left_out.text,
        "transport": left_out.what if flow else None,
        "source": _address(left_out.source),
        "destination": _address(left_out.destination),
        "bytes": None,
    }


def _line(at: float, text: str) -> dict[str, Any]:
    parts = _LINE.fullmatch(text)
    assert parts is not None  # every part of the pattern is optional but the rest
    arrow = parts["arrow"]
    return {
        "time": round(at, 6),
        "direction": DIRECTIONS[arrow] if arrow else "note",
        "channel": parts["who"] or parts["label"],
        "summary": parts["said"],
        "transport": None,
        "source": None,
        "destination": None,
        "bytes": None,
    }


def _payload(at: float, payload: Payload) -> dict[str, Any]:
    return {
        "time": round(at, 6),
        "direction": None,
        "channel": None,
        "summary": f"{payload.transport.upper()} {len(payload.data)} bytes",
        "transport": payload.transport,
        "source": _address(payload.source),
        "destination": _address(payload.destination),
        "bytes": payload.data.hex(),
    }


def _address(address: Address | None) -> str | None:
    return None if address is None else address_text(address)
