"""The Lua dissector of RCTP/2.0 and RSP for Wireshark, generated from rcmlconf's own definitions.

As pymavlink's mavgen writes its Wireshark plugin from the XML its codecs come from, `generate_lua`
writes every number and name the dissectors need — RCTP's methods, status codes and limits, the
data stream's header, payload types and FLOW layouts, RSP's header, packet types, session bodies
and Device Map table, and with a robot model its devices and their fields — from the tables the
codecs use, imported here, not typed again. The dissectors' logic, the same for every model, is
`dissector.lua` beside this module; only the `GEN` table in front of it is generated.

The text depends on nothing but its inputs (no dates, no paths), so the same model gives the same
file.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import re
import struct
import typing
from collections.abc import Iterable, Mapping
from importlib import resources

from rcmlconf import __version__
from rcmlconf.rcml.url import DEFAULT_PORT as RCTP_PORT
from rcmlconf.rctp.datastream import flow, packets
from rcmlconf.rctp.fields import MAX_CSEQ
from rcmlconf.rctp.messages import METHODS, REASONS, VERSION
from rcmlconf.rctp.reader import LIMITS
from rcmlconf.rctp.request_checks import SINGLE_FIELDS
from rcmlconf.rsp.codec import bodies, header
from rcmlconf.rsp.layout import HEADER_SIZE, MAC_SIZE, TAG_SIZE, Bit, MapPacket, bit
from rcmlconf.rsp.model import MAX_MODEL_ID, Field, RobotModel
from rcmlconf.rsp.session.wire import SIGNED
from rcmlconf.values import DATA_TYPES, Kind

#: D-RSP-9: a robot listens on UDP 7340 unless told otherwise.
RSP_PORT = 7340
#: The requirements the dissectors name beside each fault (the codecs' own).
DATASTREAM_RULE = "R-RCTP-39"
FLOW_RULE = packets.MalformedFlowPayload.rule
VALUE_RULE = "R-RCML-30"
MAP_RULE = "R-RSP-17"
#: A sealed body shorter than its tag cannot be opened (D-RSP-21).
SEALED_RULE = "R-RSP-37"
#: What the model's names become in field abbreviations: Wireshark takes letters, digits, `_`
#: and `-` (and `.` between levels).
_NOT_ABBREVIATION = re.compile(r"[^A-Za-z0-9_-]")
#: FLOW kinds whose layout `flow` writes outside its table: a NACK's fields (its reason byte).
_NACK_LAYOUT = "B"


class LuaExpression(str):
    """Lua source written as is, not as a string literal."""


def lua_literal(value: object, indent: str = "") -> str:
    """`value` as a Lua literal: None, bools, numbers, strings, lists and mappings."""
    if value is None:
        return "nil"
    if isinstance(value, LuaExpression):
        return str(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "(0/0)"
        if math.isinf(value):
            return "math.huge" if value > 0 else "-math.huge"
        return repr(value)
    if isinstance(value, str):
        return _lua_string(value)
    inner = indent + "    "
    if isinstance(value, Mapping):
        if not value:
            return "{}"
        items = [
            f"{inner}{_lua_key(key)} = {lua_literal(item, inner)}," for key, item in value.items()
        ]
        return "{\n" + "\n".join(items) + "\n" + indent + "}"
    if isinstance(value, list | tuple):
        if not value:
            return "{}"
        rendered = [lua_literal(item, inner) for item in value]
        if all("\n" not in item for item in rendered) and sum(map(len, rendered)) < 80:
            return "{" + ", ".join(rendered) + "}"
        return "{\n" + "\n".join(f"{inner}{item}," for item in rendered) + "\n" + indent + "}"
    raise TypeError(f"no Lua literal for {value!r}")


def _lua_key(key: object) -> str:
    if (
        isinstance(key, str)
        and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key)
        and key not in _LUA_WORDS
    ):
        return key
    return f"[{lua_literal(key)}]"


_LUA_WORDS = frozenset(
    {
        *("and", "break", "do", "else", "elseif", "end", "false", "for", "function", "goto"),
        *("if", "in", "local", "nil", "not", "or", "repeat", "return", "then", "true", "until"),
        "while",
    }
)


def _lua_string(text: str) -> str:
    """A Lua string of `text`'s UTF-8 bytes: printable ASCII as is, every other byte escaped."""
    out = []
    for byte in text.encode("utf-8"):
        char = chr(byte)
        if char in '"\\':
            out.append("\\" + char)
        elif 0x20 <= byte < 0x7F:
            out.append(char)
        else:
            out.append(f"\\{byte:03d}")
    return '"' + "".join(out) + '"'


def _names(members: Iterable[enum.IntEnum], lower: bool = True) -> dict[int, str]:
    """Wire value -> name, as the codecs write them to people ("get interval")."""
    return {int(m): (m.name.lower().replace("_", " ") if lower else m.name) for m in members}


# -- RCTP/2.0 control ------------------------------------------------------------------------------


def _rctp() -> dict[str, object]:
    return {
        "version": VERSION,
        "ports": str(RCTP_PORT),
        "methods": list(METHODS),
        "statuses": dict(REASONS),
        "limits": {
            "start_line": LIMITS.start_line,
            "header_line": LIMITS.header_line,
            "header_section": LIMITS.header_section,
            "header_fields": LIMITS.header_fields,
            "body": LIMITS.body,
        },
        "once": {name.lower(): True for name in SINGLE_FIELDS},
        "max_cseq": MAX_CSEQ,
    }


# -- the data stream -------------------------------------------------------------------------------

#: struct code -> what a FLOW field is (D-RCTP-22): a 64-bit NTP time, a 32-bit number of
#: microseconds, or a byte of an enum.
_FLOW_KINDS = {"Q": "time", "I": "micros", "B": "enum"}


def _flow_layouts() -> tuple[list[dict[str, object]], dict[int, object], dict[int, object]]:
    """The FLOW fields, the fixed kinds' layouts by message * 256 + operation, and the layouts of
    the kinds that take any operation (an unknown request, a NACK)."""
    fields: dict[str, dict[str, object]] = {}

    def layout(cls: type, codes: str) -> dict[str, object]:
        hints = typing.get_type_hints(cls)
        names = [
            f.name for f in dataclasses.fields(cls) if f.name not in ("request_id", "operation")
        ]
        assert len(names) == len(codes), (cls, names, codes)  # one code per field
        for name, code in zip(names, codes, strict=True):
            kind = _FLOW_KINDS[code]
            entry: dict[str, object] = {
                "name": name,
                "size": struct.calcsize(">" + code),
                "kind": kind,
                "label": name.replace("_", " ").capitalize(),
            }
            if kind == "enum":
                members = hints[name]
                assert isinstance(members, type)
                assert issubclass(members, enum.IntEnum)
                entry["enum"] = members.__name__
            assert fields.get(name, entry) == entry, name  # one meaning per name
            fields[name] = entry
        return {"name": cls.__name__, "size": struct.calcsize(">" + codes), "fields": names}

    fixed: dict[int, object] = {
        int(cls.message) * 256 + int(cls.operation): layout(cls, codes)
        for cls, codes in flow._FIXED.items()
    }
    any_operation: dict[int, object] = {
        int(flow.Message.REQUEST): {"name": flow.UnknownRequest.__name__},
        int(flow.Message.NACK): layout(flow.Nack, _NACK_LAYOUT),
    }
    return list(fields.values()), fixed, any_operation


def _datastream() -> dict[str, object]:
    flow_fields, layouts, any_operation = _flow_layouts()
    return {
        "version": packets.VERSION,
        "ports": str(RCTP_PORT),
        "header": packets.HEADER.size,
        "payload_header": packets.PAYLOAD_HEADER.size,
        "max_payloads": packets.MAX_PAYLOADS,
        "max_datagram": packets.MAX_DATAGRAM,
        "payload_types": _names(packets.PayloadType, lower=False),
        "DATA": int(packets.PayloadType.DATA),
        "FLOW": int(packets.PayloadType.FLOW),
        "messages": _names(flow.Message),
        "message_names": _names(flow.Message, lower=False),
        "operations": _names(flow.Operation),
        "enums": {
            flow.Direction.__name__: _names(flow.Direction),
            flow.NackReason.__name__: _names(flow.NackReason),
        },
        "preamble": flow.PREAMBLE.size,
        "flow_fields": flow_fields,
        "layouts": layouts,
        "any_operation": any_operation,
        "rule": DATASTREAM_RULE,
        "flow_rule": FLOW_RULE,
    }


# -- RSP -------------------------------------------------------------------------------------------


def _part(name: str, part: object) -> dict[str, object]:
    """One part of a session body's layout: octets (a nonce, a MAC), a period in milliseconds,
    or a reason byte of an enum — told apart by what the codec makes of its wire value."""
    size = part.struct.size  # type: ignore[attr-defined]
    make = part.make  # type: ignore[attr-defined]
    entry: dict[str, object] = {"name": name, "size": size}
    if make is bytes:
        entry["kind"] = "octets"
    elif isinstance(make, type) and issubclass(make, enum.IntEnum):
        entry.update(kind="reason", enum=make.__name__, names=_names(make, lower=False))
    else:
        entry["kind"] = "period"
    return entry


def _session_bodies() -> tuple[dict[int, object], dict[str, object]]:
    out: dict[int, object] = {}
    mac: dict[str, object] | None = None
    for kind, cls in bodies.BODIES.items():
        if cls is bodies.MapBody:
            continue
        names = [f.name for f in dataclasses.fields(cls)]
        parts = cls.parts  # type: ignore[union-attr]
        out[int(kind)] = {
            "name": cls.__name__,
            "signed": cls.signed,  # type: ignore[union-attr]
            "parts": [_part(name, part) for name, part in zip(names, parts, strict=False)],
        }
        if cls.signed:  # type: ignore[union-attr]
            # The MAC part comes last, after the parts of the layout (D-RSP-21).
            assert names[-1] == "mac"
            assert len(names) == len(parts) + 1
            mac = {"name": "mac", "size": MAC_SIZE, "kind": "octets"}
    assert mac is not None
    return out, mac


def _rsp() -> dict[str, object]:
    session_bodies, mac = _session_bodies()
    kinds = list(header.PacketType)
    return {
        "version": header.VERSION,
        "ports": str(RSP_PORT),
        "header": HEADER_SIZE,
        "types": _names(kinds, lower=False),
        "type_count": len(header.SENDERS),
        "senders": {int(k): s.value for k, s in header.SENDERS.items()},
        "without_session": {int(k): True for k in sorted(header.WITHOUT_SESSION)},
        "plaintext": {int(k): True for k in sorted(SIGNED | header.WITHOUT_SESSION)},
        "map_types": {int(header.PacketType[p.name]): True for p in MapPacket},
        "encryptions": _names(header.Encryption, lower=False),
        "encryption_list": str(sorted(int(e) for e in header.Encryption)),
        "clear_buffer": header.CLEAR_BUFFER,
        "max_free_buffers": header.MAX_FREE_BUFFERS,
        "max_model_id": MAX_MODEL_ID,
        "tag_size": TAG_SIZE,
        "min_period_ms": bodies.MIN_PERIOD_MS,
        "max_period_ms": bodies.MAX_PERIOD_MS,
        "refused_reasons": _names(bodies.RefusedReason, lower=False),
        "bye_reasons": _names(bodies.ByeReason, lower=False),
        "bodies": session_bodies,
        "mac_part": mac,
        "header_rule": header.RULE,
        "body_rule": bodies.RULE,
        "map_rule": MAP_RULE,
        "sealed_rule": SEALED_RULE,
    }


def _types() -> dict[str, object]:
    """D-RCML-9: what a field of each type is on the wire."""
    out: dict[str, object] = {}
    for name, data_type in DATA_TYPES.items():
        entry: dict[str, object] = {"width": data_type.width, "kind": data_type.kind.value}
        if data_type.kind is Kind.INTEGER:
            entry["signed"] = data_type.low < 0
        if data_type.sized:
            entry["sized"] = True
        out[name] = entry
    return out


def abbreviation(name: str) -> str:
    """A model's name as part of a field abbreviation."""
    return _NOT_ABBREVIATION.sub("_", name) or "_"


def _unique(names: Iterable[tuple[str, int]]) -> dict[int, str]:
    """Abbreviations by position, each distinct: a name two share gets its position added."""
    wanted = [(abbreviation(name), position) for name, position in names]
    counts: dict[str, int] = {}
    for abbr, _ in wanted:
        counts[abbr] = counts.get(abbr, 0) + 1
    out: dict[int, str] = {}
    taken = {abbr for abbr, _ in wanted if counts[abbr] == 1}
    for abbr, position in wanted:
        if counts[abbr] > 1:
            candidate = f"{abbr}_{position}"
            while candidate in taken:
                candidate += "_"
            abbr = candidate
            taken.add(abbr)
        out[position] = abbr
    return out


def _bound(field: Field, value: int | float | None) -> object:
    """A field's `min` or `max` as Lua compares it with the values read (D-RCML-12)."""
    if value is None:
        return None
    base = field.type.base
    if base.kind is Kind.FLOAT:
        number = float(value)
        if base.name == "float32":  # the float32 value the bound's text reads as
            number = struct.unpack(">f", struct.pack(">f", number))[0]
        return number
    number = int(value)
    if base.width == 8:
        cls = "Int64" if base.low < 0 else "UInt64"
        return LuaExpression(f'{cls}.fromhex("{number & 0xFFFFFFFFFFFFFFFF:016x}")')
    return number


def field_abbreviations(model: RobotModel) -> list[tuple[str, list[str]]]:
    """Each device's abbreviation and its fields', in model order: the device's fields are
    `rcmlrsp.dev.DEVICE.FIELD` and its Device Map bit `rcmlrsp.map.DEVICE`."""
    devices = _unique((d.name, d.position) for d in model.devices)
    out = []
    for device in model.devices:
        fields = _unique((f.name, i) for i, f in enumerate(device.fields))
        out.append((devices[device.position], [fields[i] for i in range(len(device.fields))]))
    return out


def _model(model: RobotModel) -> dict[str, object]:
    abbreviations = field_abbreviations(model)
    devices = []
    for device in model.devices:
        device_abbr, fields_abbr = abbreviations[device.position]
        fields = []
        for index, field in enumerate(device.fields):
            entry: dict[str, object] = {
                "name": field.name,
                "abbr": fields_abbr[index],
                "type": field.type.base.name,
            }
            if field.type.is_array:
                entry["count"] = field.type.count
            if field.type.base.sized:
                entry["size"] = field.type.size
            if field.minimum is not None or field.maximum is not None:
                entry["min"] = _bound(field, field.minimum)
                entry["max"] = _bound(field, field.maximum)
                entry["min_text"] = str(field.minimum)
                entry["max_text"] = str(field.maximum)
            if field.unit is not None:
                entry["unit"] = field.unit
            fields.append(entry)
        devices.append(
            {
                "position": device.position,
                "name": device.name,
                "abbr": device_abbr,
                "kind": device.kind.value,
                "bits": {
                    packet.value: _BIT_NAMES[bit(device.kind, packet)] for packet in MapPacket
                },
                "fields": fields,
            }
        )
    return {
        "name": model.name,
        "model_id": model.model_id,
        "id_length": model.id_length,
        "command_buffers": model.command_buffers,
        "map_size": model.map_size,
        "devices": devices,
    }


_BIT_NAMES = {
    Bit.NEVER: "never",
    Bit.FLAG: "flag",
    Bit.STATE: "state",
    Bit.OCCURRENCE: "occurrence",
    Bit.ID: "id",
}


def _comment(text: str) -> str:
    return " ".join(text.split())


def generate_lua(model: RobotModel | None = None) -> str:
    """The whole plugin: a header, the generated `GEN` table, and the dissectors."""
    tables: dict[str, object] = {
        "generator": f"rcmlconf {__version__}",
        "rctp": _rctp(),
        "datastream": _datastream(),
        "rsp": _rsp(),
        "types": _types(),
        "value_rule": VALUE_RULE,
        "model": _model(model) if model is not None else None,
    }
    if model is None:
        about = (
            "-- Without a robot model: RSP packets show their header and session bodies, and the\n"
            "-- Device Map and payloads as bytes (`rcmlconf wireshark --model M` decodes them).\n"
        )
    else:
        about = (
            f"-- Robot model: {_comment(model.name)} (model ID {model.model_id},"
            f" {len(model.devices)} devices): RSP's Device Map and payloads are decoded.\n"
        )
    head = (
        "-- RCTP/2.0 and RSP dissectors for Wireshark, written by `rcmlconf wireshark`"
        f" (rcmlconf {__version__}).\n"
        "-- Generated from the definitions of rcmlconf's codecs (specs/rctp-2.0.md,\n"
        "-- specs/rsp.md): do not edit; generate it again.\n" + about + "--\n"
        "-- Use:    tshark -X lua_script:rcml.lua -r capture.pcap\n"
        "--         or copy it to ~/.local/lib/wireshark/plugins/ (personal Lua plugins).\n"
        f"-- Ports:  RCTP control TCP {RCTP_PORT}, its data stream UDP {RCTP_PORT},"
        f" RSP UDP {RSP_PORT}; others in\n"
        "--         the preferences (rctp.tcp_ports, rctpds.udp_ports, rcmlrsp.udp_ports), and by\n"
        "--         heuristics on any port.\n"
        "-- Filter: rctp, rctpds, rcmlrsp; rctp.method, rctp.status, rctp.cseq, rctpds.seq,\n"
        "--         rcmlrsp.type, rcmlrsp.seq, ...; malformed parts: rctp.malformed,\n"
        "--         rctpds.malformed, rcmlrsp.malformed (with .offset and .rule), and\n"
        "--         _ws.expert.severity == error.\n\n"
    )
    source = resources.files("rcmlconf.wireshark").joinpath("dissector.lua")
    body = source.read_text(encoding="utf-8")
    return head + "local GEN = " + lua_literal(tables) + "\n\n" + body
