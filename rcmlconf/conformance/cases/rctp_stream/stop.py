"""rctp/stream/refused-stop: a server's STOP that its client answers with an error
(specs/rctp-2.0.md D-RCTP-14, R-RCTP-66). Only a STOP answered 200 puts an access back in
`init`; one the client refuses leaves it set up on both sides, and the server must go on from
that state.

The server's own STOP is had the one way every server sends one: a writing stream played and fed
nothing, which its receive timeout ends (R-RCTP-45, rctp/stream/receive-timeout judges that).
"""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.control import ControlProbe, describe
from rcmlconf.conformance.probes.stream import StreamSetUp
from rcmlconf.conformance.probes.stream_access import (
    set_up_writing,
    short_write_timeout,
    stream_request,
    writable_stream,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.rctp.messages import Request

KEPT = "R-RCTP-66"
#: What the case answers the server's STOP with: a client that could not take it (D-RCTP-15).
REFUSAL = (500, "Internal Server Error")


@case(
    "rctp/stream/refused-stop",
    "A server's STOP of a stream (its receive timeout) answered 500 leaves the stream playing:"
    " the client's PAUSE and STOP of it are then answered 200",
    [KEPT],
    serial=True,
)
async def refused_stop(ctx: Context) -> None:
    control, probe, set_up = await set_up_writing(ctx, writable_stream(ctx), "write")
    timeout = await short_write_timeout(probe, set_up)
    await stream_request(ctx, control, "GO", set_up)
    stop = await _server_stop(control, set_up, timeout + ctx.wait)
    await control.answer(stop, *REFUSAL)
    for method in ("PAUSE", "STOP"):  # playing, then ready: each allows the next (D-RCTP-14)
        await control.send(control.request_bytes(method, set_up.target))
        answer = await control.response(closed=KEPT)
        ctx.expect_status(
            answer,
            200,
            KEPT,
            what=f"{method} {set_up.target} after the server's STOP of it was answered"
            f" {REFUSAL[0]} (the stream still set up)",
        )
    await control.request("RELEASE", "*")  # the privilege is the whole server's: free it


async def _server_stop(control: ControlProbe, set_up: StreamSetUp, wait: float) -> Request:
    """The server's STOP of the stream, which its receive timeout sends within `wait` seconds of
    GO; the server's other requests before it are answered 200. None is not this case's to fail:
    rctp/stream/receive-timeout judges R-RCTP-45."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + wait
    while True:
        try:
            message = await control.message(max(deadline - loop.time(), 0.0))
        except Failed as failed:
            if failed.requirement != "R-RCTP-5":  # a message broken, not one missing
                raise
            message, got = None, "nothing"
        else:
            got = describe(message)
        if not isinstance(message, Request):
            raise Inconclusive(
                f"no STOP {set_up.target} from the server within {wait:g} s of GO with no DATA"
                f" ({got}; rctp/stream/receive-timeout checks R-RCTP-45)"
            )
        if message.method == "STOP" and message.target == set_up.target:
            return message
        await control.answer(message)
