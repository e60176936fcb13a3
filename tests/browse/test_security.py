"""Nobody but the user drives the robot: every request and the WebSocket need the token, the
panel's Host and its own Origin; the page's messages are checked, and a malformed one is refused
and logged, never a traceback. A real `browse` on a real `serve`, over real sockets."""

from __future__ import annotations

import http.client
import json
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
from support.browser import browsing, serving
from support.processes import BOUND, Running
from support.robots import CAMERA, ROBOTS
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

CAMERA_RXID = str(ROBOTS / "camera" / "camera.rxid")


@pytest.fixture(scope="module")
def panel(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Running]:
    directory = tmp_path_factory.mktemp("security")
    with (
        serving(directory / "serve", CAMERA) as server,
        browsing(directory / "browse", CAMERA_RXID, server) as browser,
    ):
        yield browser


def parts(panel: Running) -> tuple[int, str]:
    url = urlsplit(str(panel.ready["url"]))
    return int(panel.ready["port"]), url.query.removeprefix("token=")  # type: ignore[call-overload]


def get(port: int, target: str, **headers: str) -> http.client.HTTPResponse:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=BOUND)
    connection.putrequest("GET", target, skip_host=True)
    connection.putheader("Host", headers.pop("Host", f"127.0.0.1:{port}"))
    for name, value in headers.items():
        connection.putheader(name, value)
    connection.endheaders()
    response = connection.getresponse()
    response.read()
    connection.close()
    return response


def socket(port: int, token: str | None, origin: str | None = "same") -> ClientConnection:
    query = "" if token is None else f"?token={token}"
    if origin == "same":
        origin = f"http://127.0.0.1:{port}"
    return connect(
        f"ws://127.0.0.1:{port}/socket{query}",
        origin=origin,  # type: ignore[arg-type]
        open_timeout=BOUND,
    )


def test_the_page_and_its_files_need_the_token(panel: Running) -> None:
    port, token = parts(panel)
    page = get(port, f"/?token={token}")
    assert page.status == 200
    assert "script-src 'self'" in (page.headers["Content-Security-Policy"] or "")
    assert page.headers["Referrer-Policy"] == "no-referrer"
    assert get(port, f"/panel.js?token={token}").status == 200
    for target in ("/", "/panel.js", f"/?token={token[:-1]}", "/?token=", f"/x?token={token}"):
        assert get(port, target).status in (403, 404), target
    assert get(port, "/").status == 403


@pytest.mark.parametrize("host", ["evil.example:{port}", "127.0.0.1:1", "rebound.test", ""])
def test_a_foreign_host_is_refused(panel: Running, host: str) -> None:
    """DNS rebinding: a name that resolves to 127.0.0.1 still says its own name."""
    port, token = parts(panel)
    assert get(port, f"/?token={token}", Host=host.format(port=port)).status == 403


def test_a_foreign_origin_is_refused(panel: Running) -> None:
    port, token = parts(panel)
    assert get(port, f"/?token={token}", Origin="http://evil.example").status == 403
    assert get(port, f"/?token={token}", Origin=f"http://127.0.0.1:{port}").status == 200


@pytest.mark.parametrize(
    ("token", "origin"),
    [(None, "same"), ("wrong", "same"), ("TOKEN", "http://evil.example"), ("TOKEN", None)],
)
def test_the_socket_needs_token_and_origin(panel: Running, token: str | None, origin: str) -> None:
    port, real = parts(panel)
    with pytest.raises(InvalidStatus) as refused:
        socket(port, real if token == "TOKEN" else token, origin)
    assert refused.value.response.status_code == 403


def messages(connection: ClientConnection, kind: str) -> Iterator[dict[str, Any]]:
    while True:
        message = json.loads(connection.recv(timeout=BOUND))
        assert message["v"] == 1
        if message["type"] == kind:
            yield message


def test_the_socket_takes_no_compression(panel: Running) -> None:
    """Offered permessage-deflate (as Chromium offers it), the socket declines: messages of a
    hundred bytes at 62.5 Hz a page cost both ends CPU and time to squeeze (issue 20, Speed)."""
    port, token = parts(panel)
    with socket(port, token) as connection:
        assert "permessage-deflate" in (connection.request.headers["Sec-WebSocket-Extensions"])
        assert "Sec-WebSocket-Extensions" not in connection.response.headers
        assert next(messages(connection, "panel"))["title"] == "Camera"


def test_malformed_messages_are_refused_logged_and_the_page_goes_on(tmp_path: Path) -> None:
    with (
        serving(tmp_path / "serve", CAMERA) as server,
        browsing(tmp_path / "browse", CAMERA_RXID, server) as browser,
    ):
        refused_all(browser)
        status, _, err = browser.stop()
    assert status == 0
    assert err.count("refused a message: ") == 10
    assert "page 1: refused a message: not JSON" in err


def refused_all(panel: Running) -> None:
    port, token = parts(panel)
    with socket(port, token) as connection:
        described = next(messages(connection, "panel"))
        widgets = {w["id"] or w["caption"]: w["key"] for w in described["windows"][0]["widgets"]}
        refused = messages(connection, "refused")
        for bad, reason in [
            ("{", "not JSON"),
            ("[1]", "not a JSON object"),
            ('{"v": 2, "type": "input"}', "version 2"),
            ('{"v": 1, "type": "eval", "widget": "w0"}', 'type "eval"'),
            ('{"v": 1, "type": "input", "widget": "w999", "value": "1"}', "none of the panel's"),
            (
                json.dumps({"v": 1, "type": "input", "widget": widgets["Moving"], "value": "on"}),
                "writes nothing",
            ),
            (
                json.dumps({"v": 1, "type": "input", "widget": widgets["pan"], "value": 5}),
                "not a string",
            ),
            (
                json.dumps({"v": 1, "type": "action", "widget": widgets["pan"]}),
                "not an actionButton",
            ),
            ("[" * 100_000 + "]" * 100_000, "not JSON"),
        ]:
            connection.send(bad)
            assert reason in next(refused)["reason"], bad
        connection.send(b"\x00binary")
        assert "binary" in next(refused)["reason"]
        # Still served: a value out of the node's range is the robot's refusal, in words.
        connection.send(
            json.dumps({"v": 1, "type": "input", "widget": widgets["pan"], "value": "999"})
        )
        refusal = next(messages(connection, "refusal"))
        assert refusal["widget"] == widgets["pan"]
        assert "outside /stream/control/pan's range -180 to 180" in refusal["text"]


def test_a_host_beyond_loopback_says_the_token_guards_it(tmp_path: Path) -> None:
    with (
        serving(tmp_path / "serve", CAMERA) as server,
        browsing(tmp_path / "browse", CAMERA_RXID, server, "--host", "0.0.0.0") as browser,
    ):
        port, token = parts(browser)
        assert get(port, "/").status == 403
        assert get(port, f"/?token={token}").status == 200
        status, _, err = browser.stop(signal.SIGTERM)
    assert status == 0
    assert "serving on 0.0.0.0: other machines can reach the page" in err
    assert "only the token in the URL keeps them from driving the robot" in err
