"""The ready file of a command that listens until stopped (`serve`, `robot`): where it listens,
for the scripts that started it with port 0."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

from rcmlconf.cli.console import Output


def write_ready(output: Output, command: str, path: Path, document: object) -> bool:
    """`document` written to `path` whole, then renamed into place, so that a script polling for
    the file never reads half of it; else one line naming --ready-file and False."""
    if not path.name:  # `--ready-file ''` is `.` to click, a directory's name
        output.problem(command, f"--ready-file {str(path)!r}: not a file's name")
        return False
    partial = path.with_name(path.name + ".tmp")
    try:
        partial.write_text(json.dumps(document) + "\n", encoding="utf-8")
        os.replace(partial, path)
    except OSError as exc:
        with contextlib.suppress(OSError):  # not made, or made where it cannot be renamed from
            partial.unlink()
        output.problem(command, f"--ready-file {path}: cannot write it: {exc.strerror or exc}")
        return False
    return True
