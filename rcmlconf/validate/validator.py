"""Validate documents: parse under the XML profile, pick the language by root, check, report.

One `Validator` serves a whole run: an RCML file that several RXID sessions name (paper Fig. 3)
is read and checked once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar
from urllib.parse import unquote, urlsplit

from rcmlconf.diagnostics import Diagnostic, Severity
from rcmlconf.errors import RcmlconfError
from rcmlconf.markup.document import NAMESPACE_SEPARATOR, display_name, parse_document
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES, ParseFailure
from rcmlconf.markup.structure import Checker, TooManyFindings, check_prolog
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rxid.sessions import Broken, Resolver, SessionTarget, Unresolved
from rcmlconf.validate.languages import LANGUAGES, Language
from rcmlconf.wording import plural, shorten

if TYPE_CHECKING:
    from rcmlconf.validate.languages import Model

_Valid = TypeVar("_Valid", RcmlDocument, RobotModel)

#: Findings after which a document's checking stops (like a compiler's error limit): a hostile
#: document with a finding on each of 100,000 elements would otherwise take seconds.
DEFAULT_MAX_FINDINGS = 1000
#: The root elements the validator knows, for a message.
_ROOTS = ", ".join(f"<{root}>" for root in LANGUAGES)


@dataclass(frozen=True, slots=True)
class FileReport:
    path: str
    #: The language by root element; None when the document could not be parsed or is in none.
    kind: str | None
    diagnostics: tuple[Diagnostic, ...]
    #: Checking stopped at the validator's limit of findings; more may follow.
    truncated: bool = False

    @property
    def errors(self) -> int:
        return sum(1 for d in self.diagnostics if d.severity is Severity.ERROR)

    @property
    def warnings(self) -> int:
        return len(self.diagnostics) - self.errors

    @property
    def valid(self) -> bool:
        """No error found, and the whole document checked."""
        return self.errors == 0 and not self.truncated


def read_document(path: Path) -> bytes:
    """At most one byte more than a document may have (D-XML-5), so the limit is seen, not hit."""
    with path.open("rb") as stream:
        return stream.read(MAX_DOCUMENT_BYTES + 1)


class Validator:
    def __init__(
        self,
        session_map: Mapping[str, Path] | None = None,
        max_findings: int = DEFAULT_MAX_FINDINGS,
        resolve: Resolver | None = None,
    ) -> None:
        """`max_findings` stops checking a document at that many findings (0: never);
        `resolve`, when given, replaces D-RXID-3's rules for what an RXID session leads to: a
        browser downloads the RCML files (paper Fig. 5), `validate` never does."""
        self._resolve = resolve
        #: `--map`: an href, or an href prefix ending in '/', to a local file or directory.
        self._map = dict(session_map or {})
        self._max_findings = max_findings
        self._done: dict[Path, tuple[FileReport, Model | None]] = {}
        #: Files being checked now: a session leading back to one is a loop, not a recursion.
        self._checking: set[Path] = set()

    def validate_file(self, path: Path, display: str | None = None) -> FileReport:
        """Raises OSError when the file cannot be read."""
        return self.load_file(path, display)[0]

    def validate_bytes(
        self, data: bytes, display: str, base_dir: Path | None = None, suffix: str | None = None
    ) -> FileReport:
        return self.load_bytes(data, display, base_dir, suffix)[0]

    def load_bytes(
        self, data: bytes, display: str, base_dir: Path | None = None, suffix: str | None = None
    ) -> tuple[FileReport, Model | None]:
        """A document's report, and its model when it is valid (`display` names it in both)."""
        return self._check(data, display, base_dir, suffix)

    def load_file(self, path: Path, display: str | None = None) -> tuple[FileReport, Model | None]:
        """The file's report, and its model when it is valid. Raises OSError when unreadable."""
        display = display or str(path)
        key = path.resolve()
        done = self._done.get(key)
        if done is None:
            self._checking.add(key)
            try:
                done = self._check(read_document(path), display, path.parent, path.suffix)
            finally:
                self._checking.discard(key)
            self._done[key] = done
        report, model = done
        if report.path != display:  # the same file reached by another name
            report = replace(
                report,
                path=display,
                diagnostics=tuple(replace(d, path=display) for d in report.diagnostics),
            )
        return report, model

    def _check(
        self, data: bytes, display: str, base_dir: Path | None, suffix: str | None
    ) -> tuple[FileReport, Model | None]:
        parsed = parse_document(data)
        if isinstance(parsed, ParseFailure):
            diagnostic = Diagnostic(
                display,
                parsed.line,
                parsed.column,
                Severity.ERROR,
                parsed.rule,
                parsed.message,
                parsed.hint,
            )
            return FileReport(display, None, (diagnostic,)), None
        root = parsed.root
        language = LANGUAGES.get(root.tag)
        checker = Checker(
            parsed, display, language.elements if language else {}, self._max_findings
        )
        if language is None:
            in_namespace = NAMESPACE_SEPARATOR in root.tag
            checker.error(
                "R-XML-7",
                root,
                f"root element <{shorten(display_name(root.tag))}> is none of {_ROOTS}",
                hint="the languages' elements are in no namespace" if in_namespace else None,
            )
            return FileReport(display, None, tuple(checker.diagnostics())), None
        try:
            model = self._load(checker, language, base_dir, suffix)
        except TooManyFindings:
            return FileReport(display, language.root, tuple(checker.diagnostics()), True), None
        return FileReport(display, language.root, tuple(checker.diagnostics())), model

    def _load(
        self, checker: Checker, language: Language, base_dir: Path | None, suffix: str | None
    ) -> Model | None:
        check_prolog(checker, language.dtd)
        if suffix is not None and suffix != language.extension:
            checker.warning(
                "R-XML-10",
                checker.document.root,
                f"a <{language.root}> document in a {suffix or 'extensionless'} file",
                hint=f"name it *{language.extension}",
            )
        resolve = self._resolve or (lambda href: self._session(href, base_dir))
        return language.load(checker, base_dir, resolve)

    # -- D-RXID-3: sessions are followed only where that is safe ------------------------------

    def _session(self, href: str, base_dir: Path | None) -> SessionTarget:
        path = self._mapped(href)
        if path is None:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc:
                return Unresolved("URLs are never fetched; map it to a file with --map HREF=FILE")
            if parts.path.startswith("/") or not parts.path.endswith(".rcml"):
                return Unresolved("only relative *.rcml references are followed; use --map")
            if base_dir is None:
                return Unresolved("the RXID came from standard input; use --map")
            path = base_dir / unquote(parts.path)
        if path.resolve() in self._checking:
            return Broken(f"{path} leads back to a document being checked (a loop of sessions)")
        try:
            report, model = self.load_file(path)
        except FileNotFoundError:
            return Broken(f"{path} does not exist")
        except OSError as exc:
            return Broken(f"{path} cannot be read: {exc.strerror}")
        if isinstance(model, RcmlDocument):
            return model
        if report.kind not in (None, "rcml"):
            return Broken(f"{path} is a <{report.kind}> document, not RCML")
        return Broken(
            f"{path} is not valid RCML ({plural(report.errors, 'error')}; validate it for details)"
        )

    def _mapped(self, href: str) -> Path | None:
        if href in self._map:
            return self._map[href]
        for prefix, target in self._map.items():
            if prefix.endswith("/") and href.startswith(prefix):
                return target / unquote(href[len(prefix) :])
        return None


class InvalidRobot(RcmlconfError):
    """A robot's file that cannot be used: unreadable, not of its language, or invalid (`report`
    says why)."""

    def __init__(self, message: str, report: FileReport | None = None) -> None:
        super().__init__(message)
        self.report = report


def _load_valid(
    path: Path, cls: type[_Valid], what: str, warnings: list[Diagnostic] | None
) -> _Valid:
    try:
        report, model = Validator().load_file(path)
    except OSError as exc:
        raise InvalidRobot(f"{path}: cannot be read: {exc.strerror}") from None
    if not isinstance(model, cls):
        raise InvalidRobot(f"{path}: not {what}; `rcmlconf validate {path}` says why", report)
    if warnings is not None:
        warnings.extend(report.diagnostics)
    return model


def load_robot(path: Path, warnings: list[Diagnostic] | None = None) -> RcmlDocument:
    """The model of a valid RCML file, for what serves or drives a robot; its warnings are
    added to `warnings` when given."""
    return _load_valid(path, RcmlDocument, "valid RCML", warnings)


def load_robot_model(path: Path, warnings: list[Diagnostic] | None = None) -> RobotModel:
    """The model of a valid RSP robot model file (D-RSP-1), as `load_robot`."""
    return _load_valid(path, RobotModel, "a valid RSP robot model", warnings)
