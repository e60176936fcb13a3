"""Mutations that know the grammar (D-FUZZ-3), then bytes and splices.

Each control mutation takes a valid `Draft` and changes one part of it: a field's number to a
boundary value, `Content-Length`'s form, the line endings, a field repeated, left out or huge,
the target, the method, the version, SETUP's `Transport`, the `Session`, the body, `Nodes`. Each
data-stream mutation takes a valid datagram (§6) and changes one field: the version, the payload
count, a payload's length, type or stream, its body's size (its length following), the sequence,
the tag, a FLOW's operation or value. `bytes` flips, inserts and cuts bytes anywhere; `splice`
joins the message with a seed from `vectors/` at random points. The kind's name is the state
map's column (D-FUZZ-5).
"""

from __future__ import annotations

import random
import struct
from collections.abc import Callable, Sequence
from dataclasses import replace

from rcmlconf.fuzz.rctp_drafts import Draft
from rcmlconf.fuzz.steps import SESSION

#: Numbers at the edges of what fields hold: signs, widths, forms.
NUMBERS = (
    "0", "1", "-1", "255", "256", "65535", "65536", "2147483647", "2147483648", "4294967295",
    "4294967296", "18446744073709551616", "9" * 40, "", "00001", "+1", " 1", "0x10", "1e3", "1.5",
)  # fmt: skip
#: Sizes of huge parts: past D-RCTP-9's limits and just under them.
HUGE = (1023, 1024, 4096, 8191, 8192, 65536, 70000)
_TOKENS = ("connect", "GET", "HELLO", "OPTIONS", "CONNECT\x00", "C" * 300, "WRITE/READ")
_VERSIONS = ("RCTP/2.1", "RCTP/1.0", "RCTP/02.0", "HTTP/1.1", "RCTP/2.0000", "rctp/2.0", "RCTP/")
_TARGETS = ("*", "//", "/a/../..", "/%00", "/%zz", "/\u00e9", "?", "/x?y#z", "")
_EOLS = (b"\n", b"\r", b"\r\r\n", b"\n\r")
_SINGLE = ("CSeq", "Session", "Content-Type", "Nodes", "Transport", "Content-Length")


def _pick(rng: random.Random, items: Sequence[str]) -> str:
    return items[rng.randrange(len(items))]


def _set_field(draft: Draft, name: str, value: str) -> Draft:
    kept = tuple((n, v) for n, v in draft.fields if n.lower() != name.lower())
    return replace(draft, fields=(*kept, (name, value)))


def _field(draft: Draft, name: str) -> str | None:
    return next((v for n, v in draft.fields if n.lower() == name.lower()), None)


def cseq(draft: Draft, rng: random.Random) -> Draft:
    return _set_field(draft, "CSeq", _pick(rng, NUMBERS))


def content_length(draft: Draft, rng: random.Random) -> Draft:
    size = len(draft.body)
    body = draft.body or b"\x00" * rng.choice((1, 2, 4))
    forms = (
        f"+{size}", f"0{size}", f" {size} ", f"{size},{size}", f"{size + 1}", f"{max(size - 1, 0)}",
        "-1", "4294967296", "9" * 30, "0x10", "", f"{size}\t",
    )  # fmt: skip
    choice = rng.randrange(len(forms) + 2)
    if choice == len(forms):  # two fields
        return replace(
            draft,
            body=body,
            length=str(len(body)),
            fields=(*draft.fields, ("Content-Length", _pick(rng, NUMBERS))),
        )
    if choice == len(forms) + 1:  # a body and no field
        return replace(draft, body=body, length=None)
    return replace(draft, body=body, length=forms[choice])


def line_ending(draft: Draft, rng: random.Random) -> Draft:
    return replace(draft, eol=rng.choice(_EOLS))


def field_repeat(draft: Draft, rng: random.Random) -> Draft:
    name = _pick(rng, _SINGLE)
    value = _field(draft, name) or _pick(rng, NUMBERS)
    return replace(draft, fields=(*draft.fields, (name, value)))


def field_missing(draft: Draft, rng: random.Random) -> Draft:
    if not draft.fields:
        return replace(draft, length=None)
    drop = rng.randrange(len(draft.fields))
    return replace(draft, fields=draft.fields[:drop] + draft.fields[drop + 1 :])


def field_huge(draft: Draft, rng: random.Random) -> Draft:
    size = rng.choice(HUGE)
    if rng.random() < 0.5:
        return replace(draft, fields=(*draft.fields, ("X-Fuzz", "a" * size)))
    name = rng.choice(("Session", "Transport", "Nodes", "User-Agent", "A" * size))
    return _set_field(draft, name, "b" * size)


def fields_many(draft: Draft, rng: random.Random) -> Draft:
    count = rng.choice((64, 100, 101, 1000, 5000))
    return replace(draft, fields=draft.fields + tuple((f"X-{i}", "1") for i in range(count)))


def target(draft: Draft, rng: random.Random) -> Draft:
    if rng.random() < 0.3:
        return replace(draft, target="/" + "x" * rng.choice(HUGE))
    if rng.random() < 0.3:
        return replace(draft, target=draft.target + rng.choice(("/", "/..", "/nope", "%2F")))
    return replace(draft, target=_pick(rng, _TARGETS))


def method(draft: Draft, rng: random.Random) -> Draft:
    return replace(draft, method=_pick(rng, _TOKENS))


def version(draft: Draft, rng: random.Random) -> Draft:
    return replace(draft, version=_pick(rng, _VERSIONS))


def transport(draft: Draft, rng: random.Random) -> Draft:
    params = (
        "client_port=0", "client_port=65536", "client_port=-1", "client_port=", "mode=both",
        "mode=write", "mode=x", "stream=0", "stream=256", "stream=1", "tag=zzzzzzzz",
        "tag=ffffffff", "server_port=1", "client_port=1;client_port=2", "foo=bar", "mode",
    )  # fmt: skip
    base = _field(draft, "Transport") or "udp"
    chosen = [_pick(rng, params) for _ in range(rng.randint(1, 3))]
    form = rng.random()
    if form < 0.15:
        return _set_field(draft, "Transport", rng.choice(("tcp", "", ";", "udp;" * 500)))
    return _set_field(draft, "Transport", ";".join([base, *chosen]))


def session(draft: Draft, rng: random.Random) -> Draft:
    """The `Session` field broken, or its timeout at an edge (D-RCTP-11)."""
    own = SESSION.decode()
    if rng.random() < 0.4:
        return _set_field(draft, "Session", f"{own};timeout={_pick(rng, NUMBERS)}")
    forms = (
        "", "x", own + "x", own[:-1], own.upper(), own + " ", "0" * 100, own + ";" + own,
        own + ";timeout", own + ";TIMEOUT=60", own + ";timeout=60;timeout=1",
    )  # fmt: skip
    return _set_field(draft, "Session", _pick(rng, forms))


def body(draft: Draft, rng: random.Random) -> Draft:
    size = len(draft.body)
    choice = rng.randrange(6)
    if choice == 0:
        new = draft.body[: rng.randrange(size)] if size else b""
    elif choice == 1:
        new = draft.body + bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
    elif choice == 2:
        new = rng.choice((b"\xff" * 8, b"\x7f\xf8" + b"\x00" * 6, b"\x80" + b"\x00" * 7))[
            : max(size, 1)
        ]
    elif choice == 3:
        new = b"\x00" * rng.choice(HUGE)
    elif choice == 4:
        return _set_field(
            replace(draft, body=draft.body or b"\x00"),
            "Content-Type",
            rng.choice(("text/plain", "application/rctp-values;x=1", "")),
        )
    else:
        return replace(
            draft,
            fields=tuple(f for f in draft.fields if f[0] != "Content-Type"),
            body=draft.body or b"\x00",
        )
    return replace(draft, body=new)


def nodes(draft: Draft, rng: random.Random) -> Draft:
    given = _field(draft, "Nodes") or "x"
    forms = ("", ",", given + ", " + given, "nope", given + "," * 50,
             ", ".join(f"n{i}" for i in range(rng.choice((10, 1000)))), "a b")  # fmt: skip
    return _set_field(draft, "Nodes", _pick(rng, forms))


#: The control mutations of a Draft, by kind.
CONTROL: dict[str, Callable[[Draft, random.Random], Draft]] = {
    "cseq": cseq,
    "content-length": content_length,
    "line-ending": line_ending,
    "field-repeat": field_repeat,
    "field-missing": field_missing,
    "field-huge": field_huge,
    "fields-many": fields_many,
    "target": target,
    "method": method,
    "version": version,
    "transport": transport,
    "session": session,
    "body": body,
    "nodes": nodes,
}


#: Status codes at the edges: the classes' ends, none, three digits that are no class.
_STATUSES = ("0", "99", "100", "199", "201", "299", "300", "400", "404", "455", "500", "600",
             "999", "2000", "20", "-200", "2OO", "", "200 ")  # fmt: skip


def status(draft: Draft, rng: random.Random) -> Draft:
    """An answer's status code (`rctp_drafts.answer` keeps it where a request's target is)."""
    return replace(draft, target=_pick(rng, _STATUSES))


#: The mutations of an answer the fuzzer plays to a client (D-FUZZ-8), by kind.
ANSWER: dict[str, Callable[[Draft, random.Random], Draft]] = {
    kind: CONTROL[kind]
    for kind in ("cseq", "content-length", "line-ending", "field-repeat", "field-missing",
                 "field-huge", "fields-many", "session", "body", "transport")
}  # fmt: skip
ANSWER["status"] = status


def flip_bytes(data: bytes, rng: random.Random) -> bytes:
    """Flip, insert, delete or cut: AFL's havoc, a few at a time."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if not out:
            out.append(rng.randrange(256))
            continue
        at = rng.randrange(len(out))
        choice = rng.randrange(5)
        if choice == 0:
            out[at] ^= 1 << rng.randrange(8)
        elif choice == 1:
            out[at] = rng.choice((0, 0x7F, 0x80, 0xFF, 0x0A, 0x0D, 0x20))
        elif choice == 2:
            out.insert(at, rng.randrange(256))
        elif choice == 3:
            del out[at]
        else:
            del out[at:]
    return bytes(out)


def splice(data: bytes, seed: bytes, rng: random.Random) -> bytes:
    """The head of one message and the tail of another (AFL's splice)."""
    cut = rng.randint(0, len(data))
    return data[:cut] + seed[rng.randint(0, len(seed)) :]


# -- the data stream (specs/rctp-2.0.md §6) --------------------------------------------------------

#: version, payload count, sequence, tag, timestamp; then type, stream, length (D-RCTP-19).
_HEADER = struct.Struct(">BBHIQ")
_PAYLOAD = struct.Struct(">BBH")


def _field_at(data: bytes, offset: int, size: int, value: int) -> bytes:
    if len(data) < offset + size:
        return data
    return data[:offset] + value.to_bytes(size, "big") + data[offset + size :]


def _edge(rng: random.Random, bits: int) -> int:
    top = (1 << bits) - 1
    return rng.choice((0, 1, top, top - 1, 1 << (bits - 1), (1 << (bits - 1)) - 1))


#: Each data mutation: (datagram, rng) -> datagram, and whether the tag stays the session's.
def dgram_version(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, 0, 1, rng.choice((0, 1, 3, 0x12, 255)))


def payload_count(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, 1, 1, rng.choice((0, 2, 3, 254, 255)))


def sequence(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, 2, 2, _edge(rng, 16))


def tag(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, 4, 4, _edge(rng, 32))


def payload_type(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, _HEADER.size, 1, rng.choice((0, 3, 7, 255)))


def stream_id(data: bytes, rng: random.Random) -> bytes:
    return _field_at(data, _HEADER.size + 1, 1, rng.choice((0, 2, 7, 255)))


def payload_length(data: bytes, rng: random.Random) -> bytes:
    if len(data) < _HEADER.size + _PAYLOAD.size:
        return data
    length = int.from_bytes(data[_HEADER.size + 2 : _HEADER.size + 4], "big")
    new = rng.choice((0, max(length - 1, 0), length + 1, 0xFFFF, length * 2))
    return _field_at(data, _HEADER.size + 2, 2, new)


def flow_value(data: bytes, rng: random.Random) -> bytes:
    """A FLOW body's last field (an interval, a timeout, a time) at an edge of its width, or
    any value with its top bit set (a signed reader's negative)."""
    body = _HEADER.size + _PAYLOAD.size
    if len(data) < body + 8:
        return data
    value = _edge(rng, 32) if rng.random() < 0.7 else (1 << 31) | rng.randrange(1 << 31)
    return data[:-4] + value.to_bytes(4, "big")


def flow_operation(data: bytes, rng: random.Random) -> bytes:
    body = _HEADER.size + _PAYLOAD.size
    return _field_at(data, body + rng.choice((0, 1)), 1, rng.choice((0, 3, 6, 7, 255)))


def payload_body(data: bytes, rng: random.Random) -> bytes:
    """The first payload's body cut or extended, its length field following it: a DATA or FLOW
    body of the wrong size in a datagram whose framing holds (R-RCTP-40, R-RCTP-52)."""
    start = _HEADER.size + _PAYLOAD.size
    if len(data) < start:
        return data
    length = int.from_bytes(data[_HEADER.size + 2 : start], "big")
    body = data[start : start + length]
    if body and rng.random() < 0.5:
        body = body[: rng.randrange(len(body))]
    else:
        body += bytes(rng.randrange(256) for _ in range(rng.choice((1, 2, 3, 8))))
    rest = data[start + length :]
    head = data[: _HEADER.size + 2] + len(body).to_bytes(2, "big")
    return head + body + rest


def dgram_huge(data: bytes, rng: random.Random) -> bytes:
    return data + b"\x00" * rng.choice((1, 1000, 65507 - len(data)))


#: Where a heartbeat ACK's request id (2 bytes) and times (8 bytes each, T3 last) lie in its
#: FLOW body (D-RCTP-22).
ID_AT, T1_AT, T2_AT = 2, 4, 12


def heartbeat_times(body: bytes, rng: random.Random) -> bytes:
    """A heartbeat ACK's T2 and T3 (R-RCTP-48) at an edge of 64 bits, half the time with T3
    just before T2: an answer that left before its request arrived."""
    t2 = _edge(rng, 64) or 1
    t3 = t2 - 1 if rng.random() < 0.5 else _edge(rng, 64)
    return body[:T2_AT] + t2.to_bytes(8, "big") + t3.to_bytes(8, "big")


def heartbeat_echo(body: bytes, rng: random.Random) -> bytes:
    """The bits of T1 the ACK flips (never none): the played server sends the request's T1
    with them flipped, an ACK that does not echo it (R-RCTP-48)."""
    flipped = rng.choice((1, 1 << 63, (1 << 64) - 1, 1 << rng.randrange(64)))
    return body[:T1_AT] + flipped.to_bytes(8, "big") + body[T2_AT:]


#: The mutations of the played server's answer to a client's heartbeat (D-FUZZ-8), on its
#: FLOW body: the times, or T1's echo.
HEARTBEAT_ACK: dict[str, Callable[[bytes, random.Random], bytes]] = {
    "heartbeat-times": heartbeat_times,
    "heartbeat-echo": heartbeat_echo,
}

#: The data-stream mutations, by kind; `tag` is the one that changes the session's tag.
DATA: dict[str, Callable[[bytes, random.Random], bytes]] = {
    "dgram-version": dgram_version,
    "payload-count": payload_count,
    "sequence": sequence,
    "tag": tag,
    "payload-type": payload_type,
    "stream-id": stream_id,
    "payload-length": payload_length,
    "payload-body": payload_body,
    "flow-value": flow_value,
    "flow-operation": flow_operation,
    "dgram-huge": dgram_huge,
}
