"""How many cases the registry holds under a glob: what a test that runs `--only GLOB` expects
the summary to count (the areas grow as cases are added; a number written in a test would not)."""

from __future__ import annotations

from fnmatch import fnmatchcase

from rcmlconf.conformance.registry import all_cases


def cases_matching(glob: str) -> int:
    return sum(fnmatchcase(case, glob) for case in all_cases())


#: The cases of rctp/msg/*, the area the CLI tests run (all pass on the reference).
MSG_CASES = cases_matching("rctp/msg/*")
