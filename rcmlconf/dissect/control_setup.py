"""The data stream a SETUP's answer names (D-RCTP-18, D-RCTP-28): its tag, ports and streams,
learned so that the dissector decodes its UDP packets."""

from __future__ import annotations

from rcmlconf.dissect.context import Context, DataSession
from rcmlconf.dissect.records import Severity
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType
from rcmlconf.rctp.fields import Transport, parse_transport
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
    kind = _access_kind(ctx, path)
    if kind is False or (kind is None and asked is None):
        return  # an event access: SETUP names no data stream (D-RCTP-26)
    number, frame, time = where
    findings = ctx.findings
    text = response.headers.get("Transport")
    try:
        transport = parse_transport(text) if text is not None else None
    except ValueTextError as exc:
        findings.add(Severity.ERROR, "R-RCTP-38", f"SETUP {path}'s 200: {exc}", frame, time, number)
        return
    try:
        request_transport = parse_transport(asked or "")
    except ValueTextError as exc:
        client_part = _client_part(asked or "")
        if kind and client_part is None:
            # A stream access's Transport the server cannot read: 461 is due.
            findings.add(
                Severity.ERROR,
                "R-RCTP-38",
                f"SETUP {path} answered 200 to a Transport it cannot serve ({exc}): 461 is due",
                frame,
                time,
                number,
            )
        if transport is None:
            return
        request_transport = client_part or Transport()
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


def _access_kind(ctx: Context, path: str) -> bool | None:
    """Whether `path` is a stream access of the robot; None without its RCML."""
    rcml = ctx.options.rcml
    if rcml is None:
        return None
    node = rcml.node(path)
    return isinstance(node, AccessNode) and node.type is AccessType.STREAM


#: The Transport parameters a server gives in its answer: in a SETUP they mean nothing, and a
#: server may ignore them or refuse a bad one with 461 (D-RCTP-18).
_SERVER_PARTS = ("server_port", "tag", "stream")


def _client_part(asked: str) -> Transport | None:
    """The SETUP's Transport with the server's own parameters left out, or None when even
    that does not read."""
    kept = [
        part
        for part in asked.split(";")
        if part.partition("=")[0].strip(" \t").lower() not in _SERVER_PARTS
    ]
    try:
        return parse_transport(";".join(kept))
    except ValueTextError:
        return None
