"""A copy of the rcmlconf package with a few lines changed, to make a fault it does not have.

A test runs the copy (`rcmlconf run` with the copy's directory on PYTHONPATH) and checks that a
case fails it. The copy lives in the test's tmp_path, so the installed package is never touched.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import rcmlconf

PACKAGE = Path(rcmlconf.__file__).parent


def mutated(tmp_path: Path, module: str, *faults: tuple[str, str]) -> Path:
    """A copy of the package (and the specs it reads) in which each (line, fault) of `faults`
    in `module` (under rcmlconf/) reads its fault: the directory to run it from."""
    copy = tmp_path / "mutant"
    shutil.copytree(PACKAGE, copy / "rcmlconf", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(PACKAGE.parent / "specs", copy / "specs")
    source = copy / "rcmlconf" / module
    text = source.read_text()
    for line, fault in faults:
        assert text.count(line) == 1, f"{module} no longer has {line!r} once"
        text = text.replace(line, fault)
    source.write_text(text)
    return copy
