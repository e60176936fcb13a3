"""The oracles of the server role (D-FUZZ-4): crash, hang and violation, from one case's
outcome. The leak oracle watches the target's process (`monitor.LeakWatch`).

A violation is what the dissector, the same analysis `rcmlconf dissect` gives a capture, finds
wrong (a MUST, severity error) in a message the target sent: the case's traffic is written as
a capture in memory and read back. So the fuzzer judges an answer as every other tool of ours
does, and never by a second parser.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass

from rcmlconf.dissect.context import Options
from rcmlconf.dissect.dissector import Dissector
from rcmlconf.dissect.records import Record, Severity
from rcmlconf.fuzz.owed import UNFRAMED
from rcmlconf.fuzz.rctp_exec import Address, Outcome
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.writer import Payload, write_pcap
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rsp.model import RobotModel

CRASH, HANG, VIOLATION, LEAK = "crash", "hang", "violation", "leak"
ORACLES = (CRASH, HANG, VIOLATION, LEAK)


@dataclass(frozen=True, slots=True)
class Verdict:
    """What an oracle found: its kind, the requirement broken, and what happened."""

    oracle: str
    rule: str
    text: str


def judge(out: Outcome, robot: RcmlDocument | None, port: int) -> Verdict | None:
    """The first oracle that fires on `out`; None when the target did all it owed."""
    due = out.due
    if out.end in ("closed", "reset") and due:
        framed = [text for text in due if not text.startswith(UNFRAMED)]
        if framed:
            how = "reset" if out.end == "reset" else "closed"
            return Verdict(
                CRASH, "R-RCTP-5", f"the target {how} the connection before answering {framed[0]}"
            )
        if out.end == "closed":
            return Verdict(VIOLATION, "R-RCTP-8", f"the target closed without answering {due[0]}")
    if out.unanswered is not None and out.end == "open":
        text = f"no answer to {out.unanswered} within the wait, the connection open"
        if out.unanswered.startswith(UNFRAMED):
            return Verdict(VIOLATION, "R-RCTP-8", text)
        return Verdict(HANG, "R-RCTP-5", text)
    if out.garbled is not None:
        return Verdict(VIOLATION, "R-RCTP-1", f"an answer that cannot be framed: {out.garbled}")
    return violation(out.payloads, out.ours, robot, port)


def violation(
    payloads: Sequence[Payload],
    ours: set[Address],
    robot: RcmlDocument | None,
    port: int,
    *,
    model: RobotModel | None = None,
) -> Verdict | None:
    """The first MUST the dissector finds broken in a message the target sent (not from
    `ours`, the fuzzer's own addresses): an RCTP/2.0 server's on `port`, or with `model` an
    RSP robot's."""
    if not payloads:
        return None
    file = io.BytesIO()
    write_pcap(file, payloads)
    records: list[Record] = []
    protocol = "rctp" if model is None else "rsp"
    options = Options(rcml=robot, rsp_model=model, decode_as=((protocol, port),), heuristics=False)
    analysis = Dissector(options, records.append).run(Capture(file.getvalue(), "<case>"))
    theirs = {f"{host}:{number}" for host, number in {p.source for p in payloads} - ours}
    sources = {record.number: record.flow.source for record in records}
    for finding in analysis.findings:
        if finding.severity is Severity.ERROR and sources.get(finding.message) in theirs:
            return Verdict(VIOLATION, finding.rule, finding.text)
    return None
