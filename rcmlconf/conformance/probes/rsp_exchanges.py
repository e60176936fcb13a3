"""Exchanges the RSP robot cases share, each something sent and the robot's answer waited for
(bounded by the probe's wait; what must come, by `awaited.came`: a late robot told from one that
never sends): a session opened by hand or by the core's endpoint (`raw_session`, `reporting`), a
command acknowledged (`acked`, `must_ack`, `late_acked`), a DOWNLINK taken (`taken`, `must_take`,
`fresh_uplink`, `requested_uplinks`), a bad packet dropped and the session going on
(`dropped_then_taken`, `unanswered`, `going_on`, `replay_dropped`), and another local system's
HELLO answered (`hello_from_another`, `another_welcomed`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import came
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where, newer, sequence_of, summary
from rcmlconf.conformance.probes.rsp_devices import first, flags, occurrence, reported
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import BEFORE_REPEAT, RawSession, hand_driven
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import Encryption, Item, MapBody, PacketType
from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.rsp.session import events
from rcmlconf.values import Value


async def raw_session(
    ctx: Context, encryption: Encryption = Encryption.NONE
) -> tuple[RspProbe, RawSession]:
    """A probe with a session opened by hand (HELLO, WELCOME)."""
    probe = await open_probe(ctx)
    raw = hand_driven(probe, encryption)
    await raw.open()
    return probe, raw


async def reporting(
    ctx: Context, *, slower: int = 1
) -> tuple[RspProbe, events.SessionOpened, Device]:
    """A session of the core's endpoint, T `slower` times the model's, requesting the sensor or
    monitor with the smallest payload (`reported`), which the robot then reports every T."""
    probe = await open_probe(ctx)
    opened = await probe.open_session(period=slower * probe.model.period)
    sensor = reported(probe.model, 1)[0]
    probe.session.set_active(sensor.name, True)
    return probe, opened, sensor


def acknowledging(found: Device, ident: int) -> Where:
    """An ACK of occurrence `ident` of command or memory command `found` (R-RSP-26)."""
    return lambda d: ident in d.acks(found.position)


def _occurring(
    raw: RawSession, found: Device, ident: int, values: Mapping[str, Value] | None, buffer: int
) -> Callable[[], object]:
    """Sending occurrence `ident` of `found` in a DOWNLINK."""
    return lambda: raw.downlink([occurrence(found, ident, values)], buffer=buffer)


#: What an ACK is due by, as `came`'s `expected` cites it.
AT_ONCE = "at once (R-RSP-26: within half a period of its arrival)"


async def acked(
    probe: RspProbe,
    raw: RawSession,
    found: Device,
    ident: int,
    values: Mapping[str, Value] | None = None,
    *,
    buffer: int = 0,
) -> Datagram | None:
    """Send occurrence `ident` of command or memory command `found` in a DOWNLINK (again while
    the impairment spoils it) and return the robot's ACK of it (R-RSP-26); None if none came."""
    return await probe.answer_to(
        _occurring(raw, found, ident, values, buffer),
        PacketType.ACK,
        where=acknowledging(found, ident),
    )


async def must_ack(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    found: Device,
    ident: int,
    requirement: str,
    *,
    values: Mapping[str, Value] | None = None,
    buffer: int = 0,
    expected: str = "",
) -> Datagram:
    """`acked`'s ACK, which must come (`came`); `expected` says why, in the failure's text."""
    return await came(
        ctx,
        probe,
        PacketType.ACK,
        f"{expected or f'ACK of {found.name} #{ident}'}, {AT_ONCE}",
        requirement,
        send=_occurring(raw, found, ident, values, buffer),
        where=acknowledging(found, ident),
    )


def fresh(sequence: Callable[[], int], where: Where | None = None) -> Where:
    """An UPLINK the robot sent after it received our packet numbered `sequence()` (its last
    received sequence number has reached it, R-RSP-15), for which `where` holds."""
    return lambda d: newer(d.header.last_received, sequence()) and (where is None or where(d))


async def taken(
    probe: RspProbe,
    raw: RawSession,
    items: Iterable[Item] = (),
    *,
    buffer: int = 0,
    where: Where | None = None,
    wait: float | None = None,
) -> Datagram | None:
    """Send a DOWNLINK of `items` (again, a new packet, while the impairment spoils it) and return
    the first UPLINK the robot sent after it took it (`fresh`) for which `where` holds; None if
    none came within `wait`."""
    return await probe.answer_to(
        lambda: raw.downlink(items, buffer=buffer),
        PacketType.UPLINK,
        where=fresh(lambda: sequence_of(raw.last), where),
        wait=wait,
    )


#: What an UPLINK that took a DOWNLINK is due by, as `came`'s `expected` cites it.
NEXT_PERIOD = "the robot's next UPLINK (R-RSP-42: every period T while it has a bit to set)"


async def must_take(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    items: Iterable[Item],
    expected: str,
    requirement: str | None = None,
    *,
    where: Where | None = None,
    wait: float | None = None,
) -> Datagram:
    """`taken`'s UPLINK, which must come (`came`); `expected` says what it shows."""
    return await came(
        ctx,
        probe,
        PacketType.UPLINK,
        f"{expected}: {NEXT_PERIOD}",
        requirement,
        send=lambda: raw.downlink(items),
        where=fresh(lambda: sequence_of(raw.last), where),
        wait=wait,
    )


async def fresh_uplink(
    probe: RspProbe, sequence: int, *, wait: float | None = None, where: Where | None = None
) -> Datagram | None:
    """The first UPLINK the robot sent after it received our packet `sequence` (`fresh`), so far
    or within `wait`."""
    return await probe.next(
        PacketType.UPLINK, after=0, wait=wait, where=fresh(lambda: sequence, where)
    )


async def unanswered(
    ctx: Context, probe: RspProbe, start: int, what: str, requirement: str
) -> None:
    """What the case sent from mark `start` (`what`) must be dropped without an answer: nothing
    but UPLINKs within the quiet time (R-RSP-18: no ACK of the command it carries). A robot that
    answers late answers no less: a loaded machine cannot fail this."""
    await probe.listen(probe.quiet)
    answers = [d for d in probe.packets(after=start) if d.type is not PacketType.UPLINK]
    ctx.expect(
        not answers,
        f"{what} dropped without an answer (no ACK)",
        ", ".join(summary(probe.model, d.header, d.body) for d in answers),
        requirement,
    )


async def going_on(
    ctx: Context, probe: RspProbe, raw: RawSession, command: Device, ident: int, requirement: str
) -> None:
    """After a packet the robot had to drop, `command` #`ident` in a well-formed DOWNLINK must be
    acknowledged (`must_ack`): the bad packet did not end the session."""
    await must_ack(
        ctx,
        probe,
        raw,
        command,
        ident,
        requirement,
        expected=f"the session going on: ACK of {command.name} #{ident} in a well-formed DOWNLINK",
    )


async def dropped_then_taken(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    mutate: Callable[[bytes], bytes],
    requirement: str,
    what: str,
    *,
    sender: RspProbe | None = None,
) -> None:
    """A command in a DOWNLINK altered by `mutate` (sent from `sender`, by default the probe)
    must be dropped without an answer (`unanswered`); then the same command in a well-formed
    DOWNLINK must be acknowledged (`going_on`)."""
    command = first(probe.model, DeviceKind.COMMAND)
    ident = 7
    start = probe.mark()
    bad = mutate(raw.build(PacketType.DOWNLINK, MapBody((occurrence(command, ident),))))
    (sender or probe).send(bad, f"{what}: {probe._describe(bad)}")
    await unanswered(ctx, probe, start, what, requirement)
    if sender is not None:
        stray = sender.packets()
        ctx.expect(
            not stray,
            "no answer to the other address",
            f"{len(stray)} datagrams",
            requirement,
        )
    await going_on(ctx, probe, raw, command, ident, requirement)


async def replay_dropped(ctx: Context, probe: RspProbe, raw: RawSession, ident: int) -> None:
    """A DOWNLINK carrying command `ident` that the robot acknowledged, received again byte for
    byte, must be dropped without a second ACK, the session going on (R-RSP-18): at once, the
    newest the robot has, and again once newer ones came, late and seen before (D-RSP-15: a late
    packet's occurrences are taken, a replayed one's are not; a robot that remembers only its
    newest number takes the second). Inconclusive without the first ACK."""
    command = first(probe.model, DeviceKind.COMMAND)
    if await acked(probe, raw, command, ident) is None:
        raise Inconclusive(f"no ACK of {command.name} #{ident} in the first place")
    original = raw.last
    for what in ("the replay", "the replay behind the newest"):
        await dropped_then_taken(ctx, probe, raw, lambda _: original, "R-RSP-18", what)


async def late_acked(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    found: Device,
    ident: int,
    sequence: int,
    *,
    resume: int,
    expected: str,
    values: Mapping[str, Value] | None = None,
    buffer: int = 0,
) -> Datagram:
    """Send occurrence `ident` of command or memory command `found` in a DOWNLINK numbered
    `sequence` (its buffer byte `buffer`), older than the newest the robot has and never seen
    (again while the impairment spoils it), number our next packet `resume`, and return the
    robot's ACK of it, which must come (`came`): a late packet's occurrences are taken (D-RSP-15,
    R-RSP-26). `expected` says which packet it is."""

    def late() -> None:
        raw.rewind(sequence)
        _occurring(raw, found, ident, values, buffer)()
        raw.rewind(resume)

    return await came(
        ctx,
        probe,
        PacketType.ACK,
        f"{expected}, {AT_ONCE}",
        "R-RSP-26",
        send=late,
        where=acknowledging(found, ident),
    )


async def requested_uplinks(
    probe: RspProbe, raw: RawSession, devices: Iterable[Device], periods: int
) -> list[Datagram]:
    """Request `devices` (R-RSP-23) and return the UPLINKs of the `periods` periods after the
    robot took the request; Inconclusive if no UPLINK took it."""
    if await taken(probe, raw, flags(probe.model, *devices)) is None:
        raise Inconclusive("no UPLINK after the request")
    return await uplinks_within(probe, periods, raw.period, "the robot took the request")


async def uplinks_within(
    probe: RspProbe, periods: int, period: float, after: str
) -> list[Datagram]:
    """The UPLINKs of the next `periods` periods; Inconclusive if none came (`after`: what they
    follow). What a case checks in UPLINKs cannot be seen without one, and UPLINKs that come late
    (a robot, or a harness, short of CPU) are the pace cases' to judge (R-RSP-42), not a fail of
    the requirement the case checks, nor a pass of it."""
    found = await probe.received_within(periods * period, PacketType.UPLINK)
    if not found:
        raise Inconclusive(f"no UPLINK in the {periods} periods after {after}")
    return found


async def hello_from_another(
    ctx: Context, probe: RspProbe, requirement: str, *, expected: str = ""
) -> Datagram:
    """The robot's answer (WELCOME or REFUSED) to the HELLO of another local system (a probe of
    its own, "second" in the transcript), which must come (`came`). A session it opens ends with
    the case, as every session the robot opens for a probe."""
    other = await open_probe(ctx, robot=probe.robot, name="second")
    return await came(
        ctx,
        other,
        (PacketType.WELCOME, PacketType.REFUSED),
        f"{expected or 'WELCOME or REFUSED'}, {BEFORE_REPEAT}",
        requirement,
        send=hand_driven(other).hello,
    )


async def another_welcomed(ctx: Context, probe: RspProbe, requirement: str, expected: str) -> None:
    """Another local system's HELLO must be answered WELCOME (`expected` says why, in the
    failure's text): the robot holds no session for `probe`, ended or never opened."""
    answer = await hello_from_another(ctx, probe, requirement)
    ctx.expect(
        answer.type is PacketType.WELCOME,
        expected,
        f"REFUSED {getattr(answer.body, 'reason', '')}",
        requirement,
    )
