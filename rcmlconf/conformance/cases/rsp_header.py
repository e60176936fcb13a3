"""rsp/header: the header of D-RSP-10 in the robot's packets, and what the robot does with the
local system's, well-formed or not (D-RSP-15, R-RSP-13 to R-RSP-19). The harness plays the
local system.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import (
    ENCRYPTION_AT,
    MODEL_AT,
    SESSION_AT,
    TYPE_AT,
    VERSION_AT,
    sequence_of,
)
from rcmlconf.conformance.probes.rsp_devices import (
    first,
    flags,
    occurrence,
    reported,
)
from rcmlconf.conformance.probes.rsp_exchanges import (
    acked,
    dropped_then_taken,
    late_acked,
    must_take,
    raw_session,
    replay_dropped,
    requested_uplinks,
    taken,
    uplinks_within,
)
from rcmlconf.conformance.probes.rsp_forged import flip, patch
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import stamp_allowance
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.impair import derive_seed
from rcmlconf.rsp.codec import (
    Bye,
    ByeReason,
    Encryption,
    MapBody,
    PacketType,
    Period,
    Welcome,
)
from rcmlconf.rsp.model import DeviceKind


@case(
    "rsp/header/layout",
    "The robot's UPLINKs carry version 1, the model ID, encryption 0 and the session's ID",
    ["R-RSP-13"],
    role=Role.ROBOT,
)
async def layout(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    uplinks = await requested_uplinks(probe, raw, reported(model, 2), 6)
    for found in uplinks:
        header = found.header
        ctx.expect(
            header.version == 1
            and header.model_id == model.model_id
            and header.encryption is Encryption.NONE
            and header.session_id == raw.session_id,
            f"version 1, model {model.model_id}, encryption 0, session {raw.session_id:#x}",
            f"version {header.version}, model {header.model_id},"
            f" encryption {int(header.encryption)}, session {header.session_id:#x}",
        )


@case(
    "rsp/header/sequence",
    "The robot numbers its packets of a session 0, 1, 2, ... WELCOME, UPLINKs and ACKs alike",
    ["R-RSP-14"],
    role=Role.ROBOT,
)
async def sequence(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    command = first(model, DeviceKind.COMMAND)
    await taken(probe, raw, flags(model, reported(model, 1)[0]))
    await probe.listen(3 * raw.period)
    await acked(probe, raw, command, 0)  # an ACK among the UPLINKs
    await probe.listen(3 * raw.period)
    # One number per packet: a WELCOME sent again to a HELLO the impairment duplicated is the
    # same packet (D-RSP-12), not a number used twice.
    unique = {d.data: d for d in probe.received if d.header.session_id == raw.session_id}
    numbers = [d.header.sequence for d in unique.values()]
    expected = list(range(len(numbers)))
    ctx.expect(
        numbers == expected and len(numbers) >= 4,
        "0, 1, 2, ... without a gap (loopback loses nothing)",
        ", ".join(map(str, numbers)),
    )


@case(
    "rsp/header/timestamp",
    "The robot's timestamps start at 0 with WELCOME and count its milliseconds",
    ["R-RSP-14"],
    role=Role.ROBOT,
)
async def timestamp(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    welcome = raw.welcome
    assert welcome is not None
    ctx.expect(welcome.header.timestamp == 0, "WELCOME at 0 ms", f"{welcome.header.timestamp} ms")
    raw.downlink(flags(probe.model, reported(probe.model, 1)[0]))
    await probe.listen(max(0.4, 15 * raw.period))
    stamped = [d for d in probe.received if d.header.session_id == raw.session_id]
    stamps = [d.header.timestamp for d in stamped]
    ctx.expect(
        all(b >= a for a, b in itertools.pairwise(stamps)),
        "timestamps that never go back",
        ", ".join(map(str, stamps)),
    )
    span = stamped[-1].at - welcome.at
    told = stamps[-1] - welcome.header.timestamp
    allowed = stamp_allowance(span, ctx.scale)
    ctx.expect(  # read off the harness's clock: a timing check
        abs(told - span * 1000) <= allowed,
        f"about {span * 1000:.0f} ms between WELCOME and the last UPLINK (D-RSP-26: within"
        f" {allowed:.0f} ms)",
        f"{told} ms",
        timing=True,
        by=(abs(told - span * 1000) - allowed) / 1000,
    )


@case(
    "rsp/header/last-received",
    "The robot's last received sequence number is the newest of ours, not the latest to arrive",
    ["R-RSP-15"],
    role=Role.ROBOT,
)
async def last_received(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    request = flags(probe.model, reported(probe.model, 1)[0])
    for _ in range(2):
        raw.downlink(request)
    found = await must_take(
        ctx, probe, raw, request, "an UPLINK that took the DOWNLINKs", wait=probe.quiet
    )
    newest = sequence_of(raw.last)
    ctx.expect(
        found.header.last_received == newest,
        f"UPLINKs saying {newest}",
        str(found.header.last_received),
    )
    raw.skip(10)
    jumped = sequence_of(raw.downlink(request))
    raw.rewind(jumped - 4)
    raw.downlink(request)  # late: not newer
    later = await uplinks_within(probe, 4, raw.period, f"DOWNLINK #{jumped} and the late one")
    said = [d.header.last_received for d in later]
    ctx.expect(
        all(s == jumped for s in said[1:]) and said[-1] == jumped,
        f"UPLINKs saying {jumped} (the newest), not {jumped - 4} (the latest)",
        ", ".join(map(str, said)),
    )


@case(
    "rsp/header/other-version",
    "A DOWNLINK of version 2 is dropped unanswered (its command not taken), the session goes on",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def other_version(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await dropped_then_taken(
        ctx, probe, raw, lambda d: patch(d, VERSION_AT, b"\x02"), "R-RSP-18", "version 2"
    )


@case(
    "rsp/header/other-model",
    "A DOWNLINK of another model ID is dropped unanswered, the session goes on",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def other_model(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    other = (probe.model.model_id % 65535 + 1).to_bytes(2)
    await dropped_then_taken(
        ctx, probe, raw, lambda d: patch(d, MODEL_AT, other), "R-RSP-18", "another model ID"
    )


@case(
    "rsp/header/other-session",
    "A DOWNLINK naming another session ID is dropped unanswered, the session goes on",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def other_session(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await dropped_then_taken(
        ctx, probe, raw, lambda d: flip(d, SESSION_AT + 5), "R-RSP-18", "a spoofed session ID"
    )


@case(
    "rsp/header/other-address",
    "A DOWNLINK of the session from another address is dropped unanswered",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def other_address(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    for spoofer in await _either_side(ctx, probe):
        await dropped_then_taken(
            ctx, probe, raw, lambda d: d, "R-RSP-18", "from another port", sender=spoofer
        )


@case(
    "rsp/header/outside-session",
    "A DOWNLINK, PERIOD or BYE of another model ID from outside a session (before any HELLO, or"
    " from another port while one runs) is dropped unanswered: only a HELLO is refused",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def outside_session(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    other = (model.model_id % 65535 + 1).to_bytes(2)

    def of_other_model(data: bytes) -> bytes:
        return patch(data, MODEL_AT, other)

    stray = hand_driven(probe)  # never opened: a session ID the robot never gave
    stray.wire.session_id = random.randrange(1, 1 << 48)
    start = probe.mark()
    period = Period(round(model.period * 1000))
    for kind, body in (
        (PacketType.DOWNLINK, MapBody(())),
        (PacketType.PERIOD, period),
        (PacketType.BYE, Bye(ByeReason.CLOSED)),
    ):
        stray.send(kind, body, mutate=of_other_model)
    await probe.listen(probe.quiet)
    answers = probe.packets(after=start)
    ctx.expect(
        not answers,
        "no answer to packets of no session (R-RSP-21 answers a HELLO of another model, only)",
        ", ".join(f"{d.type.name} {getattr(d.body, 'reason', '')}" for d in answers),
    )
    raw = hand_driven(probe)
    await raw.open()
    for spoofer in await _either_side(ctx, probe):
        await dropped_then_taken(
            ctx,
            probe,
            raw,
            of_other_model,
            "R-RSP-18",
            "a DOWNLINK of another model ID from another port",
            sender=spoofer,
        )


#: How many sockets `_either_side` opens at most: each falls on a given side of the session's
#: port about half the time, so 12 miss a side once in 2,000 runs.
_SPOOF_TRIES = 12


async def _either_side(ctx: Context, probe: RspProbe) -> list[RspProbe]:
    """Probes on the robot from a port below the session's and from one above (as many as
    `_SPOOF_TRIES` sockets give): a robot that orders addresses rather than compares them for
    equality (D-RSP-12) takes one side's packets, and is caught whichever side that is."""
    below: RspProbe | None = None
    above: RspProbe | None = None
    for _ in range(_SPOOF_TRIES):
        spoofer = await open_probe(ctx, robot=probe.robot, name="other port")
        if spoofer.local < probe.local:
            below = below or spoofer
        else:
            above = above or spoofer
        if below is not None and above is not None:
            break
    return [s for s in (below, above) if s is not None]


@case(
    "rsp/header/unknown-type",
    "Packets of types 0, 9 and 255 with a DOWNLINK's body are dropped unanswered",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def unknown_type(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    for kind in (0, 9, 255):
        await dropped_then_taken(
            ctx,
            probe,
            raw,
            _typed(kind),
            "R-RSP-18",
            f"type {kind}",
        )


def _typed(kind: int) -> Callable[[bytes], bytes]:
    return lambda data: patch(data, TYPE_AT, bytes([kind]))


@case(
    "rsp/header/encryption-mismatch",
    "In a session without encryption, a DOWNLINK saying AES-256-GCM is dropped unanswered",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def encryption_mismatch(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await dropped_then_taken(
        ctx,
        probe,
        raw,
        lambda d: patch(d, ENCRYPTION_AT, bytes([Encryption.AES_256_GCM])),
        "R-RSP-18",
        "encryption byte 1",
    )


@case(
    "rsp/header/replayed",
    "A DOWNLINK received again byte for byte is dropped: its command is not acknowledged twice",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def replayed(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await replay_dropped(ctx, probe, raw, 3)


@case(
    "rsp/header/outside-window",
    "A packet 65 behind the newest is dropped; one exactly 64 behind, never seen, is handled",
    ["R-RSP-18", "R-RSP-26"],
    role=Role.ROBOT,
)
async def outside_window(ctx: Context) -> None:
    # D-RSP-15: "more than 64 behind" is dropped, so the window's edge is between 64 and 65.
    probe, raw = await raw_session(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    raw.skip(100)
    if await taken(probe, raw) is None:  # the robot's newest must be this one
        raise Inconclusive("no UPLINK after the DOWNLINK 100 ahead")
    newest = sequence_of(raw.last)
    raw.rewind(newest - 65)
    start = probe.mark()
    raw.downlink([occurrence(command, 0)])
    await probe.listen(probe.quiet)
    stale = [d for d in probe.packets(PacketType.ACK, after=start) if d.acks(command.position)]
    ctx.expect(not stale, "a packet 65 behind dropped unread (no ACK)", "an ACK", "R-RSP-18")
    await late_acked(
        ctx,
        probe,
        raw,
        command,
        0,
        newest - 64,
        resume=newest + 1,
        expected="the command of a late packet exactly 64 behind acknowledged (D-RSP-15)",
    )


@case(
    "rsp/header/local-sequence-wraps",
    "The robot follows the local system's sequence numbers across 65,535 to 0 (serial arithmetic)",
    ["R-RSP-19", "R-RSP-18"],
    role=Role.ROBOT,
)
async def local_sequence_wraps(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    before, after = reported(model, 2)
    for target in (20000, 40000, 60000, 65535):
        raw.rewind(target)  # each taken before the next: 20,000 on from the one before
        took = f"an UPLINK taking DOWNLINK {target}"
        await must_take(ctx, probe, raw, flags(model, before), took, "R-RSP-19")
    # Sequence 0: newer than 65,535 (1, 2, ... if the impairment spoiled 0).
    found = await must_take(ctx, probe, raw, flags(model, after), "an UPLINK taking DOWNLINK 0")
    ctx.expect(
        found.devices(model) == {after.name},
        f"UPLINKs reporting {after.name} only, as DOWNLINK {sequence_of(raw.last)} asked after"
        " 65,535",
        str(sorted(found.devices(model))),
    )


@case(
    "rsp/header/garbage",
    "Garbage, empty and cut-short datagrams are dropped unanswered and the session goes on",
    ["R-RSP-18"],
    role=Role.ROBOT,
)
async def garbage(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    draw = random.Random(derive_seed(ctx.seed, ctx.case.id))
    noise = bytearray(draw.randbytes(37))
    noise[0] = 0xFF  # no version 1: it cannot be a HELLO by chance
    header = raw.build(PacketType.DOWNLINK, MapBody(()))[:20]
    welcome = raw.welcome
    assert welcome is not None
    assert isinstance(welcome.body, Welcome)
    start = probe.mark()
    for junk in (
        bytes(noise),
        b"",
        b"\x01",
        header[:19],
        header,  # a DOWNLINK without its Device Map
        header + bytes(model.map_size - 1),  # a Device Map cut short
        welcome.data,  # the robot's own WELCOME sent back
    ):
        probe.send(junk, f"garbage {junk[:20].hex()} ({len(junk)} bytes)")
    await probe.listen(probe.quiet)
    answers = [d for d in probe.packets(after=start) if d.type is not PacketType.UPLINK]
    ctx.expect(not answers, "no answer", ", ".join(d.type.name for d in answers))
    await dropped_then_taken(ctx, probe, raw, lambda d: d[:20], "R-RSP-18", "a header alone")
