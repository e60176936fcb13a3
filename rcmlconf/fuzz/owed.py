"""Which of the requests a server received it owes an answer (D-FUZZ-4), read with the core's
own `MessageReader` from the bytes as the server received them.

Each request framed is owed one answer (R-RCTP-5), in order. A request that cannot be framed is
owed its error answer, and then the server closes (D-RCTP-10, R-RCTP-8): nothing after it is
owed. A message that reads as a response is owed nothing (the server closes, R-RCTP-12). Once a
BYE is answered 200 the session is over and nothing more is owed (D-RCTP-13, R-RCTP-23).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.reader import MessageReader

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

    def sent(self, data: bytes) -> None:
        """Bytes of the control connection, as the server receives them."""
        if self._done:
            return
        self._reader.feed(data)
        while not self._done:
            try:
                message = self._reader.next_message()
            except RemoteProtocolError as error:
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
            self.close_allowed = "R-RCTP-23: the BYE is answered"
            del self.requests[index + 1 :]
            del self.methods[index + 1 :]
            self._done = True
