"""`validate --format github`: each finding as a GitHub Actions workflow command
(`::error file=F,line=L,col=C,title=RULE::message`), which the runner turns into an annotation
on the file's line in the pull request and the job's summary."""

from __future__ import annotations

from rcmlconf.diagnostics import Diagnostic

#: What a workflow command's message must escape, and its properties too (GitHub's runner
#: reads `%`, CR and LF as escapes, and `:` and `,` as the properties' separators).
_MESSAGE = {"%": "%25", "\r": "%0D", "\n": "%0A"}
_PROPERTY = {**_MESSAGE, ":": "%3A", ",": "%2C"}


def annotation(diagnostic: Diagnostic) -> str:
    """One workflow command: `::error ...` or `::warning ...`."""
    properties = [f"file={_escaped(diagnostic.path, _PROPERTY)}"]
    if diagnostic.line >= 1:  # 0: the file as a whole
        properties.append(f"line={diagnostic.line}")
        if diagnostic.column >= 1:
            properties.append(f"col={diagnostic.column}")
    properties.append(f"title={_escaped(diagnostic.rule, _PROPERTY)}")
    message = diagnostic.message + (f" (hint: {diagnostic.hint})" if diagnostic.hint else "")
    return f"::{diagnostic.severity.value} {','.join(properties)}::{_escaped(message, _MESSAGE)}"


def _escaped(text: str, table: dict[str, str]) -> str:
    return "".join(table.get(char, char) for char in text)
