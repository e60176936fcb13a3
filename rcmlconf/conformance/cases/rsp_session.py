"""rsp/session: opening, keeping and ending an RSP session, the robot's side (specs/rsp.md
D-RSP-12, D-RSP-13, R-RSP-20 to R-RSP-22). The harness plays the local system.
"""

from __future__ import annotations

import functools
import itertools
import os
import statistics
from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.ics import FEATURES
from rcmlconf.conformance.probes.awaited import came
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.pace import gaps, ms, paced, spaced
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import flags, reported, values_of
from rcmlconf.conformance.probes.rsp_exchanges import (
    NEXT_PERIOD,
    another_welcomed,
    fresh,
    hello_from_another,
    must_take,
    raw_session,
    reporting,
    taken,
)
from rcmlconf.conformance.probes.rsp_forged import hello_packet
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import BEFORE_REPEAT, hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    GAP_LONGEST,
    GAP_SHORTEST,
    KEEPALIVE_PERIODS,
    KEEPALIVE_SLACK,
    SESSION_TIMEOUT,
    STAMP_ROUNDING,
    timeout_window,
)
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import (
    Bye,
    ByeReason,
    Encryption,
    PacketType,
    Refused,
    RefusedReason,
    Welcome,
)
from rcmlconf.rsp.layout import NONCE_SIZE

_ANSWERS = (PacketType.WELCOME, PacketType.REFUSED)
#: The low bits of a 48-bit session ID, above which a random one is all 0 once in 65,536.
_LOW_BITS = 32
#: Seconds rsp/session/timeout-bye keeps the session alive before its silence, a DOWNLINK every
#: _KEEPING seconds (well within the 25 periods of D-RSP-13 at any T a robot may raise to).
KEPT = 1.0
_KEEPING = 0.1
#: The encryption bytes of the AEADs and the ICS features that declare them (D-RSP-21).
_AEADS = {
    Encryption.AES_256_GCM: "rsp-aes-256-gcm",
    Encryption.CHACHA20_POLY1305: "rsp-chacha20-poly1305",
}


def _other_models(model_id: int) -> tuple[int, int]:
    """Two model IDs other than `model_id` (1 to 65,535, D-RSP-6): one that differs in its low
    byte, one that differs in its high byte only, so that a robot that compares one byte of the
    two is caught either way."""
    high = model_id ^ 0x0100 or 0x0300
    return model_id % 65535 + 1, high


def _refused(ctx: Context, answer: Datagram, reason: RefusedReason, requirement: str) -> None:
    """A REFUSED with `reason` (D-RSP-11)."""
    body = answer.body
    got = f"REFUSED {body.reason.name}" if isinstance(body, Refused) else answer.type.name
    ctx.expect(
        isinstance(body, Refused) and body.reason is reason,
        f"REFUSED {reason.name}",
        got,
        requirement,
    )


def _echoes(
    ctx: Context, answer: Datagram, model_id: int, encryption: int, requirement: str = "R-RSP-20"
) -> None:
    """D-RSP-12: REFUSED echoes the HELLO's model ID and encryption byte."""
    header = answer.header
    ctx.expect(
        header.model_id == model_id and int(header.encryption) == encryption,
        f"model ID {model_id} and encryption {encryption} echoed",
        f"model ID {header.model_id}, encryption {int(header.encryption)}",
        requirement,
    )
    ctx.expect(
        header.session_id == 0,
        "session ID 0 in REFUSED",
        f"{header.session_id:#x}",
        "R-RSP-13",
    )


@case(
    "rsp/session/welcome",
    "HELLO is answered WELCOME: a new non-zero session ID, the nonce echoed, sequence 0, a period",
    ["R-RSP-20", "R-RSP-13", "R-RSP-14", "R-RSP-15"],
    role=Role.ROBOT,
)
async def welcome(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    raw = hand_driven(probe)
    answer = await raw.expect_welcome(ctx, "R-RSP-20")
    header, body = answer.header, answer.body
    assert isinstance(body, Welcome)
    ctx.expect(header.session_id != 0, "a session ID that is not 0", "0", "R-RSP-20")
    ctx.expect(
        header.model_id == model.model_id and header.encryption is Encryption.NONE,
        f"model ID {model.model_id}, encryption 0",
        f"model ID {header.model_id}, encryption {int(header.encryption)}",
        "R-RSP-13",
    )
    ctx.expect(
        header.sequence == 0, "sequence 0 (its first packet)", str(header.sequence), "R-RSP-14"
    )
    hello = sequence_of(raw.last)  # 0, or 1, 2, ... if the impairment spoiled HELLO
    ctx.expect(
        header.last_received == hello,
        f"last received {hello} (HELLO's)",
        str(header.last_received),
        "R-RSP-15",
    )
    ctx.expect(
        body.client_nonce == raw.nonce,
        f"the client nonce {raw.nonce.hex()} echoed",
        body.client_nonce.hex(),
        "R-RSP-20",
    )
    ctx.expect(
        body.period_ms >= raw.period_ms,
        f"a period of {raw.period_ms} ms or more (the robot may only raise it, D-RSP-13)",
        f"{body.period_ms} ms",
        "R-RSP-20",
    )


@case(
    "rsp/session/fresh-session-ids",
    "Three sessions one after another get three different random non-zero 48-bit session IDs",
    ["R-RSP-20"],
    role=Role.ROBOT,
)
async def fresh_session_ids(ctx: Context) -> None:
    probe = await open_probe(ctx)
    seen: list[int] = []
    for _ in range(3):
        raw = hand_driven(probe)
        answer = await raw.open()
        seen.append(answer.header.session_id)
        raw.bye()
        await probe.listen(0.02)
    ctx.expect(
        0 not in seen and len(set(seen)) == len(seen),
        "three distinct non-zero session IDs",
        ", ".join(f"{s:#x}" for s in seen),
    )
    # D-RSP-12: 48 random bits. One has its high 16 all 0 once in 65,536, all three once in 2^48:
    # three that do are a counter or a narrower number (without encryption the session ID and
    # the address are all that protects a session, D-RSP-21).
    ctx.expect(
        any(s >> _LOW_BITS for s in seen),
        "random 48-bit session IDs: not all three below 2^32",
        ", ".join(f"{s:#x}" for s in seen),
    )


@case(
    "rsp/session/unknown-model",
    "HELLOs of other model IDs (another low byte, another high byte) are refused (1) with their"
    " model ID and encryption byte echoed",
    ["R-RSP-21"],
    role=Role.ROBOT,
)
async def unknown_model(ctx: Context) -> None:
    await _unknown_model_refused(ctx, Encryption.NONE)


@case(
    "rsp/session/unknown-model-encrypted",
    "A signed, encrypted HELLO of another model is refused (1), its encryption byte echoed",
    ["R-RSP-21"],
    role=Role.ROBOT,
)
async def unknown_model_encrypted(ctx: Context) -> None:
    await _unknown_model_refused(ctx, Encryption.CHACHA20_POLY1305)


async def _unknown_model_refused(ctx: Context, encryption: Encryption) -> None:
    """A HELLO of another model ID (signed with the pre-shared key, if known, when `encryption` is
    an AEAD) must be refused (1) with its model ID and encryption byte echoed (D-RSP-12)."""
    probe = await open_probe(ctx)
    period = round(probe.model.period * 1000)
    for other in _other_models(probe.model.model_id):
        hello = hello_packet(other, encryption, os.urandom(NONCE_SIZE), period, psk=probe.psk)
        answer = await came(
            ctx,
            probe,
            _ANSWERS,
            f"REFUSED, {BEFORE_REPEAT}",
            "R-RSP-21",
            send=functools.partial(probe.send, hello),
        )
        _refused(ctx, answer, RefusedReason.UNKNOWN_MODEL, "R-RSP-21")
        _echoes(ctx, answer, other, int(encryption), "R-RSP-21")


@case(
    "rsp/session/encryption-not-offered",
    "A HELLO with an AEAD the ICS says the robot lacks is refused (2), echoing its encryption byte",
    ["R-RSP-20"],
    role=Role.ROBOT,
)
async def encryption_not_offered(ctx: Context) -> None:
    lacking = [e for e, feature in _AEADS.items() if feature not in ctx.target.features]
    if not lacking:
        declared = ", ".join(f for f in FEATURES if f.startswith("rsp-"))
        raise NotApplicable(f"the ICS declares every AEAD ({declared}): none to refuse")
    probe = await open_probe(ctx)
    encryption = lacking[0]
    raw = hand_driven(probe, encryption) if probe.psk is not None else None
    period = round(probe.model.period * 1000)
    # Without a key to sign with: a MAC of zeros (the robot need not check it to refuse).
    unsigned = hello_packet(probe.model.model_id, encryption, os.urandom(NONCE_SIZE), period)
    answer = await came(
        ctx,
        probe,
        _ANSWERS,
        f"REFUSED, {BEFORE_REPEAT}",
        "R-RSP-20",
        send=raw.hello if raw is not None else lambda: probe.send(unsigned),
    )
    if answer.type is PacketType.WELCOME:
        if raw is not None:
            raw.accept(answer)  # closed with BYE at the end
        raise NotApplicable(f"the robot offers {encryption.name}, which the ICS does not declare")
    _refused(ctx, answer, RefusedReason.ENCRYPTION_NOT_OFFERED, "R-RSP-20")
    _echoes(ctx, answer, probe.model.model_id, int(encryption))


@case(
    "rsp/session/undefined-encryption",
    "A HELLO with encryption byte 3 (no AEAD, D-RSP-10) opens no session: dropped or refused (2)",
    ["R-RSP-18", "R-RSP-20"],
    role=Role.ROBOT,
)
async def undefined_encryption(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    start = probe.mark()
    hello = hello_packet(model.model_id, 3, os.urandom(NONCE_SIZE), round(model.period * 1000))
    probe.send(hello)
    await probe.listen(probe.quiet)
    for answer in probe.packets(after=start):
        ctx.expect(
            isinstance(answer.body, Refused)
            and answer.body.reason is RefusedReason.ENCRYPTION_NOT_OFFERED,
            ("no answer", "REFUSED ENCRYPTION_NOT_OFFERED"),
            f"{answer.type.name} {getattr(answer.body, 'reason', '')}",
        )
    await another_welcomed(ctx, probe, "R-RSP-20", "WELCOME to another local system")


@case(
    "rsp/session/busy",
    "While a session runs, another local system's HELLO is refused (3), with the free buffers the"
    " UPLINKs give, and the session goes on",
    ["R-RSP-20", "R-RSP-31"],
    role=Role.ROBOT,
)
async def busy(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    sensor = reported(model, 1)[0]
    answer = await hello_from_another(ctx, probe, "R-RSP-20", expected="REFUSED BUSY")
    if answer.type is PacketType.WELCOME:  # a robot may serve two sessions: not with one ID
        ctx.expect(
            answer.header.session_id != raw.session_id,
            "REFUSED BUSY, or a session ID of its own",
            f"the first session's ID {raw.session_id:#x} again",
        )
    else:
        _refused(ctx, answer, RefusedReason.BUSY, "R-RSP-20")
        _echoes(ctx, answer, model.model_id, 0)
    going = "the first session's UPLINKs going on"
    uplink = await must_take(ctx, probe, raw, flags(model, sensor), going, "R-RSP-20")
    ctx.expect(
        uplink.header.session_id == raw.session_id,
        going,
        f"session {uplink.header.session_id:#x}",
        "R-RSP-20",
    )
    if answer.type is PacketType.REFUSED:  # D-RSP-12: its free buffers as ever
        await probe.listen(3 * raw.period)
        _same_free(ctx, [answer], probe.packets(PacketType.UPLINK), "REFUSED")


@case(
    "rsp/session/repeated-hello",
    "A HELLO repeated with the same nonce gets the same WELCOME and opens no second session; both"
    " WELCOMEs give the free buffers the UPLINKs give",
    ["R-RSP-41", "R-RSP-20", "R-RSP-31"],
    role=Role.ROBOT,
)
async def repeated_hello(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    first = raw.welcome
    assert first is not None
    assert isinstance(first.body, Welcome)
    again = await came(  # sequence 1, the same nonce (D-RSP-12)
        ctx,
        probe,
        PacketType.WELCOME,
        f"WELCOME again, {BEFORE_REPEAT}",
        "R-RSP-41",
        send=raw.hello,
    )
    assert isinstance(again.body, Welcome)
    same = (
        again.header.session_id == first.header.session_id
        and again.body.robot_nonce == first.body.robot_nonce
        and again.body.period_ms == first.body.period_ms
        and again.body.client_nonce == raw.nonce
        and again.header.buffer == first.header.buffer
    )
    ctx.expect(
        same,
        f"session {first.header.session_id:#x}, robot nonce {first.body.robot_nonce.hex()},"
        f" {first.body.period_ms} ms, {first.header.buffer} free buffers (D-RSP-12)",
        f"session {again.header.session_id:#x}, robot nonce {again.body.robot_nonce.hex()},"
        f" {again.body.period_ms} ms, {again.header.buffer} free buffers",
    )
    sensor = reported(probe.model, 1)[0]
    going = f"the session going on, reporting {sensor.name}"
    uplink = await must_take(ctx, probe, raw, flags(probe.model, sensor), going)
    ctx.expect(
        sensor.name in uplink.devices(probe.model),
        going,
        str(sorted(uplink.devices(probe.model))),
    )
    await probe.listen(3 * raw.period)
    _same_free(ctx, [first, again], probe.packets(PacketType.UPLINK), "WELCOME")


def _same_free(ctx: Context, given: list[Datagram], uplinks: list[Datagram], what: str) -> None:
    """R-RSP-31: the free buffers in every packet, so those `given` (`what`) say what the UPLINKs
    say, in a session that sends no memory command. A count that moves among the UPLINKs (memory
    commands of an earlier session still executing) leaves the check undone."""
    free = {d.header.buffer for d in uplinks}
    if len(free) != 1:
        ctx.cannot_check(
            f"{what}'s free buffers against the UPLINKs': "
            + ("no UPLINK came" if not free else f"their count moved ({sorted(free)})")
        )
        return
    (count,) = free
    ctx.expect(
        all(d.header.buffer == count for d in given),
        f"{count} free buffers in {what}, as in every UPLINK (no memory command sent)",
        ", ".join(f"{d.header.buffer} in {d.type.name} #{d.header.sequence}" for d in given),
        "R-RSP-31",
    )


@case(
    "rsp/session/bye",
    "After BYE (reason shutdown) the robot sends nothing more of the session and takes another"
    " local system",
    ["R-RSP-22"],
    role=Role.ROBOT,
)
async def bye(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    sensor = reported(probe.model, 1)[0]
    if await taken(probe, raw, flags(probe.model, sensor)) is None:
        raise Inconclusive("the robot sent no UPLINK before BYE")
    # Reason 2 (shutdown): every case's closing BYE says 0 (closed), and a BYE ends the session
    # whatever its reason (D-RSP-12).
    sequence = sequence_of(raw.bye(ByeReason.SHUTDOWN))
    uplinks = await probe.received_within(probe.quiet, PacketType.UPLINK)
    late = [d for d in uplinks if newer(d.header.last_received, sequence)]
    ctx.expect(not late, "no UPLINK after the robot took BYE", f"{len(late)} UPLINKs")
    await another_welcomed(ctx, probe, "R-RSP-22", "WELCOME to another local system")


@case(
    "rsp/session/uplink-pace",
    "The robot sends an UPLINK every period T of WELCOME while a sensor is requested",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
)
async def uplink_pace(ctx: Context) -> None:
    probe, opened, _ = await reporting(ctx, slower=2)
    await probe.listen(3 * opened.period)
    uplinks = await probe.received_within(
        12 * opened.period, PacketType.UPLINK, session=opened.session_id
    )
    paced(ctx, uplinks, PacketType.UPLINK, opened.period)


@case(
    "rsp/session/period",
    "PERIOD changes the pace of the robot's UPLINKs while the session runs",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
)
async def period(ctx: Context) -> None:
    probe, opened, _ = await reporting(ctx)
    slower = max(opened.period * 4, 0.08)
    probe.session.set_period(slower, probe.now)
    probe.poke()
    await probe.listen(slower * 1.5)
    uplinks = await probe.received_within(slower * 6, PacketType.UPLINK, session=opened.session_id)
    paced(ctx, uplinks, PacketType.UPLINK, slower)


@case(
    "rsp/session/keep-alive",
    "With nothing requested the robot sends an empty-map UPLINK every 5 periods, no more",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
)
async def keep_alive(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    period = raw.period
    raw.downlink()
    uplinks = await probe.received_within(
        min(4.5 * KEEPALIVE_PERIODS * period, 20 * period),
        PacketType.UPLINK,
        session=raw.session_id,
    )
    carrying = [d for d in uplinks if d.items]
    ctx.expect(
        not carrying,
        "empty Device Maps",
        f"{sorted(carrying[0].devices(probe.model))}" if carrying else "",
    )
    ctx.expect(
        len(uplinks) >= 3,
        "an UPLINK every 5 periods",
        f"{len(uplinks)} UPLINKs",
        "R-RSP-42",
        timing=True,
    )
    spaced(ctx, uplinks, KEEPALIVE_PERIODS * period, "UPLINKs")
    # Every 5 periods, not 4 or 6: D-RSP-26 judges the median gap within half a period of 5 T
    # (spaced's bounds, for one gap the harness read late, let 6 through).
    between = gaps(uplinks)
    slack = KEEPALIVE_SLACK * period * ctx.scale
    off = abs(statistics.median(between) - KEEPALIVE_PERIODS * period) if between else 0.0
    ctx.expect(
        len(between) >= 2 and off <= slack,
        f"UPLINKs {KEEPALIVE_PERIODS} periods apart ({KEEPALIVE_PERIODS * period * 1000:g} ms),"
        f" their median within {slack * 1000:g} ms (D-RSP-26)",
        ms(between),
        "R-RSP-42",
        timing=True,
        by=off - slack if len(between) >= 2 else None,
    )


@case(
    "rsp/session/silence-keeps-session",
    "A second of silence from the local system (link lost) does not end the session",
    ["R-RSP-22"],
    role=Role.ROBOT,
)
async def silence_keeps_session(ctx: Context) -> None:
    probe, opened, sensor = await reporting(ctx)
    if await probe.state(sensor.name) is None:
        raise Inconclusive(f"no {sensor.name} before the silence")
    probe.muted = True
    silent = probe.now
    byes = await probe.received_within(max(1.0, 30 * opened.period), PacketType.BYE)
    ctx.expect(
        not byes,
        "no BYE before 10 s of silence",
        f"BYE after {byes[0].at - silent:.2f} s" if byes else "",
    )
    resumed = probe.session.packets_sent % 65536  # the next DOWNLINK's sequence number
    probe.muted = False
    expected = f"an UPLINK of session {opened.session_id:#x} that took the DOWNLINKs again"
    found = await came(
        ctx,
        probe,
        PacketType.UPLINK,
        f"{expected}: {NEXT_PERIOD}",
        after=0,
        where=fresh(lambda: resumed),
    )
    ctx.expect(
        found.header.session_id == opened.session_id,
        expected,
        f"session {found.header.session_id:#x}",
    )


@case(
    "rsp/session/timeout-bye",
    "After 10 s without a packet from the local system the robot sends BYE (timeout)",
    ["R-RSP-22"],
    role=Role.ROBOT,
    # The longest case: it starts with the others and ends about when they do (the suite's
    # wall time is set by the slowest case, not the sum).
    timeout=SESSION_TIMEOUT + KEPT + 4,
)
async def timeout_bye(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    # Kept alive a while first: the 10 s run from the last packet heard, not from WELCOME (a
    # robot timing the session from its start would end it KEPT seconds early).
    for _ in range(round(KEPT / _KEEPING)):
        raw.downlink()
        await probe.listen(_KEEPING)
    raw.downlink()
    silent = probe.now
    # D-RSP-26: 9.5 s to 11 s after the last packet the robot heard (the last we sent), read off
    # the harness's clock (a hold of its loop excuses a BYE read that much later, `seen_by`).
    early, late = timeout_window(raw.period, ctx.scale)
    expected = (
        f"BYE {SESSION_TIMEOUT:g} s after the last packet (D-RSP-26: {early:g} s to {late:.2f} s)"
    )
    found = await probe.next(PacketType.BYE, wait=late + margin(ctx))
    seen_by(ctx, probe, found, silent, silent + late, expected)
    assert found is not None
    raw.ended = True
    ctx.expect(
        isinstance(found.body, Bye) and found.body.reason is ByeReason.TIMEOUT,
        "BYE TIMEOUT",
        f"BYE {getattr(found.body, 'reason', '')}",
    )
    # A harness held up reads the BYE late, never early.
    ctx.expect(early <= found.at - silent, expected, f"after {found.at - silent:.2f} s")


# -- a slow T of over a second (D-RSP-13, R-RSP-42) --------------------------------------------


#: The slow T the cases ask for (ms): over a second, and three periods of it fit in a case.
SLOW_MS = 1200


#: UPLINKs a slow case watches: two gaps of T.
BEATS = 3


def _slow_enough(period: float) -> None:
    """WELCOME may raise T (D-RSP-13): not so far that the case cannot watch it."""
    if period > 2 * SLOW_MS / 1000:
        raise Inconclusive(
            f"the robot raised T to {period * 1000:g} ms (D-RSP-13 lets it): {BEATS} periods"
            " of it do not fit in the case's time"
        )


async def _uplinks(probe: RspProbe, where: Where, until: float, count: int) -> list[Datagram]:
    """The first `count` UPLINKs received (so far, and until loop time `until`) for which
    `where` holds; fewer if no more came."""
    while True:
        found = [d for d in probe.packets(PacketType.UPLINK) if where(d)]
        if len(found) >= count or probe.now >= until:
            return found[:count]
        await probe.next(PacketType.UPLINK, wait=until - probe.now)


def _watched(probe: RspProbe, period: float) -> float:
    """How long `BEATS` UPLINKs may take from the first (or from a time before it): each as late
    after the one before as `spaced` lets it be, and the probe's quiet time for the harness."""
    return (BEATS - 1) * GAP_LONGEST * period + probe.quiet


async def _rested(probe: RspProbe, period: float, bye: Callable[[], object]) -> None:
    """End the session at the slow T (`bye` sends its BYE) and keep the robot a period of that T
    more before the pool gives it to another case: a robot may keep its control loop on the slow
    T's schedule until then (the reference does: the next session's sensors are read, and so
    reported, only at the tick that schedule left), and the other cases run at the model's T."""
    bye()
    await probe.listen(period + probe.quiet)


def _beating(ctx: Context, found: list[Datagram], period: float, note: str) -> None:
    """`found` are `BEATS` UPLINKs, each a period after the one before (R-RSP-42). Their number
    is no timing check: `_watched` leaves a second or more past the last. Nor is a gap too short
    by the robot's own timestamps: a loaded harness reads packets late, which the gaps of their
    arrivals (`spaced`, a timing check) show and the timestamps do not."""
    ctx.expect(
        len(found) >= BEATS,
        f"{BEATS} UPLINKs {period * 1000:g} ms apart{note}",
        f"{len(found)} UPLINKs",
        "R-RSP-42",
    )
    stamped = [
        (later.header.timestamp - earlier.header.timestamp) % (1 << 32)
        for earlier, later in itertools.pairwise(found)
    ]
    ctx.expect(
        all(gap >= GAP_SHORTEST * period * 1000 - STAMP_ROUNDING for gap in stamped),
        f"UPLINKs {period * 1000:g} ms apart by the robot's own clock{note}",
        f"timestamps (R-RSP-14) {', '.join(map(str, stamped))} ms apart",
        "R-RSP-42",
    )
    spaced(ctx, found, period, "UPLINKs", note=note)


@case(
    "rsp/session/slow-hello",
    f"A HELLO asking T = {SLOW_MS} ms: the robot reports a requested sensor every period",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
    timeout=8.0,
)
async def slow_hello(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    raw = hand_driven(probe, period_ms=SLOW_MS)
    await raw.open()
    period = raw.period  # WELCOME's
    _slow_enough(period)
    sensor = reported(model, 1)[0]
    try:
        # R-RSP-42: with a sensor to report, an UPLINK every T: the first within a period of the
        # request, and a period between each and the next.
        first = await must_take(
            ctx,
            probe,
            raw,
            flags(model, sensor),
            f"an UPLINK within a period ({period * 1000:g} ms) of the request for {sensor.name}",
            "R-RSP-42",
            wait=GAP_LONGEST * period + probe.quiet,
        )
        request = sequence_of(raw.last)
        found = await _uplinks(
            probe,
            lambda d: newer(d.header.last_received, request),
            first.at + _watched(probe, period),
            BEATS,
        )
        _beating(ctx, found, period, f" (T of WELCOME: {period * 1000:g} ms)")
        silent = [d for d in found if values_of(d, sensor) is None]
        ctx.expect(
            not silent,
            f"{sensor.name} in each UPLINK after its request",
            f"UPLINK #{silent[0].header.sequence} without it" if silent else "",
            "R-RSP-23",
        )
    finally:
        await _rested(probe, period, raw.bye)


@case(
    "rsp/session/slow-period",
    f"After a PERIOD of {SLOW_MS} ms the next UPLINK comes a new period after the last one, not"
    " at the old pace, and the UPLINKs go on every new period",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
    timeout=8.0,
)
async def slow_period(ctx: Context) -> None:
    probe, opened, sensor = await reporting(ctx)
    if await probe.state(sensor.name) is None:
        raise Inconclusive(f"no {sensor.name} at T = {opened.period * 1000:g} ms to start from")
    # WELCOME's T is what the robot raised HELLO's to: it may raise PERIOD's as well.
    period = max(SLOW_MS / 1000, opened.period)
    _slow_enough(period)
    spoiled = probe.spoiled
    change = probe.session.packets_sent % 65536  # the PERIOD's sequence number
    at = probe.now
    probe.session.set_period(SLOW_MS / 1000, at)
    probe.poke()  # the PERIOD goes at once

    def bye() -> None:
        probe.session.close(probe.now)
        probe.poke()

    try:
        if probe.spoiled > spoiled:
            raise Inconclusive("the impairment spoiled the first PERIOD")
        found = await _uplinks(
            probe,
            lambda d: newer(d.header.last_received, change),
            at + _watched(probe, period),
            BEATS - 1,
        )
        before = [
            d for d in probe.packets(PacketType.UPLINK) if not newer(d.header.last_received, change)
        ]
        if not before:
            raise Inconclusive(f"no UPLINK at T = {opened.period * 1000:g} ms before the PERIOD")
        # D-RSP-13: the robot's next UPLINK after PERIOD comes at the new pace: a new period after
        # the last it sent at the old one, not an old period after it.
        _beating(
            ctx,
            [before[-1], *found],
            period,
            f" (the last before the robot took PERIOD #{change}, then those after: the next"
            " UPLINK comes at the new pace, D-RSP-13)",
        )
    finally:
        await _rested(probe, period, bye)
