"""The control-message reader and writer, by property: any message, any split, any garbage."""

from __future__ import annotations

import gc
import weakref

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rctp.errors import LocalProtocolError, RemoteProtocolError
from rcmlconf.rctp.messages import METHODS, Headers, Message, Request, Response
from rcmlconf.rctp.reader import LIMITS, MessageReader
from rcmlconf.rctp.writer import write_message

tokens = st.from_regex(r"[A-Za-z][A-Za-z0-9\-]{0,15}", fullmatch=True)
values = st.from_regex(r"[\x21-\x7e](?:[\x20-\x7e]{0,30}[\x21-\x7e])?", fullmatch=True) | st.just(
    ""
)
bodies = st.binary(max_size=300)


@st.composite
def messages(draw: st.DrawFn) -> Message:
    fields = draw(
        st.lists(
            st.tuples(tokens.filter(lambda n: n.lower() != "content-length"), values), max_size=8
        )
    )
    body = draw(bodies)
    if body:
        fields.append(("Content-Length", str(len(body))))
    headers = Headers(tuple(fields))
    if draw(st.booleans()):
        method = draw(st.sampled_from(METHODS) | tokens.map(str.upper))
        target = draw(st.sampled_from(["*", "/", "/a", "/drive/wheels/left", "/%E9%9B%B2"]))
        return Request(method, target, headers, body)
    status = draw(st.integers(100, 999))
    reason = draw(st.from_regex(r"[ -~]{0,20}", fullmatch=True))
    return Response(status, reason, headers, body)


def read_all(data: bytes, cuts: list[int]) -> list[Message]:
    reader = MessageReader()
    found = []
    for start, end in zip([0, *cuts], [*cuts, len(data)], strict=True):
        reader.feed(data[start:end])
        while (message := reader.next_message()) is not None:
            found.append(message)
    return found


@given(st.lists(messages(), min_size=1, max_size=4), st.data())
def test_any_messages_survive_any_split(batch: list[Message], data: st.DataObject) -> None:
    wire = b"".join(write_message(m) for m in batch)
    cuts = sorted(set(data.draw(st.lists(st.integers(1, max(1, len(wire) - 1)), max_size=10))))
    assert read_all(wire, [c for c in cuts if c < len(wire)]) == batch


@given(st.binary(max_size=400))
def test_garbage_raises_only_the_protocol_error(garbage: bytes) -> None:
    reader = MessageReader()
    reader.feed(garbage)
    try:
        while reader.next_message() is not None:
            pass
    except RemoteProtocolError as error:
        failure = error
    else:
        return
    assert failure.fatal
    assert 0 <= failure.offset <= len(garbage)
    with pytest.raises(RemoteProtocolError):  # and it stays refused
        reader.next_message()


@given(
    messages(),
    st.lists(
        st.tuples(st.integers(0, 10**6), st.binary(min_size=1, max_size=3)), min_size=1, max_size=5
    ),
)
def test_mutated_messages_raise_only_the_protocol_error(
    message: Message, edits: list[tuple[int, bytes]]
) -> None:
    wire = bytearray(write_message(message))
    for at, insert in edits:
        wire[at % (len(wire) + 1) : at % (len(wire) + 1)] = insert
    reader = MessageReader()
    reader.feed(bytes(wire))
    try:
        while reader.next_message() is not None:
            pass
    except RemoteProtocolError:
        pass


@pytest.mark.parametrize(
    ("data", "status"),
    [
        (b"X" * (LIMITS.start_line + 2), 414),
        (b"READ / RCTP/2.0\r\n" + b"A: b\r\n" * (LIMITS.header_fields + 1) + b"\r\n", 431),
        (b"READ / RCTP/2.0\r\nA: " + b"b" * LIMITS.header_line + b"\r\n\r\n", 431),
        (b"READ / RCTP/2.0\r\n" + b"A: bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb\r\n" * 460, 431),
        (b"WRITE / RCTP/2.0\r\nContent-Length: 4194305\r\n\r\n", 413),
        (b"WRITE / RCTP/2.0\r\nContent-Length: 2\r\nContent-Length: 2\r\n\r\nab", 400),
        (b"WRITE / RCTP/2.0\r\nContent-Length: -2\r\n\r\n", 400),
        (b"WRITE / RCTP/2.0\r\nTransfer-Encoding: chunked\r\n\r\n", 400),
        (b"READ / RCTP/2.0\r\n folded: no\r\n\r\n", 400),
        (b"READ / RCTP/2.0\r\nName : value\r\n\r\n", 400),
        (b"READ / RCTP/2.0\r\nName: a\x00b\r\n\r\n", 400),
        (b"READ / HTTP/1.1\r\n\r\n", 400),
        (b"READ /\r\n\r\n", 400),
        (b"READ / RCTP/2.0\rCSeq: 1\r\n\r\n", 400),
    ],
)
def test_framing_errors_are_refused_with_their_status(data: bytes, status: int) -> None:
    reader = MessageReader()
    reader.feed(data)
    with pytest.raises(RemoteProtocolError) as failure:
        read_all(data, [])
    assert failure.value.status == status
    assert failure.value.fatal


@pytest.mark.parametrize(
    ("length", "status", "reason"),
    [
        (b"99999999999", 400, "Content-Length has 11 digits, more than the 10 of its grammar"),
        (b"1" * 4000, 400, "Content-Length has 4,000 digits, more than the 10 of its grammar"),
        (b"00000000003", 400, "Content-Length has 11 digits, more than the 10 of its grammar"),
        (b"4194305", 413, "body of 4,194,305 bytes is above the limit of 4,194,304"),
        (b"3.0", 400, "Content-Length is not a decimal number"),
        (b"3\r\nContent-Length: 3", 400, "Content-Length is given more than once"),
    ],
)
def test_a_bad_content_length_is_refused_for_what_it_is(
    length: bytes, status: int, reason: str
) -> None:
    """Each is refused for what it is: an 11-digit length was "not one decimal number"."""
    with pytest.raises(RemoteProtocolError) as failure:
        read_all(b"WRITE / RCTP/2.0\r\nCSeq: 1\r\nContent-Length: " + length + b"\r\n\r\n", [])
    assert (failure.value.status, failure.value.reason[: len(reason)]) == (status, reason)


def test_limits_are_seen_before_the_bytes_are_buffered() -> None:
    """R-RCTP-16: an endless start line is refused at the limit, not at the end of memory."""
    reader = MessageReader()
    refused = False
    for _ in range(100):
        reader.feed(b"A" * 1000)
        try:
            reader.next_message()
        except RemoteProtocolError:
            refused = True
            break
    assert refused
    assert reader.buffered <= LIMITS.start_line + 1000


def test_a_broken_response_is_not_answerable() -> None:
    reader = MessageReader()
    reader.feed(b"RCTP/2.0 2x0 OK\r\n\r\n")
    with pytest.raises(RemoteProtocolError) as failure:
        reader.next_message()
    assert not failure.value.answerable


@pytest.mark.parametrize(
    "message",
    [
        Request("READ", "/a b"),
        Request("RE AD", "/a"),
        Request("READ", "/a", Headers((("CSeq", "1\r\nX: y"),))),
        Request("READ", "/a", Headers((("Bad Name", "v"),))),
        Request("READ", "/a", Headers((("Name", " padded"),))),
        Request("WRITE", "/a", body=b"x"),
        Request("WRITE", "/a", Headers((("Content-Length", "2"),)), b"x"),
        Response(200, "OK\r\n"),
        Response(42, "OK"),
    ],
)
def test_the_writer_refuses_what_the_grammar_refuses(message: Message) -> None:
    with pytest.raises(LocalProtocolError):
        write_message(message)


def test_a_failed_reader_is_freed_without_the_collector() -> None:
    """The failure it keeps holds no traceback: its frames would hold the reader in a cycle that
    only the collector frees, one per bad request of a flood (issue 18)."""
    reader = MessageReader()
    reader.feed(b"GARBAGE\n\n")
    for _ in range(2):  # the failure, then the same again
        with pytest.raises(RemoteProtocolError):
            reader.next_message()
    gone = weakref.ref(reader)
    gc.disable()
    try:
        del reader
        assert gone() is None
    finally:
        gc.enable()
