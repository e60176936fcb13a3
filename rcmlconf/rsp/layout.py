"""What a Device Map bit means, for each kind of device and each packet that has a map (D-RSP-14).

The table is data: the codec reads what follows a set bit from it, the validator sizes the largest
packet of each direction from it (R-RSP-11), and a receiver refuses a bit it says is never set
(R-RSP-17).
"""

from __future__ import annotations

import enum

from rcmlconf.rsp.model import Device, DeviceKind, RobotModel

#: The header of Table II (D-RSP-10).
HEADER_SIZE = 20
#: The AEAD tag of an encrypted packet (D-RSP-21).
TAG_SIZE = 16
#: HELLO's and WELCOME's nonces (D-RSP-11).
NONCE_SIZE = 16
#: The MAC of HELLO and WELCOME in an encrypted session: HMAC-SHA256 cut to 16 bytes (D-RSP-21).
MAC_SIZE = 16
#: The largest UDP payload over IPv4 (D-RSP-7).
MAX_DATAGRAM = 65507


class MapPacket(enum.Enum):
    """The packet types whose body is a Device Map and payloads (D-RSP-11)."""

    DOWNLINK = "DOWNLINK"
    UPLINK = "UPLINK"
    ACK = "ACK"


class Bit(enum.Enum):
    """What a set bit means and what follows it."""

    NEVER = "never set"
    #: A request, or a module's activation: nothing follows.
    FLAG = "flag"
    #: A state: the fields.
    STATE = "state"
    #: An occurrence: its ID, then the fields.
    OCCURRENCE = "occurrence"
    #: An acknowledgement: the acknowledged occurrence's ID.
    ID = "id"


_K = DeviceKind
_N, _F, _S, _O, _I = Bit.NEVER, Bit.FLAG, Bit.STATE, Bit.OCCURRENCE, Bit.ID

#: D-RSP-14: kind -> (DOWNLINK, UPLINK, ACK).
_TABLE: dict[DeviceKind, tuple[Bit, Bit, Bit]] = {
    _K.EFFECTOR: (_S, _N, _N),
    _K.SENSOR: (_F, _S, _N),
    _K.MONITOR: (_F, _S, _N),
    _K.MODULE: (_F, _N, _N),
    _K.COMMAND: (_O, _N, _I),
    _K.EVENT: (_F, _O, _N),
    _K.MEMORY_COMMAND: (_O, _N, _I),
    _K.MEMORY_EVENT: (_F, _O, _I),
}
_COLUMN = {MapPacket.DOWNLINK: 0, MapPacket.UPLINK: 1, MapPacket.ACK: 2}

#: Who sends each packet, and so who acknowledges: the robot ACKs commands and memory commands,
#: the local system memory events.
ACKED_BY_ROBOT = frozenset({_K.COMMAND, _K.MEMORY_COMMAND})
ACKED_BY_LOCAL = frozenset({_K.MEMORY_EVENT})


def bit(kind: DeviceKind, packet: MapPacket) -> Bit:
    return _TABLE[kind][_COLUMN[packet]]


def largest_payload(model: RobotModel, device: Device, packet: MapPacket) -> int:
    """Bytes of the largest payload a set bit of `device` brings in `packet` (D-RSP-7)."""
    meaning = bit(device.kind, packet)
    fields = sum(f.type.max_encoded_size for f in device.fields)
    return {
        Bit.NEVER: 0,
        Bit.FLAG: 0,
        Bit.STATE: fields,
        Bit.OCCURRENCE: model.id_length + fields,
        Bit.ID: model.id_length,
    }[meaning]


def largest_packet(model: RobotModel, packet: MapPacket) -> int:
    """Bytes of the largest packet of that type the model allows, with an AEAD tag (R-RSP-11)."""
    payloads = sum(largest_payload(model, device, packet) for device in model.devices)
    return HEADER_SIZE + model.map_size + payloads + TAG_SIZE
