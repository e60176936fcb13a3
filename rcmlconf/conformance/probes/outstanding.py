"""Which request of a probe's each answer belongs to (D-RCTP-6), judged as it is read.

The probe shows every byte it sends to `Outstanding.sent`, which reads them with the core's
`MessageReader` and keeps the requests among them, oldest first. Every response the probe reads
goes to `answered`: it answers the oldest of them, and must carry that request's CSeq
(R-RCTP-3); the CSeq of a later one means the peer answered out of order (R-RCTP-5), and a
response when none waits answers nothing (D-RCTP-10). A wrong answer fails the case whatever
the case made of it: the first is kept (`failure`), and the runner gives it the last word.

What the probe sent broken on purpose is judged only as far as it can be: an answer to a request
that could not be framed, or to one not yet whole, may carry any CSeq (the harness cannot tell
what its receiver read of it), and what was sent after is not known (D-RCTP-10); an answer to
a request without one readable CSeq carries none, or echoes what the request had.

An answer without CSeq in one of D-RCTP-10's statuses for a request that cannot be framed says
its receiver could not frame the request, though the harness could. Whether it should have is
the case's to judge, by the status it expects: a case that fails the answer for its status
keeps its own requirement (the receiver misread the request); one that finds nothing else wrong
fails it for the missing CSeq (`doubt`, R-RCTP-3). What was sent after it is not judged.

It also knows when the connection's session opens (a CONNECT answered 200): until then a server's
request is refused as the core's own checks say, 454 (D-RCTP-13), not answered 200.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NoReturn

from rcmlconf.conformance.verdicts import Failed
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.fields import SessionField
from rcmlconf.rctp.messages import REASONS, Request, Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rctp.request_checks import first_refusal, request_cseq
from rcmlconf.rctp.states import Role, SessionState, StreamState

#: Requests kept waiting at most; past them the probe judges no more answers.
MAX_WAITING = 1024
#: Characters of a request's target shown in a failure.
SHOWN_TARGET = 60
#: Answered requests kept, to name the one a second answer repeats.
REMEMBERED = 16
#: D-RCTP-10's statuses for a request that cannot be framed (a start line or header that does
#: not parse, a bad Content-Length, a limit passed): their answer may carry no CSeq.
UNFRAMED = frozenset({400, 413, 414, 431})


@dataclass(frozen=True, slots=True)
class _Sent:
    """A request the probe sent: what it was, and the CSeq its answer must carry."""

    #: `ACQUIRE /`, or `bytes that do not frame` for a request that could not be read.
    what: str
    method: str = ""
    #: None without one readable CSeq (R-RCTP-11), or when the request did not frame.
    cseq: int | None = None
    #: The request's CSeq fields as written, which an answer may echo.
    texts: tuple[str, ...] = ()
    framed: bool = True

    @classmethod
    def of(cls, request: Request) -> _Sent:
        target = request.target
        if len(target) > SHOWN_TARGET:
            target = target[:SHOWN_TARGET] + "…"
        texts = tuple(request.headers.get_all("CSeq"))
        method = request.method
        return cls(f"{method} {target}", method, request_cseq(request), texts)

    def __str__(self) -> str:
        if not self.framed:
            return self.what
        if self.cseq is not None:
            return f"CSeq {self.cseq} ({self.what})"
        return f"{self.what}, sent without one readable CSeq"


@dataclass(frozen=True, slots=True)
class _Idle:
    """What a connection shares before its CONNECT is answered 200 (D-RCTP-13: idle)."""

    session_state: SessionState = SessionState.IDLE
    session: SessionField | None = None
    streams: Mapping[str, StreamState] = field(default_factory=dict)


_IDLE = _Idle()


class Outstanding:
    """One control connection's requests from the probe still waiting for their answers."""

    def __init__(self) -> None:
        self._reader: MessageReader | None = MessageReader()
        self._waiting: deque[_Sent] = deque()
        self._answered: deque[_Sent] = deque(maxlen=REMEMBERED)
        #: Whether what was sent after the requests waiting is unknown (it did not frame).
        self._blind = False
        #: The first answer out of place (R-RCTP-3, R-RCTP-5); no answer is judged after it.
        self.failure: Failed | None = None
        #: The first answer that said a request the harness framed could not be framed (the
        #: module's docstring): the case's own failure, if any, stands before it.
        self.doubt: Failed | None = None
        #: Whether a CONNECT of this connection was answered 200 (D-RCTP-13: idle to open).
        self.session_open = False
        #: The side the probe plays: a client's requests are refused in idle (`idle_refusal`).
        self.side = Role.CLIENT

    def sent(self, data: bytes) -> None:
        """Bytes the probe sent: the requests among them wait for their answers."""
        reader = self._reader
        if reader is None:
            return
        reader.feed(data)
        while True:
            try:
                message = reader.next_message()
            except RemoteProtocolError as error:
                # D-RCTP-10: a broken request is answered, a broken response is not; either way
                # where the next message starts is unknown.
                if error.answerable:
                    self._wait(_Sent("bytes that do not frame", framed=False))
                self._go_blind()
                return
            if message is None:
                return
            if isinstance(message, Request):
                self._wait(_Sent.of(message))

    def answered(self, response: Response, requirement: str | None = None) -> None:
        """`response`, just read, answers the oldest request waiting, or the probe fails the
        case: `requirement` names what a wrong CSeq breaks, when a case judges that under its
        own (R-RCTP-3, or R-RCTP-5 for a later request's CSeq, by default)."""
        if self.failure is not None:
            return
        if not self._waiting:
            if self._blind:
                return
            if self._reader is not None and self._reader.buffered:
                self._go_blind()  # the answer to a request not yet whole: to its start, say
                return
            self._fail(
                requirement or "R-RCTP-3",
                "no response: no request waits for one (D-RCTP-10)",
                response,
            )
        oldest = self._waiting[0]
        if not oldest.framed:
            self._waiting.popleft()
            return
        if self._belongs(response, oldest):
            self._waiting.popleft()
            self._answered.append(oldest)
            if oldest.method == "CONNECT" and response.status == 200:
                self.session_open = True
            return
        if response.status in UNFRAMED and not response.headers.get_all("CSeq"):
            self._waiting.clear()  # what its receiver read after it is not known
            self._go_blind()
            self.doubt = self.doubt or Failed(
                requirement or "R-RCTP-3", f"the answer to {oldest}", self._shown(response)
            )
            return
        given = request_cseq(response)
        later = given is not None and any(s.cseq == given for s in list(self._waiting)[1:])
        self._fail(
            requirement or ("R-RCTP-5" if later else "R-RCTP-3"),
            f"the answer to {oldest}",
            response,
        )

    def idle_refusal(self, request: Request) -> tuple[int, str] | None:
        """The status and reason phrase a client whose CONNECT is not yet answered 200 refuses
        the server's `request` with, as the core's own checks say (D-RCTP-13: in idle only
        CONNECT is valid, anything else 454); None once the session is open, or when the probe
        plays the server."""
        if self.session_open or self.side is Role.SERVER:
            return None
        refusal = first_refusal(request, Role.CLIENT, None, _IDLE)
        if refusal is None or refusal.status is None:
            return None
        return refusal.status, REASONS[refusal.status]

    def _wait(self, sent: _Sent) -> None:
        if len(self._waiting) >= MAX_WAITING:
            self._go_blind()
            return
        self._waiting.append(sent)

    def _go_blind(self) -> None:
        self._reader = None
        self._blind = True

    @staticmethod
    def _belongs(response: Response, request: _Sent) -> bool:
        """Whether `response` may answer `request` by its CSeq (R-RCTP-3, D-RCTP-10)."""
        if request.cseq is not None:
            return request_cseq(response) == request.cseq
        texts = response.headers.get_all("CSeq")
        return all(text in request.texts for text in texts)

    def _fail(self, requirement: str, expected: str, response: Response) -> NoReturn:
        self.failure = Failed(requirement, expected, self._shown(response))
        raise self.failure

    def _shown(self, response: Response) -> str:
        """`200 OK with CSeq 1 (CONNECT /rover, answered already)`: the response, by CSeq."""
        texts = response.headers.get_all("CSeq")
        shown = f"{response.status} {response.reason}"
        if not texts:
            return f"{shown} without CSeq"
        shown += f" with CSeq {', '.join(text[:20] for text in texts)}"
        given = request_cseq(response)
        later = next((s for s in list(self._waiting)[1:] if s.cseq == given), None)
        if given is not None and later is not None:
            return f"{shown} ({later.what}, sent after it: answered out of order)"
        done = next((s for s in reversed(self._answered) if s.cseq == given), None)
        if given is not None and done is not None:
            return f"{shown} ({done.what}, answered already)"
        return shown
