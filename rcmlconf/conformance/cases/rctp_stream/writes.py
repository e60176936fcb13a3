"""rctp/stream, the DATA a client writes on a stream: what the server must not apply — DATA in a
duplicate or late packet, a payload that does not decode, one with a value out of range — and the
receive timeout that ends a writing stream with STOP once it is no longer fed (specs/rctp-2.0.md
§6 D-RCTP-20, D-RCTP-21, D-RCTP-33, R-RCTP-35, R-RCTP-43, R-RCTP-45, R-RCTP-58).

What the server applies shows in the DATA it sends back (`probes.stream_writing.Writing`): these
cases hold the access privilege, so they run alone (`serial`), and put back the values they found.
"""

from __future__ import annotations

import asyncio
import os

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.control import describe
from rcmlconf.conformance.probes.stream_access import (
    MODULO,
    decode_data,
    first_data,
    set_up_writing,
    short_write_timeout,
    stream_request,
    writable_stream,
)
from rcmlconf.conformance.probes.stream_writing import Writing, observable, outside_value, samples
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, NotApplicable
from rcmlconf.rctp.datastream import DataPayload, Direction, stream_codec
from rcmlconf.rctp.fields import same_token
from rcmlconf.rctp.messages import Request
from rcmlconf.values.shown import values_text


@case(
    "rctp/stream/stale-data-ignored",
    "DATA in a duplicate or late packet is not applied: the newer values stay",
    ["R-RCTP-43"],
    serial=True,
)
async def stale_data_ignored(ctx: Context) -> None:
    writing = await Writing.open(ctx)
    # The first packet, still to come, at random in the low quarter, so that the packet 32,768
    # behind reads as a larger number: a receiver that compares numbers as integers, not
    # modulo 65,536 (D-RCTP-21), takes it, whatever the run (with a random start, half the runs).
    writing.probe.sequence = int.from_bytes(os.urandom(2), "big") & 0x3FFF
    _, other = await writing.two_values()
    newest = writing.probe.last_sequence
    # Not newer: the same number, one behind, and 32,768 behind (RFC 1982's edge).
    for back in (0, 1, 0x8000):
        writing.send(other, sequence=(newest - back) % MODULO)
    await writing.holds("R-RCTP-43", f"{other} in packets numbered {newest} and behind")
    await writing.shows(other)
    await writing.finish()


@case(
    "rctp/stream/undecodable-data-ignored",
    "A DATA payload that does not hold exactly the stream's values is ignored",
    ["R-RCTP-58"],
    serial=True,
)
async def undecodable_data_ignored(ctx: Context) -> None:
    writing = await Writing.open(ctx)
    _, other = await writing.two_values()
    body = writing.writer.encode(other)
    for broken in (body + b"\x00", body[:-1], b""):
        writing.send(body=broken)
    await writing.holds("R-RCTP-58", f"DATA bodies of {len(body)} bytes +1, -1 and 0")
    await writing.shows(other)
    await writing.finish()


@case(
    "rctp/stream/out-of-range-data-ignored",
    "A DATA payload with one value outside its node's range is ignored whole",
    ["R-RCTP-58"],
    serial=True,
)
async def out_of_range_data_ignored(ctx: Context) -> None:
    access = writable_stream(ctx, observable)
    if not any(outside_value(n) is not None for n in access.writable()):
        raise NotApplicable(f"no writable node of {access.path} has a range to leave")
    writing = await Writing.open(ctx)
    _, other = await writing.two_values()
    node = next(n for n in access.writable() if outside_value(n) is not None)
    outside = outside_value(node)
    assert outside is not None
    writing.send({**other, node.name: outside})
    shown = values_text([node], {node.name: outside})[0]
    await writing.holds("R-RCTP-58", f"{shown} with the others in range")
    await writing.shows(other)
    await writing.finish()


@case(
    "rctp/stream/receive-timeout",
    "A writing stream is kept while fed and ended by STOP with Reason: timeout once not; once"
    " the STOP is answered, nothing is set up for writing: RELEASE is 200",
    ["R-RCTP-45", "R-RCTP-35"],
    serial=True,
)
async def receive_timeout(ctx: Context) -> None:
    access = writable_stream(ctx)
    readable = {n.name for n in access.readable()}
    mode = "both" if {n.name for n in access.writable()} <= readable else "write"
    control, probe, set_up = await set_up_writing(ctx, access, mode)
    assert set_up.write_interval is not None
    timeout = await short_write_timeout(probe, set_up)
    writer = stream_codec(access, Direction.WRITE)
    await stream_request(ctx, control, "GO", set_up)
    if mode == "both":  # what the robot has now: feeding it changes nothing
        _, payload = await first_data(ctx, probe, set_up)
        found = decode_data(stream_codec(access, Direction.READ), payload)
        values = {name: found[name] for name in writer.names}
    else:
        values = {n.name: samples(n)[0] for n in access.writable()}
    body = writer.encode(values)
    loop = asyncio.get_running_loop()
    watch = asyncio.ensure_future(control.message(timeout * 3 + 1.0))
    try:
        last = loop.time()
        feed_until = last + timeout + 0.1
        while loop.time() < feed_until and not watch.done():
            probe.send_packet([DataPayload(set_up.stream, body)])
            last = loop.time()
            await asyncio.wait({watch}, timeout=set_up.write_interval)
        ctx.expect(
            not watch.done(),
            f"the stream kept while DATA comes every {set_up.write_interval:g} s",
            describe(watch.result()) if watch.done() else "",
        )
        try:
            message = await watch
        except Failed:
            raise Failed(
                "R-RCTP-45",
                f"STOP {set_up.target} with Reason: timeout after {timeout:g} s",
                f"nothing within {loop.time() - last:.3f} s of the last DATA",
            ) from None
        after = loop.time() - last
    finally:
        watch.cancel()
    ctx.expect(
        isinstance(message, Request)
        and message.method == "STOP"
        and message.target == set_up.target
        and same_token(message.headers.get("Reason"), "timeout"),
        f"STOP {set_up.target} with Reason: timeout",
        describe(message),
    )
    assert isinstance(message, Request)
    await control.answer(message)
    ctx.expect(  # D-RCTP-33's bounds
        0.8 * timeout - 0.02 <= after <= timeout + max(0.3, 0.5 * timeout),
        f"the STOP {timeout:g} s after the last DATA",
        f"{after:.3f} s after it",
    )
    # D-RCTP-14: the server's STOP answered 200 put the stream back in init, as the client's
    # would (rctp/priv/release-writing-stream), so no stream is set up for writing any more.
    released = await control.request("RELEASE", "*")
    ctx.expect_status(released, 200, "R-RCTP-35", what="RELEASE * after the STOP is answered")
