"""Check a parsed tree against a language's element table ("the schema as data").

A language describes each element once: its attributes (with the lexical form and the rule each
falls under), the children it may hold and the rule a misplaced child breaks. `Checker` applies
that table generically and collects located diagnostics; the languages add what a table cannot say.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from rcmlconf.diagnostics import Diagnostic, Severity
from rcmlconf.errors import ValueTextError
from rcmlconf.markup.document import NAMESPACE_SEPARATOR, XmlDocument, XmlElement
from rcmlconf.markup.lexical import TextParser, closest
from rcmlconf.wording import shorten


@dataclass(frozen=True, slots=True)
class Attr:
    """One attribute of an element: the rule it falls under and its lexical form.

    Free text (`Attr()`) has neither a form nor a rule. A required attribute's absence breaks
    `missing_rule`, which defaults to `rule`.
    """

    rule: str = ""
    parse: TextParser | None = None
    required: bool = False
    missing_rule: str = ""

    def __post_init__(self) -> None:
        if (self.parse is not None or self.required) and not self.rule:
            raise ValueError("an attribute with a form to check needs the rule it falls under")


def parser_of(spec: ElementDef, name: str) -> TextParser:
    """The lexical form of an attribute that has one."""
    parse = spec.attributes[name].parse
    if parse is None:
        raise LookupError(f"attribute {name} is free text")
    return parse


@dataclass(frozen=True, slots=True)
class ElementDef:
    attributes: Mapping[str, Attr]
    #: Names of the elements it may contain.
    children: frozenset[str] = frozenset()
    #: The rule a child that may not stand here breaks.
    placement_rule: str = ""
    #: Attributes the language knows but this element must not have: name -> (rule, reason).
    forbidden: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    required: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        names = tuple(name for name, spec in self.attributes.items() if spec.required)
        object.__setattr__(self, "required", names)


class Attributes(dict[str, object]):
    """An element's attributes that passed their lexical check, converted, with typed getters."""

    def text(self, name: str) -> str | None:
        value = self.get(name)
        return value if isinstance(value, str) else None

    def number(self, name: str) -> float | None:
        value = self.get(name)
        return value if isinstance(value, float) else None

    def integer(self, name: str) -> int | None:
        value = self.get(name)
        return value if isinstance(value, int) else None


@dataclass(frozen=True, slots=True)
class _Finding:
    rule: str
    severity: Severity
    message: str
    hint: str | None
    #: Byte offset of the element's start tag, or None for a finding given by line and column.
    offset: int | None
    attribute: str | None = None
    line: int = 0
    column: int = 0


class TooManyFindings(Exception):
    """The checker's limit is reached: checking stops, and the report says it was cut short."""


class Checker:
    """Collects the findings of one document; positions are resolved once, at the end.

    With a limit (`max_findings`), the finding that reaches it raises `TooManyFindings`, which
    bounds the time a hostile document with a finding on every element can take.
    """

    def __init__(
        self,
        document: XmlDocument,
        path: str,
        elements: Mapping[str, ElementDef],
        max_findings: int = 0,
    ) -> None:
        self.document = document
        self.path = path
        self._elements = elements
        self._findings: list[_Finding] = []
        self._limit = max_findings
        self.error_count = 0

    def _add(self, finding: _Finding) -> None:
        if finding.severity is Severity.ERROR:
            self.error_count += 1
        self._findings.append(finding)
        if len(self._findings) == self._limit:
            raise TooManyFindings

    def error(
        self,
        rule: str,
        element: XmlElement,
        message: str,
        attribute: str | None = None,
        hint: str | None = None,
    ) -> None:
        self._add(_Finding(rule, Severity.ERROR, message, hint, element.offset, attribute))

    def warning(
        self,
        rule: str,
        element: XmlElement,
        message: str,
        attribute: str | None = None,
        hint: str | None = None,
    ) -> None:
        self._add(_Finding(rule, Severity.WARNING, message, hint, element.offset, attribute))

    def at(
        self,
        rule: str,
        severity: Severity,
        line: int,
        column: int,
        message: str,
        hint: str | None = None,
    ) -> None:
        """A finding outside any element (the DOCTYPE, an entity reference)."""
        self._add(_Finding(rule, severity, message, hint, None, None, line, column))

    def attributes(self, element: XmlElement, spec: ElementDef) -> Attributes:
        """The element's attributes in their lexical forms; reports unknown, bad, missing ones."""
        values = Attributes()
        defs = spec.attributes
        failed = False
        for name, text in element.attrs.items():
            attr = defs.get(name)
            if attr is None:
                if NAMESPACE_SEPARATOR not in name:  # namespaced ones are extensions (D-XML-6)
                    self._unexpected_attribute(element, spec, name)
                continue
            parse = attr.parse
            if parse is None:
                values[name] = text
                continue
            try:
                values[name] = parse(text)
            except ValueTextError as exc:
                failed = True
                self.error(attr.rule, element, f"{name}={_quote(text)}: {exc}", name)
        for name in spec.required:
            if name not in values and (not failed or name not in element.attrs):
                attr = defs[name]
                self.error(
                    attr.missing_rule or attr.rule,
                    element,
                    f"<{element.tag}> has no {name} attribute",
                )
        return values

    def _unexpected_attribute(self, element: XmlElement, spec: ElementDef, name: str) -> None:
        tag = element.tag
        if name in spec.forbidden:
            rule, reason = spec.forbidden[name]
            self.error(rule, element, f"<{tag}> takes no {name}: {reason}", name)
            return
        close = closest(name, spec.attributes)
        self.error(
            "R-XML-8",
            element,
            f"<{tag}> has no attribute {shorten(name)!r}",
            name,
            f"did you mean {close}?"
            if close
            else "extensions go in an attribute with a namespace (D-XML-6)",
        )

    def children(self, element: XmlElement, spec: ElementDef) -> list[XmlElement]:
        """The element's children that may stand here; reports the others and stray text."""
        if element.has_text:
            self.error(
                "R-XML-9", element, f"<{element.tag}> contains text; values go in attributes"
            )
        allowed = spec.children
        children = element.children
        if all(child.tag in allowed for child in children):
            return children
        kept = []
        for child in children:
            tag = child.tag
            if tag in allowed:
                kept.append(child)
            elif tag in self._elements:
                holds = ", ".join(f"<{name}>" for name in sorted(allowed)) or "nothing"
                self.error(
                    spec.placement_rule,
                    child,
                    f"<{tag}> cannot appear in <{element.tag}>, which holds {holds}",
                )
            else:
                close = closest(tag, self._elements)
                self.error(
                    "R-XML-8",
                    child,
                    f"unknown element <{shorten(tag)}>",
                    None,
                    f"did you mean <{close}>?"
                    if close
                    else "extensions go in an element with a namespace (D-XML-6)",
                )
        return kept

    def leaf(self, element: XmlElement, spec: ElementDef) -> None:
        """Report whatever an element that may hold nothing holds."""
        if element.children or element.has_text:
            self.children(element, spec)

    def diagnostics(self) -> list[Diagnostic]:
        """Every finding, located, in document order."""
        source = self.document.source
        findings = self._findings
        # Findings at elements: byte offsets, resolved to positions in one pass, in order.
        placed = sorted(
            (f.offset if f.attribute is None else source.attribute_offset(f.offset, f.attribute), i)
            for i, f in enumerate(findings)
            if f.offset is not None
        )
        where = {i: (f.line, f.column) for i, f in enumerate(findings) if f.offset is None}
        offsets = [offset for offset, _ in placed]
        for (_, i), position in zip(placed, source.positions(offsets), strict=True):
            where[i] = position
        order = sorted(where, key=lambda i: (*where[i], i))
        return [self._diagnostic(findings[i], *where[i]) for i in order]

    def _diagnostic(self, finding: _Finding, line: int, column: int) -> Diagnostic:
        f = finding
        return Diagnostic(self.path, line, column, f.severity, f.rule, f.message, f.hint)


def check_prolog(checker: Checker, dtd_name: str) -> None:
    """R-XML-3, R-XML-4 (the DOCTYPE) and R-XML-11 (entity references)."""
    document = checker.document
    doctype = document.doctype
    for reference in document.entity_references:
        checker.at(
            "R-XML-11",
            Severity.ERROR,
            reference.line,
            reference.column,
            f"entity reference &{reference.name}; is never expanded: DTDs are never read",
            "use a character reference such as &#233;, or the character itself",
        )
    if doctype is None:
        return
    line, column = doctype.line, doctype.column
    root = document.root.tag
    if doctype.name != root:
        checker.at(
            "R-XML-3",
            Severity.ERROR,
            line,
            column,
            f"DOCTYPE names <{doctype.name}> but the root element is <{root}>",
        )
    system_id = doctype.system_id or ""
    if system_id.rsplit("/", 1)[-1] != dtd_name:
        named = f"names {system_id!r}" if system_id else "names no DTD"
        checker.at(
            "R-XML-4",
            Severity.WARNING,
            line,
            column,
            f"DOCTYPE {named}; it is never loaded, and the bundled {dtd_name} applies",
        )


def _quote(text: str) -> str:
    """A value for a message: quoted, shortened, with invisible characters escaped."""
    short = shorten(text)
    return f'"{short}"' if short.isprintable() else repr(short)
