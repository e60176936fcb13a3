"""vectors/rctp/transcripts: whole exchanges through a client and a server connection.

Each step says who acts (`send`, `answer`, a `timer`, or `raw` bytes from a misbehaving peer),
the exact bytes that go on the wire, the events the receiving side must see, and what it must
answer on its own (`reply`). The same transcripts are replayed with every step's bytes cut into
random pieces: any split must give the same events (R-RCTP-13).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rctp.connection import Connection, Event
from rcmlconf.rctp.states import Role

TRANSCRIPTS = sorted(
    (Path(__file__).parents[2] / "vectors" / "rctp" / "transcripts").glob("*.json")
)
ROLES = {"client": Role.CLIENT, "server": Role.SERVER}
OTHER = {"client": "server", "server": "client"}

Chunker = Callable[[bytes], list[bytes]]


def whole(data: bytes) -> list[bytes]:
    return [data] if data else []


def wire(text: str) -> bytes:
    return text.encode("latin-1")


def describe(event: Event) -> dict[str, Any]:
    """The fields of an event a transcript may name."""
    found: dict[str, Any] = {"event": type(event).__name__}
    for name, attribute in (("request", "request"), ("response", "response")):
        message = getattr(event, attribute, None)
        if message is not None and name == "request" and hasattr(message, "method"):
            found["method"] = message.method
        if message is not None and name == "response":
            found["status"] = message.status
            found["body"] = message.body.hex()
    if hasattr(event, "request") and getattr(event, "cseq", None) is not None:
        found["body"] = event.request.body.hex()
    for key in ("cseq", "rule", "reason"):
        if hasattr(event, key):
            found[key] = getattr(event, key)
    if hasattr(event, "status") and not hasattr(event, "response"):
        found["status"] = event.status
    if hasattr(event, "target"):
        found["target"] = event.target.path
    if hasattr(event, "session"):
        found["session"] = event.session.id
    if hasattr(event, "by"):
        found["by"] = event.by.value
    if hasattr(event, "error"):
        found.update(status=event.error.status, rule=event.error.rule, offset=event.error.offset)
    return found


def matches(expected: list[dict[str, Any]], events: list[Event]) -> bool:
    got = [describe(e) for e in events]
    return len(got) == len(expected) and all(
        all(g.get(key) == value for key, value in e.items())
        for e, g in zip(expected, got, strict=True)
    )


class Pair:
    def __init__(self, chunk: Chunker) -> None:
        self.cores = {name: Connection(role, 0.0) for name, role in ROLES.items()}
        self.chunk = chunk
        self.now = 0.0
        #: step index -> the request the other side received in that step
        self.received: dict[int, Any] = {}

    def deliver(self, to: str, data: bytes) -> list[Event]:
        core = self.cores[to]
        for piece in self.chunk(data):
            core.receive_data(piece, self.now)
        return self.events(to)

    def events(self, name: str) -> list[Event]:
        found = []
        while (event := self.cores[name].next_event()) is not None:
            found.append(event)
        return found

    def step(self, index: int, step: dict[str, Any]) -> None:
        self.now = step.get("at", self.now + 0.01)
        if "raw" in step:
            receiver = step["raw"]
            events = self.deliver(receiver, wire(step["wire"]))
            assert matches(step["events"], events), (index, [describe(e) for e in events])
            assert self.cores[receiver].data_to_send() == wire(step["reply"]), index
            return
        actor = step.get("from") or step["timer"]
        core = self.cores[actor]
        if "send" in step:
            send = step["send"]
            core.send_request(
                send["method"],
                send["target"],
                [tuple(h) for h in send.get("headers", [])],
                bytes.fromhex(send.get("body", "")),
                now=self.now,
            )
        elif "answer" in step:
            core.send_response(
                self.received[step["answer"]],
                step["status"],
                [tuple(h) for h in step.get("headers", [])],
                bytes.fromhex(step.get("body", "")),
            )
        else:
            core.handle_timer(self.now)
        sent = core.data_to_send()
        assert sent == wire(step["wire"]), (index, sent)
        assert matches(step.get("also", {}).get(actor, []), self.events(actor)), index
        receiver = OTHER[actor]
        events = self.deliver(receiver, sent)
        assert matches(step["events"], events), (index, [describe(e) for e in events])
        for event in events:
            if hasattr(event, "cseq") and hasattr(event, "target"):
                self.received[index] = event.request
        if "reply" in step:
            reply = self.cores[receiver].data_to_send()
            assert reply == wire(step["reply"]), (index, reply)
            answered = self.deliver(actor, reply)
            assert matches(step["reply_events"], answered), (index, [describe(e) for e in answered])
        self.check_state(index, step.get("state", {}))

    def check_state(self, index: int, state: dict[str, Any]) -> None:
        for name in ("client", "server"):
            if name in state:
                assert self.cores[name].session_state.value == state[name], index
        if "streams" in state:
            for core in self.cores.values():
                assert {p: s.value for p, s in core.streams.items()} == state["streams"], index


def play(path: Path, chunk: Chunker = whole) -> None:
    transcript = json.loads(path.read_text(encoding="utf-8"))
    pair = Pair(chunk)
    for index, step in enumerate(transcript["steps"]):
        pair.step(index, step)


@pytest.mark.parametrize("path", TRANSCRIPTS, ids=lambda p: p.stem)
def test_transcript(path: Path) -> None:
    play(path)


@pytest.mark.parametrize("path", TRANSCRIPTS, ids=lambda p: p.stem)
def test_transcript_one_byte_at_a_time(path: Path) -> None:
    play(path, lambda data: [data[i : i + 1] for i in range(len(data))])


@given(st.sampled_from(TRANSCRIPTS), st.randoms(use_true_random=False))
def test_transcript_in_random_pieces(path: Path, rng: Any) -> None:
    def chunk(data: bytes) -> list[bytes]:
        cuts = sorted(rng.sample(range(1, len(data)), min(len(data) - 1, rng.randint(0, 6))))
        return [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True)]

    play(path, chunk)
