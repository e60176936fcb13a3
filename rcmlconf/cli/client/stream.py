"""`stream`: a stream access's values on the data stream (D-RCTP-18 to D-RCTP-24), live."""

from __future__ import annotations

from collections.abc import Sequence

import click

from rcmlconf.cli.client.live import clock_text, deadline_after, how_long, next_event
from rcmlconf.cli.client.requests import access_of
from rcmlconf.cli.client.running import Options, Work
from rcmlconf.cli.client.values import parse_assignments, values_json, values_text
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.rctp.datastream.clock import unix_from_ntp
from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import Closed, ServerRequest, StreamLost, StreamValues
from rcmlconf.values import Value
from rcmlconf.wording import plural


def plan_stream(
    options: Options,
    model: RcmlDocument,
    path: str,
    mode: str,
    assignments: Sequence[str],
    duration: float | None,
) -> Work:
    access = _stream_access(model, path)
    writes = mode in ("write", "both")
    if assignments and not writes:
        raise click.UsageError("--set values are written: use --mode write or --mode both")
    try:
        values = parse_assignments(access, assignments)
    except ValueTextError as exc:
        raise click.UsageError(str(exc)) from None
    writable = [node.name for node in access.writable()]
    if writes and sorted(values) != writable:
        raise click.UsageError(
            f"--mode {mode} writes {', '.join(writable) or 'nothing'} every interval:"
            " give --set NAME=VALUE for each (and no other)"
        )
    return _Streaming(options, access, mode, values, duration).run


def _stream_access(model: RcmlDocument, path: str) -> AccessNode:
    node = model.node(path)
    if isinstance(node, AccessNode) and node.type is AccessType.STREAM:
        return node
    access = access_of(model, node) if isinstance(node, DataNode) else None
    if access is not None and access.type is AccessType.STREAM:
        hint = f": use its access, `stream {access.path}`"
    else:
        hint = "; `read`, `write` and `watch` use the control connection"
    raise click.UsageError(f"{path} is not a stream access of the robot's RCML{hint}")


class _Streaming:
    """SETUP (after ACQUIRE to write), GO, values until the end, a summary, STOP."""

    def __init__(
        self,
        options: Options,
        access: AccessNode,
        mode: str,
        values: dict[str, Value],
        duration: float | None,
    ) -> None:
        self.options = options
        self.output = options.output
        self.access = access
        self.mode = mode
        self.values = values
        self.duration = duration
        self.received = 0

    async def run(self, client: Client) -> int:
        path = self.access.path
        with Interrupts() as interrupts:
            if self.values:
                await client.acquire(path)
            await client.setup(path, self.mode)
            if self.values:
                client.write_values(path, self.values)  # held, and sent every interval from GO
            await client.go(path)
            self.output.notice(f"streaming {path} ({self.mode}) {how_long(self.duration)}")
            ended = await self._show(client, interrupts)
        self._summary(client, ok=ended is None)
        if ended is not None:
            self.output.problem("client", ended)
            return 1
        await client.stop(path)
        return 0

    async def _show(self, client: Client, interrupts: Interrupts) -> str | None:
        """Print the stream's values until the end; why the server ended it, if it did."""
        path = self.access.path
        deadline = deadline_after(client, self.duration)
        while (event := await next_event(client, interrupts, deadline)) is not None:
            if isinstance(event, StreamValues) and event.path == path:
                self.received += 1
                self._values(event)
            elif isinstance(event, StreamLost):
                self.output.notice(f"no data on {event.path} for its read timeout (D-RCTP-23)")
            elif isinstance(event, ServerRequest) and event.method == "STOP" and event.path == path:
                return f"the server stopped {path} (Reason: {event.reason or 'none given'})"
            elif isinstance(event, Closed):
                return event.reason
        return None

    def _values(self, event: StreamValues) -> None:
        sent = unix_from_ntp(event.sent)
        nodes = self.access.readable()
        if self.options.json:
            document = {"event": "values", "path": event.path, "time": sent}
            self.output.json_line({**document, "values": values_json(nodes, event.values)})
        else:
            text = " ".join(values_text(nodes, event.values))
            self.output.live([(clock_text(sent), "dim"), (f" {text}", "")])

    def _summary(self, client: Client, ok: bool) -> None:
        endpoint = client.session.endpoint
        counts = endpoint.sequences.counts if endpoint is not None else None
        clock = client.clock
        summary: dict[str, object] = {
            "event": "summary",
            "path": self.access.path,
            "values": self.received,
            "packets": counts.received if counts else 0,
            "lost": counts.lost if counts else 0,
            "late": counts.late if counts else 0,
            "duplicates": counts.duplicates if counts else 0,
            "clock_offset": clock.offset if clock else None,
            "clock_uncertainty": clock.uncertainty if clock else None,
        }
        if self.options.json:
            self.output.json_line(summary)
            return
        text = (
            f"{self.access.path}: {plural(self.received, 'packet')} of values;"
            f" {summary['packets']} received in all, {summary['lost']} lost,"
            f" {summary['late']} late, {summary['duplicates']} duplicate; "
        )
        text += (
            f"the robot's clock is {clock.offset:+.6f} s ± {clock.uncertainty:.6f} s from ours"
            if clock
            else "no clock estimate yet"
        )
        self.output.summary(text, ok)
