"""DATA a case writes on a stream and reads back (`Writing`), and the values it writes: what the
cases of the DATA a server takes and ignores share (specs/rctp-2.0.md §6 D-RCTP-20, D-RCTP-21,
D-RCML-12; R-RCTP-43, R-RCTP-58).

What a server applies of DATA written on a stream is seen in the DATA it sends back on a node that
is both readable and writable (`observable`): those cases hold the access privilege, so they run
alone (`serial`), learn what the robot reads back after a value is written (a robot may limit what
it is told), and put back the values they found.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import struct
from collections.abc import Callable, Mapping

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import RW
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.stream import StreamProbe, StreamSetUp
from rcmlconf.conformance.probes.stream_access import (
    QUIET,
    decode_data,
    interval_of,
    release_stream,
    set_up_writing,
    stream_request,
    writable_stream,
)
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.errors import EncodeError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.datastream import DataPayload, Direction, stream_codec
from rcmlconf.values import Kind, Scalar, Value

# -- choosing -------------------------------------------------------------------------------------


def observable(access: AccessNode) -> bool:
    """Whether what is written on the stream can be read back: a node both readable and
    writable, with two values to tell apart, and both intervals."""
    return (
        bool(access.read_interval)
        and bool(access.write_interval)
        and any(RW in n.permission and len(set(map(repr, samples(n)))) > 1 for n in access.data)
    )


# -- values ---------------------------------------------------------------------------------------


def _scalar(node: DataNode, k: int, of: int) -> Scalar:
    """The `k`-th of `of` points spread over the node's range (D-RCML-12) and type."""
    base = node.type.base
    if base.kind is Kind.BOOL:
        return k % 2 == 1
    if base.kind is Kind.INTEGER:
        least, most = (int(end) for end in _bounds(node))
        most = min(most, least + 1000)
        return least + (most - least) * k // of
    if base.kind is Kind.FLOAT:
        low, high = _bounds(node)
        value = low + (high - low) * k / of
        if base.code == "f":  # the value float32 holds, so that it reads back equal
            value = struct.unpack(">f", struct.pack(">f", value))[0]
        return float(value)
    size = max(0, min(node.type.size, 1))
    if base.kind is Kind.STRING:
        return "abcdefgh"[k % 8] * size
    return bytes([k]) * size


def _value(node: DataNode, k: int, of: int = 7) -> Value:
    scalar = _scalar(node, k, of)
    return tuple([scalar] * node.type.count) if node.type.is_array else scalar


def samples(node: DataNode) -> list[Value]:
    """Values of the node to write, in the order tried: apart from each other and within the
    range, away from its ends (a robot may limit what it is told)."""
    return [_value(node, k) for k in (5, 2, 6, 1)]


def _bounds(node: DataNode) -> tuple[float, float]:
    """The range a value of the node may take: its `min` and `max`, else its type's (a float
    without a range: -1 to 1 about the other end)."""
    base = node.type.base
    if base.kind is Kind.INTEGER:
        least = base.low if node.minimum is None else max(base.low, math.ceil(node.minimum))
        most = base.high if node.maximum is None else min(base.high, math.floor(node.maximum))
        return float(least), float(most)
    if node.minimum is not None:
        low = float(node.minimum)
        return low, float(node.maximum) if node.maximum is not None else low + 2.0
    high = float(node.maximum) if node.maximum is not None else 1.0
    return high - 2.0, high


def _near(node: DataNode, value: Value, steps: int) -> Value:
    """A value `steps` small steps from `value` (a sixteenth of a float's range, a sixty-fourth
    of an integer's), mirrored back into the range: a robot that moves toward what it is told
    gets there soon. Other kinds get a sample."""
    if isinstance(value, tuple):
        return tuple(_near_scalar(node, item, steps) for item in value)
    return _near_scalar(node, value, steps)


def _near_scalar(node: DataNode, value: Scalar, steps: int) -> Scalar:
    base = node.type.base
    if base.kind not in (Kind.INTEGER, Kind.FLOAT) or isinstance(value, bool | str | bytes):
        return _scalar(node, (5, 2, 6, 1)[steps % 4], 7)
    low, high = _bounds(node)
    if base.kind is Kind.INTEGER:
        step = max(1, int(high - low) // 64) * steps
        whole = int(value) + step
        if not low <= whole <= high:
            whole = int(value) - step
        return int(min(max(whole, low), high))
    moved = float(value) + (high - low) / 16 * steps
    if not low <= moved <= high:
        moved = float(value) - (high - low) / 16 * steps
    moved = min(max(moved, low), high)
    if base.code == "f":
        moved = struct.unpack(">f", struct.pack(">f", moved))[0]
    return float(moved)


def outside_value(node: DataNode) -> Value | None:
    """A value of the node's type outside its range, or None when its type allows none."""
    base = node.type.base
    if base.kind not in (Kind.INTEGER, Kind.FLOAT):
        return None
    outside: float | int | None = None
    if node.maximum is not None:
        above = node.maximum + max(1, abs(node.maximum))
        outside = float(above) if base.kind is Kind.FLOAT else int(above)
    elif node.minimum is not None:
        below = node.minimum - max(1, abs(node.minimum))
        outside = float(below) if base.kind is Kind.FLOAT else int(below)
    if outside is None or (base.kind is Kind.INTEGER and not base.low <= outside <= base.high):
        return None
    if base.code == "f" and not math.isfinite(struct.unpack(">f", struct.pack(">f", outside))[0]):
        return None
    if node.type.is_array:  # one item outside is enough (D-RCML-12)
        rest = _scalar(node, 5, 7)
        return (outside, *([rest] * (node.type.count - 1)))
    return outside


# -- writing and reading back ---------------------------------------------------------------------


class Writing:
    """A stream access set up with mode both, its privilege held and playing: what the server
    applies of the DATA the case writes shows in the DATA it sends back, on the nodes that are
    both readable and writable (`watched`)."""

    def __init__(
        self, ctx: Context, control: ControlProbe, probe: StreamProbe, set_up: StreamSetUp
    ) -> None:
        self.ctx, self.control, self.probe, self.set_up = ctx, control, probe, set_up
        access = set_up.access
        self.writer = stream_codec(access, Direction.WRITE)
        self.reader = stream_codec(access, Direction.READ)
        self.watched = tuple(n.name for n in access.data if RW in n.permission)
        self.loop = asyncio.get_running_loop()
        #: The values read back first, put back at the end, and the newest read back.
        self.before: tuple[Value, ...] = ()
        self.current: tuple[Value, ...] = ()
        assert set_up.write_interval is not None
        self.every = set_up.write_interval
        #: How long the case may send nothing valid: well within the receive timeout.
        self.window = max(min(QUIET, 0.4 * set_up.write_timeout), 2 * interval_of(set_up))

    @classmethod
    async def open(
        cls, ctx: Context, where: Callable[[AccessNode], bool] = lambda _: True
    ) -> Writing:
        """On the first stream access whose writing can be read back and `where` holds of."""
        access = writable_stream(ctx, lambda a: observable(a) and where(a))
        control, probe, set_up = await set_up_writing(ctx, access, "both")
        writing = cls(ctx, control, probe, set_up)
        await stream_request(ctx, control, "GO", set_up)
        first = await writing.readback()
        if first is None:
            raise Failed("R-RCTP-44", "DATA after GO", f"none within {probe.wait:g} s")
        writing.before = writing.current = first
        return writing

    def candidates(self) -> list[dict[str, Value]]:
        """Values to write: a step or two either side of what is read back now, samples for
        the nodes not read back."""
        found = dict(zip(self.watched, self.current, strict=True))
        return [
            {
                n.name: _near(n, found[n.name], steps) if n.name in found else samples(n)[i]
                for n in self.set_up.access.writable()
            }
            for i, steps in enumerate((1, -1, 2, -2))
        ]

    def send(
        self,
        values: Mapping[str, Value] | None = None,
        body: bytes | None = None,
        *,
        sequence: int | None = None,
    ) -> None:
        if body is None:
            assert values is not None
            body = self.writer.encode(values)
        self.probe.send_packet([DataPayload(self.set_up.stream, body)], sequence=sequence)

    async def readback(self, wait: float | None = None) -> tuple[Value, ...] | None:
        """The watched nodes' values in the next DATA of the stream; None if none comes."""
        found = await self.probe.data(self.set_up.stream, wait)
        if found is None:
            return None
        values = decode_data(self.reader, found[1])
        return tuple(values[name] for name in self.watched)

    async def settle(self, values: Mapping[str, Value]) -> tuple[Value, ...] | None:
        """Write `values` every write interval until what is read back leaves the current
        values and settles: the values written, twice in a row, or other values (a robot may
        limit what it is told) unchanged for five DATA and a tenth of a second. That, or None
        when it does not within a bound."""
        bound = min(max(0.3, 15 * interval_of(self.set_up)), 1.0)
        deadline = self.loop.time() + bound * self.ctx.scale
        written = tuple(values.get(name) for name in self.watched)
        next_send = self.loop.time()
        streak: list[tuple[Value, ...]] = []
        since = 0.0
        while (now := self.loop.time()) < deadline:
            if now >= next_send:
                self.send(values)
                next_send = now + self.every
            found = await self.readback(max(0.0, min(next_send, deadline) - self.loop.time()))
            if found is None:
                continue
            if found == self.current or (streak and found != streak[-1]):
                streak = []
            if found != self.current:
                if not streak:
                    since = self.loop.time()
                streak.append(found)
            held = len(streak) >= 5 and self.loop.time() - since >= 0.1
            if (found == written and len(streak) >= 2) or held:
                self.current = found
                return found
        return None

    async def two_values(self) -> tuple[dict[str, Value], dict[str, Value]]:
        """A value written and read back (now current), and another to write."""
        candidates = self.candidates()
        deadline = self.loop.time() + 1.5 * self.ctx.scale
        for index, values in enumerate(candidates):
            if self.loop.time() > deadline:
                break
            if await self.settle(values) is not None:
                return values, candidates[(index + 1) % len(candidates)]
        raise Inconclusive(
            f"what the robot reads back of {self.watched} does not follow what is written on"
            f" {self.set_up.access.path}: whether DATA is applied cannot be seen"
        )

    async def holds(self, requirement: str, after: str) -> None:
        """What is read back stays as it is for `window` (nothing valid is written)."""
        deadline = self.loop.time() + self.window
        while (left := deadline - self.loop.time()) > 0:
            found = await self.readback(left)
            if found is not None and found != self.current:
                raise Failed(
                    requirement,
                    f"{self.set_up.access.path} {self.watched} read back as {self.current}",
                    f"{found} after {after}",
                )

    async def shows(self, values: Mapping[str, Value]) -> None:
        """The check before could have seen `values` applied: written validly, they show."""
        if await self.settle(values) is None:
            raise Inconclusive(
                f"{dict(values)} written validly on {self.set_up.access.path} does not show"
                " either: the check before could not have seen it"
            )

    async def finish(self) -> None:
        """Put back the values found, if every writable node is read back; STOP; RELEASE."""
        if set(self.watched) == set(self.writer.names):
            with contextlib.suppress(EncodeError):
                self.send(dict(zip(self.watched, self.before, strict=True)))
        await release_stream(self.control, self.set_up)
