"""The exceptions rcmlconf raises on purpose.

Every parser lets exactly one kind of exception escape for bad input: `ProtocolError` for bytes
on the wire, `ValueTextError` for a value written as text. Anything else escaping a parser is a bug.
"""

from __future__ import annotations


class RcmlconfError(Exception):
    """Base of every exception rcmlconf raises on purpose."""


class ProtocolError(RcmlconfError):
    """Bytes that break a protocol: why (`reason`) and where (`offset`, in bytes from the start).

    `rule` names the requirement of specs/ the bytes break, when one does.
    """

    def __init__(self, reason: str, offset: int, rule: str | None = None) -> None:
        super().__init__(f"{reason} (at byte {offset})")
        self.reason = reason
        self.offset = offset
        self.rule = rule


class EncodeError(RcmlconfError):
    """A value this side was asked to send does not fit its type: our mistake, not the peer's."""


class ValueTextError(RcmlconfError):
    """A value written as text (D-RCML-14) is not a value of its type."""
