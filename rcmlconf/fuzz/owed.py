"""Which of the requests a server received it owes an answer (D-FUZZ-4), read with the core's
own `MessageReader` from the bytes as the server received them.

Each request framed is owed one answer (R-RCTP-5), in order. A request that cannot be framed is
owed its error answer, and then the server closes (D-RCTP-10, R-RCTP-8): nothing after it is
owed. A message that reads as a response is owed nothing (the server closes, R-RCTP-12). Once a
BYE is answered 200 the session is over and nothing more is owed (D-RCTP-13, R-RCTP-23). Nor is
anything after an answer of 400, 413, 414 or 431: a server may find a start line unframeable (a
control byte in its target) where the core's reader frames it and finds its target wrong.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.reader import MessageReader

#: The answers to a request that cannot be framed (R-RCTP-8).
FRAMING_STATUSES = frozenset({400, 413, 414, 431})
#: How an owed request that cannot be framed is named.
UNFRAMED = "a request that cannot be framed"


@dataclass(slots=True)
class Owed:
    #: What each request owed an answer is, for people: "GO /drive (CSeq 5)".
    requests: list[str] = field(default_factory=list)
    #: The methods of the requests, in the same order (None: one that could not be framed).
    methods: list[str | None] = field(default_factory=list)
    #: The server may close once every owed answer is sent, and why (None: it may not).
    close_allowed: str | None = None
    _reader: MessageReader = field(default_factory=MessageReader)
    _done: bool = False
    #: What was sent, to tell what a message that cannot be framed began as.
    _stream: bytes = b""

    def sent(self, data: bytes) -> None:
        """Bytes of the control connection, as the server receives them."""
        if self._done:
            return
        self._reader.feed(data)
        self._stream += data
        while not self._done:
            start = self._reader.offset
            try:
                message = self._reader.next_message()
            except RemoteProtocolError as error:
                if self._stream[start : start + 5].upper() == b"RCTP/":
                    # D-RCTP-10: a broken message whose first line is a status line is a
                    # response: it gets no answer, and its receiver closes (R-RCTP-12).
                    self._done = True
                    self.close_allowed = "R-RCTP-12: a broken response is not answered"
                    return
                self.requests.append(f"{UNFRAMED} ({error.reason})")
                self.methods.append(None)
                self._done = True
                self.close_allowed = f"D-RCTP-10: {error.rule or 'a framing error'}"
                return
            if message is None:
                return
            if not isinstance(message, Request):
                self._done = True
                self.close_allowed = "R-RCTP-12: a response answers none of its requests"
                return
            cseq = message.headers.get("CSeq")
            self.requests.append(f"{message.method} {message.target[:60]} (CSeq {cseq})")
            self.methods.append(message.method)

    def answered(self, index: int, status: int) -> None:
        """The answer to owed request `index` came with `status`."""
        if index < len(self.methods) and self.methods[index] == "BYE" and status == 200:
            self._end(index, "R-RCTP-23: the BYE is answered")
        elif status in FRAMING_STATUSES:
            # D-RCTP-10: a start line or header that does not parse cannot be framed; where the
            # grammar's edge lies (a control byte in the target) a server may draw apart from
            # the core's reader, so it may close after any such answer.
            self._end(index, f"D-RCTP-10: answered {status}")

    def _end(self, index: int, why: str) -> None:
        self.close_allowed = why
        del self.requests[index + 1 :]
        del self.methods[index + 1 :]
        self._done = True
