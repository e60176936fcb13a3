"""A message's full field tree as JSON, in the form of the vectors (vectors/rctp/README.md,
vectors/rsp/README.md): NTP times and tags as hexadecimal strings, bytes as hexadecimal."""

from __future__ import annotations

import math
from typing import Any

from rcmlconf.dissect.datastream import DataValues
from rcmlconf.dissect.rsp import RspPacket
from rcmlconf.rctp.datastream.flow import FlowMessage, Message, Operation
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    Payload,
)
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rsp.codec.bodies import Bye, Hello, MapBody, Period, Refused, Welcome
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import Value

#: The FLOW fields that are NTP timestamps (T1, T2, T3 of D-RCTP-24): hexadecimal, as the vectors.
_TIMES = frozenset({"t1", "t2", "t3"})


def control_json(message: Request | Response) -> dict[str, Any]:
    if isinstance(message, Request):
        head: dict[str, Any] = {"method": message.method, "target": message.target}
    else:
        head = {"status": message.status, "reason": message.reason}
    return {
        **head,
        "version": message.version,
        "headers": [list(field) for field in message.headers],
        "body": message.body.hex(),
    }


def packet_json(packet: Packet, extra: Any = None) -> dict[str, Any]:
    """A data-stream packet as vectors/rctp/README.md writes one."""
    shown = extra.values if isinstance(extra, DataValues) else None
    payloads = []
    for index, payload in enumerate(packet.payloads):
        item = payload_json(payload)
        if shown is not None and shown[index] is not None:
            access, direction, values = shown[index]  # type: ignore[misc]
            item["values"] = {
                "access": access.split(" (")[0],
                "direction": direction,
                "values": {name: value_json(v) for name, v in values.items()},
            }
        payloads.append(item)
    return {
        "sequence": packet.sequence,
        "tag": f"{packet.tag:08x}",
        "timestamp": f"{packet.timestamp:016x}",
        "payloads": payloads,
    }


def payload_json(payload: Payload) -> dict[str, Any]:
    if isinstance(payload, DataPayload):
        return {"type": "DATA", "stream": payload.stream, "body": payload.body.hex()}
    if isinstance(payload, FlowPayload):
        return {"type": "FLOW", "stream": payload.stream, "flow": flow_json(payload.flow)}
    if isinstance(payload, MalformedFlowPayload):
        return {
            "type": "FLOW",
            "stream": payload.stream,
            "body": payload.body.hex(),
            "malformed": {"reason": payload.reason, "offset": payload.offset, "rule": payload.rule},
        }
    return {"type": payload.type, "stream": payload.stream, "body": payload.body.hex()}


def _spoken(value: Any) -> Any:
    return value.name.lower().replace("_", " ") if hasattr(value, "name") else value


def flow_json(flow: FlowMessage) -> dict[str, Any]:
    shown: dict[str, Any] = {"message": _spoken(Message(flow.message))}
    try:
        shown["operation"] = _spoken(Operation(flow.operation))
    except ValueError:
        shown["operation"] = flow.operation
    for name in flow.__slots__:
        if name == "operation":
            continue
        value = getattr(flow, name)
        if name in _TIMES:
            value = f"{value:016x}"
        elif isinstance(value, bytes):
            value = value.hex()
        shown[name] = _spoken(value) if name in ("direction", "reason") else value
    return shown


def value_json(value: Value) -> Any:
    """A value as the vectors write one: bytes as hex, non-finite floats as strings."""
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("INF" if value > 0 else "-INF")
    if isinstance(value, tuple | list):
        return [value_json(v) for v in value]
    return value


def rsp_json(packet: RspPacket, model: RobotModel | None) -> dict[str, Any]:
    """An RSP packet as vectors/rsp/README.md writes one."""
    header, body = packet
    head = header._asdict()
    head["encryption"] = header.encryption.name
    head["type"] = header.type.name
    shown: dict[str, Any]
    if type(body) is bytes:
        shown = {"encrypted" if header.encryption else "bytes": body.hex()}
    elif isinstance(body, MapBody):
        items = []
        for item in body.items:
            one: dict[str, Any] = {
                "device": model.devices[item.device].name if model is not None else item.device
            }
            if item.id is not None:
                one["id"] = item.id
            if item.values is not None:
                one["values"] = {name: value_json(v) for name, v in item.values.items()}
            items.append(one)
        shown = {"items": items}
    elif isinstance(body, Refused | Bye):
        shown = {"reason": body.reason.name}
    elif isinstance(body, Period):
        shown = {"period_ms": body.period_ms}
    elif isinstance(body, Hello | Welcome):
        shown = {"client_nonce": body.client_nonce.hex()}
        if isinstance(body, Welcome):
            shown["robot_nonce"] = body.robot_nonce.hex()
        shown.update(period_ms=body.period_ms, mac=body.mac.hex())
    else:
        shown = {}
    return {"header": head, "body": shown}
