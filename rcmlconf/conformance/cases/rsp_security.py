"""rsp/security: the robot's security processor (D-RSP-21; R-RSP-13, R-RSP-18, R-RSP-37,
R-RSP-38). The harness plays the local system.

- A sealed session, for each AEAD: WELCOME's MAC is right, DOWNLINKs are opened, and UPLINKs
  are sealed.
- A tampered, replayed or plaintext DOWNLINK in a sealed session is dropped.
- A HELLO signed with another key, or without its MAC, opens no session.
"""

from __future__ import annotations

import os
from collections.abc import Awaitable, Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import came
from rcmlconf.conformance.probes.rsp_datagram import (
    ENCRYPTION_AT,
    TIMESTAMP_AT,
    sequence_of,
)
from rcmlconf.conformance.probes.rsp_devices import first, flags, occurrence, reported
from rcmlconf.conformance.probes.rsp_exchanges import (
    NEXT_PERIOD,
    another_welcomed,
    dropped_then_taken,
    fresh,
    must_ack,
    replay_dropped,
)
from rcmlconf.conformance.probes.rsp_forged import flip, hello_packet, patch
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import BEFORE_REPEAT, RawSession, hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.rsp.codec import (
    Encryption,
    MapBody,
    PacketType,
    Refused,
    RefusedReason,
    pull_header,
)
from rcmlconf.rsp.layout import MAC_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import DeviceKind
from rcmlconf.rsp.security import mac

_AEADS = (
    (Encryption.AES_256_GCM, "rsp-aes-256-gcm", "aes-256-gcm"),
    (Encryption.CHACHA20_POLY1305, "rsp-chacha20-poly1305", "chacha20-poly1305"),
)


async def _sealed(ctx: Context, encryption: Encryption) -> tuple[RspProbe, RawSession]:
    """A sealed session by hand; its WELCOME's MAC checked (R-RSP-38)."""
    probe = await open_probe(ctx)
    raw = hand_driven(probe, encryption)
    answer = await raw.expect_welcome(ctx, "R-RSP-37", f"WELCOME ({encryption.name} declared)")
    assert probe.psk is not None
    data = answer.data
    ctx.expect(
        mac(probe.psk, data[:-MAC_SIZE]) == data[-MAC_SIZE:],
        "WELCOME's MAC: HMAC-SHA256 of its header and body with the pre-shared key",
        data[-MAC_SIZE:].hex(),
        "R-RSP-38",
    )
    return probe, raw


def _session_case(encryption: Encryption) -> Callable[[Context], Awaitable[None]]:
    async def run(ctx: Context) -> None:
        probe, raw = await _sealed(ctx, encryption)
        model = probe.model
        command = first(model, DeviceKind.COMMAND)
        sensor = reported(model, 1)[0]
        raw.standing = flags(model, sensor)
        sealed = f"a sealed ACK of {command.name} #0"
        await must_ack(ctx, probe, raw, command, 0, "R-RSP-37", expected=sealed)
        reports = f"sealed UPLINKs reporting {sensor.name}"
        took = sequence_of(raw.last)
        uplink = await came(
            ctx,
            probe,
            PacketType.UPLINK,
            f"{reports}: {NEXT_PERIOD}",
            "R-RSP-37",
            after=0,
            where=fresh(lambda: took),
        )
        ctx.expect(
            sensor.name in uplink.devices(model),
            reports,
            str(sorted(uplink.devices(model))),
            "R-RSP-37",
        )
        _all_sealed(ctx, probe, raw, encryption)

    return run


def _all_sealed(ctx: Context, probe: RspProbe, raw: RawSession, encryption: Encryption) -> None:
    """Every packet of the session after WELCOME says the session's encryption (R-RSP-13) and so
    was opened with its keys: a packet saying 0 is read in the clear, and a robot that never
    seals its ACKs and UPLINKs would pass what is checked above (D-RSP-21: every packet of the
    session after HELLO and WELCOME is sealed)."""
    mine = [
        d
        for d in probe.received
        if d.header.session_id == raw.session_id and d.type is not PacketType.WELCOME
    ]
    clear = [d for d in mine if d.header.encryption is not encryption]
    ctx.expect(
        not clear,
        f"every packet of the session sealed: encryption {int(encryption)} ({encryption.name})",
        ", ".join(
            f"{d.type.name} #{d.header.sequence} with encryption {int(d.header.encryption)}"
            for d in clear[:3]
        ),
        "R-RSP-13",
    )


def _tampered_case(encryption: Encryption) -> Callable[[Context], Awaitable[None]]:
    async def run(ctx: Context) -> None:
        probe, raw = await _sealed(ctx, encryption)
        for what, mutate in (
            ("the tag's last byte flipped", lambda d: flip(d, len(d) - 1)),
            ("the timestamp flipped (associated data)", lambda d: flip(d, TIMESTAMP_AT + 3)),
            ("the ciphertext flipped", lambda d: flip(d, 20)),
        ):
            await dropped_then_taken(ctx, probe, raw, mutate, "R-RSP-18", what)

    return run


for _encryption, _feature, _slug in _AEADS:
    case(
        f"rsp/security/{_slug}-session",
        f"A {_encryption.name} session: WELCOME's MAC right, DOWNLINKs opened, UPLINKs sealed",
        ["R-RSP-37", "R-RSP-38", "R-RSP-13"],
        role=Role.ROBOT,
        features=[_feature],
    )(_session_case(_encryption))
    case(
        f"rsp/security/{_slug}-tampered",
        f"A {_encryption.name} DOWNLINK with a flipped bit is dropped; the session goes on",
        ["R-RSP-18", "R-RSP-37"],
        role=Role.ROBOT,
        features=[_feature],
    )(_tampered_case(_encryption))


@case(
    "rsp/security/wrong-key",
    "A HELLO signed with another key is refused (4) and opens no session",
    ["R-RSP-38"],
    role=Role.ROBOT,
    features=["rsp-aes-256-gcm"],
)
async def wrong_key(ctx: Context) -> None:
    probe = await open_probe(ctx)
    raw = hand_driven(probe, Encryption.AES_256_GCM)
    key = os.urandom(32)
    answer = await came(
        ctx,
        probe,
        (PacketType.WELCOME, PacketType.REFUSED),
        f"REFUSED, {BEFORE_REPEAT}",
        "R-RSP-38",
        send=lambda: raw.hello(psk=key),
    )
    body = answer.body
    ctx.expect(
        isinstance(body, Refused) and body.reason is RefusedReason.NOT_AUTHENTICATED,
        "REFUSED NOT_AUTHENTICATED",
        f"REFUSED {body.reason.name}" if isinstance(body, Refused) else answer.type.name,
    )
    await _no_session_left(ctx, probe)


async def _no_session_left(ctx: Context, probe: RspProbe) -> None:
    """Another local system gets a session: the refused HELLO opened none."""
    await another_welcomed(
        ctx, probe, "R-RSP-38", "WELCOME to another local system (no session was opened)"
    )


@case(
    "rsp/security/unsigned-hello",
    "An AES-256-GCM HELLO without its MAC opens no session",
    ["R-RSP-38"],
    role=Role.ROBOT,
    features=["rsp-aes-256-gcm"],
)
async def unsigned_hello(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    start = probe.mark()
    period = round(model.period * 1000)
    nonce = os.urandom(NONCE_SIZE)
    probe.send(hello_packet(model.model_id, Encryption.AES_256_GCM, nonce, period, signed=False))
    await probe.listen(probe.quiet)
    welcomes = probe.packets(PacketType.WELCOME, after=start)
    ctx.expect(not welcomes, "no WELCOME (dropped, or REFUSED NOT_AUTHENTICATED)", "WELCOME")
    await _no_session_left(ctx, probe)


@case(
    "rsp/security/replayed-sealed",
    "A sealed DOWNLINK received again byte for byte is dropped: no second ACK",
    ["R-RSP-18"],
    role=Role.ROBOT,
    features=["rsp-aes-256-gcm"],
)
async def replayed_sealed(ctx: Context) -> None:
    probe, raw = await _sealed(ctx, Encryption.AES_256_GCM)
    await replay_dropped(ctx, probe, raw, 5)


@case(
    "rsp/security/plaintext-downgrade",
    "In an AES-256-GCM session, a DOWNLINK in the clear (encryption 0) is dropped",
    ["R-RSP-18"],
    role=Role.ROBOT,
    features=["rsp-aes-256-gcm"],
)
async def plaintext_downgrade(ctx: Context) -> None:
    probe, raw = await _sealed(ctx, Encryption.AES_256_GCM)
    command = first(probe.model, DeviceKind.COMMAND)
    body = MapBody((occurrence(command, 7),))

    def in_the_clear(sealed: bytes) -> bytes:
        plain = probe.codec.push_body(pull_header(sealed), body)
        return patch(sealed[:20], ENCRYPTION_AT, b"\x00") + plain

    await dropped_then_taken(ctx, probe, raw, in_the_clear, "R-RSP-18", "a DOWNLINK in the clear")
