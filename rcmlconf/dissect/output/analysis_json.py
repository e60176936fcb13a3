"""The analysis as JSON: the object of `dissect --format json`'s last line."""

from __future__ import annotations

import math
from typing import Any

from rcmlconf.dissect.dissector import Analysis


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
