"""Write vectors/rsp/packets.json: RSP packets (specs/rsp.md §2, §3) and what they decode to.

Every byte is written here field by field with `struct`, from the two robot models as this file
spells them out (`CUBO`, `EVERY_KIND`: copied by hand from their `.rmodel` files), so that the
codec of `rcmlconf.rsp.codec` is checked against a writer that shares no code with it. This file
imports nothing of rcmlconf.

    python vectors/rsp/make_packets.py            # rewrite packets.json
    python vectors/rsp/make_packets.py --check    # exit 1 if packets.json is not what it writes
"""

from __future__ import annotations

import argparse
import json
import math
import struct
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

# -- the models, as their .rmodel files give them ------------------------------------------------

#: (name, kind, fields) in model order (D-RSP-2); a field is (name, format), the format a struct
#: code with its count ("h", "4H", "2?"), or "bytes" / "string" (a 16-bit length, then the bytes).
#: A monitor has its effector's fields (D-RSP-4).
Devices = list[tuple[str, str, list[tuple[str, str]]]]

CUBO_DEVICES: Devices = [
    ("base", "module", []),
    ("leftWheel", "effector", [("speed", "h")]),  # -500 to 500
    ("rightWheel", "effector", [("speed", "h")]),  # -500 to 500
    ("leftWheelMonitor", "monitor", [("speed", "h")]),
    ("rightWheelMonitor", "monitor", [("speed", "h")]),
    ("arms", "module", []),
    ("leftArm", "effector", [("angle", "h")]),  # -900 to 900
    ("rightArm", "effector", [("angle", "h")]),  # -900 to 900
    ("head", "module", []),
    ("headTilt", "effector", [("angle", "h")]),  # -300 to 300
    ("lip", "effector", [("opening", "B")]),  # 0 to 100
    ("lcd", "effector", [("image", "bytes")]),  # size 2048
    ("speaker", "effector", [("fragment", "H"), ("samples", "bytes")]),  # size 1959
    ("microphone", "sensor", [("fragment", "H"), ("samples", "bytes")]),  # size 980
    ("proximity", "sensor", [("distance", "4H")]),
    ("floor", "sensor", [("drop", "2?")]),
    ("luminance", "sensor", [("illuminance", "H")]),
    ("temperature", "sensor", [("temperature", "h")]),
    ("battery", "sensor", [("charge", "B")]),  # 0 to 100
    ("position", "sensor", [("x", "f"), ("y", "f"), ("heading", "f")]),  # heading ±3.1416
    ("serviceButton", "event", [("pressed", "?")]),
    ("messageButton", "event", [("pressed", "?")]),
    ("irFire", "command", [("code", "H")]),
    # duration at least 1; arms -900 to 900; head -300 to 300
    ("motion", "memoryCommand", [("duration", "H"), ("leftArm", "h"), ("rightArm", "h"),
                                 ("headTilt", "h")]),
    ("lowBattery", "memoryEvent", [("charge", "B")]),  # 0 to 100
]  # fmt: skip

EVERY_KIND_DEVICES: Devices = [
    ("drive", "module", []),
    ("wheels", "effector", [("speed", "2h")]),  # -1000 to 1000
    ("wheelsActual", "monitor", [("speed", "2h")]),
    ("odometry", "sensor", [("x", "d"), ("y", "d"), ("heading", "f")]),  # heading ±3.5
    ("arm", "effector", [("shoulder", "b"), ("elbow", "B"), ("grip", "?")]),  # ±90, max 180
    ("armActual", "monitor", [("shoulder", "b"), ("elbow", "B"), ("grip", "?")]),
    ("display", "effector", [("text", "string"), ("picture", "bytes")]),  # sizes 64, 1024
    ("counters", "sensor", [("a", "i"), ("b", "I"), ("c", "2q"), ("d", "Q"), ("e", "i"),
                            ("f", "100H")]),  # e at least 0
    ("beep", "command", [("tone", "H")]),  # 100 to 8000
    ("bumped", "event", [("where", "string")]),  # size 16
    ("pose", "memoryCommand", [("duration", "H"), ("shoulder", "b")]),
    ("poseDone", "memoryEvent", [("remaining", "B")]),
]  # fmt: skip


class Model:
    def __init__(self, key: str, path: str, model_id: int, id_code: str, devices: Devices) -> None:
        self.key = key
        #: The .rmodel file, relative to vectors/.
        self.path = path
        self.model_id = model_id
        #: An occurrence's ID: 1 byte ("B") or 2 ("H") (D-RSP-5).
        self.id_code = id_code
        self.devices = devices
        self.position = {name: n for n, (name, _, _) in enumerate(devices)}
        self.fields = {name: fields for name, _, fields in devices}
        self.map_size = (len(devices) + 7) // 8


CUBO = Model("CUBO", "../rcmlconf/reference/robots/cubo/cubo.rmodel", 1, "B", CUBO_DEVICES)
EVERY_KIND = Model("every-kind", "xml/valid/rmodel-every-kind.rmodel", 42, "H", EVERY_KIND_DEVICES)

# -- the header (D-RSP-10) -------------------------------------------------------------------

HELLO, WELCOME, REFUSED, DOWNLINK, UPLINK, ACK, BYE, PERIOD = range(1, 9)
TYPE_NAMES = {1: "HELLO", 2: "WELCOME", 3: "REFUSED", 4: "DOWNLINK", 5: "UPLINK", 6: "ACK",
              7: "BYE", 8: "PERIOD"}  # fmt: skip
ENCRYPTION_NAMES = {0: "NONE", 1: "AES_256_GCM", 2: "CHACHA20_POLY1305"}
SESSION = 0xA1B2C3D4E5F6
CLEAR_BUFFER = 0x80


def header(
    kind: int,
    *,
    model: Model = CUBO,
    sequence: int = 0,
    timestamp: int = 0,
    session: int = SESSION,
    last: int = 0,
    buffer: int = 0,
    encryption: int = 0,
    version: int = 1,
    model_id: int | None = None,
) -> tuple[bytes, dict[str, Any]]:
    """The 20 bytes of Table II, and their decoding."""
    model_id = model.model_id if model_id is None else model_id
    data = struct.pack(
        ">BHBBHIHIHB",
        version,
        model_id,
        encryption,
        kind,
        sequence,
        timestamp,
        session >> 32,
        session & 0xFFFFFFFF,
        last,
        buffer,
    )
    shown = {
        "version": version,
        "model_id": model_id,
        "encryption": ENCRYPTION_NAMES.get(encryption, encryption),
        "type": TYPE_NAMES.get(kind, kind),
        "sequence": sequence,
        "timestamp": timestamp,
        "session_id": session,
        "last_received": last,
        "buffer": buffer,
    }
    return data, shown


# -- payloads (D-RSP-14, D-RCML-10) ------------------------------------------------------------


def value_bytes(fmt: str, value: Any) -> bytes:
    if fmt in ("bytes", "string"):
        raw = bytes(value) if fmt == "bytes" else str(value).encode("utf-8")
        return struct.pack(">H", len(raw)) + raw
    if fmt[0].isdigit():
        return struct.pack(">" + fmt, *value)
    return struct.pack(">" + fmt, value)


def value_json(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("INF" if value > 0 else "-INF")
    if isinstance(value, tuple | list):
        return [value_json(v) for v in value]
    return value


class Item:
    """One set bit: a flag, a state (values), an occurrence (id and values), or an ACK (id)."""

    def __init__(self, device: str, ident: int | None = None, **values: Any) -> None:
        self.device = device
        self.id = ident
        self.values = values or None

    def payload(self, model: Model) -> bytes:
        data = b"" if self.id is None else struct.pack(">" + model.id_code, self.id)
        if self.values is not None:
            fields = model.fields[self.device]
            assert [name for name, _ in fields] == list(self.values), self.device
            data += b"".join(value_bytes(fmt, self.values[name]) for name, fmt in fields)
        return data

    def shown(self) -> dict[str, Any]:
        shown: dict[str, Any] = {"device": self.device}
        if self.id is not None:
            shown["id"] = self.id
        if self.values is not None:
            shown["values"] = {name: value_json(v) for name, v in self.values.items()}
        return shown


def device_map(model: Model, positions: list[int]) -> bytes:
    """The first device in the most significant bit of the first byte (D-RSP-14)."""
    number = 0
    for position in positions:
        number |= 1 << (8 * model.map_size - 1 - position)
    return number.to_bytes(model.map_size, "big")


class Written:
    """A packet's bytes, its decoding, and where each item's payload starts (for offsets)."""

    def __init__(self, data: bytes, shown: dict[str, Any], starts: dict[str, int]) -> None:
        self.data = data
        self.shown = shown
        self.starts = starts


def map_packet(kind: int, items: list[Item], model: Model = CUBO, **fields: Any) -> Written:
    head, shown = header(kind, model=model, **fields)
    positions = [model.position[item.device] for item in items]
    assert positions == sorted(set(positions)), "items in model order, once each"
    data = head + device_map(model, positions)
    starts = {}
    for item in items:
        starts[item.device] = len(data)
        data += item.payload(model)
    body = {"items": [item.shown() for item in items]}
    return Written(data, {"header": shown, "body": body}, starts)


def session_packet(kind: int, body: bytes, shown: dict[str, Any], **fields: Any) -> Written:
    head, header_shown = header(kind, **fields)
    return Written(head + body, {"header": header_shown, "body": shown}, {})


NONCE = bytes(range(16))
ROBOT_NONCE = bytes(range(0xF0, 0x100))
MAC = bytes(range(0xA0, 0xB0))


def hello(period: int, mac: bytes = b"", **fields: Any) -> Written:
    body = NONCE + struct.pack(">H", period) + mac
    shown = {"client_nonce": NONCE.hex(), "period_ms": period, "mac": mac.hex()}
    return session_packet(HELLO, body, shown, session=0, **fields)


def welcome(period: int, mac: bytes = b"", **fields: Any) -> Written:
    body = NONCE + ROBOT_NONCE + struct.pack(">H", period) + mac
    shown = {
        "client_nonce": NONCE.hex(),
        "robot_nonce": ROBOT_NONCE.hex(),
        "period_ms": period,
        "mac": mac.hex(),
    }
    return session_packet(WELCOME, body, shown, **fields)


def reason(kind: int, number: int, name: str, **fields: Any) -> Written:
    return session_packet(kind, struct.pack(">B", number), {"reason": name}, **fields)


def period(milliseconds: int, **fields: Any) -> Written:
    return session_packet(
        PERIOD, struct.pack(">H", milliseconds), {"period_ms": milliseconds}, **fields
    )


def patched(data: bytes, offset: int, new: bytes) -> bytes:
    """`data` with the bytes at `offset` replaced."""
    assert offset + len(new) <= len(data)
    return data[:offset] + new + data[offset + len(new) :]


def f32(value: float) -> float:
    """The float32 nearest `value`, as a Python float: what a float32 field holds."""
    return float(struct.unpack(">f", struct.pack(">f", value))[0])


# -- the packets ---------------------------------------------------------------------------------

#: CUBO's heading bound, 3.1416 as a float32.
PI = f32(3.1416)
SAMPLES = bytes((7 * n + 3) & 0xFF for n in range(1959))


def typical_downlink() -> Written:
    """Two wheels and their module, both arms and theirs, the lip and its head, the position
    requested and an IR command in flight: what bench/rsp_codec_speed.py encodes and decodes."""
    return map_packet(
        DOWNLINK,
        [
            Item("base"),
            Item("leftWheel", speed=120),
            Item("rightWheel", speed=118),
            Item("arms"),
            Item("leftArm", angle=450),
            Item("rightArm", angle=-450),
            Item("head"),
            Item("lip", opening=40),
            Item("position"),
            Item("irFire", 3, code=0x20DF),
        ],
        sequence=1042,
        timestamp=20840,
        last=1038,
    )


def typical_uplink() -> Written:
    """The position, both wheel monitors and a button press."""
    return map_packet(
        UPLINK,
        [
            Item("leftWheelMonitor", speed=117),
            Item("rightWheelMonitor", speed=-116),
            Item("position", x=1.5, y=-2.25, heading=0.5),
            Item("serviceButton", 7, pressed=True),
        ],
        sequence=1038,
        timestamp=20760,
        last=1041,
        buffer=16,
    )


def music_downlink() -> Written:
    return map_packet(
        DOWNLINK,
        [
            Item("arms"),
            Item("leftArm", angle=300),
            Item("rightArm", angle=-300),
            Item("head"),
            Item("lip", opening=65),
            Item("speaker", fragment=0xFFFF, samples=SAMPLES),
        ],
        sequence=512,
        timestamp=10240,
        last=509,
    )


def floor_battery() -> Written:
    return map_packet(
        UPLINK,
        [Item("floor", drop=(True, True)), Item("battery", charge=0)],
        sequence=20,
        timestamp=400,
        last=90,
        buffer=16,
    )


def every_kind_downlink() -> Written:
    return map_packet(
        DOWNLINK,
        [
            Item("drive"),
            Item("wheels", speed=(-1000, 1000)),
            Item("wheelsActual"),
            Item("odometry"),
            Item("arm", shoulder=-90, elbow=180, grip=True),
            Item("armActual"),
            Item("display", text="héllo, 世界", picture=bytes([1, 2, 3, 4])),
            Item("counters"),
            Item("beep", 0x1234, tone=8000),
            Item("bumped"),
            Item("pose", 0xFFFF, duration=500, shoulder=-128),
            Item("poseDone"),
        ],
        model=EVERY_KIND,
        sequence=7,
        timestamp=35,
        last=6,
        buffer=CLEAR_BUFFER,
    )


def every_kind_uplink() -> Written:
    return map_packet(
        UPLINK,
        [
            Item("wheelsActual", speed=(12, -12)),
            Item("odometry", x=1234.5678, y=-1e300, heading=3.5),
            Item("armActual", shoulder=90, elbow=0, grip=False),
            Item(
                "counters",
                a=-(1 << 31),
                b=(1 << 32) - 1,
                c=(-(1 << 63), (1 << 63) - 1),
                d=(1 << 64) - 1,
                e=0,
                f=tuple(661 * n for n in range(100)),
            ),
            Item("bumped", 0xFFFF, where="left"),
            Item("poseDone", 1, remaining=0),
        ],
        model=EVERY_KIND,
        sequence=6,
        timestamp=30,
        last=7,
        buffer=127,
    )


def valid() -> list[tuple[str, str, Model, Written]]:
    """(name, why, model, packet)."""
    return [
        # -- session packets (D-RSP-11, D-RSP-12) --
        ("hello", "HELLO opens a session: sequence 0, session ID 0, no MAC without encryption"
         " (D-RSP-11, D-RSP-12)", CUBO, hello(20)),
        ("hello-aes-256-gcm", "HELLO of an encrypted session ends with a 16-byte MAC; the codec"
         " carries it and does not check it (D-RSP-21)", CUBO, hello(20, MAC, encryption=1)),
        ("hello-repeated-shortest-period", "a repeated HELLO is a new packet with the same nonce"
         " (D-RSP-12), asking for the shortest T, 5 ms (D-RSP-13)", CUBO,
         hello(5, sequence=1, timestamp=250)),
        ("welcome", "WELCOME gives the session ID and raises the period to 40 ms; the robot's"
         " buffer byte is its free memory-command buffers, 16 of 16 (D-RSP-10, D-RSP-13)", CUBO,
         welcome(40, buffer=16)),
        ("welcome-chacha20-poly1305", "WELCOME of an encrypted session, with its MAC (D-RSP-21)",
         CUBO, welcome(20, MAC, encryption=2, last=1, buffer=16)),
        ("refused-busy", "REFUSED 3 (busy): session ID 0 (D-RSP-10, D-RSP-11)", CUBO,
         reason(REFUSED, 3, "BUSY", session=0, buffer=16)),
        ("refused-not-authenticated", "REFUSED 4 to an encrypted HELLO whose MAC was wrong:"
         " REFUSED has no MAC (D-RSP-11, R-RSP-38)", CUBO,
         reason(REFUSED, 4, "NOT_AUTHENTICATED", session=0, encryption=1, buffer=16)),
        ("bye-closed", "BYE 0 from the local system (D-RSP-11)", CUBO,
         reason(BYE, 0, "CLOSED", sequence=900, timestamp=18000, last=880)),
        ("bye-timeout", "BYE 1 from the robot after 10 s of silence (D-RSP-13, R-RSP-22)", CUBO,
         reason(BYE, 1, "TIMEOUT", sequence=880, timestamp=27600, last=899, buffer=16)),
        ("period-longest", "PERIOD changes T to 10 s, the longest (D-RSP-13)", CUBO,
         period(10000, sequence=40, timestamp=800, last=39)),
        # -- DOWNLINK (D-RSP-14) --
        ("downlink-typical", "modules active, effector values, a sensor requested and a command"
         " in flight: the bench's DOWNLINK (D-RSP-14, D-RSP-17)", CUBO, typical_downlink()),
        ("downlink-every-kind", "every kind's DOWNLINK bit: a module active, an effector value"
         " (headTilt at its -300 bound), sensors, a monitor, events and a memory event requested,"
         " a command (ID 255, the largest of 1 byte), a memory command (duration at its minimum"
         " 1, angles at their bounds), and Clear Buffer (D-RSP-10, D-RSP-14, D-RSP-19)", CUBO,
         map_packet(DOWNLINK, [
             Item("base"), Item("rightWheelMonitor"), Item("head"), Item("headTilt", angle=-300),
             Item("floor"), Item("battery"), Item("serviceButton"), Item("messageButton"),
             Item("irFire", 255, code=0), Item("motion", 0, duration=1, leftArm=900,
                                                rightArm=-900, headTilt=300),
             Item("lowBattery"),
         ], sequence=77, timestamp=1540, last=70, buffer=CLEAR_BUFFER)),
        ("downlink-music", "the largest music DOWNLINK: lip, both arms and a full speaker"
         " fragment (1,959 bytes), 1,992 bytes in all (D-RSP-8, D-RSP-22; fragment 65,535)",
         CUBO, music_downlink()),
        ("downlink-lcd-empty-image", "a bytes field of length 0, and a short speaker fragment"
         " (D-RCML-9)", CUBO,
         map_packet(DOWNLINK, [Item("head"), Item("lcd", image=b""),
                               Item("speaker", fragment=0, samples=b"\x80\x7f\x00\xff")],
                    sequence=3, timestamp=60, last=2)),
        ("downlink-keepalive", "an empty Device Map: nothing to set this period (D-RSP-13)", CUBO,
         map_packet(DOWNLINK, [], sequence=5, timestamp=100, last=4)),
        ("downlink-before-wrap", "sequence 65,535, timestamp 2^32 - 1, the largest session ID and"
         " last received 65,535 (R-RSP-14, R-RSP-15)", CUBO,
         map_packet(DOWNLINK, [Item("base"), Item("leftWheel", speed=-500),
                               Item("rightWheel", speed=500)],
                    sequence=0xFFFF, timestamp=0xFFFFFFFF, session=0xFFFFFFFFFFFF, last=0xFFFF)),
        ("downlink-after-wrap", "the next DOWNLINK: sequence 0 and timestamp 19, both modulo"
         " (R-RSP-14)", CUBO,
         map_packet(DOWNLINK, [Item("base"), Item("leftWheel", speed=0),
                               Item("rightWheel", speed=0)],
                    sequence=0, timestamp=19, session=0xFFFFFFFFFFFF, last=0)),
        # -- UPLINK --
        ("uplink-typical", "the position, both wheel monitors (their effector's fields) and an"
         " event occurrence: the bench's UPLINK (D-RSP-14)", CUBO, typical_uplink()),
        ("uplink-every-sensor", "every sensor's value: bytes, an array, bools, signed and"
         " unsigned numbers, a charge at its bound 100, a heading at its bound -3.1416 as"
         " float32; no free buffer (D-RSP-14, D-RSP-19)", CUBO,
         map_packet(UPLINK, [
             Item("microphone", fragment=42, samples=bytes(range(8))),
             Item("proximity", distance=(0, 150, 65535, 1200)),
             Item("floor", drop=(False, True)),
             Item("luminance", illuminance=320),
             Item("temperature", temperature=-125),
             Item("battery", charge=100),
             Item("position", x=-0.0, y=f32(1e-45), heading=-PI),
         ], sequence=12, timestamp=240, last=13, buffer=0)),
        ("uplink-floor-battery", "a bool array and a charge at its min 0 (D-RCML-9, D-RCML-12)",
         CUBO, floor_battery()),
        ("uplink-non-finite", "unbounded float32 fields hold NaN and infinities (D-RCML-9)",
         CUBO, map_packet(UPLINK, [Item("position", x=math.nan, y=-math.inf, heading=PI)],
                          sequence=13, timestamp=260, last=13, buffer=16)),
        ("uplink-events", "an event (ID 255) and a memory event occurrence (ID 0) (D-RSP-14,"
         " D-RSP-17)", CUBO,
         map_packet(UPLINK, [Item("messageButton", 255, pressed=False),
                             Item("lowBattery", 0, charge=15)],
                    sequence=14, timestamp=280, last=13, buffer=3)),
        ("uplink-keepalive", "an empty Device Map from the robot (D-RSP-13)", CUBO,
         map_packet(UPLINK, [], sequence=15, timestamp=300, last=13, buffer=16)),
        # -- ACK --
        ("ack-from-robot", "the robot acknowledges a command and a memory command: one ID per"
         " set bit (D-RSP-14, D-RSP-17)", CUBO,
         map_packet(ACK, [Item("irFire", 3), Item("motion", 0)],
                    sequence=16, timestamp=320, last=77, buffer=15)),
        ("ack-from-local", "the local system acknowledges a memory event (D-RSP-14, D-RSP-17)",
         CUBO, map_packet(ACK, [Item("lowBattery", 0)], sequence=78, timestamp=1560, last=14)),
        # -- the every-kind model: 2-byte IDs, 12 devices, 127 buffers --
        ("every-kind-downlink", "idLength 2: 2-byte IDs (0x1234, 65,535); an int16 array at its"
         " bounds, int8, uint8 and bool fields, a UTF-8 string and bytes; every request bit"
         " (D-RSP-5, D-RSP-14)", EVERY_KIND, every_kind_downlink()),
        ("every-kind-uplink", "float64 fields, a float32 at its bound 3.5, 32- and 64-bit"
         " extremes, a uint16 array of 100, a string event with ID 65,535; 127 free buffers,"
         " the most a model has (D-RSP-6, D-RSP-14)", EVERY_KIND, every_kind_uplink()),
        ("every-kind-ack", "2-byte IDs acknowledged by the robot (D-RSP-17)", EVERY_KIND,
         map_packet(ACK, [Item("beep", 0x1234), Item("pose", 0xFFFF)], model=EVERY_KIND,
                    sequence=8, timestamp=40, last=7, buffer=126)),
        ("every-kind-ack-from-local", "a 2-byte memory event ID acknowledged by the local"
         " system", EVERY_KIND,
         map_packet(ACK, [Item("poseDone", 1)], model=EVERY_KIND, sequence=8, timestamp=40,
                    last=6)),
    ]  # fmt: skip


def never(kind: int, device: str, ident: int | None = None, **values: Any) -> tuple[bytes, int]:
    """A packet with `device`'s bit set where D-RSP-14 says it never is, and the map byte."""
    position = CUBO.position[device]
    head, _ = header(kind, buffer=16 if kind == UPLINK else 0)
    payload = Item(device, ident, **values).payload(CUBO)
    return head + device_map(CUBO, [position]) + payload, 20 + position // 8


def malformed() -> list[tuple[str, str, Model, bytes, int, str]]:
    """(name, why, model, bytes, offset, rule)."""
    down = typical_downlink()
    up = typical_uplink()
    music = music_downlink()
    every_down = every_kind_downlink()
    every_up = every_kind_uplink()
    cases: list[tuple[str, str, Model, bytes, int, str]] = [
        ("empty", "no header at all", CUBO, b"", 0, "R-RSP-13"),
        (
            "header-cut-short",
            "12 of the header's 20 bytes: the fault is where the rest was due",
            CUBO,
            down.data[:12],
            12,
            "R-RSP-13",
        ),
        ("version-2", "version 2 (R-RSP-13)", CUBO, patched(down.data, 0, b"\x02"), 0, "R-RSP-13"),
        (
            "version-2-short",
            "another version is reported as that before the length: its layout may differ",
            CUBO,
            b"\x02\x00\x01",
            0,
            "R-RSP-13",
        ),
        (
            "model-2",
            "another model's ID (R-RSP-13, R-RSP-18)",
            CUBO,
            patched(down.data, 1, b"\x00\x02"),
            1,
            "R-RSP-13",
        ),
        (
            "encryption-3",
            "an encryption byte none of 0, 1, 2 (D-RSP-10)",
            CUBO,
            patched(down.data, 3, b"\x03"),
            3,
            "R-RSP-13",
        ),
        ("type-0", "packet type 0 (D-RSP-11)", CUBO, patched(down.data, 4, b"\x00"), 4, "R-RSP-13"),
        ("type-9", "packet type 9 (D-RSP-11)", CUBO, patched(down.data, 4, b"\x09"), 4, "R-RSP-13"),
        (
            "downlink-session-0",
            "a DOWNLINK with session ID 0: only HELLO and REFUSED have it (D-RSP-10)",
            CUBO,
            patched(down.data, 11, bytes(6)),
            11,
            "R-RSP-13",
        ),
        (
            "hello-with-session",
            "a HELLO with a session ID (D-RSP-10, D-RSP-12)",
            CUBO,
            patched(hello(20).data, 16, b"\x01"),
            11,
            "R-RSP-13",
        ),
        (
            "refused-with-session",
            "a REFUSED with a session ID (D-RSP-10)",
            CUBO,
            reason(REFUSED, 3, "BUSY", buffer=16).data,
            11,
            "R-RSP-13",
        ),
        (
            "downlink-buffer-01",
            "the local system's buffer byte is Clear Buffer or 0: bits 0 to 6 are 0 (D-RSP-10)",
            CUBO,
            patched(down.data, 19, b"\x01"),
            19,
            "R-RSP-13",
        ),
        (
            "period-buffer-81",
            "Clear Buffer with a low bit set, from the local system",
            CUBO,
            patched(period(40).data, 19, b"\x81"),
            19,
            "R-RSP-13",
        ),
        (
            "uplink-buffer-17",
            "17 free buffers of CUBO's 16 (D-RSP-10, D-RSP-19)",
            CUBO,
            patched(up.data, 19, b"\x11"),
            19,
            "R-RSP-13",
        ),
        (
            "uplink-buffer-80",
            "Clear Buffer from the robot (D-RSP-10)",
            CUBO,
            patched(up.data, 19, b"\x80"),
            19,
            "R-RSP-13",
        ),
        # -- the Device Map (D-RSP-14, R-RSP-17) --
        (
            "map-bit-past-last-device",
            "bit 25 of CUBO's 25 devices (0 to 24) is set: the bits"
            " past the last device are 0 (D-RSP-14, R-RSP-17)",
            CUBO,
            patched(down.data, 23, bytes([down.data[23] | 0x40])),
            23,
            "R-RSP-17",
        ),
        (
            "map-cut-short",
            "a DOWNLINK with 2 of its Device Map's 4 bytes",
            CUBO,
            down.data[:22],
            22,
            "R-RSP-16",
        ),
    ]
    never_cells = [
        ("effector-in-uplink", UPLINK, "leftWheel", None, {"speed": 1}),
        ("effector-in-ack", ACK, "leftArm", None, {}),
        ("sensor-in-ack", ACK, "battery", None, {}),
        ("monitor-in-ack", ACK, "leftWheelMonitor", None, {}),
        ("module-in-uplink", UPLINK, "base", None, {}),
        ("module-in-ack", ACK, "head", None, {}),
        ("command-in-uplink", UPLINK, "irFire", 1, {"code": 2}),
        ("event-in-ack", ACK, "serviceButton", 1, {}),
        ("memory-command-in-uplink", UPLINK, "motion", 1, {}),
    ]
    for name, kind, device, ident, values in never_cells:
        data, offset = never(kind, device, ident, **values)
        why = f"{device}'s bit in {TYPE_NAMES[kind]}: D-RSP-14's table says never (R-RSP-17)"
        cases.append((f"never-{name}", why, CUBO, data, offset, "R-RSP-17"))
    code = down.starts["irFire"] + 1
    samples = music.starts["speaker"] + 4
    lip = down.starts["lip"]
    heading = up.starts["position"] + 8
    floor_data = floor_battery()
    event = up.starts["serviceButton"] + 1
    cases += [
        # -- payloads (R-RSP-16, R-RCML-30) --
        ("payload-cut-short", "the DOWNLINK's last byte missing: the command's code was due at"
         " its first byte", CUBO, down.data[:-1], code, "R-RSP-16"),
        ("bytes-cut-short", "the music DOWNLINK 10 bytes short: the samples' 1,959 bytes were"
         " due after their length", CUBO, music.data[:-10], samples, "R-RSP-16"),
        ("payload-trailing-byte", "a byte after the last payload (R-RSP-16)", CUBO,
         down.data + b"\x00", len(down.data), "R-RSP-16"),
        ("keepalive-trailing-byte", "a byte after an empty Device Map", CUBO,
         map_packet(DOWNLINK, []).data + b"\x00", 24, "R-RSP-16"),
        ("wheel-speed-501", "leftWheel's speed above its max 500 (D-RCML-12, R-RSP-16)", CUBO,
         patched(down.data, down.starts["leftWheel"], struct.pack(">h", 501)),
         down.starts["leftWheel"], "R-RSP-16"),
        ("lip-101", "lip's opening above its max 100 (a uint8)", CUBO,
         patched(down.data, lip, b"\x65"), lip, "R-RSP-16"),
        ("heading-3.2", "position's heading above 3.1416 (a float32)", CUBO,
         patched(up.data, heading, struct.pack(">f", 3.2)), heading, "R-RSP-16"),
        ("heading-nan", "NaN is outside any range (D-RCML-12)", CUBO,
         patched(up.data, heading, bytes.fromhex("7fc00000")), heading, "R-RSP-16"),
        ("motion-duration-0", "a memory command's duration below its min 1: the offset is the"
         " field's, after the ID", CUBO,
         map_packet(DOWNLINK, [Item("motion", 4, duration=0, leftArm=0, rightArm=0,
                                    headTilt=0)]).data, 25, "R-RSP-16"),
        ("motion-head-tilt-301", "the last field of a memory command out of range", CUBO,
         map_packet(DOWNLINK, [Item("motion", 4, duration=10, leftArm=0, rightArm=0,
                                    headTilt=301)]).data, 31, "R-RSP-16"),
        ("floor-bool-2", "a bool byte 0x02 in an array (R-RCML-30)", CUBO,
         patched(floor_data.data, floor_data.starts["floor"] + 1, b"\x02"),
         floor_data.starts["floor"] + 1, "R-RCML-30"),
        ("event-bool-02", "an event's bool byte 0x02, after its ID (R-RCML-30)", CUBO,
         patched(up.data, event, b"\x02"), event, "R-RCML-30"),
        ("battery-charge-101", "a uint8 above its max 100 after a bool array", CUBO,
         patched(floor_data.data, floor_data.starts["battery"], b"\x65"),
         floor_data.starts["battery"], "R-RSP-16"),
        ("lcd-2049-bytes", "a bytes length above the field's size 2048 (R-RCML-30)", CUBO,
         map_packet(DOWNLINK, [Item("lcd", image=bytes(2049))]).data, 24, "R-RCML-30"),
        # -- session bodies (D-RSP-11, R-RSP-16) --
        ("hello-period-4", "a HELLO asking for T = 4 ms, below 5 ms (D-RSP-13)", CUBO,
         hello(4).data, 36, "R-RSP-16"),
        ("hello-period-10001", "a HELLO asking for T above 10 s (D-RSP-13)", CUBO,
         hello(10001).data, 36, "R-RSP-16"),
        ("welcome-period-0", "a WELCOME with period 0", CUBO, welcome(0, buffer=16).data, 52,
         "R-RSP-16"),
        ("period-65535", "a PERIOD above 10 s", CUBO, period(65535).data, 20, "R-RSP-16"),
        ("hello-with-mac-unencrypted", "a HELLO without encryption carries no MAC: 16 bytes too"
         " many (D-RSP-21)", CUBO, hello(20, MAC).data, 38, "R-RSP-16"),
        ("hello-encrypted-without-mac", "an encrypted HELLO without its MAC (D-RSP-21)", CUBO,
         hello(20, encryption=1).data, 38, "R-RSP-16"),
        ("welcome-mac-cut-short", "an encrypted WELCOME with 15 of its MAC's 16 bytes", CUBO,
         welcome(20, MAC, encryption=1, buffer=16).data[:-1], 54, "R-RSP-16"),
        ("refused-reason-0", "REFUSED's reason is 1 to 4 (D-RSP-11)", CUBO,
         reason(REFUSED, 0, "?", session=0, buffer=16).data, 20, "R-RSP-16"),
        ("bye-reason-3", "BYE's reason is 0 to 2 (D-RSP-11)", CUBO,
         reason(BYE, 3, "?").data, 20, "R-RSP-16"),
        ("bye-without-reason", "a BYE with no body", CUBO, reason(BYE, 0, "CLOSED").data[:20],
         20, "R-RSP-16"),
        # -- the every-kind model --
        ("every-kind-wheel-1001", "the second item of an int16 array above its max 1000: every"
         " item is bounded (D-RCML-12)", EVERY_KIND,
         patched(every_down.data, every_down.starts["wheels"] + 2, struct.pack(">h", 1001)),
         every_down.starts["wheels"] + 2, "R-RSP-16"),
        ("every-kind-text-not-utf-8", "a string field that is not UTF-8 (R-RCML-30): at the"
         " first bad byte", EVERY_KIND,
         patched(every_down.data, every_down.starts["display"] + 3, b"\xff"),
         every_down.starts["display"] + 3, "R-RCML-30"),
        ("every-kind-where-17-bytes", "a string length above its size 16 (R-RCML-30)",
         EVERY_KIND,
         patched(every_up.data, every_up.starts["bumped"] + 2, struct.pack(">H", 17)),
         every_up.starts["bumped"] + 2, "R-RCML-30"),
        ("every-kind-id-cut-short", "one byte of a 2-byte ID (D-RSP-5)", EVERY_KIND,
         map_packet(ACK, [Item("beep", 0x1234)], model=EVERY_KIND).data[:-1], 22, "R-RSP-16"),
        ("every-kind-counter-e-negative", "e, an int32 with min 0, at -1", EVERY_KIND,
         patched(every_up.data, every_up.starts["counters"] + 32, struct.pack(">i", -1)),
         every_up.starts["counters"] + 32, "R-RSP-16"),
        ("every-kind-uplink-buffer-128", "128 free buffers: at most 127 (D-RSP-6, D-RSP-10)",
         EVERY_KIND, patched(every_up.data, 19, b"\x80"), 19, "R-RSP-13"),
    ]  # fmt: skip
    return cases


def build() -> dict[str, Any]:
    return {
        "models": {model.key: model.path for model in (CUBO, EVERY_KIND)},
        "valid": [
            {"name": name, "why": why, "model": model.key, "hex": written.data.hex(),
             "packet": written.shown}
            for name, why, model, written in valid()
        ],
        "malformed": [
            {"name": name, "why": why, "model": model.key, "hex": data.hex(), "offset": offset,
             "rule": rule}
            for name, why, model, data, offset, rule in malformed()
        ],
    }  # fmt: skip


def text() -> str:
    return json.dumps(build(), indent=1, ensure_ascii=False) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare, do not write")
    args = parser.parse_args()
    target = HERE / "packets.json"
    if args.check:
        if target.read_text(encoding="utf-8") != text():
            sys.exit(f"{target} is not what {Path(__file__).name} writes")
        return
    target.write_text(text(), encoding="utf-8")


if __name__ == "__main__":
    main()
