"""The robot's RCML, which a client needs to encode and decode values (bodies carry no types).

From a file or an http(s) URL the user names, or else the way a browser finds it (paper Fig. 5):
a server lists the robot's files on HTTP at the port after RCTP's (D-RCTP-29), so the client
reads that index and takes its one `.rcml` link. Nothing fetched may exceed a document's limit
(16 MiB, D-XML-5), one deadline bounds the index and the file together (`fetching`), and every
fetched document is validated like a local one. The reference client's command line, its
conformance scenario (a case's index, D-RCTP-31) and the conformance run (`run --target` without
`--rcml`) use it.
"""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlsplit

from rcmlconf.errors import RcmlconfError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.reference.client.fetching import Deadline, Unfetched, fetch
from rcmlconf.validate.validator import InvalidRobot, Validator, load_robot
from rcmlconf.wording import plural

_HINT = "pass the robot's RCML with --rcml PATH_OR_URL"
_ROBOT_FILES = "the robot's files, at the port after RCTP's: D-RCTP-29"


class NoModel(RcmlconfError):
    """The RCML could not be had or is not valid; the message says which and why."""


def is_http_url(text: str) -> bool:
    """Whether `text` names an http(s) URL rather than a file."""
    scheme, colon, _ = text.partition(":")
    return bool(colon) and scheme.lower() in ("http", "https")


def load_model(url: RctpUrl, rcml: str | None, within: Deadline) -> RcmlDocument:
    """The model `rcml` names (a file or an http(s) URL), or else the one the robot's files
    index links to (D-RCTP-29), fetched by the deadline `within`."""
    if rcml is None:
        return from_index(url.files_url, within)  # D-RCTP-29
    return load_rcml(rcml, within)


def load_rcml(rcml: str, within: Deadline) -> RcmlDocument:
    """The model in the file or at the http(s) URL `rcml` names (fetched by `within`)."""
    if is_http_url(rcml):
        return _from_url(rcml, within)
    try:
        return load_robot(Path(rcml))
    except InvalidRobot as exc:
        raise NoModel(str(exc)) from None


def from_index(
    index: str, within: Deadline, hint: str | None = _HINT, files: str = _ROBOT_FILES
) -> RcmlDocument:
    """The model that the files index at the http URL `index` links to: a robot's at the port
    after RCTP's (`RctpUrl.files_url`, D-RCTP-29), or a conformance case's (D-RCTP-31); both
    fetched by the deadline `within`. An error says what the index is (`files`) and what to do
    instead (`hint`)."""
    advice = "" if hint is None else f"; {hint}"
    try:
        page = fetch(index, within)
    except Unfetched as exc:
        raise NoModel(f"{exc} ({files}){advice}") from None
    links = _Links()
    links.feed(page.decode("utf-8", "replace"))
    found = sorted({link for href in links.hrefs if (link := _rcml_link(index, href))})
    if len(found) != 1:
        raise NoModel(f"{index} links to {plural(len(found), 'RCML file')}, not one{advice}")
    return _from_url(found[0], within)


def _rcml_link(index: str, href: str) -> str | None:
    """The URL an index's link names, if it is an RCML file's; a link that is no URL is none."""
    try:
        url = urljoin(index, href)
        return url if urlsplit(url).path.endswith(".rcml") else None
    except ValueError:  # `http://[::1`: the page is the server's, not to be trusted
        return None


def _from_url(url: str, within: Deadline) -> RcmlDocument:
    try:
        data = fetch(url, within)
    except Unfetched as exc:
        raise NoModel(str(exc)) from None
    # No directory: the document's relative links are not followed (D-RXID-3's rule for URLs).
    report, model = Validator().load_bytes(data, url, suffix=".rcml")
    if isinstance(model, RcmlDocument):
        return model
    if report.kind != "rcml":
        raise NoModel(f"{url} is not an RCML document; {_HINT}")
    first = report.diagnostics[0].to_text() if report.diagnostics else "checking was cut short"
    raise NoModel(f"{url} is not valid RCML ({plural(report.errors, 'error')}): {first}")


class _Links(HTMLParser):
    """The `href` of every `<a>` of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.hrefs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "a":
            self.hrefs.extend(value for name, value in attrs if name == "href" and value)
