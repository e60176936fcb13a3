"""The RCTP URL `rctp://host[:port][/path]` (D-RCML-17)."""

from __future__ import annotations

import pytest

from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.url import RctpUrl, parse_rctp_url


@pytest.mark.parametrize(
    ("text", "url"),
    [
        ("rctp://rrr.rcml.org", RctpUrl("rrr.rcml.org", None, "/")),
        ("RCTP://robot.example:5000/camera", RctpUrl("robot.example", 5000, "/camera")),
        ("rctp://127.0.0.1:1/", RctpUrl("127.0.0.1", 1, "/")),
        ("rctp://[::1]:65535/a/b", RctpUrl("::1", 65535, "/a/b")),
        ("rctp://[FE80:0::1%25eth0]/", RctpUrl("fe80::1%eth0", None, "/")),
    ],
)
def test_urls(text: str, url: RctpUrl) -> None:
    assert parse_rctp_url(text) == url
    assert parse_rctp_url(str(url)) == url  # what it prints, it reads back


@pytest.mark.parametrize(
    "text",
    [
        "http://robot.example",
        "rctp:/robot",
        "rctp://",
        "rctp://user@robot",
        "rctp://robot:0",
        "rctp://robot:65536",
        "rctp://robot:",
        "rctp://robot/a?b",
        "rctp://robot/a#b",
        "rctp://robot/a b",
        "rctp://[::1",
        "rctp://[::g]/",
        "rctp://[fe80::1%eth0]",
        "rctp://[fe80::1%25a b]",
        "rctp://robot:123456",
    ],
)
def test_not_urls(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_rctp_url(text)
