"""How fast is the RCTP/2.0 protocol core? (issue: RCTP core, "Speed")

1. One READ request and its response, each written and parsed: by the bare reader and writer, and
   by two `Connection`s (client and server, with every check of D-RCTP-25 and the transaction
   bookkeeping). Anchor: h11 doing the same with an HTTP/1.1 GET and its response, padded to the
   same sizes, on a kept-alive pair.
2. The four-payload data-stream packet of vectors/rctp/packets.json (two DATA payloads, a
   heartbeat ACK, a set-interval ACK: 117 bytes), encoded and decoded. Anchor: h11 parsing an
   HTTP/1.1 request of the same size; for context, a hand-written `struct` codec of the same
   fixed layout (one `Struct`, no checks, no objects: the floor a Python codec could reach).

Goal: no slower than h11. Anchors are measured in the same run (the machine is shared and noisy:
the ratios are the figures that travel). Figures are µs per operation, the median of --rounds.

    python bench/rctp_core_speed.py [--rounds 7]
"""

from __future__ import annotations

import argparse
import json
import statistics
import struct
import time
from collections.abc import Callable
from pathlib import Path

import h11

from rcmlconf.rctp.connection import Connection, RequestReceived
from rcmlconf.rctp.datastream import pull_packet, push_packet
from rcmlconf.rctp.messages import Headers, Request, Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rctp.states import Role
from rcmlconf.rctp.writer import write_message

SESSION = "4f1c9e0a7b3d2e85"
REQUEST = Request("READ", "/stream/control/pan", Headers((("CSeq", "2"), ("Session", SESSION))))
RESPONSE = Response(
    200,
    "OK",
    Headers(
        (
            ("CSeq", "2"),
            ("Session", SESSION),
            ("Content-Length", "4"),
            ("Content-Type", "application/rctp-values"),
        )
    ),
    b"\x00\x00\x00\x2a",
)
REQUEST_SIZE = len(write_message(REQUEST))
RESPONSE_SIZE = len(write_message(RESPONSE))


def rctp_bare() -> None:
    reader = MessageReader()
    reader.feed(write_message(REQUEST))
    reader.next_message()
    reader.feed(write_message(RESPONSE))
    reader.next_message()


def connections() -> tuple[Connection, Connection]:
    client, server = Connection(Role.CLIENT, 0.0), Connection(Role.SERVER, 0.0)
    client.send_request("CONNECT", "/", now=0.0)
    server.receive_data(client.data_to_send(), 0.0)
    event = server.next_event()
    assert isinstance(event, RequestReceived)
    server.send_response(event.request, 200, [("Session", f"{SESSION};timeout=60")])
    client.receive_data(server.data_to_send(), 0.0)
    while client.next_event() or server.next_event():
        pass
    return client, server


def rctp_connections(client: Connection, server: Connection) -> Callable[[], None]:
    def exchange() -> None:
        client.send_request("READ", "/stream/control/pan", now=1.0)
        server.receive_data(client.data_to_send(), 1.0)
        event = server.next_event()
        server.send_response(event.request, 200, body=b"\x00\x00\x00\x2a")  # type: ignore[union-attr]
        client.receive_data(server.data_to_send(), 1.0)
        client.next_event()

    return exchange


def h11_exchange() -> Callable[[], None]:
    """The same exchange over HTTP/1.1 on a kept-alive pair, padded to the RCTP messages' sizes."""
    client, server = h11.Connection(h11.CLIENT), h11.Connection(h11.SERVER)
    base = len(b"GET /stream/control/pan HTTP/1.1\r\nhost: r\r\nx-p: \r\n\r\n")
    request = h11.Request(
        method="GET",
        target="/stream/control/pan",
        headers=[("Host", "r"), ("X-P", "p" * max(0, REQUEST_SIZE - base))],
    )
    response = h11.Response(
        status_code=200,
        headers=[("Content-Length", "4"), ("X-P", "p" * max(0, RESPONSE_SIZE - 60))],
    )
    body = h11.Data(data=b"\x00\x00\x00\x2a")

    def exchange() -> None:
        server.receive_data(client.send(request) + client.send(h11.EndOfMessage()))
        server.next_event(), server.next_event()
        client.receive_data(
            server.send(response) + server.send(body) + server.send(h11.EndOfMessage())
        )
        client.next_event(), client.next_event(), client.next_event()
        client.start_next_cycle()
        server.start_next_cycle()

    return exchange


PACKETS = Path(__file__).resolve().parent.parent / "vectors" / "rctp" / "packets.json"
#: The four-payload packet as one layout: header; DATA of 32 bytes; DATA of 16; FLOW heartbeat
#: ACK (preamble, T1, T2, T3); FLOW set-interval ACK (preamble, direction, interval).
FLAT = struct.Struct(">BBHIQ" + "BBH32s" + "BBH16s" + "BBH" + "BBHQQQ" + "BBH" + "BBHBI")


def four_payloads() -> bytes:
    cases = json.loads(PACKETS.read_text(encoding="utf-8"))["valid"]
    return bytes.fromhex(next(c["hex"] for c in cases if c["name"] == "four-payloads"))


def h11_parse(size: int) -> Callable[[], None]:
    """h11 parsing an HTTP/1.1 request of `size` bytes, on a kept-alive server connection."""
    server = h11.Connection(h11.SERVER)
    head = b"GET /stream/control/pan HTTP/1.1\r\nHost: r\r\nX-P: \r\n\r\n"
    request = head.replace(b"X-P: ", b"X-P: " + b"p" * max(0, size - len(head)))
    response = h11.Response(status_code=204, headers=[])

    def parse() -> None:
        server.receive_data(request)
        server.next_event(), server.next_event()
        server.send(response), server.send(h11.EndOfMessage())
        server.start_next_cycle()

    return parse


def per_call(function: Callable[[], object], rounds: int, calls: int = 2000) -> float:
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            function()
        times.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    anchor = per_call(h11_exchange(), args.rounds)
    bare = per_call(rctp_bare, args.rounds)
    client, server = connections()
    full = per_call(rctp_connections(client, server), args.rounds)
    print(
        f"1. READ request ({REQUEST_SIZE} B) and response ({RESPONSE_SIZE} B), written and"
        f" parsed; median of {args.rounds} rounds"
    )
    print(f"   {'h11, HTTP/1.1 of the same sizes (anchor)':<46} {anchor:8.1f} µs")
    print(f"   {'rcmlconf reader + writer':<46} {bare:8.1f} µs  {bare / anchor:5.2f}x")
    print(f"   {'rcmlconf client + server Connection':<46} {full:8.1f} µs  {full / anchor:5.2f}x")

    data = four_payloads()
    packet = pull_packet(data)
    fields = FLAT.unpack(data)
    assert push_packet(packet) == data
    assert FLAT.pack(*fields) == data
    parse = per_call(h11_parse(len(data)), args.rounds)
    ours = per_call(lambda: pull_packet(push_packet(packet)), args.rounds)
    floor = per_call(lambda: FLAT.unpack(FLAT.pack(*fields)), args.rounds)
    print(f"2. the {len(data)}-byte four-payload data-stream packet, encoded and decoded")
    print(f"   {'h11 parsing a request of the same size (anchor)':<46} {parse:8.1f} µs")
    print(f"   {'rcmlconf push_packet + pull_packet':<46} {ours:8.1f} µs  {ours / parse:5.2f}x")
    floor_label = "one struct.Struct, no checks (the floor)"
    print(f"   {floor_label:<46} {floor:8.1f} µs  {floor / parse:5.2f}x")


if __name__ == "__main__":
    main()
