"""The text and JSON forms of records and of the analysis.

Text: one summary line per message —

    number  seconds  source → destination  PROTOCOL  method/status/type  key fields

then the analysis. JSON: JSON Lines, one object per message (`record_json`), then one last object
whose only key is `"analysis"` (`analysis_json`). A message's `"fields"` is its full field tree,
in the form of the vectors (vectors/rctp/README.md, vectors/rsp/README.md): a data-stream packet
as `{"sequence", "tag", "timestamp", "payloads"}`, an RSP packet as `{"header", "body"}`, with NTP
times and tags as hexadecimal strings and bytes as hexadecimal.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from functools import cache
from typing import Any

from rcmlconf.dissect.control_results import Answer, BodyValues, ControlReport
from rcmlconf.dissect.datastream import DataValues, HeartbeatReport
from rcmlconf.dissect.dissector import Analysis
from rcmlconf.dissect.records import LABELS, RCTP, RCTP_DATA, RSP, Finding, Record, Severity
from rcmlconf.dissect.rsp import RspPacket, RspSessionReport
from rcmlconf.dissect.streams import StreamReport
from rcmlconf.rctp.datastream.flow import FlowMessage, Message, Operation
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    Payload,
    UnknownPayload,
)
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rsp.codec.bodies import Bye, Hello, MapBody, Period, Refused, Welcome
from rcmlconf.rsp.codec.header import Encryption
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import Value
from rcmlconf.wording import plural

_TIMES = frozenset({"t1", "t2", "t3"})
#: Header fields a summary line shows, in this order.
_SHOWN_FIELDS = ("Session", "Transport", "Nodes", "Reason", "Allow")


@cache
def _decimals() -> tuple[str, ...]:
    """The decimal text of 0 to 65,535, the fields of 16 bits and fewer (sequence numbers,
    lengths, stream ids, ...): taken from here, a number of a line costs a fifth of writing it,
    and a line's numbers cost more than the rest of it. Made once, when the first `TextFormat`
    or `JsonFormat` is (4 MB, 10 ms)."""
    return tuple(map(str, range(1 << 16)))


# -- text ------------------------------------------------------------------------------------------


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
        self._decimal = _decimals()
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


# -- JSON --------------------------------------------------------------------------------------

_ENCRYPTIONS = {member: member.name for member in Encryption}
#: What a summary line calls an RSP body it shows as bytes.
_BODY_WORD = {member: member.name if member else "body" for member in Encryption}
_BODY_KEY = {member: "encrypted" if member else "bytes" for member in Encryption}
#: One compact line per message.
_dumps = json.JSONEncoder(ensure_ascii=False, separators=(",", ":")).encode
#: An NTP timestamp as the vectors write one (`%` costs two thirds of an f-string's `:016x`).
_hex16 = "%016x"


class JsonFormat:
    """One JSON object per message, on one line: `record_json`'s, written by hand for the common
    packets (a data-stream packet of one DATA payload, an RSP packet whose body stays bytes),
    several times faster than `json` writes them. Their time is written with the capture's
    decimals (6 for microsecond stamps, 9 for nanosecond ones), not `repr`'s shortest form: it
    reads back as the same float."""

    def __init__(self, model: RobotModel | None = None, decimals: int = 6) -> None:
        self.model = model
        self._time = f"%.{decimals}f"
        self._decimal = _decimals()
        self._tags: dict[int, str] = {}
        self._sessions: dict[int, str] = {}

    def line(self, record: Record) -> str:
        number, frame, time, flow, kind, _, value, malformed, extra = record
        if malformed is None and extra is None:
            protocol = flow.protocol
            if kind == "DATA" and protocol == RCTP_DATA:
                sequence, tag_id, timestamp, (payload,) = value
                tag = self._tags.get(tag_id) or self._tag(tag_id)
                seq = self._decimal[sequence]
                return (
                    f'{{"number":{number},"frame":{frame},"time":{self._time % time},'
                    f'{flow.json},"type":"DATA","sequence":{seq},'
                    f'"fields":{{"sequence":{seq},"tag":"{tag}",'
                    f'"timestamp":"{_hex16 % timestamp}","payloads":[{{"type":"DATA",'
                    f'"stream":{self._decimal[payload.stream]},"body":"{payload.body.hex()}"}}]}}}}'
                )
            if protocol == RSP:
                header, body = value
                if type(body) is bytes:
                    version, model_id, encryption, _, sequence, stamp, session_id, last, buffer = (
                        header
                    )
                    decimal = self._decimal
                    seq = decimal[sequence]
                    session = self._sessions.get(session_id) or self._session(session_id)
                    return (
                        f'{{"number":{number},"frame":{frame},"time":{self._time % time},'
                        f'{flow.json},"type":"{kind}","sequence":{seq},'
                        f'"fields":{{"header":{{"version":{decimal[version]},'
                        f'"model_id":{decimal[model_id]},"encryption":"{_ENCRYPTIONS[encryption]}",'
                        f'"type":"{kind}","sequence":{seq},"timestamp":{stamp},"session_id":{session},'
                        f'"last_received":{decimal[last]},"buffer":{decimal[buffer]}}},'
                        f'"body":{{"{_BODY_KEY[encryption]}":"{body.hex()}"}}}}}}'
                    )
        return _dumps(record_json(record, self.model))

    def _tag(self, tag: int) -> str:
        text = self._tags[tag] = f"{tag:08x}"
        return text

    def _session(self, session_id: int) -> str:
        text = self._sessions[session_id] = str(session_id)
        return text


def record_json(record: Record, model: RobotModel | None = None) -> dict[str, Any]:
    """One message as JSON (one line of the JSON Lines output)."""
    shown: dict[str, Any] = {
        "number": record.number,
        "frame": record.frame,
        "time": record.time,
        "source": record.flow.source,
        "destination": record.flow.destination,
        "protocol": record.flow.protocol,
        "type": record.kind,
        "sequence": record.sequence,
    }
    value = record.value
    protocol = record.flow.protocol
    if value is not None:
        if protocol == RCTP:
            shown["fields"] = control_json(value)
            extra = record.extra
            values = None
            if isinstance(extra, Answer):
                shown["answers"] = {
                    "method": extra.request.method,
                    "message": extra.message,
                    "elapsed": extra.elapsed,
                }
                values = extra.values
            elif isinstance(extra, BodyValues):
                values = extra.values
            if values is not None:
                shown["values"] = {name: value_json(v) for name, v in values.items()}
        elif protocol == RCTP_DATA:
            shown["fields"] = packet_json(value, record.extra)
        else:
            shown["fields"] = rsp_json(value, model)
    malformed = record.malformed
    if malformed is not None:
        shown["malformed"] = {
            "reason": malformed.reason,
            "offset": malformed.offset,
            "rule": malformed.rule,
            "file_offset": malformed.file_offset,
        }
    return shown


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


# -- the analysis --------------------------------------------------------------------------------


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1000:.3f} ms"


def analysis_lines(analysis: Analysis) -> Iterator[tuple[str, str]]:
    """The analysis as (text, rich style) lines."""
    capture = analysis.capture
    span = (
        f", {capture.last - capture.first:.6f} s"
        if capture.first is not None and capture.last is not None
        else ""
    )
    messages = ", ".join(f"{LABELS[p]} {n:,}" for p, n in capture.messages.items()) or "none"
    yield "", ""
    yield "Analysis", "bold"
    yield (
        (
            f"  capture {capture.name} ({capture.format}): {plural(capture.frames, 'frame')}{span};"
            f" messages: {messages}; {plural(capture.other, 'frame')} of other traffic"
        ),
        "",
    )
    if capture.error is not None:
        offset, reason = capture.error
        yield f"  the file cannot be read past byte {offset}: {reason}", "bold red"
    for frame, offset, reason in capture.problems:
        yield f"  frame {frame} (file byte {offset}): {reason}", "yellow"
    if capture.problems_left_out:
        yield f"  ... and {plural(capture.problems_left_out, 'more frame')} like these", "yellow"
    if analysis.control:
        yield "RCTP control connections", "bold"
        for control in analysis.control:
            yield from _control_lines(control)
    if analysis.streams:
        yield "Streams (one sender's packets of one session)", "bold"
        for stream in analysis.streams:
            yield from _stream_lines(stream)
    if analysis.heartbeats:
        yield "Heartbeats and clocks (D-RCTP-24)", "bold"
        for beats in analysis.heartbeats:
            yield from _heartbeat_lines(beats)
    if analysis.rsp_sessions:
        yield "RSP sessions", "bold"
        for session in analysis.rsp_sessions:
            yield from _rsp_lines(session)
    left = sum(analysis.left_out.values())
    yield (
        (
            f"Findings: {plural(len(analysis.findings) + left, 'finding')}"
            f" ({plural(analysis.errors, 'error')})"
        ),
        "bold",
    )
    for finding in analysis.findings:
        yield finding_text(finding), _STYLE[finding.severity]
    for (severity, rule), count in sorted(analysis.left_out.items(), key=lambda i: i[0][1]):
        yield f"  ... and {plural(count, 'more ' + severity.value)} [{rule}]", _STYLE[severity]


_STYLE = {Severity.ERROR: "bold red", Severity.WARNING: "yellow", Severity.NOTE: ""}


def finding_text(finding: Finding) -> str:
    where = []
    if finding.frame:
        where.append(f"frame {finding.frame}")
    if finding.message:
        where.append(f"message {finding.message}")
    if finding.file_offset is not None:
        where.append(f"file byte {finding.file_offset}")
    at = f" ({', '.join(where)})" if where else ""
    return f"  {finding.severity.value}: [{finding.rule}] {finding.text}{at}"


def _control_lines(control: ControlReport) -> Iterator[tuple[str, str]]:
    session = control.session or "no session"
    timeout = f", timeout {control.timeout} s" if control.timeout is not None else ""
    yield (
        (
            f"  {control.client} → {control.server}: session {session}{timeout}, state"
            f" {control.state}; {plural(control.requests, 'request')},"
            f" {plural(control.responses, 'response')}"
            + (f", {control.malformed} malformed" if control.malformed else "")
        ),
        "",
    )
    if control.retransmissions or control.out_of_order or control.holes:
        yield (
            (
                f"    TCP: {plural(control.retransmissions, 'retransmission')},"
                f" {control.out_of_order} out of order, {plural(control.holes, 'hole')} [R-RCTP-13]"
            ),
            "",
        )
    for method, (count, low, median, high) in control.response_times.items():
        yield (
            (
                f"    {method}: {count} answered, request to response {_ms(low)} min,"
                f" {_ms(median)} median, {_ms(high)} max [R-RCTP-5]"
            ),
            "",
        )
    for path, state in control.streams.items():
        yield f"    access {path}: {state} [R-RCTP-20]", ""


def _stream_lines(stream: StreamReport) -> Iterator[tuple[str, str]]:
    label = f" ({stream.label})" if stream.label else ""
    kind = "tag" if stream.protocol == RCTP_DATA else "session"
    yield (
        (
            f"  {LABELS[stream.protocol]} {stream.source} → {stream.destination} {kind}"
            f" {stream.session}{label}: {plural(stream.packets, 'packet')},"
            f" {plural(stream.bytes, 'byte')}, {stream.lost} lost, {stream.late} late (reordered),"
            f" {plural(stream.duplicates, 'duplicate')}, {plural(stream.gaps, 'gap')}"
            + (f" (largest {stream.largest_gap})" if stream.gaps else "")
            + f"; jitter {_ms(stream.jitter)}, inter-arrival {_ms(stream.interarrival_mean)} mean,"
            f" {_ms(stream.interarrival_max)} max [{stream.rule}]"
        ),
        "",
    )


def _heartbeat_lines(beats: HeartbeatReport) -> Iterator[tuple[str, str]]:
    trip = (
        f"round trip {_ms(beats.round_trip[0])} min, {_ms(beats.round_trip[1])} median,"
        f" {_ms(beats.round_trip[2])} max"
        if beats.round_trip is not None
        else "no round trip"
    )
    clock = beats.clock
    offset = (
        f"; {beats.answerer}'s clock {clock.offset * 1000:+.3f} ms ± {clock.uncertainty * 1000:.3f}"
        f" ms from the capture's (δ {_ms(clock.delay)}, best of {clock.samples})"
        if clock is not None
        else ""
    )
    yield (
        (
            f"  tag {beats.tag} {beats.requester} → {beats.answerer}:"
            f" {plural(beats.requests, 'request')},"
            f" {beats.answered} answered; {trip}{offset} [R-RCTP-50]"
        ),
        "",
    )


def _rsp_lines(session: RspSessionReport) -> Iterator[tuple[str, str]]:
    periods = " → ".join(f"{p} ms" for p in session.periods) or "-"
    ended = session.ended or "not ended in the capture"
    yield (
        (
            f"  session {session.session}: {session.local} ⇄ {session.robot}, model"
            f" {session.model_id}, {session.encryption}, period {periods}; HELLO to WELCOME"
            f" {_ms(session.handshake)} ({plural(session.hellos, 'HELLO')}); {ended} [R-RSP-20]"
        ),
        "",
    )
    if session.occurrences:
        ack = session.ack_time
        times = (
            f", first send to ACK {_ms(ack[0])} min, {_ms(ack[1])} median, {_ms(ack[2])} max"
            if ack is not None
            else ""
        )
        yield (
            (
                f"    reliable occurrences: {session.occurrences} sent,"
                f" {session.acknowledged} acknowledged, {session.repeated} retransmitted"
                f" ({plural(session.resends, 'resend')}){times} [R-RSP-26]"
            ),
            "",
        )


def analysis_json(analysis: Analysis) -> dict[str, Any]:
    capture = analysis.capture
    return {
        "capture": {
            "name": capture.name,
            "format": capture.format,
            "frames": capture.frames,
            "first": capture.first,
            "last": capture.last,
            "messages": capture.messages,
            "other": capture.other,
            "problems": [
                {"frame": f, "file_offset": o, "reason": r} for f, o, r in capture.problems
            ],
            "problems_left_out": capture.problems_left_out,
            "error": (
                {"file_offset": capture.error[0], "reason": capture.error[1]}
                if capture.error is not None
                else None
            ),
        },
        "control": [_asdict(c) for c in analysis.control],
        "streams": [_asdict(s) for s in analysis.streams],
        "heartbeats": [
            {
                **_asdict(h, skip=("clock",)),
                "clock": (
                    {
                        "offset": h.clock.offset,
                        "delay": h.clock.delay,
                        "uncertainty": h.clock.uncertainty,
                        "samples": h.clock.samples,
                    }
                    if h.clock is not None
                    else None
                ),
            }
            for h in analysis.heartbeats
        ],
        "rsp_sessions": [_asdict(s) for s in analysis.rsp_sessions],
        "findings": [
            {
                "severity": f.severity.value,
                "rule": f.rule,
                "text": f.text,
                "frame": f.frame,
                "time": f.time,
                "message": f.message,
                "file_offset": f.file_offset,
            }
            for f in analysis.findings
        ],
        "left_out": [
            {"severity": s.value, "rule": r, "count": n}
            for (s, r), n in sorted(analysis.left_out.items(), key=lambda i: i[0][1])
        ],
        "errors": analysis.errors,
    }


def _asdict(report: Any, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    out = {}
    for name in report.__slots__:
        if name in skip:
            continue
        value = getattr(report, name)
        if isinstance(value, float) and not math.isfinite(value):
            value = None
        out[name] = value
    return out
