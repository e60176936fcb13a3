"""tshark with the generated plugin: run it on a capture and read what it shows, message by message.

Used by the tests (tshark's fields against rcmlconf's codecs), by `captures/record.py` (the
expected analysis of each capture, as tshark sees it) and by the bench. tshark runs with a clean
`WIRESHARK_CONFIG_DIR`, so no one's preferences change what it shows, and with `-T pdml`, whose
nesting keeps each message's fields together (several RCTP messages in a segment, several payloads
in a datagram). A Lua plugin that fails to load still exits 0: `Run.problems` holds what tshark
said on standard error, and each frame its Lua errors and expert errors.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

#: The plugin's protocols.
PROTOCOLS = ("rctp", "rctpds", "rcmlrsp")
#: `_ws.expert.severity` of an error (PI_ERROR).
_ERROR = str(0x00800000)
#: What tshark says on standard error that is no problem of the plugin's.
_HARMLESS = ("Running as user",)


class TsharkError(Exception):
    """tshark is missing, or failed."""


def tshark_path() -> str | None:
    return shutil.which("tshark")


@dataclass(frozen=True, slots=True)
class Field:
    name: str
    show: str
    #: The bytes of the field, in hexadecimal, when tshark gives them.
    value: str | None
    pos: int
    size: int
    children: tuple[Field, ...] = ()

    def walk(self) -> Iterator[Field]:
        yield self
        for child in self.children:
            yield from child.walk()


@dataclass(frozen=True, slots=True)
class Layer:
    """One protocol item: one RCTP message, one data-stream datagram, one RSP packet."""

    name: str
    pos: int
    size: int
    fields: tuple[Field, ...]

    def walk(self) -> Iterator[Field]:
        for item in self.fields:
            yield from item.walk()

    def all(self, name: str) -> list[str]:
        return [f.show for f in self.walk() if f.name == name]

    def first(self, name: str) -> str | None:
        return next((f.show for f in self.walk() if f.name == name), None)

    def groups(self, name: str) -> list[Field]:
        """The top-level items named `name` (each payload, each device), with their children."""
        return [f for f in self.fields if f.name == name]


@dataclass(slots=True)
class Frame:
    number: int
    time: float
    source: tuple[str, int] | None = None
    destination: tuple[str, int] | None = None
    transport: str | None = None
    tcp_stream: int | None = None
    #: This frame's items of the plugin's protocols, in order.
    layers: list[Layer] = field(default_factory=list)
    lua_errors: list[str] = field(default_factory=list)
    #: Messages of expert errors (ours and tshark's own).
    errors: list[str] = field(default_factory=list)
    malformed: bool = False

    def of(self, protocol: str) -> list[Layer]:
        return [layer for layer in self.layers if layer.name == protocol]


@dataclass(slots=True)
class Run:
    frames: list[Frame]
    #: What tshark said on standard error, but for its notice about running as root.
    problems: list[str]


def _field(element: ET.Element) -> Field:
    return Field(
        element.get("name", ""),
        element.get("show", element.get("showname", "")),
        element.get("value"),
        int(element.get("pos", "0")),
        int(element.get("size", "0")),
        tuple(_field(child) for child in element if child.tag in ("field", "proto")),
    )


def _frame(packet: ET.Element) -> Frame:
    frame = Frame(0, 0.0)
    addresses: dict[str, str] = {}
    for proto in packet.findall("proto"):
        name = proto.get("name", "")
        if name == "frame":
            for item in proto.iter("field"):
                if item.get("name") == "frame.number":
                    frame.number = int(item.get("show", "0"))
                elif item.get("name") == "frame.time_epoch":
                    frame.time = float(item.get("show", "0"))
        elif name in ("ip", "ipv6"):
            for item in proto:
                if item.get("name") in ("ip.src", "ip.dst", "ipv6.src", "ipv6.dst"):
                    addresses[item.get("name", "").split(".")[1]] = item.get("show", "")
        elif name in ("tcp", "udp"):
            frame.transport = name
            ports = {item.get("name"): item.get("show", "0") for item in proto}
            if "src" in addresses:
                frame.source = (addresses["src"], int(ports.get(f"{name}.srcport") or 0))
                frame.destination = (addresses["dst"], int(ports.get(f"{name}.dstport") or 0))
            if name == "tcp" and ports.get("tcp.stream") is not None:
                frame.tcp_stream = int(ports["tcp.stream"] or 0)
        elif name in PROTOCOLS:
            frame.layers.append(
                Layer(
                    name,
                    int(proto.get("pos", "0")),
                    int(proto.get("size", "0")),
                    tuple(_field(child) for child in proto if child.tag in ("field", "proto")),
                )
            )
        for item in proto.iter():
            item_name = item.get("name")
            if item_name == "_ws.lua.error":
                frame.lua_errors.append(item.get("showname", ""))
            elif item_name == "_ws.malformed":
                frame.malformed = True
            elif item_name == "_ws.expert":
                severity = next(
                    (c.get("show") for c in item if c.get("name") == "_ws.expert.severity"), None
                )
                if severity == _ERROR:
                    frame.errors.append(item.get("showname", ""))
    return frame


def run_tshark(pcap: Path, plugin: Path, options: Sequence[str] = ()) -> Run:
    """tshark's PDML of `pcap` with the Lua `plugin`, frame by frame."""
    tshark = tshark_path()
    if tshark is None:
        raise TsharkError("tshark is not installed")
    with tempfile.TemporaryDirectory(prefix="rcmlconf-wireshark-") as config:
        environment = {**os.environ, "WIRESHARK_CONFIG_DIR": config}
        command = [tshark, "-n", "-r", str(pcap), "-X", f"lua_script:{plugin}", "-T", "pdml"]
        done = subprocess.run(
            [*command, *options], capture_output=True, env=environment, check=False
        )
    problems = [
        line
        for line in done.stderr.decode("utf-8", "replace").splitlines()
        if line.strip() and not line.startswith(_HARMLESS)
    ]
    if done.returncode != 0:
        raise TsharkError(f"tshark exited {done.returncode}: {' '.join(problems)[:500]}")
    root = ET.fromstring(done.stdout)
    return Run([_frame(packet) for packet in root.findall("packet")], problems)


def run_fields(pcap: Path, plugin: Path, names: Sequence[str]) -> list[list[list[str]]]:
    """`tshark -T fields -e NAME...`: for each frame, each field's values (all occurrences)."""
    tshark = tshark_path()
    if tshark is None:
        raise TsharkError("tshark is not installed")
    command = [tshark, "-n", "-r", str(pcap), "-X", f"lua_script:{plugin}", "-T", "fields"]
    for name in names:
        command += ["-e", name]
    command += ["-E", "occurrence=a", "-E", "aggregator=|"]
    with tempfile.TemporaryDirectory(prefix="rcmlconf-wireshark-") as config:
        done = subprocess.run(
            command,
            capture_output=True,
            env={**os.environ, "WIRESHARK_CONFIG_DIR": config},
            check=False,
        )
    if done.returncode != 0:
        raise TsharkError(f"tshark exited {done.returncode}: {done.stderr.decode()[:500]}")
    rows = done.stdout.decode("utf-8", "replace").splitlines()
    return [[cell.split("|") if cell else [] for cell in row.split("\t")] for row in rows]


# -- the analysis of a capture, as tshark shows it -------------------------------------------------


def _number(text: str | None) -> int:
    return int(text, 0) if text else 0


def _endpoint(address: tuple[str, int] | None) -> str:
    return f"{address[0]}:{address[1]}" if address is not None else "?"


@dataclass(slots=True)
class SequenceCounts:
    """A sender's sequence numbers as a receiver sees them: RTP's counting (RFC 3550 A.3) on
    16 bits, with serial arithmetic (RFC 1982) for newer and older."""

    packets: int = 0
    duplicates: int = 0
    late: int = 0
    _highest: int | None = None
    _seen: set[int] = field(default_factory=set)

    def see(self, sequence: int) -> None:
        self.packets += 1
        if self._highest is None:
            extended = sequence
            self._highest = extended
        else:
            ahead = (sequence - self._highest) & 0xFFFF
            if 0 < ahead < 0x8000:
                extended = self._highest + ahead
            else:
                extended = self._highest - ((self._highest - sequence) & 0xFFFF)
        if extended in self._seen:
            self.duplicates += 1
            return
        self._seen.add(extended)
        if extended < self._highest:
            self.late += 1
        else:
            self._highest = extended

    def summary(self) -> dict[str, int]:
        first = min(self._seen) if self._seen else 0
        last = self._highest if self._highest is not None else 0
        expected = last - first + 1 if self._seen else 0
        return {
            "packets": self.packets,
            "first": first & 0xFFFF,
            "last": last & 0xFFFF,
            "expected": expected,
            "lost": expected - len(self._seen),
            "duplicates": self.duplicates,
            "late": self.late,
        }


def _malformed(frame: Frame, layer: Layer) -> dict[str, object] | None:
    reason = layer.first(f"{layer.name}.malformed")
    if reason is None:
        return None
    return {
        "frame": frame.number,
        "protocol": layer.name,
        "offset": _number(layer.first(f"{layer.name}.malformed.offset")),
        "rule": layer.first(f"{layer.name}.malformed.rule"),
        "reason": reason,
    }


def _rctp(frames: Sequence[Frame]) -> dict[str, object]:
    connections: set[int] = set()
    clients: dict[int, tuple[str, int] | None] = {}
    client_requests: Counter[str] = Counter()
    server_requests: Counter[str] = Counter()
    responses: Counter[str] = Counter()
    sessions: list[str] = []
    pending: dict[tuple[int, str, int], float] = {}
    answered = 0
    messages = 0
    for frame in frames:
        stream = frame.tcp_stream if frame.tcp_stream is not None else -1
        for layer in frame.of("rctp"):
            if layer.first("rctp.malformed") is not None:
                connections.add(stream)
                continue
            method = layer.first("rctp.method")
            status = layer.first("rctp.status")
            if method is None and status is None:
                continue  # bytes after a framing error
            connections.add(stream)
            messages += 1
            cseq = layer.first("rctp.cseq")
            sender = _endpoint(frame.source)
            if method is not None:
                # The client opens the connection and speaks first (D-RCTP-1, D-RCTP-12).
                clients.setdefault(stream, frame.source)
                by_client = clients.get(stream) == frame.source
                (client_requests if by_client else server_requests)[method] += 1
                if cseq is not None:
                    pending[(stream, sender, int(cseq))] = frame.time
            else:
                responses[str(status)] += 1
                session = layer.first("rctp.session.id")
                timeout = layer.first("rctp.session.timeout")
                if session is not None and timeout is not None and session not in sessions:
                    sessions.append(session)  # CONNECT's answer: Session with its timeout
                if cseq is not None:
                    key = (stream, _endpoint(frame.destination), int(cseq))
                    if pending.pop(key, None) is not None:
                        answered += 1
    return {
        "connections": len(connections),
        "sessions": sessions,
        "messages": messages,
        "client_requests": dict(sorted(client_requests.items())),
        "server_requests": dict(sorted(server_requests.items())),
        "responses": dict(sorted(responses.items())),
        "answered": answered,
        "unanswered": len(pending),
    }


def _ntp_seconds(text: str | None) -> float:
    value = _number(text)
    return (value >> 32) + (value & 0xFFFFFFFF) / 2**32


#: Seconds from the NTP era to the Unix epoch.
_NTP_UNIX = 2208988800


def _datastream(frames: Sequence[Frame]) -> dict[str, object]:
    flows: dict[tuple[str, str, str], dict[str, object]] = {}
    counts: dict[tuple[str, str, str], SequenceCounts] = {}
    requests: dict[tuple[str, str, int], tuple[int, float]] = {}
    heartbeats: list[dict[str, object]] = []
    packets = 0
    for frame in frames:
        for layer in frame.of("rctpds"):
            if any(g.name == "rctpds.malformed" for g in layer.fields):
                continue  # broken framing: no packet (R-RCTP-42)
            packets += 1
            tag = f"{_number(layer.first('rctpds.tag')):08x}"
            key = (_endpoint(frame.source), _endpoint(frame.destination), tag)
            flow = flows.setdefault(
                key,
                {"source": key[0], "destination": key[1], "tag": tag, "data": {}, "flow": {}},
            )
            counts.setdefault(key, SequenceCounts()).see(_number(layer.first("rctpds.seq")))
            for payload in layer.groups("rctpds.payload"):
                fields = {f.name: f.show for f in payload.walk()}
                kind = fields.get("rctpds.payload.type")
                data = flow["data"]
                flows_seen = flow["flow"]
                assert isinstance(data, dict)
                assert isinstance(flows_seen, dict)
                if kind == "1":
                    stream = fields.get("rctpds.payload.stream", "0")
                    data[stream] = data.get(stream, 0) + 1
                elif kind == "2":
                    if "rctpds.flow.message" not in fields:
                        label = "malformed"
                    else:
                        label = _flow_label(payload)
                    flows_seen[label] = flows_seen.get(label, 0) + 1
                    _heartbeat(frame, fields, requests, heartbeats)
    out = []
    for key, flow in flows.items():
        flow.update(counts[key].summary())
        flow["data"] = dict(sorted(flow["data"].items()))  # type: ignore[attr-defined]
        flow["flow"] = dict(sorted(flow["flow"].items()))  # type: ignore[attr-defined]
        out.append(flow)
    return {"packets": packets, "flows": out, "heartbeats": heartbeats}


def _flow_label(payload: Field) -> str:
    """'heartbeat request', 'set interval ack': the operation and message, named as the codec
    names them."""
    from rcmlconf.rctp.datastream.flow import Message, Operation

    names = {f.name: f.show for f in payload.walk()}
    operation = int(names["rctpds.flow.operation"])
    message = int(names["rctpds.flow.message"])
    known = {int(o): o.name.lower().replace("_", " ") for o in Operation}
    return f"{known.get(operation, f'operation {operation}')} {Message(message).name.lower()}"


def _heartbeat(
    frame: Frame,
    fields: dict[str, str],
    requests: dict[tuple[str, str, int], tuple[int, float]],
    heartbeats: list[dict[str, object]],
) -> None:
    """D-RCTP-24: each heartbeat's request and ACK, and the offset and round trip they give,
    with T4 the ACK's capture time."""
    if fields.get("rctpds.flow.operation") != "1":
        return
    message = fields.get("rctpds.flow.message")
    request_id = int(fields.get("rctpds.flow.request_id", "0"))
    if message == "0":
        key = (_endpoint(frame.source), _endpoint(frame.destination), request_id)
        requests.setdefault(key, (frame.number, frame.time))
        return
    if message != "1":
        return
    key = (_endpoint(frame.destination), _endpoint(frame.source), request_id)
    request = requests.get(key)
    t1, t2, t3 = (_ntp_seconds(fields.get(f"rctpds.flow.{n}")) for n in ("t1", "t2", "t3"))
    t4 = frame.time + _NTP_UNIX
    heartbeats.append(
        {
            "request_id": request_id,
            "request_frame": request[0] if request is not None else None,
            "ack_frame": frame.number,
            "t1": fields.get("rctpds.flow.t1"),
            "t2": fields.get("rctpds.flow.t2"),
            "t3": fields.get("rctpds.flow.t3"),
            "offset_us": round(((t2 - t1) + (t3 - t4)) / 2 * 1e6),
            "round_trip_us": round(((t4 - t1) - (t3 - t2)) * 1e6),
        }
    )


def _rsp(frames: Sequence[Frame]) -> dict[str, object]:
    flows: dict[tuple[str, str, int], dict[str, object]] = {}
    counts: dict[tuple[str, str, int], SequenceCounts] = {}
    types: Counter[str] = Counter()
    occurrences: dict[str, dict[str, object]] = {}
    packets = 0
    for frame in frames:
        for layer in frame.of("rcmlrsp"):
            if layer.first("rcmlrsp.malformed") is not None:
                continue
            packets += 1
            kind = layer.first("rcmlrsp.type") or "0"
            name = _RSP_TYPES.get(kind, kind)
            types[name] += 1
            session = _number(layer.first("rcmlrsp.session_id"))
            key = (_endpoint(frame.source), _endpoint(frame.destination), session)
            flow = flows.setdefault(
                key,
                {"source": key[0], "destination": key[1], "session_id": session, "types": {}},
            )
            seen = flow["types"]
            assert isinstance(seen, dict)
            seen[name] = seen.get(name, 0) + 1
            counts.setdefault(key, SequenceCounts()).see(_number(layer.first("rcmlrsp.seq")))
            for item in layer.groups("rcmlrsp.device"):
                ident = next((f.show for f in item.walk() if f.name == "rcmlrsp.id"), None)
                if ident is None:
                    continue
                entry = occurrences.setdefault(f"{name} {item.show}", {"packets": 0, "ids": set()})
                entry["packets"] = int(str(entry["packets"])) + 1
                ids = entry["ids"]
                assert isinstance(ids, set)
                ids.add(int(ident))
    out = []
    for key, flow in flows.items():
        flow.update(counts[key].summary())
        flow["types"] = dict(sorted(flow["types"].items()))  # type: ignore[attr-defined]
        out.append(flow)
    carried = {}
    for label, entry in sorted(occurrences.items()):
        ids = entry["ids"]
        assert isinstance(ids, set)
        sent = int(str(entry["packets"]))
        carried[label] = {"packets": sent, "ids": len(ids), "repeats": sent - len(ids)}
    return {
        "packets": packets,
        "types": dict(sorted(types.items())),
        "flows": out,
        "occurrences": carried,
    }


#: Packet type numbers as tshark shows them -> names: filled by `analyse` from the plugin's
#: own value strings, which come from `rcmlconf.rsp.codec.PacketType`.
_RSP_TYPES: dict[str, str] = {}


def analyse(run: Run) -> dict[str, object]:
    """What a capture holds, as the plugin shows it: messages by kind, sessions, streams and their
    sequence numbers (lost, duplicated, late), heartbeats, RSP occurrences, malformed parts."""
    from rcmlconf.rsp.codec import PacketType

    _RSP_TYPES.update({str(int(t)): t.name for t in PacketType})
    frames = run.frames
    malformed = [
        found
        for frame in frames
        for layer in frame.layers
        if (found := _malformed(frame, layer)) is not None
    ]
    return {
        "frames": len(frames),
        "rctp": _rctp(frames),
        "rctpds": _datastream(frames),
        "rcmlrsp": _rsp(frames),
        "malformed": malformed,
        "expert_errors": sum(len(frame.errors) for frame in frames),
        "lua_errors": sum(len(frame.lua_errors) for frame in frames),
    }
