"""What can go wrong on an RCTP/2.0 control connection, and who is to blame (after h11).

`RemoteProtocolError` is the only exception the control-message parser lets escape: the peer
broke the protocol, here is where (`offset`), what to answer (`status`), which requirement
(`rule`), and whether the connection can go on (`fatal`: the next message's start is unknown).
`LocalProtocolError` means this side was asked to send something RCTP/2.0 does not allow.
"""

from __future__ import annotations

from rcmlconf.errors import ProtocolError, RcmlconfError


class RemoteProtocolError(ProtocolError):
    def __init__(
        self,
        reason: str,
        offset: int,
        status: int,
        rule: str | None = None,
        *,
        fatal: bool = False,
        answerable: bool = True,
    ) -> None:
        super().__init__(reason, offset, rule)
        #: The status code the peer's request should be answered with (D-RCTP-15).
        self.status = status
        #: Whether framing is lost and the connection must close after the answer (D-RCTP-10).
        self.fatal = fatal
        #: False for a broken response, which gets no answer (D-RCTP-10).
        self.answerable = answerable


class LocalProtocolError(RcmlconfError):
    """This side tried to send something RCTP/2.0 does not allow."""
