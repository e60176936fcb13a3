"""What a test case sends: steps, each one message or datagram, and the state they start from.

A step's bytes are a template. What the target chose in this run goes in when the step is
sent: `{session}` becomes the session's ID (D-RCTP-11) and `{client_port}` the fuzzer's UDP
port; a data-stream step marked `tagged` gets the session's tag (D-RCTP-18) in bytes 4 to 8,
and its first payload's stream byte, where the template says 1, the stream's ID.
So a finding replays against a target that picks other IDs (D-FUZZ-6).

Played to a client (D-FUZZ-8), `{cseq}` is the `CSeq` the played server gives the message (the
client's request's, in an answer; the next of its own, in a request of its own) and
`{transport}` the `Transport` its SETUP answer gives; a request of the server's keeps the valid
request its mutation began from (`origin`), which the played server's core sends in its place.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal

Channel = Literal["control", "data"]
#: Where the session's ID goes in a control step.
SESSION = b"{session}"
#: Where the fuzzer's own UDP port goes (SETUP's Transport, D-RCTP-19).
CLIENT_PORT = b"{client_port}"
#: Played to a client (D-FUZZ-8): where the message's CSeq goes, and the SETUP answer's Transport.
CSEQ = b"{cseq}"
TRANSPORT = b"{transport}"
#: The step kind of what a valid prefix sends (D-FUZZ-1).
PREFIX = "prefix"


@dataclass(frozen=True, slots=True)
class Step:
    channel: Channel
    data: bytes
    #: "prefix", or the mutation that made it (`mutate.KINDS`).
    kind: str = PREFIX
    #: A data-stream step whose tag field is the session's (the fuzzer's mutation left it).
    tagged: bool = False
    #: Played to a client: the valid request of the server's this step's mutation began from.
    origin: bytes = b""

    def to_json(self) -> dict[str, Any]:
        item = {
            "channel": self.channel,
            "kind": self.kind,
            "tagged": self.tagged,
            "hex": self.data.hex(),
        }
        if self.origin:
            item["origin_hex"] = self.origin.hex()
        return item

    @classmethod
    def from_json(cls, item: dict[str, Any]) -> Step:
        channel = item["channel"]
        if channel not in ("control", "data"):
            raise ValueError(f"step channel {channel!r} is not control or data")
        origin = bytes.fromhex(item.get("origin_hex", ""))
        return cls(
            channel, bytes.fromhex(item["hex"]), str(item["kind"]), bool(item["tagged"]), origin
        )


@dataclass(frozen=True, slots=True)
class TestCase:
    """A valid prefix that drives the target to `state`, then the mutated steps (D-FUZZ-1)."""

    __test__ = False  # not a pytest class

    state: str
    prefix: tuple[Step, ...]
    steps: tuple[Step, ...]
    #: The mutation kinds that made `steps`, for the state map.
    kinds: tuple[str, ...] = field(default=())

    def with_steps(self, steps: tuple[Step, ...]) -> TestCase:
        return replace(self, steps=steps)

    @property
    def shape(self) -> tuple[str, ...]:
        """What the steps are, without their bytes: one bug gives one finding (D-FUZZ-6)."""
        return tuple(f"{s.channel}:{s.kind}" for s in self.steps)

    def to_json(self) -> dict[str, Any]:
        return {
            "state": self.state,
            "prefix": [s.to_json() for s in self.prefix],
            "steps": [s.to_json() for s in self.steps],
            "kinds": list(self.kinds),
        }

    @classmethod
    def from_json(cls, item: dict[str, Any]) -> TestCase:
        return cls(
            str(item["state"]),
            tuple(Step.from_json(s) for s in item["prefix"]),
            tuple(Step.from_json(s) for s in item["steps"]),
            tuple(str(k) for k in item.get("kinds", ())),
        )
