"""rsp/local: an RSP local system under test, the harness playing its robot (`--role local`). The
local system runs the conformance scenario of D-RSP-24 each time it is started; each case takes
one run: its HELLO, numbering and stamps (D-RSP-10, D-RSP-12), its DOWNLINK every T (D-RSP-13),
taking occurrences once and acknowledging memory events (D-RSP-16), the WELCOME's MAC (D-RSP-21)
and BYE (R-RSP-13 to R-RSP-16, R-RSP-22, R-RSP-23, R-RSP-25, R-RSP-26, R-RSP-37, R-RSP-38,
R-RSP-41 to R-RSP-43).

How it sends its own commands and memory commands is in `sending`. This module also holds the
helpers that all the rsp/local cases share."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import held
from rcmlconf.conformance.probes.local_probe import LocalProbe
from rcmlconf.conformance.probes.local_scenario import REQUESTED
from rcmlconf.conformance.probes.pace import paced, spaced
from rcmlconf.conformance.probes.rsp_datagram import Datagram, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import first, of_kind, zero_values
from rcmlconf.conformance.registry import CaseFunction, case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    GAP_LONGEST,
    GAP_SHORTEST,
    HELLO_INTERVAL,
    HELLO_RETRIES,
    KEEPALIVE_PERIODS,
    stamp_allowance,
    unheard_for,
)
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import ByeReason, Encryption, Hello, Item, PacketType, Period, RefusedReason
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS
from rcmlconf.rsp.layout import MAC_SIZE
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.security import mac_matches

_SEQUENCE = 1 << 16


def local_case(
    id: str, purpose: str, requirements: list[str], *, timeout: float = 5.0
) -> Callable[[CaseFunction], CaseFunction]:
    """A local-system case: one run of the scenario at a time, so never two at once."""
    return case(id, purpose, requirements, role=Role.LOCAL, timeout=timeout, serial=True)


# -- sessions as the scenario opens them -----------------------------------------------------------


async def session(
    ctx: Context,
    *,
    free: int | None = None,
    slower: int = 1,
    withheld: Iterable[Device] = (),
    beating: bool = True,
    used: bool = True,
    repeats: int = 0,
) -> LocalProbe:
    """The next run's session, its HELLO answered with WELCOME (D-RSP-24 step 1), or its
    `repeats`-th repeat (D-RSP-12); `free` buffers announced from WELCOME on, the occurrences of
    `withheld` not acknowledged, T `slower` times the HELLO's; `used`: returned once the scenario
    uses the robot (`running`, step 2)."""
    probe = await ctx.local()
    if probe.encryption is not Encryption.NONE and probe.psk is None:
        probe.refuse(RefusedReason.ENCRYPTION_NOT_OFFERED)
        raise Inconclusive(
            "the local system's first HELLO is encrypted (D-RSP-24 begins without) and the"
            " robot's pre-shared key is not known (ICS [rsp] psk-file)"
        )
    if free is not None:
        probe.free = free
    probe.withheld = {d.position for d in withheld}
    probe.beating = beating
    if repeats:
        repeated = await probe.next(
            PacketType.HELLO, after=0, where=lambda _: len(probe.hellos) > repeats
        )
        if repeated is None:
            raise Inconclusive(f"the HELLO not repeated {repeats} times unanswered (D-RSP-12)")
    asked = probe.hello.body
    assert isinstance(asked, Hello)
    probe.welcome(min(slower * asked.period_ms, MAX_PERIOD_MS))
    if free is not None:
        # The free count in an UPLINK too, at once: a local system that reads it from UPLINKs
        # alone (WELCOME's buffer byte overlooked) is not this helper's to catch.
        probe.uplink()
    if used:
        await running(probe)
    return probe


def requested(model: RobotModel) -> set[int]:
    """What the scenario requests in every DOWNLINK (D-RSP-24 step 2)."""
    return {d.position for d in model.devices if d.kind in REQUESTED}


def names(model: RobotModel, positions: Iterable[int]) -> str:
    return ", ".join(model.devices[p].name for p in sorted(positions))


async def running(probe: LocalProbe) -> Datagram:
    """The first DOWNLINK of the scenario's use of the robot: requesting all it requests."""
    wanted = requested(probe.model)
    found = await probe.next(
        PacketType.DOWNLINK,
        after=0,
        where=lambda d: wanted <= {i.device for i in d.items},
    )
    if found is None:
        raise Inconclusive(
            f"no DOWNLINK requesting {names(probe.model, wanted) or 'anything'} within"
            f" {probe.wait:.2g} s of WELCOME (D-RSP-24 step 2)"
        )
    return found


def carries(device: Device, ident: int | None = None) -> Callable[[Datagram], bool]:
    """Whether a DOWNLINK carries an occurrence of `device` (of ID `ident`)."""

    def holds(found: Datagram) -> bool:
        item = found.item(device.position)
        return item is not None and item.id is not None and (ident is None or item.id == ident)

    return holds


def ids(downlinks: Iterable[Datagram], device: Device) -> list[int]:
    """The IDs of `device`'s occurrences in the order they first appear."""
    seen: list[int] = []
    for found in downlinks:
        item = found.item(device.position)
        if item is not None and item.id is not None and item.id not in seen:
            seen.append(item.id)
    return seen


def numbered(device: Device, idents: Iterable[int]) -> str:
    """Occurrences of `device` by ID, for a failure's text."""
    return f"{device.name} #{', #'.join(map(str, idents))}"


def occurrence(device: Device, ident: int) -> Item:
    return Item(device.position, ident, zero_values(device))


# -- HELLO --------------------------------------------------------------------------------------


@local_case(
    "rsp/local/hello",
    "The local system's HELLO: the model's ID, sequence 0, stamp 0, session ID 0, MAC if encrypted",
    ["R-RSP-13", "R-RSP-14", "R-RSP-15", "R-RSP-16"],
)
async def hello(ctx: Context) -> None:
    probe = await ctx.local()
    found = probe.hello
    header = found.header
    model = probe.model
    ctx.expect(header.model_id == model.model_id, str(model.model_id), str(header.model_id))
    ctx.expect(header.session_id == 0, "session ID 0", f"{header.session_id:#x}")
    ctx.expect(
        header.sequence == 0, "sequence 0 (its first packet)", str(header.sequence), "R-RSP-14"
    )
    ctx.expect(
        header.timestamp <= 10, "timestamp 0 (its first packet)", str(header.timestamp), "R-RSP-14"
    )
    ctx.expect(
        header.last_received == 0,
        "last received 0 (nothing received)",
        str(header.last_received),
        "R-RSP-15",
    )
    body = found.body
    assert isinstance(body, Hello)
    ctx.expect(
        (header.encryption is Encryption.NONE) == (body.mac == b""),
        "a MAC exactly when the session is encrypted (D-RSP-11)",
        f"encryption {int(header.encryption)}, {len(body.mac)}-byte MAC",
        "R-RSP-16",
    )


@local_case(
    "rsp/local/hello-retries",
    "A HELLO without answer is repeated every 250 ms, at most 5 times, each a new packet",
    ["R-RSP-41", "R-RSP-14"],
    timeout=6.0,
)
async def hello_retries(ctx: Context) -> None:
    probe = await ctx.local()
    start = probe.hello
    await probe.listen(start.at + HELLO_INTERVAL * HELLO_RETRIES + probe.quiet * 1.2 - probe.now)
    hellos = probe.hellos
    others = [d for d in probe.received if d.type is not PacketType.HELLO]
    ctx.expect(
        not others, "nothing but HELLO before an answer", f"{others[0].type.name}" if others else ""
    )
    ctx.expect(
        len(hellos) > 1,
        "HELLO repeated 250 ms later with the same nonce (D-RSP-12)",
        "one HELLO and no repeat",
    )
    numbers = [d.header.sequence for d in hellos]
    ctx.expect(
        numbers == list(range(len(numbers))),
        "sequence numbers 0, 1, 2, ...: each repeat a new packet",
        ", ".join(map(str, numbers)),
        "R-RSP-14",
    )
    spaced(ctx, hellos, HELLO_INTERVAL, "repeats", "R-RSP-41", note=" (D-RSP-12)")
    ctx.expect(
        len(hellos) <= HELLO_RETRIES + 1,
        f"at most {HELLO_RETRIES} repeats (D-RSP-12)",
        f"{len(hellos) - 1} repeats",
    )
    stamped_since(ctx, start, hellos, 0)


def stamped_since(ctx: Context, start: Datagram, found: Iterable[Datagram], base: int) -> None:
    """Each of `found` is stamped `base` and the milliseconds since `start`, the local system's
    first HELLO, as the harness's clock shows them within D-RSP-26's 5 % and 50 ms (a timing
    check: it reads the arrivals off the harness's clock). A stamp behind its arrival is a packet
    read late, which a harness kept waiting may not see as a hold (the embedded local system
    shares its loop): D-RSP-26 lets a quarter of them fall behind, none ahead."""
    behind: list[str] = []
    judged = list(found)
    for d in judged:
        span = d.at - start.at
        expected = span * 1000 + base
        allowed = stamp_allowance(span, ctx.scale)
        got = f"{d.header.timestamp} in {d.type.name} #{d.header.sequence}"
        wanted = (
            f"timestamp about {expected:.0f} (ms since the first HELLO, D-RSP-26: within"
            f" {allowed:.0f} ms)"
        )
        if d.header.timestamp < expected - allowed:
            behind.append(f"{wanted}; got {got}")
            continue
        ahead = (d.header.timestamp - expected - allowed) / 1000
        ctx.expect(ahead <= 0, wanted, got, "R-RSP-14", timing=True, by=ahead)
    ctx.expect(
        len(behind) <= len(judged) // 4,
        f"at most {len(judged) // 4} of {len(judged)} stamps behind their arrivals (D-RSP-26)",
        "; ".join(behind),
        "R-RSP-14",
        timing=True,
    )


# -- the DOWNLINK beat and its header ------------------------------------------------------------


@local_case(
    "rsp/local/downlink-header",
    "DOWNLINKs carry the session, numbers after HELLO's, stamps, and the newest number received",
    ["R-RSP-13", "R-RSP-14", "R-RSP-15"],
)
async def downlink_header(ctx: Context) -> None:
    occurring = of_kind(played_model(ctx), DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
    # Nothing acknowledged and no keep-alive: the robot's numbers move only as the case says.
    probe = await session(ctx, withheld=occurring, beating=False)
    wire = probe.wire
    assert wire is not None
    period = probe.period
    ten = wire.sent + 9
    sent: list[bytes] = []

    def high_one() -> None:  # sequence 10, again while the impairment spoils it
        wire.sent = ten
        sent.append(probe.uplink())

    probe.send_intact(high_one)
    high = sent[-1]
    wire.sent = 5
    probe.uplink()  # sequence 5: late (D-RSP-15), not the newest
    high_at = probe.now
    await probe.listen(8 * period)
    first_hello = probe.hellos[0]
    numbers = [d.header.sequence for d in probe.received]
    ctx.expect(
        all((b - a) % _SEQUENCE == 1 for a, b in itertools.pairwise(numbers)),
        "sequence numbers one more a packet, the HELLO's first",
        ", ".join(map(str, numbers[:24])),
        "R-RSP-14",
    )
    session_packets = [d for d in probe.received if d.type is not PacketType.HELLO]
    for found in session_packets:
        header = found.header
        ctx.expect(
            header.session_id == probe.session_id,
            f"session ID {probe.session_id:#x} (WELCOME's)",
            f"{header.session_id:#x} in {found.type.name} #{header.sequence}",
            "R-RSP-13",
        )
        ctx.expect(
            header.encryption is probe.encryption,
            f"encryption {int(probe.encryption)} (the HELLO's)",
            f"{int(header.encryption)} in {found.type.name} #{header.sequence}",
            "R-RSP-13",
        )
    stamped_since(ctx, first_hello, session_packets, first_hello.header.timestamp)
    sequence_high = int.from_bytes(high[5:7])
    lasts = [(d.at, d.header.last_received) for d in session_packets]
    ctx.expect(
        all(last in (0, sequence_high) for _, last in lasts),
        f"last received 0 (WELCOME's), then {sequence_high}: never the late 5",
        ", ".join(str(last) for _, last in lasts),
        "R-RSP-15",
    )
    ctx.expect(
        all(last == sequence_high for at, last in lasts if at >= high_at + 2 * period),
        f"last received {sequence_high} two periods after UPLINK #{sequence_high}",
        ", ".join(str(last) for at, last in lasts if at >= high_at + 2 * period) or "no DOWNLINK",
        "R-RSP-15",
    )


@local_case(
    "rsp/local/every-period",
    "A DOWNLINK every T of WELCOME (raised above HELLO's), each requesting all the scenario wants",
    ["R-RSP-23", "R-RSP-42"],
)
async def every_period(ctx: Context) -> None:
    probe = await session(ctx, slower=2)
    period = probe.period
    found = await running(probe)  # the DOWNLINK session() waited for: at once
    await probe.listen(10 * period)
    downlinks = [found, *probe.packets(PacketType.DOWNLINK, after=probe.after(found))]
    wanted = requested(probe.model)
    for down in downlinks:
        missing = wanted - {i.device for i in down.items}
        ctx.expect(
            not missing,
            f"every DOWNLINK requesting {names(probe.model, wanted)}",
            f"DOWNLINK #{down.header.sequence} without {names(probe.model, missing)}",
        )
    paced(ctx, downlinks, PacketType.DOWNLINK, period, " (WELCOME's T, twice HELLO's)")


# -- occurrences from the robot (D-RSP-16) -------------------------------------------------------


@local_case(
    "rsp/local/event-taken-once",
    "An event that rides four UPLINKs is taken once: it issues one command (D-RSP-24 step 3)",
    # R-RSP-17: every packet the local system sends is read against D-RSP-14's table, and an
    # ACK after an UPLINK of an event is where an implementation that acknowledges events
    # sets a bit it may not.
    ["R-RSP-25", "R-RSP-17"],
)
async def event_taken_once(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    event = first(model, DeviceKind.EVENT)
    probe = await session(ctx)
    period = probe.period
    before = await _first_command(probe, command)
    for _ in range(4):  # the three of R-RSP-30, and a late copy
        probe.uplink([occurrence(event, 0)])
        await probe.listen(period)
    echo = await probe.next(
        PacketType.DOWNLINK,
        after=0,
        where=lambda d: carries(command)(d) and not carries(command, before)(d),
    )
    if echo is None:
        raise Inconclusive(
            f"no {command.name} issued for {event.name} #0: whether it was taken cannot be seen"
            " (D-RSP-24 step 3)"
        )
    await probe.listen(8 * period)
    issued = [i for i in ids(probe.packets(PacketType.DOWNLINK), command) if i != before]
    ctx.expect(
        len(issued) == 1,
        f"{event.name} #0 taken once: one {command.name} for it",
        f"{len(issued)} commands: {numbered(command, issued)}",
    )


async def _first_command(probe: LocalProbe, command: Device) -> int:
    """The ID of the command the scenario issues on its own (D-RSP-24 step 2): the commands
    after it are echoes of events taken (step 3)."""
    start = await probe.next(PacketType.DOWNLINK, after=0, where=carries(command))
    if start is None:
        raise Inconclusive(f"no {command.name} command issued (D-RSP-24 step 2)")
    item = start.item(command.position)
    assert item is not None
    assert item.id is not None
    return item.id


@local_case(
    "rsp/local/events-taken-per-device",
    "Events of two devices with the same ID are each taken: each issues a command",
    ["R-RSP-25"],
)
async def events_taken_per_device(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    events = of_kind(model, DeviceKind.EVENT)
    if len(events) < 2:
        # Occurrence IDs are per device (R-RSP-24): only two devices of a kind with the same ID
        # show a receiver that keeps its last taken ID per kind; taken memory events all look
        # alike on the wire (one PERIOD, D-RSP-24 step 4), so events alone can show it.
        raise NotApplicable(f"the model {model.name} has fewer than two event devices")
    one, other = events[:2]
    probe = await session(ctx)
    period = probe.period
    before = await _first_command(probe, command)
    for _ in range(3):  # R-RSP-30's three UPLINKs, both events #0 in each
        probe.uplink([occurrence(one, 0), occurrence(other, 0)])
        await probe.listen(period)

    def echoes() -> list[int]:
        return [i for i in ids(probe.packets(PacketType.DOWNLINK), command) if i != before]

    if await probe.next(PacketType.DOWNLINK, after=0, where=lambda _: len(echoes()) >= 2):
        await probe.listen(4 * period)  # and no third
    issued = echoes()
    ctx.expect(
        len(issued) == 2,
        f"{one.name} #0 and {other.name} #0 each taken once (IDs are per device, R-RSP-24):"
        f" two {command.name} commands for them (D-RSP-24 step 3)",
        f"{len(issued)} commands: {numbered(command, issued)}",
    )


@local_case(
    "rsp/local/acks-memory-event",
    "A memory event is acknowledged at once, again when repeated, and taken once",
    ["R-RSP-26", "R-RSP-25"],
)
async def acks_memory_event(ctx: Context) -> None:
    found = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx)
    period = probe.period
    sent: list[bytes] = []
    for attempt in ("", "repeated "):
        mark, first_sent = probe.mark(), len(sent)
        ack = await probe.expect_answer_to(
            lambda: sent.append(probe.uplink([occurrence(found, 0)])),
            PacketType.ACK,
            "R-RSP-26",
            where=lambda d: 0 in d.acks(found.position),
            expected=f"an ACK of the {attempt}{found.name} #0",
        )
        # Only a DOWNLINK that says it received the UPLINK (R-RSP-15) shows the ACK put off: one
        # made before the local system read it (a loaded machine keeps it from its socket) does
        # not, however late it came.
        uplink = sequence_of(sent[first_sent])
        between = probe.packets(PacketType.DOWNLINK, after=mark)[: probe.after(ack) - mark]
        between = [
            d
            for d in between
            if d.at < ack.at
            and (d.header.last_received == uplink or newer(d.header.last_received, uplink))
        ]
        ctx.expect(
            len(between) <= 1,
            f"the ACK of {found.name} #0 at once, not after later DOWNLINKs",
            f"after {len(between)} DOWNLINKs",
            "R-RSP-26",
        )
    await probe.listen(3 * period)
    periods = {
        d.body.period_ms for d in probe.packets(PacketType.PERIOD) if isinstance(d.body, Period)
    }
    ctx.expect(
        len(periods) <= 1,
        f"{found.name} #0 taken once: T changed once (D-RSP-24 step 4)",
        f"PERIOD of {', '.join(map(str, sorted(periods)))} ms",
        "R-RSP-25",
    )


@local_case(
    "rsp/local/idle-keep-alive",
    "Idle, the local system sends PERIOD three periods running, then an empty DOWNLINK every 5 T",
    ["R-RSP-43", "R-RSP-42"],
)
async def idle_keep_alive(ctx: Context) -> None:
    found = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx, free=0)  # memory commands held (R-RSP-32): nothing left to send
    period = probe.period
    await probe.listen(3 * period)  # the command acknowledged and gone
    mark, asked = probe.mark(), probe.now
    change = await probe.answer_to(  # taken, the scenario goes idle at 2 T (step 4)
        lambda: probe.uplink([occurrence(found, 0)]), PacketType.PERIOD
    )
    if change is None or not isinstance(change.body, Period):
        _welcome_pace_kept(ctx, probe, mark, asked, period)
        raise Inconclusive(f"no PERIOD after {found.name} #0 (D-RSP-24 step 4)")
    slower = change.body.period_ms / 1000
    keep = KEEPALIVE_PERIODS * slower
    start = probe.after(change) - 1
    await probe.next(
        PacketType.DOWNLINK,
        after=start,
        wait=2.6 * keep,
        where=lambda _: len(_empty(probe.packets(PacketType.DOWNLINK, after=start))) >= 2,
    )
    periods = probe.packets(PacketType.PERIOD, after=start)
    values = {d.body.period_ms for d in periods if isinstance(d.body, Period)}
    ctx.expect(
        len(periods) == 3 and len(values) == 1,
        f"PERIOD of {slower * 1000:g} ms in each of three periods running (D-RSP-13)",
        f"{len(periods)} PERIODs of {', '.join(map(str, sorted(values)))} ms",
        "R-RSP-43",
    )
    # Read off the harness's clock: a timing check (D-RSP-26), excused as far as the holds add
    # up to how far past three periods and a half the last came (a CI run held the embedded
    # reference, and the harness with it, 150 ms between two PERIODs).
    spread = periods[-1].at - periods[0].at if periods else 0.0
    ctx.expect(
        spread <= 3.5 * slower,
        f"the PERIODs within three periods of {slower * 1000:g} ms",
        f"over {spread * 1000:.0f} ms",
        "R-RSP-43",
        timing=True,
        by=spread - 3.5 * slower,
    )
    # Nor all at once, where one loss loses them all: in three periods, the first and the last
    # are a period apart or more (D-RSP-13's least single gap, 0.6 of it), by the local system's
    # own clock (R-RSP-14): a harness held up reads datagrams that waited together at once. A
    # timing check all the same: the embedded reference shares the harness's process, and held
    # with it, it sent two PERIODs in one ms (D-RSP-26: excused as far as the holds add up).
    stamped = (periods[-1].header.timestamp - periods[0].header.timestamp) % (1 << 32)
    ctx.expect(
        stamped >= GAP_SHORTEST * slower * 1000,
        f"the PERIODs spread over three periods of {slower * 1000:g} ms, not sent at once",
        f"stamped {', '.join(str(d.header.timestamp) for d in periods)} ms",
        "R-RSP-43",
        timing=True,
        by=(GAP_SHORTEST * slower * 1000 - stamped) / 1000,
    )
    downlinks = probe.packets(PacketType.DOWNLINK, after=start)
    busy = [d for d in downlinks if d.items and d.at > change.at + 1.5 * slower]
    if busy:
        raise Inconclusive(
            f"not idle after {found.name} #0: DOWNLINK #{busy[0].header.sequence} carries"
            f" {', '.join(sorted(busy[0].devices(probe.model)))} (D-RSP-24 step 4)"
        )
    empty = _empty(downlinks)
    ctx.expect(
        len(empty) >= 2,
        f"an empty DOWNLINK every {KEEPALIVE_PERIODS} periods ({keep * 1000:g} ms)",
        f"{len(empty)} in {(probe.now - change.at) * 1000:.0f} ms",
        "R-RSP-42",
        timing=True,
    )
    spaced(ctx, empty, keep, "empty DOWNLINKs")


def _welcome_pace_kept(
    ctx: Context, probe: LocalProbe, mark: int, since: float, period: float
) -> None:
    """No PERIOD came since `since` (received from `mark` on): T is still WELCOME's `period`
    (R-RSP-42: the T of the newest WELCOME or PERIOD), so a DOWNLINK came every period, or an
    empty one every 5 periods at least. A T changed without PERIOD shows as longer gaps."""
    keep = KEEPALIVE_PERIODS * period
    times = [since, *(d.at for d in probe.packets(PacketType.DOWNLINK, after=mark)), probe.now]
    longest = max(b - a for a, b in itertools.pairwise(times))
    ctx.expect(
        longest <= GAP_LONGEST * keep,
        f"no PERIOD, so WELCOME's T of {period * 1000:g} ms kept: a DOWNLINK every period, or"
        f" an empty one every {KEEPALIVE_PERIODS} ({keep * 1000:g} ms)",
        f"no DOWNLINK for {longest * 1000:.0f} ms",
        "R-RSP-42",
        timing=True,
        by=longest - GAP_LONGEST * keep,
    )


def _empty(downlinks: list[Datagram]) -> list[Datagram]:
    return [d for d in downlinks if not d.items]


def sent_after(
    ctx: Context, probe: LocalProbe, sent: bytes, at: float
) -> Callable[[Datagram], bool]:
    """Whether a packet of the local system's was sent after it had `sent` (which went at loop
    time `at`), judged now, once the case has waited: it says it received it or newer (R-RSP-15),
    or it was read D-RSP-26's two periods and slack later, and as much more as the harness's loop
    was held (held up, it reads late)."""
    sequence = sequence_of(sent)
    last = at + unheard_for(probe.period, ctx.scale) + held(ctx, at)
    return lambda d: newer(d.header.last_received, sequence) or d.at > last


# -- the end ------------------------------------------------------------------------------------


@local_case(
    "rsp/local/bye-ends",
    "After the robot's BYE the local system sends nothing more of the session",
    ["R-RSP-22"],
)
async def bye_ends(ctx: Context) -> None:
    probe = await session(ctx)
    period = probe.period
    bye = probe.bye(ByeReason.SHUTDOWN)
    at = probe.now
    seen = await probe.received_within(
        max(8 * period, probe.quiet) + unheard_for(period, ctx.scale)
    )
    after_bye = sent_after(ctx, probe, bye, at)
    late = [d for d in seen if d.type is not PacketType.BYE and after_bye(d)]
    ctx.expect(
        not late,
        "nothing of the session after BYE",
        f"{late[0].type.name} #{late[0].header.sequence}" if late else "",
    )


# -- security (D-RSP-21) ------------------------------------------------------------------------


@local_case(
    "rsp/local/welcome-mac",
    "A WELCOME with a wrong MAC is dropped (HELLO repeated); the right one opens a sealed session",
    ["R-RSP-38", "R-RSP-37", "R-RSP-13"],
)
async def welcome_mac(ctx: Context) -> None:
    psk = ctx.target.rsp_psk
    if psk is None:
        raise NotApplicable("the robot's pre-shared key is not known (ICS [rsp] psk-file)")
    probe = await ctx.local()
    if probe.encryption is Encryption.NONE:
        probe.refuse(RefusedReason.ENCRYPTION_NOT_OFFERED)  # D-RSP-24 step 1: it tries an AEAD
        probe = await ctx.local(again=True)
        if probe.encryption is Encryption.NONE:
            probe.refuse(RefusedReason.ENCRYPTION_NOT_OFFERED)
            raise NotApplicable("the local system offers no encrypted session (D-RSP-24 step 1)")
    signed = probe.hello
    ctx.expect(
        mac_matches(psk, signed.data[:-MAC_SIZE], signed.data[-MAC_SIZE:]),
        "a HELLO signed with the pre-shared key (D-RSP-21)",
        f"MAC {signed.data[-MAC_SIZE:].hex()}",
        "R-RSP-37",
    )
    mark = probe.mark()
    probe.welcome(key=bytes(b ^ 0x5A for b in psk))
    again = await probe.next(PacketType.HELLO, after=mark, wait=2 * HELLO_INTERVAL + probe.quiet)
    stray = [d for d in probe.packets(after=mark) if d.type is not PacketType.HELLO]
    ctx.expect(
        not stray,
        "the forged WELCOME dropped: nothing of its session",
        f"{stray[0].type.name} #{stray[0].header.sequence}" if stray else "",
    )
    ctx.expect(again is not None, "HELLO repeated: no session yet", "no HELLO again")
    mark = probe.mark()
    probe.welcome()
    down = await probe.expect(
        PacketType.DOWNLINK,
        "R-RSP-37",
        after=mark,
        where=lambda d: d.body is not None,
        expected="a DOWNLINK sealed with the session's keys",
    )
    # One saying encryption 0 is read in the clear: sealed, it says the session's (D-RSP-21).
    ctx.expect(
        down.header.encryption is probe.encryption,
        f"a DOWNLINK sealed: encryption {int(probe.encryption)} ({probe.encryption.name})",
        f"DOWNLINK #{down.header.sequence} with encryption {int(down.header.encryption)}",
        "R-RSP-13",
    )


def played_model(ctx: Context) -> RobotModel:
    """The robot model the harness plays to the local system under test (--model)."""
    if ctx.target.rsp_model is None:
        raise NotApplicable("the robot model the harness plays is not known (give --model)")
    return ctx.target.rsp_model
