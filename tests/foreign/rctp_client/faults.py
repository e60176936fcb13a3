"""The faults this client can be started with (--fault NAME), each breaking one MUST."""

FAULTS: dict[str, tuple[str, str]] = {
    "cseq-starts-at-zero": (
        "R-RCTP-4",
        "the client numbers its requests 0, 1, 2, ... (off by one)",
    ),
    "answer-own-cseq": (
        "R-RCTP-3",
        "answers to the server's requests carry the client's own last CSeq, not the request's",
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
    "accept-any-cseq": (
        "R-RCTP-12",
        "a response is taken as the answer of the oldest request whatever its CSeq",
    ),
    "skip-bad-response": (
        "R-RCTP-12",
        "a response that cannot be framed is skipped line by line instead of closing",
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
        "the answer to a server STOP waits for the stream's sender to wind down, so requests "
        "after it are answered first",
    ),
    "bare-lf-user-agent": ("R-RCTP-1", "the User-Agent line of CONNECT ends in a bare LF"),
    "header-line-unbounded": (
        "R-RCTP-16",
        "header lines of received messages are buffered to any length (no 431)",
    ),
    "seq-starts-at-zero": ("R-RCTP-41", "data-stream sequence numbers start at 0, not at random"),
    "apply-duplicate-packets": (
        "R-RCTP-43",
        "a packet with the newest sequence number again counts as newer (off by one)",
    ),
    "tag-not-checked": (
        "R-RCTP-42",
        "data-stream packets are not checked for the session's tag or the server's address",
    ),
    "flow-repeat-recomputed": (
        "R-RCTP-46",
        "a repeated FLOW request id is answered afresh, not with the answer already given",
    ),
    "unknown-op-nack-5": (
        "R-RCTP-53",
        "a FLOW request for an unknown operation is answered NACK 5 (malformed), not NACK 1",
    ),
    "heartbeat-unix-epoch": (
        "R-RCTP-48",
        "heartbeat ACKs carry T2 and T3 counted from 1970, not NTP's 1900",
    ),
    "nodes-document-order": (
        "R-RCTP-30",
        "the client's event-type WRITE lists its Nodes (and values) in document order",
    ),
    "int16-little-endian": ("R-RCML-30", "int16 and uint16 values are sent little-endian"),
    "data-after-pause": (
        "R-RCTP-44",
        "the client keeps sending DATA of a writing stream after PAUSE is answered",
    ),
}
