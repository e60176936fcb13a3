"""`watch`: the server's own requests (D-RCTP-12) — data-change WRITEs, STOP, BYE — live."""

from __future__ import annotations

import time
from collections.abc import Sequence

import click

from rcmlconf.cli.client.live import clock_text, deadline_after, how_long, next_event
from rcmlconf.cli.client.running import Options, Work
from rcmlconf.cli.client.values import values_json
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import Closed, ServerRequest
from rcmlconf.values.shown import values_text


def plan_watch(
    options: Options, model: RcmlDocument, paths: Sequence[str], duration: float | None
) -> Work:
    if paths:
        accesses = [_event_access(model, path) for path in paths]
    else:
        accesses = [a for a in model.access_nodes() if a.type is AccessType.EVENT and a.readable()]
        if not accesses:
            raise click.UsageError("the robot's RCML has no event access with a readable node")
    output = options.output

    async def watch(client: Client) -> int:
        by_path = {access.path: access for access in accesses}
        said_bye = False
        with Interrupts() as interrupts:
            for path in by_path:
                await client.setup(path)
                await client.go(path)
            output.notice(f"watching {', '.join(by_path)} {how_long(duration)}")
            deadline = deadline_after(client, duration)
            while (event := await next_event(client, interrupts, deadline)) is not None:
                if isinstance(event, ServerRequest):
                    _request(options, event, by_path.get(event.path))
                    said_bye = said_bye or event.method == "BYE"
                elif isinstance(event, Closed) and not said_bye:
                    output.problem("client", event.reason)
                    return 1
        return 0

    return watch


def _event_access(model: RcmlDocument, path: str) -> AccessNode:
    node = model.node(path)
    if not isinstance(node, AccessNode) or node.type is not AccessType.EVENT:
        raise click.UsageError(f"{path} is not an event access of the robot's RCML")
    return node


def _request(options: Options, event: ServerRequest, access: AccessNode | None) -> None:
    """One line for a server's WRITE (its values), STOP or BYE (its Reason)."""
    now = time.time()
    nodes: tuple[DataNode, ...] = access.data if access is not None else ()
    values = event.values or {}
    if options.json:
        document: dict[str, object] = {
            "event": event.method.lower(),
            "path": event.path,
            "time": now,
            "status": event.status,
        }
        if event.values is not None:
            document["values"] = values_json(nodes, values)
        if event.reason is not None:
            document["reason"] = event.reason
        options.output.json_line(document)
        return
    words = [event.method, *([] if event.method == "BYE" else [event.path])]
    words += values_text(nodes, values)
    if event.reason is not None:
        words.append(f"(Reason: {event.reason})")
    if event.status != 200:
        words.append(f"(answered {event.status})")
    options.output.live([(clock_text(now), "dim"), (" " + " ".join(words), "")])
