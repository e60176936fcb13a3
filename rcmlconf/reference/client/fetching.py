"""A GET over http(s), bounded as a whole: in time by a deadline, in size by a limit (D-RCTP-29).

urllib's timeout bounds each wait for the peer, not the fetch: a server that sends a byte a
second answers every wait, and holds the fetch for ever. Here every read of an answer, its head
as well as its body, waits at most until the deadline, so one deadline bounds a fetch of one
document or of several (an index and the file it links, a panel and its RCML files). A fetch the
deadline ends says how far the server got. Redirects and proxies are urllib's, and bounded the
same way. The reference client, `browse` and `run --target` without `--rcml` fetch with it.
"""

from __future__ import annotations

import http.client
import io
import socket
import time
import urllib.error
import urllib.request
from typing import Any

from rcmlconf.errors import RcmlconfError
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES
from rcmlconf.wording import plural


class Unfetched(RcmlconfError):
    """A GET that failed, did not end by its deadline, or gave more than its limit; the
    message names the URL and why."""


class Deadline:
    """The time by which one fetch or several must have ended, `seconds` from now."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._end = time.monotonic() + seconds

    def left(self) -> float:
        """Seconds until the deadline; 0 or less once it passed."""
        return self._end - time.monotonic()


def fetch(url: str, within: Deadline, limit: int = MAX_DOCUMENT_BYTES) -> bytes:
    """The body of a GET of `url`, at most `limit` bytes (a document's by default), read whole
    before the deadline `within`."""
    reads = _Reads(within)
    try:
        opener = urllib.request.build_opener(_handler(reads))
        with opener.open(url, timeout=reads.wait()) as response:
            data: bytes = response.read(limit + 1)
    except urllib.error.HTTPError as exc:
        raise Unfetched(f"cannot fetch {url}: {exc.code} {exc.reason}") from None
    except urllib.error.URLError as exc:
        if isinstance(exc.reason, TimeoutError):
            raise reads.unfinished(url) from None
        raise Unfetched(f"cannot fetch {url}: {exc.reason}") from None
    except TimeoutError:
        raise reads.unfinished(url) from None
    except (OSError, ValueError, http.client.HTTPException) as exc:
        raise Unfetched(f"cannot fetch {url}: {exc or type(exc).__name__}") from None
    if len(data) > limit:
        raise Unfetched(f"{url} is larger than it may be ({limit:,} bytes)")
    return data


class _Reads:
    """One GET's reads: each waits at most until the deadline; the bytes they got."""

    def __init__(self, deadline: Deadline) -> None:
        self.deadline = deadline
        self.started = time.monotonic()
        self.received = 0

    def wait(self) -> float:
        """How long the next wait for the peer may take: until the deadline."""
        left = self.deadline.left()
        if left <= 0:
            raise TimeoutError
        return left

    def unfinished(self, url: str) -> Unfetched:
        took = f"{round(time.monotonic() - self.started, 1):g} s"
        if not self.received:
            return Unfetched(f"cannot fetch {url}: no answer within {took}")
        got = plural(self.received, "byte")
        return Unfetched(f"{url} sent {got} in {took} and did not finish")


class _Bounded(io.RawIOBase):
    """A socket's bytes as http.client reads an answer, each read waiting until the deadline
    at most."""

    def __init__(self, raw: io.RawIOBase, sock: socket.socket, reads: _Reads) -> None:
        super().__init__()
        self._raw, self._sock, self._reads = raw, sock, reads

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int | None:
        self._sock.settimeout(self._reads.wait())
        got = self._raw.readinto(buffer)
        self._reads.received += got or 0
        return got

    def close(self) -> None:
        self._raw.close()
        super().close()


def _handler(reads: _Reads) -> urllib.request.BaseHandler:
    """urllib's handler of http and https URLs, whose answers are read through `_Bounded`."""

    class Answer(http.client.HTTPResponse):
        def __init__(self, sock: socket.socket, *args: Any, **kwargs: Any) -> None:
            super().__init__(sock, *args, **kwargs)
            self.fp = io.BufferedReader(_Bounded(self.fp.detach(), sock, reads))

    class Http(http.client.HTTPConnection):
        response_class = Answer

    class Https(http.client.HTTPSConnection):
        response_class = Answer

    class Handler(urllib.request.HTTPHandler, urllib.request.HTTPSHandler):
        def http_open(self, req: urllib.request.Request) -> http.client.HTTPResponse:
            return self.do_open(Http, req)

        def https_open(self, req: urllib.request.Request) -> http.client.HTTPResponse:
            return self.do_open(Https, req)  # the default TLS context, as urlopen's

    return Handler()
