"""A record as one line of JSON Lines: `record_json`'s object, written by `JsonFormat`."""

from __future__ import annotations

import json
from typing import Any

from rcmlconf.dissect.control_results import Answer, BodyValues
from rcmlconf.dissect.output.decimal_texts import decimal_texts
from rcmlconf.dissect.output.fields_json import control_json, packet_json, rsp_json, value_json
from rcmlconf.dissect.records import RCTP, RCTP_DATA, RSP, Record
from rcmlconf.rsp.codec.header import Encryption
from rcmlconf.rsp.model import RobotModel

#: An RSP header's encryption, and the key of its body kept as bytes, as the vectors write them.
_ENCRYPTIONS = {member: member.name for member in Encryption}
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
        self._decimal = decimal_texts()
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
