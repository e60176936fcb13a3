"""Faults the reference implementations can be told to make, for testing a conformance harness.

A harness must pass a conforming implementation, and it must fail a broken one too. So
`rcmlconf serve --fault NAME` and `rcmlconf robot --fault NAME` make the reference server or
RSP robot misbehave as an implementer's bug would. `ServerSettings.faults` and
`RobotSettings.faults` do the same. Each fault breaks one requirement. A test then checks that
some case of the harness fails and names that requirement.

Each fault lives where such a bug would, outside the core:

- The control connection's bytes: one rewrite of what the server writes (`rewrite_control`,
  applied in the adapter's flush).
- The server's sessions, robot and privileges: subclasses of the core's classes
  (`reference.server.faulty_session`, `faulty_robot`, `faulty_privileges`).
- The data stream: a subclass of the core's endpoint (`reference.server.faulty_stream`).
- The RSP robot: a subclass of the core's robot endpoint (`reference.rsp.faulty_session`).
- Values: a codec the server reads and writes bodies with (`faulty_codec`), and `loose_model`
  for the robot's packets.

Each spot is marked `# fault: NAME`. Without faults, none of this runs: the reference makes the
core's classes.

Never for a real robot: a faulty server or robot breaks the protocols on purpose.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Literal

from rcmlconf.buffer import Buffer
from rcmlconf.rcml.model import DataNode, RcmlDocument
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.messages import REASONS
from rcmlconf.rsp.model import Field as RspField
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import DATA_TYPES, Kind, Value, ValueType
from rcmlconf.values.types import MAX_SIZE

Implementation = Literal["server", "robot"]


@dataclass(frozen=True, slots=True)
class FaultInfo:
    #: Which reference implementation makes it: the RCTP/2.0 server or the RSP robot.
    implementation: Implementation
    #: One line: the misbehaviour.
    description: str
    #: The requirements of specs/ it breaks.
    requirements: tuple[str, ...]


class Fault(enum.Enum):
    # -- the server: the bytes of the control connection (rewrite_control) ----------------------
    BARE_LF = "bare-lf"
    NO_CSEQ_ECHO = "no-cseq-echo"
    WRONG_STATUS = "wrong-status"
    UNKNOWN_METHOD_400 = "unknown-method-400"
    VERSION_IGNORED = "version-ignored"
    SESSION_UNCHECKED = "session-unchecked"
    NO_ALLOW = "no-allow"
    NO_TIMEOUT_BYE = "no-timeout-bye"
    NO_CONTENT_TYPE = "no-content-type"
    # -- the server: the values of bodies and payloads (faulty_codec) ---------------------------
    # The first two show only on a robot with a writable bool, string or bytes node, which the
    # embedded reference's rover lacks: the test of the harness serves the test robot for them.
    BOOL_NONZERO_TRUE = "bool-nonzero-true"
    STRING_SIZE_UNCHECKED = "string-size-unchecked"
    DOCUMENT_ORDER_VALUES = "document-order-values"
    NAN_IN_RANGE = "nan-in-range"
    # -- the server: sessions, nodes and privileges ----------------------------------------------
    OPEN_AFTER_BAD_FRAMING = "open-after-bad-framing"
    REFRESH_REFUSED = "refresh-refused"
    PERMISSION_IGNORED = "permission-ignored"
    PARTIAL_WRITE = "partial-write"
    CASE_SENSITIVE_TOKENS = "case-sensitive-tokens"
    NO_CHANGE_PUSH = "no-change-push"
    ECHO_OWN_WRITES = "echo-own-writes"
    UNBOUNDED_PUSHES = "unbounded-pushes"
    ACQUIRE_NOT_EXCLUSIVE = "acquire-not-exclusive"
    WRITE_WITHOUT_ACQUIRE = "write-without-acquire"
    RELEASE_UNHELD = "release-unheld"
    RELEASE_WHILE_WRITING = "release-while-writing"
    PRIVILEGES_KEPT = "privileges-kept"
    # -- the server: streams (faulty_session) and the data stream (faulty_stream) ----------------
    NO_TIMEOUT_STOP = "no-timeout-stop"
    PAUSE_IGNORED = "pause-ignored"
    FIRST_CLIENT_PORT = "first-client-port"
    STALE_DATA_APPLIED = "stale-data-applied"
    SEQUENCE_SKIPS = "sequence-skips"
    HEARTBEAT_NO_T1 = "heartbeat-no-t1"
    SHORT_INTERVAL_ACCEPTED = "short-interval-accepted"
    UNKNOWN_PAYLOAD_DROPS = "unknown-payload-drops"
    FLOW_ANSWERS_FORGOTTEN = "flow-answers-forgotten"
    # -- the RSP robot ---------------------------------------------------------------------------
    NO_RETRANSMISSION = "no-retransmission"
    ACK_NEXT_ID = "ack-next-id"
    REPEAT_NOT_ACKED = "repeat-not-acked"
    DUPLICATES_TAKEN = "duplicates-taken"
    REPLAY_WINDOW_OFF = "replay-window-off"
    SESSION_ID_UNCHECKED = "session-id-unchecked"
    SOURCE_UNCHECKED = "source-unchecked"
    REFUSED_OWN_MODEL = "refused-own-model"
    FREE_BUFFERS_STUCK = "free-buffers-stuck"
    UNREQUESTED_REPORTED = "unrequested-reported"
    SEQUENCE_FROZEN = "sequence-frozen"
    CLEAR_BUFFER_IGNORED = "clear-buffer-ignored"
    SILENT_TIMEOUT = "silent-timeout"
    NO_STOP_ON_LOSS = "no-stop-on-loss"
    PAYLOAD_SIZE_UNCHECKED = "payload-size-unchecked"

    @property
    def info(self) -> FaultInfo:
        return DESCRIPTIONS[self]

    @property
    def description(self) -> str:
        return DESCRIPTIONS[self].description

    @property
    def implementation(self) -> Implementation:
        return DESCRIPTIONS[self].implementation

    @property
    def requirements(self) -> tuple[str, ...]:
        return DESCRIPTIONS[self].requirements


def _server(description: str, *requirements: str) -> FaultInfo:
    return FaultInfo("server", description, requirements)


def _robot(description: str, *requirements: str) -> FaultInfo:
    return FaultInfo("robot", description, requirements)


_F = Fault
DESCRIPTIONS: dict[Fault, FaultInfo] = {
    _F.BARE_LF: _server("ends the lines of what it sends with a bare LF, not CRLF", "R-RCTP-1"),
    _F.NO_CSEQ_ECHO: _server("leaves the request's CSeq out of its responses", "R-RCTP-3"),
    _F.WRONG_STATUS: _server(
        "answers every 4xx error with 400 Bad Request, whatever its cause",
        "R-RCTP-16",
        "R-RCTP-17",
        "R-RCTP-19",
        "R-RCTP-20",
        "R-RCTP-26",
        "R-RCTP-27",
        "R-RCTP-28",
        "R-RCTP-31",
        "R-RCTP-33",
        "R-RCTP-34",
        "R-RCTP-35",
        "R-RCTP-57",
    ),
    _F.UNKNOWN_METHOD_400: _server(
        "answers a request with a method it does not know with 400, not 501", "R-RCTP-9"
    ),
    _F.VERSION_IGNORED: _server(
        "answers a request of another version (RCTP/1.0) with 200, not 505", "R-RCTP-10"
    ),
    _F.SESSION_UNCHECKED: _server(
        "answers 200 where 454 is due: a request before CONNECT or naming another session",
        "R-RCTP-17",
        "R-RCTP-19",
    ),
    _F.NO_ALLOW: _server("leaves the Allow field out of its 405 responses", "R-RCTP-26"),
    _F.NO_TIMEOUT_BYE: _server(
        "ends a session whose timeout passed by closing the connection, without BYE",
        "R-RCTP-21",
    ),
    _F.NO_CONTENT_TYPE: _server("sends bodies without Content-Type", "R-RCTP-6"),
    _F.BOOL_NONZERO_TRUE: _server(
        "takes a bool byte other than 0x00 and 0x01 in a WRITE body or DATA payload as true",
        "R-RCML-30",
        "R-RCTP-28",
        "R-RCTP-58",
    ),
    _F.STRING_SIZE_UNCHECKED: _server(
        "takes a string or bytes value longer than its node's size in a WRITE body or DATA payload",
        "R-RCML-30",
        "R-RCTP-28",
        "R-RCTP-58",
    ),
    _F.DOCUMENT_ORDER_VALUES: _server(
        "writes and reads the values of READ, WRITE and data-change bodies in the nodes'"
        " document order, not canonical order (Nodes still lists them canonically)",
        "R-RCML-29",
    ),
    _F.NAN_IN_RANGE: _server(
        "checks a WRITE's values against min and max with < and >, which NaN passes",
        "R-RCTP-28",
    ),
    _F.OPEN_AFTER_BAD_FRAMING: _server(
        "keeps the connection open after a message it could not frame or take (and answers"
        " nothing more)",
        "R-RCTP-8",
        "R-RCTP-12",
    ),
    _F.REFRESH_REFUSED: _server(
        "answers a CONNECT that refreshes the session with 455, not 200", "R-RCTP-22"
    ),
    _F.PERMISSION_IGNORED: _server(
        "reads and writes nodes whatever their permission (no 403)", "R-RCTP-27"
    ),
    _F.CASE_SENSITIVE_TOKENS: _server(
        "compares Content-Type and Transport as written, so Application/RCTP-Values gets 415"
        " and UDP;MODE=Read 400",
        "R-RCTP-59",
    ),
    _F.PARTIAL_WRITE: _server(
        "applies the in-range values of an event-type WRITE with one out of range, answering 422",
        "R-RCTP-28",
        "R-RCTP-29",
    ),
    _F.NO_CHANGE_PUSH: _server(
        "sends no data-change WRITE while an event access is playing", "R-RCTP-32"
    ),
    _F.ECHO_OWN_WRITES: _server(
        "sends a session the data-change WRITE of a change its own WRITE made", "R-RCTP-54"
    ),
    _F.UNBOUNDED_PUSHES: _server(
        "has any number of its WRITE and STOP requests unanswered, not four at most", "R-RCTP-55"
    ),
    _F.ACQUIRE_NOT_EXCLUSIVE: _server(
        "grants ACQUIRE of a path another session holds, or holds above or below (no 471)",
        "R-RCTP-33",
        "R-RCTP-37",
    ),
    _F.WRITE_WITHOUT_ACQUIRE: _server(
        "takes WRITE, SETUP for writing and GO of a writing stream on a path no session holds"
        " (no 470)",
        "R-RCTP-34",
    ),
    _F.RELEASE_UNHELD: _server(
        "answers RELEASE of a path the session does not hold with 200, not 470", "R-RCTP-35"
    ),
    _F.RELEASE_WHILE_WRITING: _server(
        "answers RELEASE with 200 while a writing stream below the path is set up, not 455",
        "R-RCTP-35",
    ),
    _F.PRIVILEGES_KEPT: _server("keeps a session's privileges after the session ends", "R-RCTP-36"),
    _F.NO_TIMEOUT_STOP: _server(
        "sends no STOP when a stream's receive timeout passes", "R-RCTP-45"
    ),
    _F.PAUSE_IGNORED: _server(
        "answers PAUSE of a stream access with 200 but goes on sending its DATA", "R-RCTP-44"
    ),
    _F.FIRST_CLIENT_PORT: _server(
        "keeps the data stream on the client_port of the first SETUP, not the latest",
        "R-RCTP-56",
    ),
    _F.STALE_DATA_APPLIED: _server(
        "applies the DATA of data-stream packets that are not newer than the newest seen",
        "R-RCTP-43",
    ),
    _F.SEQUENCE_SKIPS: _server(
        "numbers its data-stream packets two apart, skipping a number each time", "R-RCTP-41"
    ),
    _F.HEARTBEAT_NO_T1: _server(
        "answers a heartbeat with its own T2 where the request's T1 is to be echoed", "R-RCTP-48"
    ),
    _F.SHORT_INTERVAL_ACCEPTED: _server(
        "accepts a FLOW set interval shorter than the RCML's (no NACK 3)", "R-RCTP-47"
    ),
    _F.UNKNOWN_PAYLOAD_DROPS: _server(
        "drops a data-stream packet with a payload of an unknown type instead of skipping it",
        "R-RCTP-51",
    ),
    _F.FLOW_ANSWERS_FORGOTTEN: _server(
        "answers a repeated FLOW request id anew instead of with the answer already given",
        "R-RCTP-46",
    ),
    _F.NO_RETRANSMISSION: _robot(
        "sends nothing again: no memory event after its RTO, no WELCOME to a repeated HELLO",
        "R-RSP-28",
        "R-RSP-20",
    ),
    _F.ACK_NEXT_ID: _robot(
        "acknowledges an occurrence with the ID after its own (TCP's next expected)", "R-RSP-26"
    ),
    _F.REPEAT_NOT_ACKED: _robot(
        "acknowledges a command or memory command the first time only, not when repeated",
        "R-RSP-26",
    ),
    _F.DUPLICATES_TAKEN: _robot(
        "takes a repeated command or memory command again: its ID is not checked", "R-RSP-25"
    ),
    _F.REPLAY_WINDOW_OFF: _robot(
        "reads packets seen before or older than the newest, and applies their states",
        "R-RSP-18",
        "R-RSP-19",
    ),
    _F.SESSION_ID_UNCHECKED: _robot(
        "takes the packets of its peer whatever session ID they name", "R-RSP-18"
    ),
    _F.SOURCE_UNCHECKED: _robot(
        "takes a session's packets from any address, not only the HELLO's", "R-RSP-18"
    ),
    _F.REFUSED_OWN_MODEL: _robot(
        "puts its own model ID in REFUSED, not the HELLO's", "R-RSP-21", "R-RSP-20"
    ),
    _F.FREE_BUFFERS_STUCK: _robot(
        "reports every memory-command buffer free, and takes memory commands past its buffers",
        "R-RSP-31",
    ),
    _F.UNREQUESTED_REPORTED: _robot(
        "reports sensors and monitors in its UPLINKs that the newest DOWNLINK did not request",
        "R-RSP-23",
    ),
    _F.SEQUENCE_FROZEN: _robot(
        "gives every packet after WELCOME the same sequence number", "R-RSP-14"
    ),
    _F.CLEAR_BUFFER_IGNORED: _robot(
        "keeps its memory commands when a DOWNLINK has Clear Buffer set", "R-RSP-33"
    ),
    _F.SILENT_TIMEOUT: _robot(
        "ends a session whose peer went silent for 10 s without sending BYE", "R-RSP-22"
    ),
    _F.NO_STOP_ON_LOSS: _robot(
        "goes on driving the effectors whose onLoss is zero while the link is lost", "R-RSP-36"
    ),
    _F.PAYLOAD_SIZE_UNCHECKED: _robot(
        "takes a DOWNLINK whose string or bytes field is longer than its size, not dropping it",
        "R-RSP-18",
    ),
}

SERVER_FAULTS = frozenset(f for f in Fault if f.implementation == "server")
ROBOT_FAULTS = frozenset(f for f in Fault if f.implementation == "robot")
#: The server's faults that are a rewrite of the control connection's bytes (`rewrite_control`).
CONTROL_FAULTS = frozenset(
    {
        Fault.BARE_LF,
        Fault.NO_CSEQ_ECHO,
        Fault.WRONG_STATUS,
        Fault.UNKNOWN_METHOD_400,
        Fault.VERSION_IGNORED,
        Fault.SESSION_UNCHECKED,
        Fault.NO_ALLOW,
        Fault.NO_TIMEOUT_BYE,
        Fault.NO_CONTENT_TYPE,
    }
)
#: The server's faults of the data stream (`reference.server.faulty_stream.FaultyEndpoint`).
STREAM_FAULTS = frozenset(
    {
        Fault.STALE_DATA_APPLIED,
        Fault.SEQUENCE_SKIPS,
        Fault.HEARTBEAT_NO_T1,
        Fault.SHORT_INTERVAL_ACCEPTED,
        Fault.UNKNOWN_PAYLOAD_DROPS,
        Fault.FLOW_ANSWERS_FORGOTTEN,
        Fault.BOOL_NONZERO_TRUE,
        Fault.STRING_SIZE_UNCHECKED,
    }
)
#: The faults of decoding values: READ and WRITE bodies (`faulty_codec`), DATA (faulty_stream).
LENIENT_VALUES = frozenset({Fault.BOOL_NONZERO_TRUE, Fault.STRING_SIZE_UNCHECKED})


def names(implementation: Implementation) -> list[str]:
    """The names of one implementation's faults, in declaration order (`--fault`'s choices)."""
    return [f.value for f in Fault if f.implementation == implementation]


def faults_named(chosen: Iterable[str]) -> frozenset[Fault]:
    return frozenset(Fault(name) for name in chosen)


def describe(faults: Iterable[Fault]) -> str:
    """`bare-lf, no-cseq-echo`: for the warning a faulty implementation logs at start."""
    return ", ".join(sorted(f.value for f in faults))


# -- the control connection's bytes ----------------------------------------------------------------

Field = tuple[bytes, bytes]


def rewrite_control(data: bytes, faults: frozenset[Fault]) -> bytes:
    """What the server writes on a control connection, broken as `faults` say. `data` is whole
    messages, as the core writes them (`Connection.data_to_send`)."""
    out = bytearray()
    at = 0
    while at < len(data):
        end = data.find(b"\r\n\r\n", at)
        if end < 0:  # not what the core writes: left alone
            out += data[at:]
            break
        start, *lines = data[at:end].split(b"\r\n")
        fields = [(name, value.strip()) for name, _, value in (ln.partition(b":") for ln in lines)]
        length = next((int(v) for n, v in fields if n.lower() == b"content-length"), 0)
        at = end + 4 + length
        rewritten = _rewrite(start, fields, data[end + 4 : at], faults)
        if rewritten is not None:
            out += rewritten
    return bytes(out)


def _status(code: int, faults: frozenset[Fault]) -> int:
    if code == 501 and Fault.UNKNOWN_METHOD_400 in faults:
        return 400
    if code == 505 and Fault.VERSION_IGNORED in faults:
        return 200
    if code == 454 and Fault.SESSION_UNCHECKED in faults:
        return 200
    if 400 < code < 500 and Fault.WRONG_STATUS in faults:
        return 400
    return code


def _rewrite(
    start: bytes, fields: list[Field], body: bytes, faults: frozenset[Fault]
) -> bytes | None:
    dropped: set[bytes] = set()
    if start.startswith(b"RCTP/"):  # a response
        version, code_text, _ = start.split(b" ", 2)
        code = _status(int(code_text), faults)
        if code != int(code_text):
            start = b"%s %d %s" % (version, code, REASONS[code].encode())
            if code == 200:
                body = b""
                dropped |= {b"content-length", b"content-type"}
        if Fault.NO_CSEQ_ECHO in faults:
            dropped.add(b"cseq")
        if Fault.NO_ALLOW in faults:
            dropped.add(b"allow")
    elif (
        Fault.NO_TIMEOUT_BYE in faults
        and start.startswith(b"BYE ")
        and any(n.lower() == b"reason" and v == b"timeout" for n, v in fields)
    ):
        return None
    if Fault.NO_CONTENT_TYPE in faults:
        dropped.add(b"content-type")
    eol = b"\n" if Fault.BARE_LF in faults else b"\r\n"
    lines = [start] + [n + b": " + v for n, v in fields if n.lower() not in dropped]
    return eol.join(lines) + eol + eol + body


# -- values: how the server and the robot read them ------------------------------------------------


class FaultyCodec(ValuesCodec[DataNode]):
    """The values of some data nodes in the order given, decoded as `LENIENT_VALUES` say: a bool
    is any byte (true unless 0x00), a string or bytes any length the prefix claims."""

    def __init__(
        self, nodes: Sequence[DataNode], where: str, rule: str, faults: frozenset[Fault]
    ) -> None:
        super().__init__(nodes, where, rule, canonical=False)
        lenient = faults & LENIENT_VALUES
        #: The bools read as uint8: their values go back and forth as numbers.
        self._bools = frozenset(
            n.name
            for n in self.nodes
            if n.type.base.kind is Kind.BOOL and Fault.BOOL_NONZERO_TRUE in lenient
        )
        loose = [_loose(n, lenient) for n in self.nodes]
        self._loose = ValuesCodec(loose, where, rule, canonical=False)

    def push(self, buf: Buffer, values: Mapping[str, Value]) -> None:
        loose = dict(values)
        for name in self._bools & loose.keys():
            value = loose[name]
            loose[name] = tuple(map(int, value)) if isinstance(value, tuple) else int(value)
        self._loose.push(buf, loose)

    def pull(self, buf: Buffer) -> dict[str, Value]:
        values = self._loose.pull(buf)
        for name in self._bools:  # fault: bool-nonzero-true
            value = values[name]
            values[name] = tuple(v != 0 for v in value) if isinstance(value, tuple) else value != 0
        return values


def _loose(node: DataNode, faults: frozenset[Fault]) -> DataNode:
    """The node as a decoder with `faults` reads it: a bool as a uint8, any size the largest."""
    base, count, size = node.type.base, node.type.count, node.type.size
    if base.kind is Kind.BOOL and Fault.BOOL_NONZERO_TRUE in faults:
        base = DATA_TYPES["uint8"]
    if base.sized and Fault.STRING_SIZE_UNCHECKED in faults:  # fault: string-size-unchecked
        size = MAX_SIZE
    return node._replace(type=ValueType(base, count, size))


def faulty_codec(
    model: RcmlDocument,
    nodes: Sequence[DataNode],
    where: str,
    rule: str,
    faults: frozenset[Fault],
) -> ValuesCodec[DataNode]:
    """The codec of READ and WRITE bodies of `nodes`, broken as `faults` say; the core's
    without them."""
    if Fault.DOCUMENT_ORDER_VALUES in faults:  # fault: document-order-values
        return FaultyCodec(model.in_document_order(nodes), where, rule, faults)
    if faults & LENIENT_VALUES:
        return FaultyCodec(sorted(nodes, key=lambda node: node.name), where, rule, faults)
    return ValuesCodec(nodes, where, rule)


def faulty_stream_codec(
    codec: ValuesCodec[DataNode], faults: frozenset[Fault]
) -> ValuesCodec[DataNode]:
    """A DATA codec of the data stream's, decoding as `LENIENT_VALUES` say."""
    return FaultyCodec(codec.nodes, codec.where, codec.rule, faults)


def nan_blind(node: DataNode, value: Value) -> str | None:
    """`DataNode.out_of_range` as a range check written with `<` and `>` is: NaN compares false
    with everything, so it passes (fault: nan-in-range)."""
    items = value if isinstance(value, tuple) else (value,)
    for item in items:
        if not isinstance(item, int | float) or isinstance(item, bool):
            continue
        if (node.minimum is not None and item < node.minimum) or (
            node.maximum is not None and item > node.maximum
        ):
            return f"{item!r} is outside {node.path}'s range {node.minimum} to {node.maximum}"
    return None


def loose_model(model: RobotModel) -> RobotModel:
    """The robot model as a robot with `payload-size-unchecked` reads packets: every string
    and bytes field of the largest size."""

    def field(found: RspField) -> RspField:
        if not found.type.base.sized:
            return found
        return found._replace(type=ValueType(found.type.base, found.type.count, MAX_SIZE))

    devices = tuple(d._replace(fields=tuple(map(field, d.fields))) for d in model.devices)
    return replace(model, devices=devices, by_name={d.name: d for d in devices})
