"""rsp/local, the header against what the robot did: an RSP local system under test stamps its
packets from its first HELLO however late the WELCOME (R-RSP-14), and names in every packet the
newest the robot sent, an ACK as much as an UPLINK (R-RSP-15). The harness plays the robot
(`--role local`)."""

from __future__ import annotations

from rcmlconf.conformance.cases.rsp_local.session import (
    carries,
    local_case,
    played_model,
    session,
    stamped_since,
)
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import held
from rcmlconf.conformance.probes.rsp_datagram import sequence_of
from rcmlconf.conformance.probes.rsp_devices import first, of_kind
from rcmlconf.conformance.rsp_numbers import unheard_for
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import Item, PacketType
from rcmlconf.rsp.model import DeviceKind

#: The DOWNLINKs rsp/local/stamps-since-first-hello judges: enough that D-RSP-26's quarter
#: behind leaves most of them to show a clock that started late.
_JUDGED_PERIODS = 8


@local_case(
    "rsp/local/stamps-since-first-hello",
    "Answered at a repeated HELLO, the local system still stamps from its first HELLO",
    ["R-RSP-14"],
)
async def stamps_since_first_hello(ctx: Context) -> None:
    # The first HELLO unanswered: R-RSP-14's start is the session's first packet, that HELLO
    # (D-RSP-10), not the WELCOME a repeat got 250 ms later (D-RSP-12).
    probe = await session(ctx, repeats=1)
    await probe.listen(_JUDGED_PERIODS * probe.period)
    start = probe.hello
    after_welcome = [d for d in probe.received if d.type is not PacketType.HELLO]
    stamped_since(ctx, start, after_welcome, start.header.timestamp)


@local_case(
    "rsp/local/last-received-ack",
    "An ACK of the robot's numbered after its UPLINK is the newest the local system names",
    ["R-RSP-15"],
)
async def last_received_ack(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    # Nothing acknowledged at once and no keep-alive: the robot sends only what the case says,
    # so the newest packet it sent is the case's ACK.
    withheld = of_kind(model, DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
    probe = await session(ctx, withheld=withheld, beating=False)
    carrying = await probe.next(PacketType.DOWNLINK, after=0, where=carries(command))
    if carrying is None:
        raise Inconclusive(f"no {command.name} command issued (D-RSP-24 step 2)")
    item = carrying.item(command.position)
    assert item is not None
    uplink = sequence_of(probe.uplink())
    ack = sequence_of(probe.ack([Item(command.position, item.id)]))
    at = probe.now
    # D-RSP-26: what it sends more than two periods and the wire's slack after the ACK went (and
    # as long as the harness was held) was made after it had the ACK.
    window = unheard_for(probe.period, ctx.scale)
    await probe.listen(window + 4 * probe.period)
    since = at + window + held(ctx, at)
    later = [d for d in probe.packets(PacketType.DOWNLINK) if d.at > since]
    if not later:
        raise Inconclusive(f"no DOWNLINK more than {window * 1000:.0f} ms after the robot's ACK")
    wrong = [d for d in later if d.header.last_received != ack]
    ctx.expect(
        not wrong,
        f"last received {ack} (the robot's ACK of {command.name} #{item.id}, sent after its"
        f" UPLINK #{uplink}) in every DOWNLINK made after it",
        ", ".join(f"{d.header.last_received} in DOWNLINK #{d.header.sequence}" for d in wrong[:4]),
    )
