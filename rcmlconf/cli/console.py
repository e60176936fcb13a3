"""The one place rcmlconf writes to the terminal, for every command.

Results go to standard output, summaries and failures to standard error, so that
`rcmlconf validate --format json . > report.json` stays machine-readable. rich styles output for
a terminal (or when FORCE_COLOR is set); otherwise lines are written plain and rich, which takes
about 30 ms to import, is never loaded.
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING, Any

from rcmlconf.diagnostics import Diagnostic, Severity

if TYPE_CHECKING:
    from rich.console import Console

#: A line as (text, rich style) segments.
Segments = Sequence[tuple[str, str]]

_SEVERITY_STYLE = {Severity.ERROR: "bold red", Severity.WARNING: "yellow"}


class _Stream:
    def __init__(self, file: IO[str]) -> None:
        self.file = file
        styled = file.isatty() or bool(os.environ.get("FORCE_COLOR"))
        self._console: Console | None = None
        if styled:
            from rich.console import Console

            # soft_wrap: one diagnostic is one line, whatever the terminal width (D-XML-9).
            self._console = Console(file=file, highlight=False, soft_wrap=True)

    def line(self, segments: Segments) -> None:
        if self._console is None:
            self.file.write(printable("".join(text for text, _ in segments)) + "\n")
            return
        from rich.text import Text

        self._console.print(Text.assemble(*((printable(text), style) for text, style in segments)))

    def lines(self, texts: Sequence[str]) -> None:
        """Plain lines at once (a batch of a capture's records), each made printable."""
        self.file.write("".join(printable(text) + "\n" for text in texts))


#: What must not reach a terminal as it is: control characters but the tab (a file named with a
#: newline would split its diagnostic in two, D-XML-9; one with ESC would drive the terminal), and
#: the lone surrogates that stand for a file name's bytes that are not UTF-8.
_UNPRINTABLE = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f\ud800-\udfff]")
_ESCAPES = {"\n": "\\n", "\r": "\\r"}


def printable(text: str) -> str:
    """`text` with what must not reach a terminal written as escapes (\\n, \\x1b, \\xff)."""
    if _UNPRINTABLE.search(text) is None:
        return text
    return _UNPRINTABLE.sub(_escape, text)


def _escape(found: re.Match[str]) -> str:
    char = found.group()
    if char in _ESCAPES:
        return _ESCAPES[char]
    code = ord(char)
    if 0xDC80 <= code <= 0xDCFF:  # the undecodable byte code - 0xDC00 (PEP 383)
        return f"\\x{code - 0xDC00:02x}"
    return f"\\x{code:02x}" if code <= 0xFF else f"\\u{code:04x}"


class Output:
    def __init__(self, stdout: IO[str] | None = None, stderr: IO[str] | None = None) -> None:
        self.out = _Stream(stdout or sys.stdout)
        self.err = _Stream(stderr or sys.stderr)

    def diagnostic(self, d: Diagnostic) -> None:
        segments = [
            (f"{d.path}:{d.line}:{d.column}:", "bold"),
            (" ", ""),
            (f"{d.severity.value}:", _SEVERITY_STYLE[d.severity]),
            (" ", ""),
            (f"[{d.rule}]", "cyan"),
            (f" {d.message}", ""),
        ]
        if d.hint:
            segments.append((f" (hint: {d.hint})", "dim"))
        self.out.line(segments)

    def json(self, document: object) -> None:
        self.out.file.write(json.dumps(document, indent=2, ensure_ascii=False) + "\n")

    def live(self, segments: Segments) -> None:
        """A line of a command that runs on (a request log, a stream's values), flushed at once:
        a pipe (`| grep`) sees it now, not when a buffer fills."""
        self.out.line(segments)
        self.out.file.flush()

    def json_line(self, document: object) -> None:
        """One compact JSON document a line (JSON Lines), flushed like `live`."""
        self.out.file.write(json.dumps(document, ensure_ascii=False) + "\n")
        self.out.file.flush()

    def notice(self, text: str) -> None:
        """What a running command tells the person watching it, beside its results."""
        self.err.line([(text, "yellow")])

    def summary(self, text: str, ok: bool) -> None:
        self.err.line([(text, "green" if ok else "bold red")])

    def failure(self, text: str) -> None:
        self.err.line([(f"error: {text}", "bold red")])

    def problem(self, command: str, text: str) -> None:
        """The one line that says why a command ends: `rcmlconf client: READ /x: 404 ...`."""
        self.err.line([(f"rcmlconf {command}: ", "bold"), (text, "bold red")])

    def progress(self, total: int, what: str) -> Progress:
        """A live bar on standard error while `total` things run, on a terminal only."""
        return Progress(self.err, total, what)


class Progress:
    """`with output.progress(n, "cases") as step:` then `step(label)` as each one ends."""

    def __init__(self, stream: _Stream, total: int, what: str) -> None:
        self._stream, self._total, self._what = stream, total, what
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> Callable[[str], None]:
        console = self._stream._console
        if console is not None:
            from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
            from rich.progress import Progress as Bar

            self._bar = Bar(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("{task.fields[last]}", style="dim"),
                console=console,
                transient=True,
            )
            self._bar.start()
            self._task = self._bar.add_task(f"running {self._what}", total=self._total, last="")
        return self._step

    def _step(self, label: str) -> None:
        if self._bar is not None:
            self._bar.update(self._task, advance=1, last=label)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()
