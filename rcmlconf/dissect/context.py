"""What the protocol decoders of one dissection share: options, output, findings, registries."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from rcmlconf.dissect.classify import Classifier
from rcmlconf.dissect.records import Finding, Record, Severity
from rcmlconf.dissect.streams import Stream
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rctp.fields import Transport
from rcmlconf.rsp.model import RobotModel

#: Findings kept of each (severity, rule); the rest are counted (a capture of a million broken
#: packets would otherwise keep a million findings).
FINDINGS_KEPT = 200


@dataclass(frozen=True, slots=True)
class Options:
    """How to dissect. `decode_as` maps ports to protocols (`rctp`, `rctp-data`, `rsp`), before
    the default ports and the ports learned from SETUP."""

    rsp_model: RobotModel | None = None
    rcml: RcmlDocument | None = None
    decode_as: tuple[tuple[str, int], ...] = ()
    #: Recognise our protocols on other ports by their first packet (a valid RSP header, a valid
    #: data-stream packet, an RCTP start line), as Wireshark's heuristic dissectors do.
    heuristics: bool = True
    #: Keep each stream's time series (for --plot).
    series: bool = False


class Findings:
    def __init__(self, kept: int = FINDINGS_KEPT) -> None:
        self.kept = kept
        self.items: list[Finding] = []
        self._counts: Counter[tuple[Severity, str]] = Counter()
        #: (severity, rule) -> findings left out past `kept`.
        self.left_out: Counter[tuple[Severity, str]] = Counter()

    def add(
        self,
        severity: Severity,
        rule: str,
        text: str,
        frame: int = 0,
        time: float | None = None,
        message: int = 0,
        file_offset: int | None = None,
    ) -> None:
        key = (severity, rule)
        self._counts[key] += 1
        if self._counts[key] > self.kept:
            self.left_out[key] += 1
            return
        self.items.append(Finding(severity, rule, text, frame, time, message, file_offset))

    def count(self, severity: Severity) -> int:
        return sum(n for (s, _), n in self._counts.items() if s is severity)


@dataclass(slots=True)
class DataSession:
    """A data stream set up by SETUP (D-RCTP-18, D-RCTP-28): its tag, its ends and its streams."""

    tag: int
    client_address: bytes
    server_address: bytes
    server_port: int | None
    #: The client port of the latest SETUP (D-RCTP-28).
    client_port: int | None
    #: The RCTP session's id, when known.
    session: str | None
    #: Stream id -> (access path, Transport of the answer).
    streams: dict[int, tuple[str, Transport]] = field(default_factory=dict)
    #: Seconds of the robot's timePrecision (D-RCTP-24), from the RCML.
    precision: float = 0.0


class Context:
    """Shared by the decoders of one run."""

    def __init__(self, options: Options, emit: Callable[[Record], None]) -> None:
        self.options = options
        self.emit = emit
        self.findings = Findings()
        #: Messages decoded so far (a record's number is this after its own).
        self.count = 0
        self.by_protocol: Counter[str] = Counter()
        self.streams: list[Stream] = []
        #: Data streams by tag, and the UDP endpoints SETUP named: (address, port) -> session.
        self.data_sessions: dict[int, DataSession] = {}
        self.data_endpoints: dict[tuple[bytes, int], DataSession] = {}
        #: Which protocol each flow carries; it learns the endpoints SETUP names.
        self.flows = Classifier(options.decode_as, options.heuristics)
        #: Called when SETUP names new endpoints: the UDP flows already seen are classified again.
        self.learned: Callable[[], None] = lambda: None

    def stream(
        self, protocol: str, source: str, destination: str, session: str, rule: str
    ) -> Stream:
        stream = Stream(protocol, source, destination, session, rule, self.options.series)
        self.streams.append(stream)
        return stream

    def learn(self, session: DataSession) -> None:
        """A SETUP's answer named a data stream's tag and ports."""
        self.data_sessions[session.tag] = session
        client = (session.client_address, session.client_port)
        server = (session.server_address, session.server_port)
        for address, port in (client, server):
            if port is not None:
                self.data_endpoints[(address, port)] = session
        if self.flows.learn(client, server):
            self.learned()
