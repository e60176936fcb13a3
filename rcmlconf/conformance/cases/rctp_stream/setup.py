"""rctp/stream, SETUP of a stream access: its Transport and the data stream it answers (one tag and
server_port a session, an id a stream), the refusals of a SETUP without a usable Transport, for a
mode the access cannot carry or for writing without the privilege, and a SETUP again that moves
the DATA to another client_port (specs/rctp-2.0.md §5 D-RCTP-28, R-RCTP-34, R-RCTP-38, R-RCTP-56,
R-RCTP-57).

Each case opens its own session and data-stream socket (`probes.stream`) and picks the stream
access it needs (`probes.stream_access`).
"""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.probes.stream import open_stream
from rcmlconf.conformance.probes.stream_access import (
    GRACE,
    first_data,
    quiet_for,
    readable_stream,
    set_up_reading,
    stream_request,
    writable_stream,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rcml.model import AccessType
from rcmlconf.rctp.targets import format_target

# -- SETUP ----------------------------------------------------------------------------------------


@case(
    "rctp/stream/setup-transport",
    "SETUP of a stream access is answered 200 with a Transport holding server_port, tag and stream",
    ["R-RCTP-38"],
)
async def setup_transport(ctx: Context) -> None:
    control = await ctx.session()
    probe = await open_stream(ctx, control)
    await probe.setup(control, readable_stream(ctx), precondition=False)


@case(
    "rctp/stream/setup-without-transport",
    "SETUP of a stream access without a Transport is answered 461",
    ["R-RCTP-57"],
)
async def setup_without_transport(ctx: Context) -> None:
    control = await ctx.session()
    access = readable_stream(ctx)
    answer = await control.request("SETUP", format_target(access.path))
    ctx.expect_status(answer, 461)


@case(
    "rctp/stream/setup-without-client-port",
    "SETUP of a stream access whose Transport names no client_port is answered 461",
    ["R-RCTP-57"],
)
async def setup_without_client_port(ctx: Context) -> None:
    control = await ctx.session()
    access = readable_stream(ctx)
    target = format_target(access.path)
    answer = await control.request("SETUP", target, [("Transport", "udp;mode=read")])
    ctx.expect_status(answer, 461)


@case(
    "rctp/stream/setup-bad-transport",
    "SETUP with a Transport that is not udp or does not parse is refused (400 or 461), not set up",
    ["R-RCTP-38"],
)
async def setup_bad_transport(ctx: Context) -> None:
    control = await ctx.session()
    probe = await open_stream(ctx, control)
    target = format_target(readable_stream(ctx).path)
    port = probe.port
    for transport in (
        f"tcp;client_port={port};mode=read",
        "udp;client_port=0;mode=read",
        f"udp;client_port={port};mode=sideways",
    ):
        answer = await control.request("SETUP", target, [("Transport", transport)])
        ctx.expect(
            answer.status in (400, 461),
            ("400", "461"),
            f"{answer.status} {answer.reason} to Transport: {transport}",
        )


@case(
    "rctp/stream/setup-mode-without-nodes",
    "SETUP whose mode asks for a direction in which the access has no node is answered 403",
    ["R-RCTP-57"],
)
async def setup_mode_without_nodes(ctx: Context) -> None:
    found = [
        a
        for a in ctx.robot.access_nodes()
        if a.type is AccessType.STREAM and not (a.readable() and a.writable())
    ]
    if not found:
        raise NotApplicable("every stream access of the robot has readable and writable nodes")
    access = found[0]
    mode = "read" if not access.readable() else "write"
    control = await ctx.session()
    probe = await open_stream(ctx, control)
    transport = f"udp;client_port={probe.port};mode={mode}"
    answer = await control.request("SETUP", format_target(access.path), [("Transport", transport)])
    ctx.expect_status(answer, 403)


@case(
    "rctp/stream/setup-write-not-acquired",
    "SETUP of a stream access for writing (mode write, and both) without the privilege is"
    " answered 470",
    ["R-RCTP-34"],
    # Alone: the serial cases ACQUIRE / and the accesses, which made this one inconclusive
    # (471) about two runs in ten when it ran beside them.
    serial=True,
)
async def setup_write_not_acquired(ctx: Context) -> None:
    access = writable_stream(ctx)
    control = await ctx.session()
    probe = await open_stream(ctx, control)
    # D-RCTP-28: `both` writes too, and needs the privilege as `write` does
    for mode in ("write", "both") if access.readable() else ("write",):
        transport = f"udp;client_port={probe.port};mode={mode}"
        fields = [("Transport", transport)]
        answer = await control.request("SETUP", format_target(access.path), fields)
        if answer.status == 471:
            raise Inconclusive(f"another session holds {access.path} (471)")
        expect_answer(ctx, answer, 470, f"SETUP {access.path} with Transport: {transport}")


@case(
    "rctp/stream/one-data-stream",
    "A session's streams share one tag and server_port, each with its own id, kept on SETUP again",
    ["R-RCTP-38"],
)
async def one_data_stream(ctx: Context) -> None:
    first = readable_stream(ctx)
    others = [
        a
        for a in ctx.robot.access_nodes()
        if a.type is AccessType.STREAM and a.readable() and a.path != first.path
    ]
    control, probe, set_up = await set_up_reading(ctx, first)
    if others:
        second = await probe.setup(control, others[0])
        ctx.expect(
            (second.tag, second.server) == (set_up.tag, set_up.server),
            f"tag {set_up.tag:08x}, server_port {set_up.server[1]} (one data stream, D-RCTP-28)",
            f"tag {second.tag:08x}, server_port {second.server[1]} for {second.access.path}",
        )
        ctx.expect(
            second.stream != set_up.stream,
            f"a stream id other than {set_up.stream} for {second.access.path}",
            f"stream {second.stream}",
        )
    again = await probe.setup(control, first)
    ctx.expect(
        (again.stream, again.tag) == (set_up.stream, set_up.tag),
        f"stream {set_up.stream}, tag {set_up.tag:08x} kept (D-RCTP-28)",
        f"stream {again.stream}, tag {again.tag:08x}",
    )


# -- SETUP again ----------------------------------------------------------------------------------


@case(
    "rctp/stream/latest-client-port",
    "After a second SETUP with another client_port, DATA goes there and no longer to the first",
    ["R-RCTP-56"],
)
async def latest_client_port(ctx: Context) -> None:
    control, first, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    await first_data(ctx, first, set_up)
    await stream_request(ctx, control, "PAUSE", set_up)
    second = await open_stream(ctx, control, flow=1)
    moved = await second.setup(control, set_up.access)
    await asyncio.sleep(GRACE)
    first.drain()
    await stream_request(ctx, control, "GO", moved)
    await first_data(ctx, second, moved, "R-RCTP-56")
    stray = await first.packets(quiet_for(set_up), strict=False)
    ctx.expect(
        not stray,
        f"nothing more at the first client_port {first.port}",
        f"{len(stray)} packets there after SETUP named {second.port}",
    )
