"""The analysis as text: (text, rich style) lines, the last part of `dissect`'s text output."""

from __future__ import annotations

from collections.abc import Iterator

from rcmlconf.dissect.control_results import ControlReport
from rcmlconf.dissect.datastream import HeartbeatReport
from rcmlconf.dissect.dissector import Analysis
from rcmlconf.dissect.records import LABELS, RCTP_DATA, Finding, Severity
from rcmlconf.dissect.rsp import RspSessionReport
from rcmlconf.dissect.streams import StreamReport
from rcmlconf.wording import plural


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
