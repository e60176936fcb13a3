"""rctp/stream, the packets a server drops — another tag, another version, another source port,
broken framing — and the unknown payload it skips by its length (specs/rctp-2.0.md §6 D-RCTP-19,
D-RCTP-23, R-RCTP-42, R-RCTP-51).

What a server does with a packet it receives is seen through FLOW: FLOW requests are answered
(D-RCTP-22), so a packet the server must drop carries a heartbeat request that must go unanswered,
and one it must handle carries one that must be answered.
"""

from __future__ import annotations

from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.stream import (
    StreamProbe,
    StreamSetUp,
    answers,
    flow_text,
    open_stream,
)
from rcmlconf.conformance.probes.stream_access import (
    QUIET,
    UNKNOWN_TYPE,
    heartbeat_request,
    only_heartbeat_answered,
    set_up_reading,
)
from rcmlconf.conformance.registry import case
from rcmlconf.rctp.datastream import FlowPayload, HeartbeatAck, UnknownPayload, encode_flow


async def _dropped(
    ctx: Context, send_bad: Callable[[StreamProbe, StreamSetUp, int], None], what: str
) -> None:
    """`send_bad` sends a packet that must be dropped unanswered, holding a heartbeat request
    with the id given; a good heartbeat after it must be answered."""
    _, probe, set_up = await set_up_reading(ctx)
    bad = probe.next_request_id()
    send_bad(probe, set_up, bad)
    got = await probe.answer(bad, QUIET)
    ctx.expect(got is None, f"no answer to {what}", f"{got[1] if got else ''}")
    answer = await probe.ask(heartbeat_request)
    ctx.expect(
        isinstance(answer, HeartbeatAck),
        f"an ACK of a good heartbeat after {what}",
        flow_text(answer),
        "R-RCTP-46",
    )
    late = [f for d in probe.history for f in answers(d) if f.request_id == bad]
    ctx.expect(not late, f"no answer to {what}", flow_text(late[0] if late else None))


@case(
    "rctp/stream/drop-wrong-tag",
    "A packet with a tag that is not the session's is dropped unanswered",
    ["R-RCTP-42"],
)
async def drop_wrong_tag(ctx: Context) -> None:
    def send(probe: StreamProbe, set_up: StreamSetUp, request_id: int) -> None:
        flow = FlowPayload(0, heartbeat_request(request_id))
        probe.send_packet([flow], tag=set_up.tag ^ 0x5A5A5A5A)

    await _dropped(ctx, send, "a packet with another tag")


@case(
    "rctp/stream/drop-wrong-version",
    "A packet with a version other than 2 is dropped unanswered",
    ["R-RCTP-42"],
)
async def drop_wrong_version(ctx: Context) -> None:
    def send(probe: StreamProbe, set_up: StreamSetUp, request_id: int) -> None:
        data = bytearray(probe.packet_bytes([FlowPayload(0, heartbeat_request(request_id))]))
        data[0] = 3
        probe.send(bytes(data))

    await _dropped(ctx, send, "a packet of version 3")


@case(
    "rctp/stream/drop-wrong-source",
    "A packet with the session's tag from another port than client_port is dropped unanswered",
    ["R-RCTP-42"],
)
async def drop_wrong_source(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    other = await open_stream(ctx, control, flow=1)
    bad = probe.next_request_id()
    other.send_packet([FlowPayload(0, heartbeat_request(bad))], tag=set_up.tag, to=set_up.server)
    got = await probe.answer(bad, QUIET)
    ctx.expect(
        got is None, "no answer to a packet from another port", flow_text(got[1] if got else None)
    )
    stray = other.drain()
    ctx.expect(not stray, "nothing sent to the other port", f"{len(stray)} datagrams")
    answer = await probe.ask(heartbeat_request)
    ctx.expect(
        isinstance(answer, HeartbeatAck),
        "an ACK of a good heartbeat after the packet from another port",
        flow_text(answer),
        "R-RCTP-46",
    )


@case(
    "rctp/stream/drop-broken-framing",
    "Packets whose payloads do not fill the datagram exactly are dropped unanswered",
    ["R-RCTP-42"],
)
async def drop_broken_framing(ctx: Context) -> None:
    def send(probe: StreamProbe, set_up: StreamSetUp, request_id: int) -> None:
        def good() -> bytes:
            return probe.packet_bytes([FlowPayload(0, heartbeat_request(request_id))])

        probe.send(good()[:1] + b"\x02" + good()[2:], "payload count 2, one payload")
        probe.send(good() + b"\x00", "a byte after the last payload")
        probe.send(good()[:-1], "the last body one byte short")

    await _dropped(ctx, send, "packets with broken framing")


@case(
    "rctp/stream/skip-unknown-payload",
    "A payload of an unknown type is skipped by its length and the packet's next one handled",
    ["R-RCTP-51"],
)
async def skip_unknown_payload(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    decoy, wanted = probe.next_request_id(), probe.next_request_id()
    # The unknown body looks like a FLOW heartbeat: answered, it was not skipped.
    unknown = UnknownPayload(UNKNOWN_TYPE, 0, encode_flow(heartbeat_request(decoy)))
    await only_heartbeat_answered(ctx, probe, [unknown], wanted, "the unknown payload")
