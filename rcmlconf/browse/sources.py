"""The panel's documents as the RCML browser gets them (paper Fig. 5): the RXID file from a path or
an http(s) URL, then the RCML file each of its sessions names, every one validated as `validate`
validates it.

Unlike the validator (D-RXID-3), a browser downloads what a session names: that is what it is
for. It still reads nothing else: an http(s) URL is fetched (within a document's limit, D-XML-5),
a relative `*.rcml` beside a local RXID file is read, and any other href is left unresolved, so
an RXID cannot make it read `/etc/passwd` or a `file:` URL. An unresolved session is an error
here (the panel cannot link without its RCML), located as the validator locates it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path, PurePosixPath
from urllib.parse import unquote, urljoin, urlsplit

from rcmlconf.diagnostics import Diagnostic, Severity
from rcmlconf.errors import RcmlconfError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.reference.client.fetching import Deadline, Unfetched, fetch
from rcmlconf.reference.client.files import NoModel, is_http_url, load_rcml
from rcmlconf.rxid.model import RxidDocument
from rcmlconf.rxid.sessions import Broken, SessionTarget, Unresolved
from rcmlconf.validate.validator import FileReport, Validator, read_document

#: The diagnostic of a session whose RCML could not be had (a warning to `validate`).
_UNRESOLVED = "R-RXID-10"


class Unreadable(RcmlconfError):
    """The RXID file cannot be read or fetched: the message names it and says why."""


class Invalid(RcmlconfError):
    """The RXID, or an RCML it names, is invalid or cannot be had: `report` says where."""

    def __init__(self, report: FileReport) -> None:
        super().__init__(f"{report.path} cannot be shown")
        self.report = report


@dataclass(frozen=True, slots=True)
class Robot:
    """The RCML one session href leads to."""

    href: str
    #: Where it was read from: a URL or a file's path.
    location: str
    model: RcmlDocument


@dataclass(frozen=True, slots=True)
class Sources:
    rxid: RxidDocument
    #: The RXID's URL or path, as given.
    location: str
    #: Session href -> its robot: every href of the document has one.
    robots: dict[str, Robot]
    #: The RXID's warnings, for the command to print.
    report: FileReport


def load_sources(source: str, timeout: float) -> Sources:
    """The RXID that `source` (a path or an http(s) URL) names and the RCML of each session,
    every one fetched within `timeout` seconds of the start: one deadline bounds them all.

    Raises Unreadable when the RXID cannot be had, Invalid when it or an RCML is not valid."""
    within = Deadline(timeout)
    base_url, base_dir, data = _read(source, within)
    robots: dict[str, Robot] = {}

    def resolve(href: str) -> SessionTarget:
        found = _resolve(validator, href, base_url, base_dir, within)
        if isinstance(found, Robot):
            robots[href] = found
            return found.model
        return found

    validator = Validator(resolve=resolve)
    suffix = PurePosixPath(urlsplit(source).path if base_url else source).suffix
    report, model = validator.load_bytes(data, source, base_dir, suffix)
    if any(d.rule == _UNRESOLVED for d in report.diagnostics):
        report = replace(report, diagnostics=tuple(map(_needed, report.diagnostics)))
    if not isinstance(model, RxidDocument) or not report.valid:
        if report.valid:  # valid, in another language
            raise Unreadable(f"{source} is a valid <{report.kind}> document, not an RXID panel")
        raise Invalid(report)
    return Sources(model, source, robots, report)


def _read(source: str, within: Deadline) -> tuple[str | None, Path | None, bytes]:
    """(base URL, base directory, bytes) of the RXID."""
    if is_http_url(source):
        try:
            return source, None, fetch(source, within)
        except Unfetched as exc:
            raise Unreadable(str(exc)) from None
    path = Path(source)
    try:
        return None, path.parent, read_document(path)
    except OSError as exc:
        raise Unreadable(f"cannot read {source}: {exc.strerror or exc}") from None


def _resolve(
    validator: Validator, href: str, base_url: str | None, base_dir: Path | None, within: Deadline
) -> Robot | Unresolved | Broken:
    try:
        parts = urlsplit(href)
        url = urljoin(base_url, href) if base_url is not None else href
    except ValueError as exc:  # `http://[::1`
        return Broken(f"{href!r} is not a URL: {exc}")
    if is_http_url(url):
        try:
            return Robot(href, url, load_rcml(url, within))
        except NoModel as exc:
            return Broken(str(exc))
    if base_dir is None or parts.scheme or parts.netloc:
        return Unresolved("the browser fetches http(s) URLs only")
    if parts.path.startswith("/") or not parts.path.endswith(".rcml"):
        return Unresolved("a local panel's session names a relative *.rcml file or an http(s) URL")
    path = base_dir / unquote(parts.path)
    try:
        model = validator.load_file(path)[1]
    except OSError as exc:
        return Broken(f"{path} cannot be read: {exc.strerror}")
    if isinstance(model, RcmlDocument):
        return Robot(href, str(path), model)
    return Broken(f"{path} is not valid RCML; `rcmlconf validate {path}` says why")


def _needed(diagnostic: Diagnostic) -> Diagnostic:
    """R-RXID-10 as an error: a panel cannot link through a session it has no RCML for."""
    if diagnostic.rule != _UNRESOLVED:
        return diagnostic
    return replace(diagnostic, severity=Severity.ERROR, hint="the browser needs every RCML")
