"""The data stream a SETUP's answer names (D-RCTP-18, D-RCTP-28): its tag, ports and streams,
learned so that the dissector decodes its UDP packets."""

from __future__ import annotations

from rcmlconf.dissect.context import Context, DataSession
from rcmlconf.dissect.records import Severity
from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.fields import parse_transport
from rcmlconf.rctp.messages import Request, Response


def learn_data_stream(
    ctx: Context,
    addresses: tuple[bytes, bytes],
    session_id: str | None,
    request: Request,
    response: Response,
    path: str,
    where: tuple[int, int, float],
) -> None:
    """D-RCTP-18, D-RCTP-28: the 200 to SETUP of a stream access names the data stream.

    `addresses` are the client's and the server's; `session_id` is the RCTP session's, when
    known; `where` is the response's (record number, frame, time), for findings."""
    asked = request.headers.get("Transport")
    if asked is None:
        return  # an event access
    number, frame, time = where
    findings = ctx.findings
    text = response.headers.get("Transport")
    try:
        request_transport = parse_transport(asked)
        transport = parse_transport(text) if text is not None else None
    except ValueTextError as exc:
        findings.add(Severity.ERROR, "R-RCTP-38", f"SETUP {path}'s 200: {exc}", frame, time, number)
        return
    if transport is None or None in (transport.server_port, transport.tag, transport.stream):
        findings.add(
            Severity.ERROR,
            "R-RCTP-38",
            f"SETUP {path}'s 200 does not give the Transport's server_port, tag and stream",
            frame,
            time,
            number,
        )
        if transport is None or transport.tag is None:
            return
    tag = transport.tag
    assert tag is not None
    session = ctx.data_sessions.get(tag)
    client_port = transport.client_port or request_transport.client_port
    if session is None:
        rcml = ctx.options.rcml
        session = DataSession(
            tag,
            addresses[0],
            addresses[1],
            transport.server_port,
            client_port,
            session_id,
            precision=(rcml.time_precision or 0.0) if rcml is not None else 0.0,
        )
    else:
        session.client_port = client_port
        if transport.server_port is not None:
            session.server_port = transport.server_port
    if transport.stream is not None:
        session.streams[transport.stream] = (path, transport)
    ctx.learn(session)
