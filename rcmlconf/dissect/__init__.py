"""The protocol analyser's fast path: `rcmlconf dissect` without scapy (issue 8).

A capture (`rcmlconf.pcap.reader`) goes frame by frame through the flow table (`dissector`),
each flow's protocol told by `classify` (which the scapy layers' `capture` shares):
TCP connections of RCTP are put in order (`tcp`) and framed by the core's `MessageReader`
(`control`), UDP datagrams of the data stream and of RSP are read by the core's codecs
(`datastream`, `rsp`). Each message becomes a `Record` handed to the caller as it is decoded;
streams, sessions and findings make the `Analysis` at the end. Every finding names the
requirement of specs/ it concerns. `output` gives both their text and JSON forms.

    from rcmlconf.dissect import Dissector, Options
    from rcmlconf.pcap.reader import Capture

    with Capture.open("run.pcap") as capture:
        analysis = Dissector(Options(), records.append).run(capture)
"""

from rcmlconf.dissect.context import Options
from rcmlconf.dissect.dissector import Analysis, CaptureReport, Dissector
from rcmlconf.dissect.records import (
    PROTOCOLS,
    RCTP,
    RCTP_DATA,
    RSP,
    Endpoints,
    Finding,
    Malformed,
    Record,
    Severity,
)

__all__ = [
    "PROTOCOLS",
    "RCTP",
    "RCTP_DATA",
    "RSP",
    "Analysis",
    "CaptureReport",
    "Dissector",
    "Endpoints",
    "Finding",
    "Malformed",
    "Options",
    "Record",
    "Severity",
]
