"""Python source text laid out as `ruff format` lays it out (100 columns): text escaped for a
string literal, docstring or comment, widths as ruff counts them, calls split one item a line when
they do not fit, and the writer of the lines (`rcmlconf.rsp.generate` writes its modules with it).
"""

from __future__ import annotations

import textwrap
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass

#: The project's line length (pyproject.toml), which `ruff format` and `ruff check` apply.
LINE_LENGTH = 100
#: One level of indentation.
STEP = 4


def escape(text: str) -> str:
    """Text as it may stand in a string literal, docstring or comment: printable ASCII, with
    escapes for the rest (so that no lint finds a confusable character) and for `"` and `\\`."""
    out = []
    for char in text:
        code = ord(char)
        if char == "\\":
            out.append("\\\\")
        elif char == '"':
            out.append("\\x22")
        elif 0x20 <= code < 0x7F:
            out.append(char)
        elif code < 0x100:
            out.append(f"\\x{code:02x}")
        elif code < 0x10000:
            out.append(f"\\u{code:04x}")
        else:
            out.append(f"\\U{code:08x}")
    return "".join(out)


def prose(text: str) -> str:
    """Free text of the model (a title, a description) for a docstring or comment: one line."""
    return escape(" ".join(text.split()))


def string_literal(text: str) -> str:
    return f'"{escape(text)}"'


def width(text: str) -> int:
    """Columns, as ruff counts them: East Asian wide characters take two, combining ones none."""
    total = 0
    for char in text:
        if unicodedata.combining(char):
            continue
        total += 2 if unicodedata.east_asian_width(char) in ("W", "F") else 1
    return total


@dataclass(frozen=True)
class Call:
    """Something in brackets that may be split one item a line, as `ruff format` splits it when
    it does not fit: the trailing comma then keeps it split (the magic trailing comma)."""

    open: str
    items: tuple[tuple[str, Expr], ...]
    close: str

    def flat(self) -> str:
        return self.open + ", ".join(p + flattened(e) for p, e in self.items) + self.close


Expr = str | Call


def flattened(expr: Expr) -> str:
    return expr if isinstance(expr, str) else expr.flat()


def call(open_: str, *args: Expr, close: str = ")") -> Call:
    return Call(open_, tuple(("", a) for a in args), close)


class Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def blank(self, count: int = 1) -> None:
        self.lines.extend([""] * count)

    def line(self, indent: int, text: str) -> None:
        """A line of code. One too long, which only names too long for any line make, gets a
        `# noqa: E501` (which ruff format does not count) unless ruff's E501 allows it anyway,
        as it does a line of one word."""
        text = " " * indent + text if text else ""
        if not self.fits(0, text) and len(text.split()) > 1:
            text += "  # noqa: E501"
        self.lines.append(text)

    def stmt(
        self, indent: int, prefix: str, expr: Expr, suffix: str = "", *, parens: bool = False
    ) -> None:
        """`prefix`, `expr` and `suffix` on one line if they fit, else split as `ruff format`
        splits them. `parens`: the statement is an assignment or a `return`, whose value ruff
        puts in parentheses when that is what makes it fit."""
        flat = prefix + flattened(expr) + suffix
        if self.fits(indent, flat):
            self.line(indent, flat)
            return
        inner = indent + STEP
        splits = isinstance(expr, Call) and bool(expr.items)
        head = prefix + expr.open if isinstance(expr, Call) and splits else flat
        # In parentheses when its own brackets cannot help and the parentheses can.
        if (
            parens
            and self.fits(indent, prefix + "(")
            and not (splits and self.fits(indent, head))
            and self.fits(
                inner, expr.open if isinstance(expr, Call) and splits else flattened(expr)
            )
        ):
            self.line(indent, prefix + "(")
            self.stmt(inner, "", expr)
            self.line(indent, ")" + suffix)
            return
        if not isinstance(expr, Call) or not splits:
            self.line(indent, flat)  # nothing to split: ruff leaves it too long too
            return
        self.line(indent, head)
        for item_prefix, item in expr.items:
            self.stmt(inner, item_prefix, item, ",")
        self.line(indent, expr.close + suffix)

    @staticmethod
    def fits(indent: int, text: str) -> bool:
        return indent + width(text) <= LINE_LENGTH

    def doc(self, indent: int, *paragraphs: str | Sequence[str]) -> None:
        """A docstring: a paragraph of (escaped) text is wrapped, a sequence of lines is kept.
        Its closing quotes have a line of their own unless the docstring is one line of text,
        where ruff puts them on that line however long it is."""
        pad = " " * indent
        paragraphs = tuple(p for p in paragraphs if p)
        first = paragraphs[0]
        if len(paragraphs) == 1 and isinstance(first, str):
            lines = wrap(f'"""{first}"""', pad, pad)
            if len(lines) == 1:
                self.lines.extend(lines)
                return
            # Two lines at least, so that the closing quotes stay on their own.
            lines = wrap(first, pad + '"""', pad, LINE_LENGTH - 3)
            if len(lines) == 1:
                self.lines.append(lines[0] + '"""')
                return
            self.lines.extend(lines)
            self.lines.append(pad + '"""')
            return
        for index, paragraph in enumerate(paragraphs):
            start = pad + '"""' if index == 0 else pad
            if index:
                self.blank()
            if isinstance(paragraph, str):
                self.lines.extend(wrap(paragraph, start, pad))
                continue
            for number, line in enumerate(paragraph):
                self.lines.append((start if number == 0 else pad) + line if line else "")
        self.lines.append(pad + '"""')

    def comment(self, text: str) -> None:
        self.lines.extend(wrap(text, "# ", "# "))

    def text(self) -> str:
        return "\n".join(self.lines).rstrip("\n") + "\n"


def wrap(text: str, first: str, rest: str, width: int = LINE_LENGTH) -> list[str]:
    """Lines of at most `width` columns, but for a word too long for any (which ruff allows
    alone on its line)."""
    return textwrap.wrap(
        text,
        width,
        initial_indent=first,
        subsequent_indent=rest,
        break_long_words=False,
        break_on_hyphens=False,
    )
