"""The faults this client can be started with (--fault NAME), each breaking one requirement
of specs/ (the R- id) and otherwise leaving the client working."""

FAULTS: dict[str, tuple[str, str]] = {
    # ---- the control connection
    "cseq-starts-at-zero": ("R-RCTP-4", "the client numbers its requests 0, 1, 2, ..."),
    "connect-to-root": (
        "R-RCTP-60",
        "CONNECT names / whatever the site path of the case URL",
    ),
    "cseq-reused-after-write": (
        "R-RCTP-4",
        "the request after each WRITE reuses the WRITE's CSeq (the counter is not advanced)",
    ),
    "session-missing-on-stream-methods": (
        "R-RCTP-19",
        "GO, PAUSE and STOP are sent without the Session field",
    ),
    "answer-own-cseq": (
        "R-RCTP-3",
        "answers to the server's requests carry the client's own last CSeq, not the request's",
    ),
    "bare-lf-user-agent": ("R-RCTP-1", "the User-Agent line of CONNECT ends in a bare LF"),
    "accept-any-cseq": (
        "R-RCTP-12",
        "a response is taken as the answer of the oldest request whatever its CSeq",
    ),
    "skip-bad-response": (
        "R-RCTP-12",
        "a response that cannot be framed is skipped instead of closing the connection",
    ),
    "unknown-method-400": ("R-RCTP-9", "a request with an unknown method is answered 400, not 501"),
    "version-not-checked": (
        "R-RCTP-10",
        "a request of another RCTP version is handled as if it were RCTP/2.0",
    ),
    "missing-cseq-ignored": (
        "R-RCTP-11",
        "a server request without CSeq is handled (and answered without CSeq) instead of 400",
    ),
    "session-not-checked": (
        "R-RCTP-19",
        "the Session of a server request is not compared with the session's ID",
    ),
    "stop-answered-late": (
        "R-RCTP-5",
        "the answer to a server STOP is sent 50 ms late, after answers to later requests",
    ),
    "header-line-unbounded": (
        "R-RCTP-16",
        "header lines of received messages are buffered to any length (no 431)",
    ),
    "bye-unanswered": (
        "R-RCTP-23",
        "on the server's BYE the client closes the connection without answering it",
    ),
    "bye-not-closed": (
        "R-RCTP-23",
        "after its own BYE is answered the client keeps the connection open until the server "
        "closes it",
    ),
    "request-after-bye": (
        "R-RCTP-60",
        "RELEASE * is sent after the client's own BYE is answered, instead of before it",
    ),
    # ---- values and Nodes
    "int16-little-endian": ("R-RCML-30", "int16 and uint16 values are sent little-endian"),
    "float64-little-endian": ("R-RCML-30", "float64 values are sent little-endian"),
    "string-length-in-characters": (
        "R-RCML-30",
        "a string's length prefix counts characters, not UTF-8 bytes",
    ),
    "bool-as-text": ("R-RCML-30", "bool values are sent as the ASCII digits '0' and '1'"),
    "array-count-prefix": (
        "R-RCML-30",
        "an array (count > 1) is sent with a 16-bit element count before its elements",
    ),
    "bool-nonzero-accepted": (
        "R-RCML-30",
        "a received bool byte other than 0x00 and 0x01 is taken as true, not as malformed",
    ),
    "refused-push-taken": (
        "R-RCTP-61",
        "a data-change WRITE refused for a value outside its node's range still updates the "
        "newest values (stored before the range check)",
    ),
    "nodes-document-order": (
        "R-RCTP-30",
        "the client's event-type WRITE lists its Nodes (and values) in document order",
    ),
    "stream-document-order": (
        "R-RCTP-40",
        "DATA payloads hold the writable nodes' values in document order, not canonical order",
    ),
    # ---- data-stream packets
    "packet-version-1": ("R-RCTP-39", "data-stream packets carry version 1 in their header"),
    "tag-little-endian": ("R-RCTP-39", "the session tag is put in the header little-endian"),
    "packet-timestamp-unix": (
        "R-RCTP-39",
        "the header timestamp counts seconds from 1970, not NTP's 1900",
    ),
    "seq-starts-at-zero": ("R-RCTP-41", "data-stream sequence numbers start at 0, not at random"),
    "seq-separate-flow-counter": (
        "R-RCTP-41",
        "packets holding only FLOW payloads are numbered by a second counter of their own",
    ),
    # ---- DATA sending
    "data-at-setup": ("R-RCTP-44", "DATA starts when SETUP is answered, before GO"),
    "data-after-pause": ("R-RCTP-44", "DATA goes on after PAUSE is answered"),
    "data-after-stop": ("R-RCTP-44", "DATA goes on after STOP is answered (until BYE)"),
    "data-at-read-interval": (
        "R-RCTP-44",
        "DATA is sent every readInterval of the stream, not every writeInterval",
    ),
    "write-interval-not-applied": (
        "R-RCTP-44",
        "a set-interval request for the write direction is ACKed, but DATA keeps the old interval",
    ),
    # ---- data-stream receiving and FLOW
    "tag-not-checked": (
        "R-RCTP-42",
        "data-stream packets are not checked for the session's tag or the server's address",
    ),
    "apply-duplicate-packets": (
        "R-RCTP-43",
        "a packet with the newest sequence number again counts as newer (off by one)",
    ),
    "apply-stale-packets": (
        "R-RCTP-43",
        "DATA of packets older than the newest seen is applied too",
    ),
    "data-range-unchecked": (
        "R-RCTP-58",
        "a DATA payload with a value outside its node's min/max is applied (and echoed)",
    ),
    "flow-repeat-recomputed": (
        "R-RCTP-46",
        "no answer cache: a repeated FLOW request id is answered afresh",
    ),
    "flow-ack-wrong-id": (
        "R-RCTP-46",
        "ACKs and NACKs carry the client's own next request id, not the request's",
    ),
    "flow-ack-no-direction": (
        "R-RCTP-52",
        "interval and timeout ACKs leave out the direction byte (8-byte bodies)",
    ),
    "unknown-op-nack-5": (
        "R-RCTP-53",
        "a FLOW request for an unknown operation is answered NACK 5 (malformed), not NACK 1",
    ),
    "heartbeat-unix-epoch": (
        "R-RCTP-48",
        "heartbeat ACKs carry T2 and T3 counted from 1970, not NTP's 1900",
    ),
    "no-heartbeats": ("R-RCTP-49", "the client never sends a heartbeat"),
    "clock-offset-negated": (
        "R-RCTP-50",
        "the clock offset is computed as the client's clock minus the robot's (sign wrong)",
    ),
    # ---- reading the RCML
    "load-dtd": ("R-XML-12", "the RCML reader fetches and applies the DTD its DOCTYPE names"),
    "read-foreign-namespace": (
        "R-XML-13",
        "elements in another namespace are read by their local name, as RCML elements",
    ),
    # ---- added later (helper-FF)
    "media-type-exact": (
        "R-RCTP-59",
        "Content-Type is compared exactly: Application/RCTP-Values is refused (415, not read)",
    ),
    "write-while-paused-taken": (
        "R-RCTP-68",
        "a data-change WRITE of a paused event access (ready) is answered 200 and taken",
    ),
    "nodes-repeat-accepted": (
        "R-RCTP-30",
        "a Nodes field naming a node twice in a row is accepted (> where >= belongs)",
    ),
    "set-interval-read-acked": (
        "R-RCTP-46",
        "a set-interval of the read direction (the server's value) is ACKed, not NACK 4",
    ),
    "timeout-min-one-interval": (
        "R-RCTP-47",
        "a set-timeout is refused only below one read interval, not below twice it",
    ),
    "broken-flow-ends-packet": (
        "R-RCTP-53",
        "a FLOW body shorter than its preamble makes the packet's later payloads unread",
    ),
    "data-partial-apply": (
        "R-RCTP-58",
        "a DATA payload with a bad value has the values before it applied",
    ),
    "event-write-no-content-type": (
        "R-RCTP-6",
        "the event access WRITE carries Content-Length but no Content-Type",
    ),
}
