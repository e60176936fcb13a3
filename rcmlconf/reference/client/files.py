"""The robot's RCML, which a client needs to encode and decode values (bodies carry no types).

From a file or an http(s) URL the user names, or else the way a browser finds it (paper Fig. 5):
a server lists the robot's files on HTTP at the port after RCTP's (D-RCTP-29), so the client
reads that index and takes its one `.rcml` link. Nothing fetched may exceed a document's limit
(16 MiB, D-XML-5), and every fetched document is validated like a local one. The reference
client's command line and the conformance run (`run --target` without `--rcml`) both use it.
"""

from __future__ import annotations

import http.client
import urllib.error
import urllib.request
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlsplit

from rcmlconf.errors import RcmlconfError
from rcmlconf.markup.document import MAX_DOCUMENT_BYTES
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rctp.url import RctpUrl
from rcmlconf.validate.validator import InvalidRobot, Validator, load_robot
from rcmlconf.wording import plural

_HINT = "pass the robot's RCML with --rcml PATH_OR_URL"


class NoModel(RcmlconfError):
    """The RCML could not be had or is not valid; the message says which and why."""


def is_http_url(text: str) -> bool:
    """Whether `text` names an http(s) URL rather than a file."""
    scheme, colon, _ = text.partition(":")
    return bool(colon) and scheme.lower() in ("http", "https")


def load_model(url: RctpUrl, rcml: str | None, timeout: float) -> RcmlDocument:
    """The model `rcml` names (a file or an http(s) URL), or else the one the robot's files
    index links to (D-RCTP-29)."""
    if rcml is None:
        return from_index(url, timeout)
    if is_http_url(rcml):
        return _from_url(rcml, timeout)
    try:
        return load_robot(Path(rcml))
    except InvalidRobot as exc:
        raise NoModel(str(exc)) from None


def from_index(url: RctpUrl, timeout: float, hint: str = _HINT) -> RcmlDocument:
    """The model the robot's files index at the port after RCTP's links to (D-RCTP-29)."""
    index = url.files_url  # D-RCTP-29
    try:
        page = _fetch(index, timeout)
    except NoModel as exc:
        raise NoModel(
            f"{exc} (the robot's files, at the port after RCTP's: D-RCTP-29); {hint}"
        ) from None
    links = _Links()
    links.feed(page.decode("utf-8", "replace"))
    found = sorted({link for href in links.hrefs if (link := _rcml_link(index, href))})
    if len(found) != 1:
        raise NoModel(f"{index} links to {plural(len(found), 'RCML file')}, not one; {hint}")
    return _from_url(found[0], timeout)


def _rcml_link(index: str, href: str) -> str | None:
    """The URL an index's link names, if it is an RCML file's; a link that is no URL is none."""
    try:
        url = urljoin(index, href)
        return url if urlsplit(url).path.endswith(".rcml") else None
    except ValueError:  # `http://[::1`: the page is the server's, not to be trusted
        return None


def _from_url(url: str, timeout: float) -> RcmlDocument:
    # No directory: the document's relative links are not followed (D-RXID-3's rule for URLs).
    report, model = Validator().load_bytes(_fetch(url, timeout), url, suffix=".rcml")
    if isinstance(model, RcmlDocument):
        return model
    if report.kind != "rcml":
        raise NoModel(f"{url} is not an RCML document; {_HINT}")
    first = report.diagnostics[0].to_text() if report.diagnostics else "checking was cut short"
    raise NoModel(f"{url} is not valid RCML ({plural(report.errors, 'error')}): {first}")


def _fetch(url: str, timeout: float) -> bytes:
    """The body of a GET, at most MAX_DOCUMENT_BYTES; `timeout` bounds each wait for the peer."""
    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            data: bytes = response.read(MAX_DOCUMENT_BYTES + 1)
    except urllib.error.HTTPError as exc:
        raise NoModel(f"cannot fetch {url}: {exc.code} {exc.reason}") from None
    except urllib.error.URLError as exc:
        raise NoModel(f"cannot fetch {url}: {exc.reason}") from None
    except (OSError, ValueError, http.client.HTTPException) as exc:
        raise NoModel(f"cannot fetch {url}: {exc or type(exc).__name__}") from None
    if len(data) > MAX_DOCUMENT_BYTES:
        raise NoModel(f"{url} is larger than a document may be ({MAX_DOCUMENT_BYTES} bytes)")
    return data


class _Links(HTMLParser):
    """The `href` of every `<a>` of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.hrefs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "a":
            self.hrefs.extend(value for name, value in attrs if name == "href" and value)
