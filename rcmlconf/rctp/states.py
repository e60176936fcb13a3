"""The state machines of RCTP/2.0 as data (D-RCTP-13, D-RCTP-14), for either role.

A table maps (state, what happened) to the next state; what is not in a table is not allowed.
The connection consults these tables and nothing else to decide what is valid when.
"""

from __future__ import annotations

import enum


class Role(enum.Enum):
    CLIENT = "client"
    SERVER = "server"


class SessionState(enum.Enum):
    IDLE = "idle"
    OPEN = "open"
    CLOSING = "closing"
    CLOSED = "closed"


class SessionEvent(enum.Enum):
    CONNECT_ACCEPTED = "CONNECT answered 200"
    CONNECT_REFUSED = "CONNECT answered with an error"
    ANSWERED = "another request answered"
    BYE = "BYE sent or received"
    BYE_ANSWERED = "the BYE answered"
    CLOSED = "the connection closed"


_S = SessionState
_E = SessionEvent

#: D-RCTP-13.
SESSION_TRANSITIONS: dict[tuple[SessionState, SessionEvent], SessionState] = {
    (_S.IDLE, _E.CONNECT_ACCEPTED): _S.OPEN,
    (_S.IDLE, _E.CONNECT_REFUSED): _S.IDLE,
    (_S.OPEN, _E.CONNECT_ACCEPTED): _S.OPEN,  # a refresh (D-RCTP-11)
    (_S.OPEN, _E.CONNECT_REFUSED): _S.OPEN,
    (_S.OPEN, _E.ANSWERED): _S.OPEN,
    (_S.OPEN, _E.BYE): _S.CLOSING,
    (_S.CLOSING, _E.BYE_ANSWERED): _S.CLOSED,
    (_S.CLOSING, _E.ANSWERED): _S.CLOSING,  # requests sent before the BYE, answered after it
    **{(state, _E.CLOSED): _S.CLOSED for state in SessionState},
}


class StreamState(enum.Enum):
    INIT = "init"
    READY = "ready"
    PLAYING = "playing"


_T = StreamState

#: D-RCTP-14: (state, method answered 200) -> next state. A request whose (state, method) is
#: not here is answered 455.
STREAM_TRANSITIONS: dict[tuple[StreamState, str], StreamState] = {
    (_T.INIT, "SETUP"): _T.READY,
    (_T.READY, "SETUP"): _T.READY,
    (_T.READY, "GO"): _T.PLAYING,
    (_T.PLAYING, "GO"): _T.PLAYING,
    (_T.PLAYING, "PAUSE"): _T.READY,
    (_T.READY, "PAUSE"): _T.READY,
    (_T.READY, "STOP"): _T.INIT,
    (_T.PLAYING, "STOP"): _T.INIT,
}
STREAM_METHODS = frozenset(method for _, method in STREAM_TRANSITIONS)

#: D-RCTP-26, D-RCTP-27: the server's WRITE is a data-change event of an access playing on the
#: client's side; in any other state the client answers 455.
PUSH_STATES = frozenset({_T.PLAYING})
