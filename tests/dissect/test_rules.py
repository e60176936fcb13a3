"""Every requirement and decision the dissector names exists in specs/, and every finding of a
dissection names a requirement."""

from __future__ import annotations

import re
from pathlib import Path

from support.pcaps import TcpFlow, dissect, ipv4_udp, pcap

from rcmlconf.specs import decisions, requirements

SOURCES = [
    *sorted((Path(__file__).parents[2] / "rcmlconf" / "dissect").glob("*.py")),
    Path(__file__).parents[2] / "rcmlconf" / "cli" / "dissect.py",
]


def test_every_id_named_in_the_code_exists() -> None:
    known_requirements = requirements()
    known_decisions = decisions()
    for path in SOURCES:
        text = path.read_text(encoding="utf-8")
        for found in re.findall(r"R-[A-Z]+-\d+", text):
            assert found in known_requirements, (path.name, found)
        for found in re.findall(r"D-[A-Z]+-\d+", text):
            assert found in known_decisions, (path.name, found)


def test_findings_name_requirements() -> None:
    flow = TcpFlow(("10.0.0.2", 40000), ("10.0.0.7", 7330)).handshake()
    flow.send(flow.client, b"READ /a RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(flow.server, b"RCTP/2.0 200 OK\r\nCSeq: 1\r\n\r\n")
    flow.send(flow.client, b"GO /a RCTP/2.0\r\n\r\n")
    frames = [*flow.frames, (flow.time + 1, ipv4_udp(("10.0.0.2", 1), ("10.0.0.7", 7340), b"\1"))]
    analysis = dissect(pcap(frames)).analysis
    known = requirements()
    assert len(analysis.findings) >= 3
    assert all(finding.rule in known for finding in analysis.findings)
