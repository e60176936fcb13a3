"""Exchanges the RSP robot cases share, each something sent and the robot's answer waited for
(bounded by the probe's wait): a session opened by hand or by the core's endpoint
(`raw_session`, `reporting`), what must come checked once for all, a late robot told from one that
never sends (`came`), a command acknowledged (`acked`, `must_ack`, `late_acked`), a DOWNLINK taken
(`taken`, `must_take`, `fresh_uplink`, `requested_uplinks`), a bad packet dropped and the session
going on (`dropped_then_taken`, `unanswered`, `going_on`, `replay_dropped`), and another local
system's HELLO answered (`hello_from_another`, `another_welcomed`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where, newer, sequence_of, summary
from rcmlconf.conformance.probes.rsp_devices import first, flags, occurrence, reported
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import RawSession, hand_driven
from rcmlconf.conformance.rsp_numbers import HELLO_INTERVAL
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


#: Seconds (times --timeout-scale) of the case's time that `came`'s second window leaves for the
#: verdict: the check's own, not the case's timeout (a fail that says nothing of what was late).
_SPARE = 0.1


async def came(
    ctx: Context,
    probe: RspProbe,
    kinds: PacketType | tuple[PacketType, ...],
    expected: str,
    requirement: str | None = None,
    *,
    send: Callable[[], object] | None = None,
    after: int | None = None,
    where: Where | None = None,
    wait: float | None = None,
    instead: Callable[[], str] | None = None,
) -> Datagram:
    """The first datagram of `kinds` for which `where` holds from `after` (by default: from now,
    `send` sending its packet first as `answer_to` does), which must come (Failed: `requirement`,
    `expected`; `instead` says what came in its place) within `wait` (the probe's by default).
    That window lies well past the bound of specs/ the robot sends it by (`expected` cites it):
    the case does not judge its timing. A robot or a harness short of CPU may still miss it, so
    when nothing came in it, the case waits as long again to learn how late it comes: a timing
    check (D-RSP-26: a hold of the harness's loop delays what it reads by its length at most),
    excused as far as the holds add up to how late it came, or when it never came, to how long
    the case waited past the window. On a machine that holds nothing, a robot that never sends
    it fails, and so does one that sends it that late."""
    start = probe.mark() if after is None else after
    window = probe.wait if wait is None else wait
    since = probe.now
    if send is None:
        found = await probe.next(kinds, after=start, where=where, wait=window)
    else:
        found = await probe.answer_to(send, kinds, where=where, wait=window)
    if found is None:
        due = since + window
        again = min(window, ctx.left - _SPARE * ctx.scale)
        late = await probe.next(kinds, after=start, where=where, wait=again)
        seen = probe.now if late is None else late.at
        got = (
            f"none within {(seen - since) * 1000:.0f} ms"
            if late is None
            else f"none within {window * 1000:.0f} ms: it came {(seen - since) * 1000:.0f} ms after"
        )
        ctx.expect(
            False,
            expected,
            got + (f"; {instead()}" if instead is not None else ""),
            requirement,
            timing=True,
            by=seen - due,
        )
    assert found is not None  # expect failed the case otherwise
    return found


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
    expected: str = "",
) -> Datagram:
    """`acked`'s ACK, which must come (`came`); `expected` says why, in the failure's text."""
    return await came(
        ctx,
        probe,
        PacketType.ACK,
        f"{expected or f'ACK of {found.name} #{ident}'}, {AT_ONCE}",
        requirement,
        send=_occurring(raw, found, ident, values, 0),
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
) -> Datagram:
    """Send occurrence `ident` of command `found` in a DOWNLINK numbered `sequence`, older than
    the newest the robot has and never seen (again while the impairment spoils it), number our
    next packet `resume`, and return the robot's ACK of it, which must come (`came`): a late
    packet's occurrences are taken (D-RSP-15, R-RSP-26). `expected` says which packet it is."""

    def late() -> None:
        raw.rewind(sequence)
        raw.downlink([occurrence(found, ident)])
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
        f"{expected or 'WELCOME or REFUSED'}, before the local system's first repeat of its"
        f" HELLO (D-RSP-12: {HELLO_INTERVAL * 1000:g} ms)",
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
