"""Header field values and request-targets (specs/rctp-2.0.md §2.1)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.fields import (
    SessionField,
    Transport,
    format_nodes,
    parse_cseq,
    parse_nodes,
    parse_session,
    parse_transport,
    same_token,
)
from rcmlconf.rctp.targets import format_target, parse_target

names = st.from_regex(
    r"[A-Za-z_\u00c0-\u00d6\u4e00-\u4e10][A-Za-z0-9_.\-\u4e00-\u4e10]{0,8}", fullmatch=True
)


@given(st.lists(names, min_size=1, max_size=5))
def test_targets_round_trip(path: list[str]) -> None:
    text = "/" + "/".join(path)
    assert parse_target(format_target(text)).path == text
    assert format_target(text).isascii()


@pytest.mark.parametrize("text", ["a", "//a", "/a/", "/a//b", "/1a", "/a%zz", "/%FF", "/a b", ""])
def test_not_targets(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_target(text)


@given(st.lists(names, min_size=1, max_size=6, unique=True))
def test_nodes_round_trip_in_canonical_order(listed: list[str]) -> None:
    assert parse_nodes(format_nodes(listed)) == tuple(sorted(listed))


@pytest.mark.parametrize("text", ["b, a", "a, a", "a,, b", "1a", ""])
def test_not_nodes(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_nodes(text)


@pytest.mark.parametrize(
    ("text", "value"),
    [("1", 1), ("2147483647", 2147483647), ("007", 7)],
)
def test_cseq(text: str, value: int) -> None:
    assert parse_cseq(text) == value


@pytest.mark.parametrize("text", ["0", "2147483648", "-1", "1.0", " 1", "", "99999999999"])
def test_not_cseq(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_cseq(text)


def test_session() -> None:
    assert parse_session("abcdefgh;timeout=60") == SessionField("abcdefgh", 60)
    assert parse_session("a$-_.+bcd") == SessionField("a$-_.+bcd")
    for bad in ("short", "x" * 65, "abcdefgh;timeout=", "abcdefgh;time=1", "abc defgh"):
        with pytest.raises(ValueTextError):
            parse_session(bad)


@given(
    st.builds(
        Transport,
        st.none() | st.integers(1, 65535),
        st.sampled_from(["read", "write", "both"]),
        st.none() | st.integers(1, 65535),
        st.none() | st.integers(0, 2**32 - 1),
        st.none() | st.integers(1, 255),
    )
)
def test_transport_round_trip(transport: Transport) -> None:
    assert parse_transport(str(transport)) == transport


@pytest.mark.parametrize(
    "text",
    [
        "tcp;client_port=1",
        "udp;client_port=0",
        "udp;client_port=70000",
        "udp;mode=rw",
        "udp;tag=xyz",
        "udp;stream=0",
        "udp;stream=256",
        "udp;color=red",
        "udp;client_port",
        "udp;client_port=1;client_port=2",
    ],
)
def test_not_transports(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_transport(text)


# -- letter case (D-RCTP-30): vectors/rctp/fields.json -------------------------------------------

FIELDS = json.loads((Path(__file__).parents[2] / "vectors" / "rctp" / "fields.json").read_text())


@pytest.mark.parametrize("vector", FIELDS["transport"], ids=lambda v: v["text"])
def test_transport_in_any_letter_case(vector: dict[str, Any]) -> None:
    value = dict(vector["value"])
    if "tag" in value:
        value["tag"] = int(value["tag"], 16)
    assert parse_transport(vector["text"]) == Transport(**value)


@pytest.mark.parametrize("vector", FIELDS["not_transport"], ids=lambda v: v["text"])
def test_not_transport_in_any_letter_case(vector: dict[str, Any]) -> None:
    with pytest.raises(ValueTextError):
        parse_transport(vector["text"])


@pytest.mark.parametrize("vector", FIELDS["session"], ids=lambda v: v["text"])
def test_session_timeout_in_any_letter_case(vector: dict[str, Any]) -> None:
    assert parse_session(vector["text"]) == SessionField(vector["id"], vector["timeout"])


@pytest.mark.parametrize("vector", FIELDS["not_session"], ids=lambda v: v["text"])
def test_not_session_in_any_letter_case(vector: dict[str, Any]) -> None:
    with pytest.raises(ValueTextError):
        parse_session(vector["text"])


@pytest.mark.parametrize("vector", FIELDS["tokens"], ids=lambda v: f"{v['given']}")
def test_tokens_compare_without_ascii_case(vector: dict[str, Any]) -> None:
    assert same_token(vector["given"], vector["token"]) is vector["same"]


@given(st.sampled_from(["udp", "client_port", "mode", "both"]), st.data())
def test_transport_tokens_fold_in_any_mix_of_case(word: str, data: st.DataObject) -> None:
    mixed = "".join(c.upper() if data.draw(st.booleans()) else c for c in word)
    text = {
        "udp": f"{mixed};mode=read",
        "client_port": f"udp;{mixed}=9",
        "mode": f"udp;{mixed}=both",
        "both": f"udp;mode={mixed}",
    }[word]
    assert parse_transport(text) == parse_transport(text.lower())
