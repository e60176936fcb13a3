"""vectors/xml/: documents and the diagnostics each must produce (vectors/xml/README.md)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
XML_VECTORS = ROOT / "vectors" / "xml"
DOCUMENT_SUFFIXES = (".rcml", ".rxid", ".rmodel")

#: (line, column, severity, rule)
Expected = tuple[int, int, str, str]


@dataclass(frozen=True)
class XmlVector:
    path: Path
    #: Whether it lies under valid/ (no error expected) or invalid/ (at least one).
    valid: bool
    expected: tuple[Expected, ...]

    @property
    def id(self) -> str:
        return str(self.path.relative_to(XML_VECTORS))

    @property
    def error_rules(self) -> set[str]:
        return {rule for _, _, severity, rule in self.expected if severity == "error"}


def _read_expected(path: Path) -> tuple[Expected, ...]:
    if not path.exists():
        return ()
    found = []
    for number, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        where, severity, rule = line.split()
        row, column = where.split(":")
        if severity not in ("error", "warning"):
            raise ValueError(f"{path}:{number}: severity must be error or warning")
        found.append((int(row), int(column), severity, rule))
    return tuple(found)


def xml_vectors() -> list[XmlVector]:
    vectors = []
    for kind in ("valid", "invalid"):
        for path in sorted((XML_VECTORS / kind).rglob("*")):
            if path.suffix in DOCUMENT_SUFFIXES:
                expected = _read_expected(path.with_name(path.name + ".expected"))
                vectors.append(XmlVector(path, kind == "valid", expected))
    return vectors
