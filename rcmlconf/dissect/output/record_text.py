"""A record's summary line: `number seconds source → destination PROTOCOL kind key fields`."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from rcmlconf.dissect.control_results import Answer, BodyValues
from rcmlconf.dissect.datastream import DataValues
from rcmlconf.dissect.output.decimal_texts import decimal_texts
from rcmlconf.dissect.records import RCTP, RCTP_DATA, RSP, Record
from rcmlconf.rctp.datastream.flow import FlowMessage, Message, Operation
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    UnknownPayload,
)
from rcmlconf.rctp.messages import Request
from rcmlconf.rsp.codec.bodies import Bye, Hello, MapBody, Period, Refused, Welcome
from rcmlconf.rsp.codec.header import Encryption
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import Value

#: Header fields a summary line shows, in this order.
_SHOWN_FIELDS = ("Session", "Transport", "Nodes", "Reason", "Allow")
#: What a summary line calls an RSP body it shows as bytes.
_BODY_WORD = {member: member.name if member else "body" for member in Encryption}


class TextFormat:
    """Summary lines; times are seconds from the first frame of the capture (`base`).

    Made for a million lines a run: the number is not padded, and the hexadecimal of tags and
    session IDs (which change once a session) is kept, since formatting is most of a line's cost.
    """

    def __init__(
        self, model: RobotModel | None = None, base: float | None = None, decimals: int = 6
    ) -> None:
        #: The time lines count from: the capture's first frame, else the first record's.
        self.base = base
        self.model = model
        self._time = f"%.{decimals}f"
        self._decimal = decimal_texts()
        self._hex8: dict[int, str] = {}
        self._hex12: dict[int, str] = {}
        self._details: dict[str, Callable[[Record], str]] = {
            RCTP: self._control,
            RCTP_DATA: self._datastream,
            RSP: self._rsp,
        }

    def line(self, record: Record) -> str:
        number, _, time, flow, kind, _, value, malformed, extra = record
        base = self.base
        if base is None:
            base = self.base = time
        if malformed is not None:
            where = f"byte {malformed.offset}" + (
                f", file byte {malformed.file_offset}" if malformed.file_offset is not None else ""
            )
            detail = f"{kind} malformed: {malformed.reason} ({where}) [{malformed.rule}]"
        elif extra is None and kind == "DATA" and flow.protocol == RCTP_DATA:
            # The data stream's common case, a packet of one DATA payload, without a call.
            seq, tag_id, _, (payload,) = value
            tag = self._hex8.get(tag_id) or self._tag(tag_id)
            decimal = self._decimal
            return (
                f"{number} {self._time % (time - base)} {flow.text} DATA seq={decimal[seq]}"
                f" tag={tag} s{decimal[payload.stream]}:{decimal[len(payload.body)]}B"
            )
        elif flow.protocol == RSP and type(value.body) is bytes:
            _, _, encryption, _, seq, stamp, session_id, last, buffer = value.header
            session = self._hex12.get(session_id) or self._session(session_id)
            decimal = self._decimal
            return (
                f"{number} {self._time % (time - base)} {flow.text} {kind} seq={decimal[seq]}"
                f" ts={stamp} session={session} last={decimal[last]} buffer={decimal[buffer]}"
                f" {_BODY_WORD[encryption]}={decimal[len(value.body)]}B"
            )
        else:
            detail = self._details[flow.protocol](record)
        return f"{number} {self._time % (time - base)} {flow.text} {detail}"

    def _tag(self, tag: int) -> str:
        text = self._hex8[tag] = f"{tag:08x}"
        return text

    def _session(self, session: int) -> str:
        text = self._hex12[session] = f"{session:012x}"
        return text

    # -- RCTP ------------------------------------------------------------------------------------

    @staticmethod
    def _control(record: Record) -> str:
        message = record.value
        parts = []
        if isinstance(message, Request):
            parts.append(f"{message.method} {message.target}")
            if message.version != "RCTP/2.0":
                parts.append(message.version)
        else:
            parts.append(record.kind)
        parts.append(f"CSeq={record.sequence}" if record.sequence is not None else "CSeq=?")
        answer = record.extra
        values = None
        if isinstance(answer, Answer):
            parts.append(f"({answer.request.method}, {answer.elapsed * 1000:.3f} ms)")
            values = answer.values
        elif isinstance(answer, BodyValues):
            values = answer.values
        for name in _SHOWN_FIELDS:
            value = message.headers.get(name)
            if value is not None:
                if name == "Session" and len(value) > 12:
                    rest = value[value.find(";") :] if ";" in value else ""
                    value = value[:8] + "…" + rest
                parts.append(f"{name}={value}")
        if values is not None:
            parts.append(f"{{{_values_text(values)}}}")
        elif message.body:
            parts.append(f"body={len(message.body)} B")
        return " ".join(parts)

    # -- the data stream ---------------------------------------------------------------------------

    @staticmethod
    def _datastream(record: Record) -> str:
        packet: Packet = record.value
        shown = record.extra.values if isinstance(record.extra, DataValues) else None
        parts = [f"{record.kind} seq={packet.sequence} tag={packet.tag:08x}"]
        for index, payload in enumerate(packet.payloads):
            kind = type(payload)
            if kind is DataPayload:
                assert isinstance(payload, DataPayload)
                values = shown[index] if shown is not None else None
                if values is not None:
                    access, _, decoded = values
                    parts.append(f"s{payload.stream} {access}: {_values_text(decoded)}")
                else:
                    parts.append(f"s{payload.stream}:{len(payload.body)}B")
            elif kind is FlowPayload:
                assert isinstance(payload, FlowPayload)
                parts.append(f"s{payload.stream}:{_flow_text(payload.flow)}")
            elif kind is MalformedFlowPayload:
                assert isinstance(payload, MalformedFlowPayload)
                parts.append(f"s{payload.stream}:FLOW malformed ({payload.reason}) [R-RCTP-52]")
            else:
                assert isinstance(payload, UnknownPayload)
                parts.append(f"s{payload.stream}:type {payload.type} {len(payload.body)}B")
        return " ".join(parts)

    # -- RSP -----------------------------------------------------------------------------------

    def _rsp(self, record: Record) -> str:
        header, body = record.value
        text = (
            f"{record.kind} seq={header.sequence} ts={header.timestamp}"
            f" session={header.session_id:012x} last={header.last_received}"
            f" buffer={header.buffer}"
        )
        if type(body) is MapBody:
            model = self.model
            if model is None or not body.items:
                return f"{text} items={len(body.items)}"
            return f"{text} " + " ".join(_item_text(model, item) for item in body.items)
        if type(body) is bytes:
            return f"{text} body={len(body)}B"
        return f"{text} {_session_body_text(body)}"


def _values_text(values: dict[str, Value]) -> str:
    return " ".join(f"{name}={_value_text(value)}" for name, value in values.items())


def _value_text(value: Value) -> str:
    if isinstance(value, bytes):
        return value.hex() if len(value) <= 16 else f"{value[:16].hex()}…({len(value)}B)"
    if isinstance(value, tuple):
        inner = ",".join(_value_text(v) for v in value[:8])
        return f"[{inner}{',…' if len(value) > 8 else ''}]"
    if isinstance(value, str):
        return json.dumps(value if len(value) <= 40 else value[:40] + "…", ensure_ascii=False)
    if isinstance(value, float):
        text = repr(value)
        # A float32's exact value in a float64 is long: the shortest that reads back as float32.
        return text if len(text) <= 10 else f"{value:.7g}"
    return str(value)


def _item_text(model: RobotModel, item: Any) -> str:
    name: str = model.devices[item.device].name
    if item.id is not None:
        name += f"#{item.id}"
    if item.values is None:
        return name
    return f"{name}{{{_values_text(item.values)}}}"


def _session_body_text(body: Any) -> str:
    if isinstance(body, Hello):
        return f"nonce={body.client_nonce[:4].hex()}… period={body.period_ms}ms"
    if isinstance(body, Welcome):
        return f"nonce={body.client_nonce[:4].hex()}… period={body.period_ms}ms"
    if isinstance(body, Refused | Bye):
        return f"reason={body.reason.name}"
    if isinstance(body, Period):
        return f"period={body.period_ms}ms"
    return ""


def _flow_text(flow: FlowMessage) -> str:
    message = Message(flow.message).name.lower()
    try:
        operation = Operation(flow.operation).name.lower().replace("_", " ")
    except ValueError:
        operation = f"operation {flow.operation}"
    text = f"FLOW {operation} {message} #{flow.request_id}"
    for name in ("direction", "interval", "timeout", "reason"):
        value = getattr(flow, name, None)
        if value is not None:
            text += f" {name}={value.name.lower() if hasattr(value, 'name') else value}"
    return text
