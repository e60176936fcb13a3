"""`stream`: a stream access's values on the data stream (D-RCTP-18 to D-RCTP-24), live."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import click

from rcmlconf.cli.client.live import clock_text, deadline_after, how_long, next_event
from rcmlconf.cli.client.requests import access_of
from rcmlconf.cli.client.running import Options, Work
from rcmlconf.cli.client.values import parse_assignments, values_json
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.rctp.datastream.clock import unix_from_ntp
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.session import Closed, ServerRequest, StreamLost, StreamValues
from rcmlconf.values import Value
from rcmlconf.values.shown import values_text
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
    if assignments and mode == "read":
        raise click.UsageError("--set values are written: use --mode write or --mode both")
    try:
        values = parse_assignments(access, assignments)
    except ValueTextError as exc:
        raise click.UsageError(str(exc)) from None
    kept = _kept(access, mode, values) if mode != "read" else ()
    return _Streaming(options, access, mode, values, kept, duration).run


def _kept(access: AccessNode, mode: str, values: Mapping[str, Value]) -> tuple[DataNode, ...]:
    """The writable nodes --set leaves out: each interval writes them as the robot had them."""
    writable = access.writable()
    if not writable:
        raise click.UsageError(f"{access.path} has no node to write: use --mode read")
    names = {node.name for node in writable}
    wrong = next((name for name in values if name not in names), None)
    if wrong is not None or not values:
        why = f" ({wrong} is read-only)" if wrong is not None else ""
        raise click.UsageError(
            f"--mode {mode} writes {', '.join(n.name for n in writable)} every interval: give"
            f" --set NAME=VALUE for one or more of them{why}; the others keep the robot's values"
        )
    kept = tuple(node for node in writable if node.name not in values)
    unreadable = next((node.name for node in kept if node not in access.readable()), None)
    if unreadable is not None:
        raise click.UsageError(
            f"give --set {unreadable}=VALUE too: {access.path}/{unreadable} cannot be read,"
            " so the value it has cannot be kept"
        )
    return kept


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
    """SETUP (after ACQUIRE to write), GO, values until the end, a summary, STOP.

    To write some nodes and keep the others (`kept`), the robot's values come first, and the
    values written each interval are the given ones with those. They are read on the stream
    itself (a stream access is not READ over the control connection, D-RCTP-17): in mode both
    they are its first values; mode write sets the stream up in mode read, and once the values
    have come, PAUSE and a SETUP in mode write change its mode (D-RCTP-14, D-RCTP-28).
    """

    def __init__(
        self,
        options: Options,
        access: AccessNode,
        mode: str,
        values: dict[str, Value],
        kept: tuple[DataNode, ...],
        duration: float | None,
    ) -> None:
        self.options = options
        self.output = options.output
        self.access = access
        self.mode = mode
        self.values = values
        self.kept = kept
        self.duration = duration
        self.received = 0

    async def run(self, client: Client) -> int:
        path = self.access.path
        with Interrupts() as interrupts:
            if self.mode != "read":
                await client.acquire(path)
            await client.setup(path, "read" if self.kept and self.mode == "write" else self.mode)
            if self.values and not self.kept:
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
        # The robot's values to keep come within --timeout, or the command gives up.
        first = deadline_after(client, self.options.timeout) if self.kept else None
        while (event := await next_event(client, interrupts, _sooner(deadline, first))) is not None:
            if isinstance(event, StreamValues) and event.path == path:
                if self.mode != "write":
                    self.received += 1
                    self._values(event)
                if first is not None:
                    first = None
                    await self._write_kept(client, event.values)
            elif isinstance(event, StreamLost):
                self.output.notice(f"no data on {event.path} for its read timeout (D-RCTP-23)")
            elif isinstance(event, ServerRequest) and event.method == "STOP" and event.path == path:
                return f"the server stopped {path} (Reason: {event.reason or 'none given'})"
            elif isinstance(event, Closed):
                return event.reason
        if first is not None and not interrupts.count and client.loop.time() >= first:
            raise RctpError(
                f"{path}: no values from the robot within {self.options.timeout:g} s: the values"
                f" of {', '.join(node.name for node in self.kept)} to keep are unknown"
            )
        return None

    async def _write_kept(self, client: Client, read: Mapping[str, Value]) -> None:
        """From now on, write the given values with the robot's own for the other nodes."""
        path = self.access.path
        kept = {node.name: read[node.name] for node in self.kept}
        if self.mode == "write":
            await client.pause(path)
            await client.setup(path, "write")
        client.write_values(path, {**self.values, **kept})
        if self.mode == "write":
            await client.go(path)
        given = " ".join(values_text(self.access.writable(), self.values))
        self.output.notice(f"writing {given}, and {' '.join(values_text(self.kept, kept))} as read")

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


def _sooner(one: float | None, other: float | None) -> float | None:
    """The earlier of two deadlines, either of which may be None (none)."""
    return other if one is None else one if other is None else min(one, other)
