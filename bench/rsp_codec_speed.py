"""How fast is the RSP codec? (rcmlconf.rsp.codec; specs/rsp.md §2, §3)

A typical CUBO DOWNLINK and UPLINK of vectors/rsp/packets.json, each encoded and decoded
(`push_packet` then `pull_packet`), the way a session does it every period T (D-RSP-13):

- DOWNLINK (`downlink-typical`, 36 bytes): the base module and both wheels, the arms module and
  both arms, the head module and the lip, the position sensor requested, an IR command in flight;
- UPLINK (`uplink-typical`, 42 bytes): both wheel monitors, the position sensor, a button event.

Anchor: a hand-written `struct` codec of each packet's one layout, the fair competitor. It reads
and writes the same bytes and makes the same objects (a `Header` NamedTuple with its enum members,
a `MapBody` of `Item`s with value dicts, a `Packet`), built as cheaply as Python allows (the
NamedTuples by `tuple.__new__`, the flags' Items made once, the MapBody as the codec makes it);
and it checks what the codec checks: reading, the datagram's length, the version, model ID,
encryption, type, session ID and buffer byte, the Device Map (equal to the one map it knows),
every bound of every field and bool byte; writing, the header's fields likewise, each item's
device, ID and value types, every bound, and that each payload has exactly its fields. It knows
one layout and nothing else: what the codec finds in the model, it has written in. The ratio
codec / hand codec is the generic codec's cost.

For context, the floor: one `struct.Struct` packing and unpacking the same fields, with no checks
and no objects.

Goal: a ratio of at most 3. Anchors are measured in the same run (the machine is shared and
noisy: the ratios are the figures that travel), taking turns within each round. Figures are µs
per encode + decode, the median of --rounds.

    python bench/rsp_codec_speed.py [--rounds 7] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rsp.codec import Encryption, Header, Item, MapBody, Packet, PacketType, RspCodec
from rcmlconf.rsp.codec.bodies import map_body
from rcmlconf.rsp.codec.maps import COMPILE_AT
from rcmlconf.validate.validator import load_robot_model

ROOT = Path(__file__).resolve().parent.parent
CUBO = ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
PACKETS = ROOT / "vectors" / "rsp" / "packets.json"

_new = tuple.__new__
_ENCRYPTIONS = {int(e): e for e in Encryption}
_MODEL_ID = 1
#: The header of Table II (D-RSP-10) with the session ID's high 16 and low 32 bits.
_HEADER = ">BHBBHIHIHB"


# -- the hand codec of the DOWNLINK ----------------------------------------------------------------

#: header; Device Map; leftWheel, rightWheel, leftArm, rightArm (int16), lip (uint8), irFire's ID
#: (uint8) and code (uint16).
DOWN = struct.Struct(_HEADER + "4s" + "hhhhBBH")
DOWN_MAP = bytes.fromhex("e7a01200")  # base, wheels, arms, leftArm, rightArm, head, lip, ...
DOWN_BUFFERS = frozenset({0, 0x80})
BASE, ARMS, HEAD, POSITION = Item(0), Item(5), Item(8), Item(19)


def hand_pull_downlink(data: bytes) -> Packet:
    if len(data) != DOWN.size:
        raise ProtocolError(f"a DOWNLINK of this map is {DOWN.size} bytes", min(len(data), 20))
    (version, model_id, encryption, kind, sequence, timestamp, high, low, last, buffer,
     device_map, left, right, left_arm, right_arm, lip, ident, code) = DOWN.unpack(
        data
    )  # fmt: skip
    enum = _ENCRYPTIONS.get(encryption)
    if not (
        version == 1
        and model_id == _MODEL_ID
        and enum is not None
        and kind == 4
        and (high or low)
        and buffer in DOWN_BUFFERS
    ):
        raise ProtocolError("header", 0, "R-RSP-13")
    if device_map != DOWN_MAP:
        raise ProtocolError("another Device Map", 20, "R-RSP-16")
    if not (
        -500 <= left <= 500
        and -500 <= right <= 500
        and -900 <= left_arm <= 900
        and -900 <= right_arm <= 900
        and lip <= 100
    ):
        raise ProtocolError("a value out of range", 24, "R-RSP-16")
    header = _new(
        Header,
        (
            1,
            model_id,
            enum,
            PacketType.DOWNLINK,
            sequence,
            timestamp,
            high << 32 | low,
            last,
            buffer,
        ),
    )
    items = (
        BASE,
        _new(Item, (1, None, {"speed": left})),
        _new(Item, (2, None, {"speed": right})),
        ARMS,
        _new(Item, (6, None, {"angle": left_arm})),
        _new(Item, (7, None, {"angle": right_arm})),
        HEAD,
        _new(Item, (10, None, {"opening": lip})),
        POSITION,
        _new(Item, (22, ident, {"code": code})),
    )
    return _new(Packet, (header, map_body(items)))


def hand_push_downlink(packet: Packet) -> bytes:
    header, body = packet
    version, model_id, encryption, kind, sequence, timestamp, session, last, buffer = header
    if not (
        version == 1
        and model_id == _MODEL_ID
        and encryption in _ENCRYPTIONS
        and kind == 4
        and session != 0
        and buffer in DOWN_BUFFERS
    ):
        raise EncodeError("header")
    if type(body) is not MapBody or len(body.items) != 10:
        raise EncodeError("not this layout")
    base, left, right, arms, left_arm, right_arm, head, lip, position, fire = body.items
    # Each item names its device, and has an ID and values exactly where its bit brings them.
    if not (
        type(base.device) is int and base.device == 0 and base.id is None and base.values is None
        and type(left.device) is int and left.device == 1 and left.id is None
        and left.values is not None and len(left.values) == 1
        and type(right.device) is int and right.device == 2 and right.id is None
        and right.values is not None and len(right.values) == 1
        and type(arms.device) is int and arms.device == 5 and arms.id is None
        and arms.values is None
        and type(left_arm.device) is int and left_arm.device == 6 and left_arm.id is None
        and left_arm.values is not None and len(left_arm.values) == 1
        and type(right_arm.device) is int and right_arm.device == 7 and right_arm.id is None
        and right_arm.values is not None and len(right_arm.values) == 1
        and type(head.device) is int and head.device == 8 and head.id is None
        and head.values is None
        and type(lip.device) is int and lip.device == 10 and lip.id is None
        and lip.values is not None and len(lip.values) == 1
        and type(position.device) is int and position.device == 19 and position.id is None
        and position.values is None
        and type(fire.device) is int and fire.device == 22
        and fire.values is not None and len(fire.values) == 1
    ):  # fmt: skip
        raise EncodeError("not this layout")
    values = (
        left.values["speed"],
        right.values["speed"],
        left_arm.values["angle"],
        right_arm.values["angle"],
        lip.values["opening"],
        fire.id,
        fire.values["code"],
    )
    w1, w2, a1, a2, opening, ident, code = values
    if not (
        type(w1) is int
        and -500 <= w1 <= 500
        and type(w2) is int
        and -500 <= w2 <= 500
        and type(a1) is int
        and -900 <= a1 <= 900
        and type(a2) is int
        and -900 <= a2 <= 900
        and type(opening) is int
        and opening <= 100
        and type(ident) is int
        and type(code) is int
    ):
        raise EncodeError("a value of another type or out of range")
    try:
        return DOWN.pack(
            version, model_id, encryption, kind, sequence, timestamp, session >> 32,
            session & 0xFFFFFFFF, last, buffer, DOWN_MAP, *values,
        )  # fmt: skip
    except struct.error as exc:
        raise EncodeError(str(exc)) from None


# -- the hand codec of the UPLINK ------------------------------------------------------------------

#: header; Device Map; the monitors (int16), position x, y, heading (float32), serviceButton's ID
#: (uint8) and pressed (bool, read as a byte to check it).
UP = struct.Struct(_HEADER + "4s" + "hh" + "fff" + "BB")
UP_MAP = bytes.fromhex("18001800")
UP_BUFFERS = frozenset(range(17))
HEADING = struct.unpack(">f", struct.pack(">f", 3.1416))[0]


def hand_pull_uplink(data: bytes) -> Packet:
    if len(data) != UP.size:
        raise ProtocolError(f"an UPLINK of this map is {UP.size} bytes", min(len(data), 20))
    (version, model_id, encryption, kind, sequence, timestamp, high, low, last, buffer,
     device_map, left, right, x, y, heading, ident, pressed) = UP.unpack(data)  # fmt: skip
    enum = _ENCRYPTIONS.get(encryption)
    if not (
        version == 1
        and model_id == _MODEL_ID
        and enum is not None
        and kind == 5
        and (high or low)
        and buffer in UP_BUFFERS
    ):
        raise ProtocolError("header", 0, "R-RSP-13")
    if device_map != UP_MAP:
        raise ProtocolError("another Device Map", 20, "R-RSP-16")
    if pressed > 1:
        raise ProtocolError("a bool byte", 41, "R-RCML-30")
    if not (-500 <= left <= 500 and -500 <= right <= 500 and -HEADING <= heading <= HEADING):
        raise ProtocolError("a value out of range", 24, "R-RSP-16")
    header = _new(
        Header,
        (1, model_id, enum, PacketType.UPLINK, sequence, timestamp, high << 32 | low, last, buffer),
    )
    items = (
        _new(Item, (3, None, {"speed": left})),
        _new(Item, (4, None, {"speed": right})),
        _new(Item, (19, None, {"x": x, "y": y, "heading": heading})),
        _new(Item, (20, ident, {"pressed": pressed == 1})),
    )
    return _new(Packet, (header, map_body(items)))


def hand_push_uplink(packet: Packet) -> bytes:
    header, body = packet
    version, model_id, encryption, kind, sequence, timestamp, session, last, buffer = header
    if not (
        version == 1
        and model_id == _MODEL_ID
        and encryption in _ENCRYPTIONS
        and kind == 5
        and session != 0
        and buffer in UP_BUFFERS
    ):
        raise EncodeError("header")
    if type(body) is not MapBody or len(body.items) != 4:
        raise EncodeError("not this layout")
    left, right, position, button = body.items
    if not (
        type(left.device) is int and left.device == 3 and left.id is None
        and left.values is not None and len(left.values) == 1
        and type(right.device) is int and right.device == 4 and right.id is None
        and right.values is not None and len(right.values) == 1
        and type(position.device) is int and position.device == 19 and position.id is None
        and position.values is not None and len(position.values) == 3
        and type(button.device) is int and button.device == 20
        and button.values is not None and len(button.values) == 1
    ):  # fmt: skip
        raise EncodeError("not this layout")
    where = position.values
    values = (
        left.values["speed"],
        right.values["speed"],
        where["x"],
        where["y"],
        where["heading"],
        button.id,
        button.values["pressed"],
    )
    w1, w2, x, y, heading, ident, pressed = values
    if not (
        type(w1) is int
        and -500 <= w1 <= 500
        and type(w2) is int
        and -500 <= w2 <= 500
        and type(x) is float
        and type(y) is float
        and type(heading) is float
        and -HEADING <= heading <= HEADING
        and type(ident) is int
        and type(pressed) is bool
    ):
        raise EncodeError("a value of another type or out of range")
    try:
        return UP.pack(
            version, model_id, encryption, kind, sequence, timestamp, session >> 32,
            session & 0xFFFFFFFF, last, buffer, UP_MAP, *values,
        )  # fmt: skip
    except (struct.error, OverflowError) as exc:
        raise EncodeError(str(exc)) from None


# -- measuring -------------------------------------------------------------------------------------


def vector(name: str) -> bytes:
    cases = json.loads(PACKETS.read_text(encoding="utf-8"))["valid"]
    return bytes.fromhex(next(c["hex"] for c in cases if c["name"] == name))


def per_call(functions: list[Callable[[], object]], rounds: int, calls: int = 5000) -> list[float]:
    """µs per call of each function, the median of `rounds`; the functions take turns within a
    round, so that the machine's load falls on all of them alike."""
    times: list[list[float]] = [[] for _ in functions]
    for _ in range(rounds):
        for function, taken in zip(functions, times, strict=True):
            start = time.perf_counter()
            for _ in range(calls):
                function()
            taken.append((time.perf_counter() - start) / calls * 1e6)
    return [statistics.median(taken) for taken in times]


def measure(
    codec: RspCodec,
    name: str,
    hand_pull: Callable[[bytes], Packet],
    hand_push: Callable[[Packet], bytes],
    flat: struct.Struct,
    rounds: int,
) -> dict[str, Any]:
    data = vector(name)
    packet = codec.pull_packet(data)
    # The same bytes and the same objects, by both.
    assert hand_pull(data) == packet, "the hand codec reads another packet"
    assert hand_push(packet) == data == codec.push_packet(packet)
    for _ in range(COMPILE_AT):  # a session's steady map: the codec has compiled its layout
        assert codec.pull_packet(codec.push_packet(packet)) == packet
    fields = flat.unpack(data)

    def ours() -> None:
        codec.pull_packet(codec.push_packet(packet))

    def hand() -> None:
        hand_pull(hand_push(packet))

    def floor() -> None:
        flat.unpack(flat.pack(*fields))

    rcmlconf, anchor, bare = per_call([ours, hand, floor], rounds)
    return {
        "packet": name,
        "bytes": len(data),
        "rcmlconf_us": round(rcmlconf, 3),
        "hand_struct_us": round(anchor, 3),
        "ratio": round(rcmlconf / anchor, 2),
        "bare_struct_us": round(bare, 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    codec = RspCodec(load_robot_model(CUBO))
    rows = [
        measure(
            codec, "downlink-typical", hand_pull_downlink, hand_push_downlink, DOWN, args.rounds
        ),
        measure(codec, "uplink-typical", hand_pull_uplink, hand_push_uplink, UP, args.rounds),
    ]
    if args.json:
        json.dump({"rounds": args.rounds, "goal_ratio": 3, "packets": rows}, sys.stdout, indent=1)
        print()
        return
    print(f"RSP encode + decode, µs per packet, median of {args.rounds} rounds")
    print(
        f"{'packet':<18} {'bytes':>5} {'rcmlconf':>9} {'hand struct':>12} {'ratio':>6}"
        f" {'bare struct':>12}"
    )
    for row in rows:
        print(
            f"{row['packet']:<18} {row['bytes']:>5} {row['rcmlconf_us']:>9.2f}"
            f" {row['hand_struct_us']:>12.2f} {row['ratio']:>5.2f}x {row['bare_struct_us']:>12.2f}"
        )
    print(
        "goal: ratio <= 3 (hand struct: the same checks and objects; bare: no checks, no objects)"
    )


if __name__ == "__main__":
    main()
