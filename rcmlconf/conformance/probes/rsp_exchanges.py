"""Exchanges the RSP robot cases share, each something sent and the robot's answer waited for
(bounded by the probe's wait): a session opened by hand or by the core's endpoint
(`raw_session`, `reporting`), a command acknowledged (`acked`, `ack_of`, `late_acked`), a DOWNLINK
taken (`taken`, `fresh_uplink`, `requested_uplinks`), a bad packet dropped and the session going on
(`dropped_then_taken`, `replay_dropped`), and another local system's HELLO answered
(`hello_from_another`, `another_welcomed`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where, newer, sequence_of, summary
from rcmlconf.conformance.probes.rsp_devices import first, flags, occurrence, reported
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import RawSession
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
    raw = probe.raw(encryption)
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
        lambda: raw.downlink([occurrence(found, ident, values)], buffer=buffer),
        PacketType.ACK,
        where=lambda d: ident in d.acks(found.position),
    )


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
    the first UPLINK the robot sent after it took it (its last received sequence number has
    reached it, R-RSP-15) for which `where` holds; None if none came within `wait`."""

    def fits(d: Datagram) -> bool:
        return newer(d.header.last_received, sequence_of(raw.last)) and (where is None or where(d))

    return await probe.answer_to(
        lambda: raw.downlink(items, buffer=buffer), PacketType.UPLINK, where=fits, wait=wait
    )


async def ack_of(
    probe: RspProbe, found: Device, ident: int, *, after: int, wait: float | None = None
) -> Datagram | None:
    """The robot's ACK of occurrence `ident` of `found` received from `after`, within `wait`."""
    return await probe.next(
        PacketType.ACK, after=after, wait=wait, where=lambda d: ident in d.acks(found.position)
    )


async def fresh_uplink(
    probe: RspProbe, sequence: int, *, wait: float | None = None, where: Where | None = None
) -> Datagram | None:
    """The first UPLINK the robot sent after it received our packet `sequence` (its last
    received sequence number has reached it, R-RSP-15)."""

    def fits(d: Datagram) -> bool:
        return newer(d.header.last_received, sequence) and (where is None or where(d))

    return await probe.next(PacketType.UPLINK, after=0, wait=wait, where=fits)


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
    must be dropped without an answer (no ACK within the quiet time); then the same command in a
    well-formed DOWNLINK must be acknowledged: the bad packet did not end the session."""
    command = first(probe.model, DeviceKind.COMMAND)
    ident = 7
    start = probe.mark()
    bad = mutate(raw.build(PacketType.DOWNLINK, MapBody((occurrence(command, ident),))))
    (sender or probe).send(bad, f"{what}: {probe._describe(bad)}")
    await probe.listen(probe.quiet)
    answers = [d for d in probe.packets(after=start) if d.type is not PacketType.UPLINK]
    ctx.expect(
        not answers,
        f"{what} dropped without an answer (no ACK)",
        ", ".join(summary(probe.model, d.header, d.body) for d in answers),
        requirement,
    )
    if sender is not None:
        stray = sender.packets()
        ctx.expect(
            not stray,
            "no answer to the other address",
            f"{len(stray)} datagrams",
            requirement,
        )
    ack = await acked(probe, raw, command, ident)
    ctx.expect(
        ack is not None,
        f"the session going on: ACK of {command.name} #{ident} in a well-formed DOWNLINK",
        "no ACK",
        requirement,
    )


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
    probe: RspProbe, raw: RawSession, found: Device, ident: int, sequence: int, *, resume: int
) -> Datagram | None:
    """Send occurrence `ident` of command `found` in a DOWNLINK numbered `sequence`, older than
    the newest the robot has and never seen (again while the impairment spoils it), number our
    next packet `resume`, and return the robot's ACK of it: a late packet's occurrences are taken
    (D-RSP-15, R-RSP-26). None if no ACK came."""

    def late() -> None:
        raw.rewind(sequence)
        raw.downlink([occurrence(found, ident)])
        raw.rewind(resume)

    return await probe.answer_to(
        late, PacketType.ACK, where=lambda d: ident in d.acks(found.position)
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
    its own, "second" in the transcript); Failed (`requirement`) if none comes. A session it
    opens ends with the case, as every session the robot opens for a probe."""
    other = await open_probe(ctx, robot=probe.robot, name="second")
    return await other.expect_answer_to(
        other.raw().hello,
        (PacketType.WELCOME, PacketType.REFUSED),
        requirement,
        expected=expected,
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
