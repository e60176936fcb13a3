"""rctp/client, the robot's RCML as the client reads it (D-RCTP-31 step 1): the harness serves a
case its own RCML, the harness's robot with a DOCTYPE whose DTD lives on the files port or with
nodes in another namespace, and judges what the client fetched and asked for (R-XML-12,
R-XML-13; specs/xml.md D-XML-3)."""

from __future__ import annotations

import re

from rcmlconf.conformance.cases.rctp_client.scenario import scenario_case, whole_run
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.clients import ClientListener
from rcmlconf.conformance.verdicts import Inconclusive

#: The DTD the DOCTYPE names: the bundled one's name (R-XML-4), at a URL of the case's files.
DTD_NAME = "rcml.dtd"
#: An access in another namespace, before the robot's own: a reader that reads elements by their
#: local name takes it for the robot's.
FOREIGN = (
    b'<o:access xmlns:o="urn:example:not-rcml" name="ghost" permission="rw">'
    b'<o:data name="g" type="uint8"/></o:access>'
)


def _listener(ctx: Context) -> ClientListener:
    listener = ctx.target.clients
    assert listener is not None  # a client case runs with a client role only
    return listener


def _with_doctype(rcml: bytes, files_url: str) -> bytes:
    """The RCML with a DOCTYPE after its XML declaration, naming a DTD among the case's files."""
    declared = rcml.index(b"?>") + 2
    doctype = f'\n<!DOCTYPE rcml SYSTEM "{files_url}{DTD_NAME}">'.encode()
    return rcml[:declared] + doctype + rcml[declared:]


def _with_foreign(rcml: bytes, files_url: str) -> bytes:
    """The RCML with an access in another namespace as the root's first child."""
    root = re.search(rb"<rcml\b[^>]*>", rcml)
    assert root is not None
    return rcml[: root.end()] + b"\n  " + FOREIGN + rcml[root.end() :]


@scenario_case(
    "rctp/client/dtd-not-loaded",
    "The client reads an RCML whose DOCTYPE names a DTD on the harness's files port without"
    " asking for the DTD",
    ["R-XML-12"],
    served=_with_doctype,
)
async def dtd_not_loaded(ctx: Context) -> None:
    listener = _listener(ctx)
    dtd = listener.files_url(ctx.case.id) + DTD_NAME
    server = await whole_run(ctx)
    asked = [p for p in listener.fetched(ctx.case.id) if p.endswith("/" + DTD_NAME)]
    ctx.expect(not asked, f"no GET of {dtd} (D-XML-3)", f"GET {', '.join(asked)}", "R-XML-12")
    if not server.requests():
        raise Inconclusive("the client sent no request: did it read the RCML? (step 1)")


@scenario_case(
    "rctp/client/foreign-namespace-ignored",
    "The client ignores an access of the RCML in another namespace: it never reads or writes it",
    ["R-XML-13"],
    served=_with_foreign,
)
async def foreign_namespace_ignored(ctx: Context) -> None:
    server = await whole_run(ctx)
    if not server.read_paths():
        raise Inconclusive("the client read nothing (D-RCTP-31 step 3)")
    ghost = [
        f"{s.request.method} {s.request.target}"
        for s in server.requests()
        if s.path is not None and s.path.startswith("/ghost")
    ]
    ctx.expect(
        not ghost,
        "no request of /ghost: its elements are in another namespace",
        ", ".join(ghost),
        "R-XML-13",
    )
