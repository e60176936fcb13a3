"""
RSP: the Robot Simulacrum Protocol (specs/rsp.md)

RSP runs over UDP port 7340 (D-RSP-9). Every packet starts with the 20-byte header of Table II
(``RSP``, D-RSP-10); its type picks the body (D-RSP-11): ``RSPHello``, ``RSPWelcome``,
``RSPRefused``, ``RSPDownlink``, ``RSPUplink``, ``RSPAck``, ``RSPBye``, ``RSPPeriod``, and
``RSPSealed`` for a body an encrypted session sealed (D-RSP-21).

The Device Map of DOWNLINK, UPLINK and ACK is one bit per device of the robot model, and what
follows a set bit depends on the device's kind and the packet (D-RSP-14): the map's size and the
payloads are known only with the model. Give it once, and the map bodies are decoded device by
device (`rsp_model` reads the model for the layers, `rsp_device_map` the map and its payloads);
without it they stay raw bytes::

    >>> from rcmlconf.scapy_layers import rsp
    >>> rsp.use_model("rcmlconf/reference/robots/cubo/cubo.rmodel")
    >>> packets = rdpcap("cubo.pcap")
    >>> packets[5][rsp.RSPDownlink].payloads

A second implementation of the wire format, kept apart from ``rcmlconf.rsp.codec`` on purpose (as
scapy's contrib layers are apart from the implementations they dissect): the tests check both
against every vector. The layer dissects the layout and shows the values it finds: what does not
fit the layout (a body cut short, bytes after it, a bit the table says is never set) is left to
scapy's ``Raw``; a value the rules refuse (out of its range, a period too short) is shown as it is.
"""

# scapy.contrib.description = RSP, the Robot Simulacrum Protocol
# scapy.contrib.status = loads

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from scapy.config import conf
from scapy.fields import (
    ByteEnumField,
    ByteField,
    ConditionalField,
    Field,
    IntField,
    ShortField,
    StrField,
    XStrFixedLenField,
)
from scapy.layers.inet import UDP
from scapy.packet import Packet, bind_bottom_up, bind_layers

# Payloads built by hand are lists of rsp.RSPItem, as scapy users know it.
from rcmlconf.scapy_layers.rsp_device_map import RSPItem as RSPItem
from rcmlconf.scapy_layers.rsp_device_map import (
    read_payloads,
    set_bits,
    show_item,
    write_payloads,
)
from rcmlconf.scapy_layers.rsp_model import ModelLayout

if TYPE_CHECKING:
    from rcmlconf.rsp.model import RobotModel

RSP_PORT = 7340
RSP_VERSION = 1
RSP_HEADER_SIZE = 20

#: D-RSP-10, D-RSP-21.
RSP_ENCRYPTIONS = {0: "none", 1: "AES-256-GCM", 2: "ChaCha20-Poly1305"}
#: D-RSP-11.
RSP_TYPES = {
    1: "HELLO",
    2: "WELCOME",
    3: "REFUSED",
    4: "DOWNLINK",
    5: "UPLINK",
    6: "ACK",
    7: "BYE",
    8: "PERIOD",
}
RSP_REFUSED_REASONS = {
    1: "unknown model",
    2: "encryption not offered",
    3: "busy",
    4: "not authenticated",
}
RSP_BYE_REASONS = {0: "closed", 1: "timeout", 2: "shutdown"}
#: D-RSP-10: bit 7 of the buffer byte of the local system.
RSP_CLEAR_BUFFER = 0x80
RSP_NONCE_SIZE = 16
RSP_MAC_SIZE = 16
RSP_TAG_SIZE = 16

#: Who sends each packet type (D-RSP-11), which decides what its buffer byte says.
_FROM_LOCAL = frozenset({1, 4, 8})
_FROM_ROBOT = frozenset({2, 3, 5})
#: Bodies sent before a session has keys: never sealed (D-RSP-21).
_NEVER_SEALED = frozenset({1, 2, 3})


# -- the robot model in use (`rsp_model` reads it, `rsp_device_map` its maps) ------------------

_layout: ModelLayout | None = None
_model: RobotModel | None = None


def use_model(model: RobotModel | str | os.PathLike[str] | None) -> RobotModel | None:
    """Decode Device Maps and payloads with this robot model (or the model file at that path)
    from now on; None for raw bytes. Returns the model used before."""
    global _layout, _model
    if isinstance(model, str | os.PathLike):
        from pathlib import Path

        from rcmlconf.validate.validator import load_robot_model

        model = load_robot_model(Path(model))
    before = _model
    _model = model
    _layout = None if model is None else ModelLayout.of(model)
    return before


def current_model() -> RobotModel | None:
    return _model


# -- fields ---------------------------------------------------------------------------------------


class _SessionIdField(Field[int, bytes]):
    """48 bits the robot chose for the session (D-RSP-12)."""

    def __init__(self, name: str, default: int) -> None:
        super().__init__(name, default, "6s")

    def m2i(self, pkt: Packet | None, x: bytes) -> int:
        return int.from_bytes(x, "big")

    def i2m(self, pkt: Packet | None, x: int | None) -> bytes:
        return (x or 0).to_bytes(6, "big")

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        return f"0x{x:012x}" if x is not None else "None"


class _BufferField(ByteField):
    """From the local system, Clear Buffer in bit 7; from the robot, its free memory-command
    buffers (D-RSP-10, D-RSP-19)."""

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        kind = getattr(pkt, "type", None)
        if x is None:
            return "None"
        if kind in _FROM_LOCAL:
            return f"0x{x:02x} (Clear Buffer)" if x & RSP_CLEAR_BUFFER else f"0x{x:02x}"
        if kind in _FROM_ROBOT:
            return f"{x} (free buffers)"
        return str(x)


class _MillisecondsField(ShortField):
    def i2repr(self, pkt: Packet | None, x: int) -> str:
        return f"{x} ms" if x is not None else "None"


class _TimestampField(IntField):
    def i2repr(self, pkt: Packet | None, x: int) -> str:
        return f"{x} ms" if x is not None else "None"


def _fits(layout: ModelLayout | None, header: Packet | None) -> ModelLayout | None:
    """The layout, when it is the model of the packet's header (D-RSP-6)."""
    if layout is None:
        return None
    if header is not None and getattr(header, "model_id", None) != layout.model_id:
        return None
    return layout


def _layout_of(pkt: Packet) -> ModelLayout | None:
    """The model a map body was dissected with; for one built by hand, the model now in use."""
    kept: dict[str, ModelLayout | None] = pkt.__dict__
    if "layout" in kept:
        return kept["layout"]
    return _fits(_layout, pkt.underlayer)


def _decoded(pkt: Packet) -> bool:
    return _layout_of(pkt) is not None


class _DeviceMapField(Field[int, bytes]):
    """One bit per device in model order, the first in the most significant bit (D-RSP-14)."""

    def __init__(self, name: str, default: int) -> None:
        super().__init__(name, default, "0s")

    @staticmethod
    def _size(pkt: Packet | None) -> int:
        layout = _layout_of(pkt) if pkt is not None else None
        return layout.map_size if layout is not None else 0

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, int]:
        size = self._size(pkt)
        return s[size:], int.from_bytes(s[:size], "big")

    def addfield(self, pkt: Packet, s: bytes, val: int | None) -> bytes:
        return s + (val or 0).to_bytes(self._size(pkt), "big")

    def i2len(self, pkt: Packet, x: Any) -> int:
        return self._size(pkt)

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        layout = _layout_of(pkt) if pkt is not None else None
        if layout is None or x is None:
            return repr(x)
        size = layout.map_size
        names = [
            layout.devices[n].name if n < len(layout.devices) else f"bit {n} (no device)"
            for n in set_bits(x, size)
        ]
        return f"0x{x:0{2 * size}x} ({', '.join(names) or 'no bit set'})"


class _PayloadsField(Field[list[RSPItem], bytes]):
    """The payloads of the set bits, in model order, with nothing between them (D-RSP-14)."""

    islist = 1
    ismutable = True

    def __init__(self, name: str, default: list[RSPItem] | None) -> None:
        super().__init__(name, default, "0s")

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, list[RSPItem]]:
        layout = _layout_of(pkt)
        if layout is None:
            return s, []
        return read_payloads(layout, pkt.column, pkt.device_map or 0, s)

    def addfield(self, pkt: Packet, s: bytes, val: list[RSPItem] | None) -> bytes:
        layout = _layout_of(pkt)
        if layout is None:
            return s
        return s + write_payloads(layout, val)

    def i2len(self, pkt: Packet, x: Any) -> int:
        return len(self.addfield(pkt, b"", x))

    def i2repr(self, pkt: Packet | None, x: list[RSPItem] | None) -> str:
        if not x:
            return "(none)"
        lines = [show_item(item) for item in x]
        return ("\n" + " " * max(0, 10 - len(self.name))).join(lines)

    def do_copy(self, x: list[RSPItem]) -> list[RSPItem]:
        return list(x)


class _AllButTagField(StrField):
    """A sealed body: everything but the last 16 bytes, the AEAD tag (D-RSP-21)."""

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, bytes]:
        cut = max(0, len(s) - RSP_TAG_SIZE)
        return s[cut:], s[:cut]


# -- the header -----------------------------------------------------------------------------------


class RSP(Packet):
    """The 20 bytes of Table II that start every packet (D-RSP-10)."""

    name = "RSP"
    #  0                   1                   2                   3
    #  0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |  version = 1  |           model ID            |  encryption   |  bytes 0-3
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |     type      |        sequence number        |   timestamp   :  bytes 4-7
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # :        timestamp (bytes 7-10, 32 bits)        |  session ID   :  bytes 8-11
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # :               session ID (bytes 11-16, 48 bits)               :  bytes 12-15
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # :  session ID   | last received sequence number |    buffer     |  bytes 16-19
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteField("version", RSP_VERSION),
        ShortField("model_id", 1),
        ByteEnumField("encryption", 0, RSP_ENCRYPTIONS),
        ByteEnumField("type", 4, RSP_TYPES),
        ShortField("seq", 0),
        _TimestampField("timestamp", 0),
        _SessionIdField("session_id", 0),
        ShortField("last_received", 0),
        _BufferField("buffer", 0),
    ]

    @classmethod
    def dispatch_hook(cls, _pkt: bytes | None = None, *args: Any, **kargs: Any) -> type[Packet]:
        if _pkt is not None and len(_pkt) < RSP_HEADER_SIZE:
            return conf.raw_layer  # a header cut short (R-RSP-13)
        return cls

    def guess_payload_class(self, payload: bytes) -> type[Packet]:
        if self.encryption and self.type not in _NEVER_SEALED:
            return RSPSealed
        return super().guess_payload_class(payload)

    def mysummary(self) -> str:
        return self.describe()

    def describe(self) -> str:
        """The packet type, sequence number, session and what the body says, on one line."""
        kind = RSP_TYPES.get(self.type, f"type {self.type}")
        text = f"RSP {kind} seq={self.seq} session=0x{self.session_id:012x}"
        body = self.payload
        if isinstance(body, _RSPBody):
            detail = body.detail()
            if detail:
                text += " " + detail
        return text


# -- the bodies -----------------------------------------------------------------------------------


def _encrypted(pkt: Packet) -> bool:
    header = pkt.underlayer
    return header is not None and bool(getattr(header, "encryption", False))


class _RSPBody(Packet):
    #: Bytes of the body's fields, without a MAC: shorter bodies are left to Raw.
    size = 0
    #: HELLO and WELCOME end with a MAC in an encrypted session (D-RSP-21).
    signed = False
    #: The header's summary line tells what the body says (`detail`): `IP / UDP / RSP HELLO ...`.
    show_summary = False

    def mysummary(self) -> str:
        return ""

    def detail(self) -> str:
        """What the body adds to the header's summary line."""
        return ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # scapy asks only a class's own dispatch_hook (Packet_metaclass.__call__): every body
        # class gets one, so that a body cut short is left to Raw.
        type.__setattr__(cls, "dispatch_hook", classmethod(_body_hook))

    @classmethod
    def needed(cls, header: Packet | None) -> int:
        """Bytes a body of this class has at least."""
        if cls.signed and header is not None and getattr(header, "encryption", False):
            return cls.size + RSP_MAC_SIZE
        return cls.size


def _body_hook(
    cls: type[_RSPBody], _pkt: bytes | None = None, *args: Any, **kargs: Any
) -> type[Packet]:
    if _pkt is not None and len(_pkt) < cls.needed(kargs.get("_underlayer")):
        return conf.raw_layer  # cut short (R-RSP-16)
    return cls


class RSPHello(_RSPBody):
    """The local system opens a session (D-RSP-12)."""

    name = "RSP HELLO"
    size = RSP_NONCE_SIZE + 2
    signed = True
    # | client nonce (16 bytes) | period (uint16, ms) | MAC (16 bytes, encrypted sessions) |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        XStrFixedLenField("client_nonce", b"\0" * RSP_NONCE_SIZE, RSP_NONCE_SIZE),
        _MillisecondsField("period_ms", 20),
        ConditionalField(XStrFixedLenField("mac", b"", RSP_MAC_SIZE), _encrypted),
    ]

    def detail(self) -> str:
        return f"period {self.period_ms} ms"


class RSPWelcome(_RSPBody):
    """The robot opens the session its header names (D-RSP-12)."""

    name = "RSP WELCOME"
    size = 2 * RSP_NONCE_SIZE + 2
    signed = True
    # | client nonce (16) | robot nonce (16) | period in force (uint16, ms) | MAC (16, encrypted) |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        XStrFixedLenField("client_nonce", b"\0" * RSP_NONCE_SIZE, RSP_NONCE_SIZE),
        XStrFixedLenField("robot_nonce", b"\0" * RSP_NONCE_SIZE, RSP_NONCE_SIZE),
        _MillisecondsField("period_ms", 20),
        ConditionalField(XStrFixedLenField("mac", b"", RSP_MAC_SIZE), _encrypted),
    ]

    def detail(self) -> str:
        return f"period {self.period_ms} ms"


class RSPRefused(_RSPBody):
    name = "RSP REFUSED"
    size = 1
    # | reason (uint8) |
    fields_desc = [ByteEnumField("reason", 3, RSP_REFUSED_REASONS)]  # noqa: RUF012

    def detail(self) -> str:
        return RSP_REFUSED_REASONS.get(self.reason, f"reason {self.reason}")


class RSPBye(_RSPBody):
    name = "RSP BYE"
    size = 1
    # | reason (uint8) |
    fields_desc = [ByteEnumField("reason", 0, RSP_BYE_REASONS)]  # noqa: RUF012

    def detail(self) -> str:
        return RSP_BYE_REASONS.get(self.reason, f"reason {self.reason}")


class RSPPeriod(_RSPBody):
    """T changed while the session runs (D-RSP-13)."""

    name = "RSP PERIOD"
    size = 2
    # | the new period (uint16, ms) |
    fields_desc = [_MillisecondsField("period_ms", 20)]  # noqa: RUF012

    def detail(self) -> str:
        return f"period {self.period_ms} ms"


class _RSPMapBody(_RSPBody):
    """A Device Map and the payloads of its set bits (D-RSP-14); raw bytes without the model."""

    #: The column of RSP_BITS.
    column = 0
    # | Device Map: one bit per device, model order, ceil(devices / 8) bytes |
    # | the payloads of the set bits, in model order, nothing between them   |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ConditionalField(_DeviceMapField("device_map", 0), _decoded),
        ConditionalField(_PayloadsField("payloads", []), _decoded),
    ]

    @classmethod
    def needed(cls, header: Packet | None) -> int:
        layout = _fits(_layout, header)
        return layout.map_size if layout is not None else 0  # the Device Map

    def pre_dissect(self, s: bytes) -> bytes:
        # The model this body is read with, kept: it is shown with the same one later.
        self.__dict__["layout"] = _fits(_layout, self.underlayer)
        return s

    def _keep_layout(self, clone: Packet) -> Any:
        if "layout" in self.__dict__:
            clone.__dict__["layout"] = self.__dict__["layout"]
        return clone

    def copy(self) -> Any:
        return self._keep_layout(super().copy())

    def clone_with(self, payload: Any = None, **kargs: Any) -> Any:
        return self._keep_layout(super().clone_with(payload, **kargs))

    def detail(self) -> str:
        items: Sequence[RSPItem] = self.getfieldval("payloads") or ()
        if not _decoded(self):
            return f"{len(bytes(self.payload))} bytes (no model)"
        names = [item.device + (f"#{item.id}" if item.id is not None else "") for item in items]
        return "items: " + (", ".join(names) or "none")


class RSPDownlink(_RSPMapBody):
    name = "RSP DOWNLINK"
    column = 0


class RSPUplink(_RSPMapBody):
    name = "RSP UPLINK"
    column = 1


class RSPAck(_RSPMapBody):
    name = "RSP ACK"
    column = 2


class RSPSealed(_RSPBody):
    """A body an encrypted session sealed (D-RSP-21): ciphertext, then the 16-byte tag."""

    name = "RSP sealed body"
    size = RSP_TAG_SIZE
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        _AllButTagField("ciphertext", b""),
        XStrFixedLenField("tag", b"", RSP_TAG_SIZE),
    ]

    def detail(self) -> str:
        return f"sealed {len(self.ciphertext or b'')}B"


# -- bindings ------------------------------------------------------------------------------------


def bind_port(port: int) -> None:
    """Dissect UDP `port` as RSP, in either direction (D-RSP-9: 7340 unless told otherwise)."""
    bind_bottom_up(UDP, RSP, sport=port)
    bind_bottom_up(UDP, RSP, dport=port)


bind_port(RSP_PORT)
bind_layers(UDP, RSP, sport=RSP_PORT, dport=RSP_PORT)
bind_layers(RSP, RSPHello, type=1)
bind_layers(RSP, RSPWelcome, type=2)
bind_layers(RSP, RSPRefused, type=3)
bind_layers(RSP, RSPDownlink, type=4)
bind_layers(RSP, RSPUplink, type=5)
bind_layers(RSP, RSPAck, type=6)
bind_layers(RSP, RSPBye, type=7)
bind_layers(RSP, RSPPeriod, type=8)
