"""Each case lives in the module of its area, named after the area's ID.

rctp/msg/connect is in `cases.rctp_msg`; a big area is a package (`cases.rctp_client`), and its
cases are in its submodules. A module whose name starts with `_` holds helpers and no case.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections import defaultdict

from rcmlconf.conformance import cases
from rcmlconf.conformance.registry import all_cases


def area_module(area: str) -> str:
    """The module of an area: rctp/msg -> rcmlconf.conformance.cases.rctp_msg."""
    return f"{cases.__name__}.{area.replace('/', '_')}"


def test_every_case_is_in_the_module_of_its_area() -> None:
    misplaced = {
        c.id: c.run.__module__
        for c in all_cases().values()
        if c.run.__module__ != area_module(c.area)
        and not c.run.__module__.startswith(f"{area_module(c.area)}.")
    }
    assert not misplaced, misplaced


def test_every_case_module_holds_one_area_and_a_helper_module_none() -> None:
    areas: dict[str, set[str]] = defaultdict(set)
    for c in all_cases().values():
        areas[c.run.__module__].add(c.area)
    for found in pkgutil.walk_packages(cases.__path__, f"{cases.__name__}."):
        module = importlib.import_module(found.name)
        last = found.name.rsplit(".", 1)[1]
        if last.startswith("_"):
            assert not areas[found.name], (found.name, areas[found.name])
        elif not found.ispkg:
            assert len(areas[found.name]) == 1, (module.__file__, areas[found.name])
