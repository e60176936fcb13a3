"""The registry of cases.

Each case is an async function registered with `@case`. It lives in a module of
`rcmlconf.conformance.cases` named after its area. Its ID is stable, such as
`rctp/msg/unknown-method`: it is never a number that shifts when a case is added.

A case declares itself in its decorator:

    @case("rctp/priv/write-not-acquired", "WRITE of a node no session holds is answered 470",
          ["R-RCTP-34"], serial=True, timeout=5.0)

The ID, the purpose and the requirements come first. The rest are keywords; `Case` says what
each one means.
"""

from __future__ import annotations

import fnmatch
import importlib
import pkgutil
import re
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rcmlconf.conformance.roles import Role

if TYPE_CHECKING:
    from rcmlconf.conformance.context import Context
    from rcmlconf.conformance.probes.clients import Served

_ID = re.compile(r"^(rctp|rsp)/[a-z0-9-]+/[a-z0-9-]+$")


CaseFunction = Callable[["Context"], Awaitable[None]]


@dataclass(frozen=True, slots=True, kw_only=True)
class Case:
    """One registered case. Built by `@case`; give every field by name."""

    id: str
    #: One line: what the target must do.
    purpose: str
    #: The requirement IDs of specs/ that it checks. A failure names one of them.
    requirements: tuple[str, ...]
    role: Role
    #: Seconds, before --timeout-scale multiplies them.
    timeout: float
    #: An impairment spec (rcmlconf.impair) for its UDP flows, or None.
    impairment: str | None
    #: Optional features (ICS keys) it needs. A target that lacks one: not applicable.
    features: tuple[str, ...]
    #: Shares state with the other serial cases of its role, such as the access privilege or
    #: the one client connection. They run one after another, beside the rest.
    serial: bool
    #: The coroutine function that runs the case.
    run: CaseFunction
    #: Waits out the server's session timeout. Its time grows by what --session-wait adds to
    #: run_defaults.SESSION_WAIT.
    waits_session: bool = False
    #: A client case's own RCML, made from its robot's RCML and the case's files URL. A case
    #: may serve another RCML to test step 1 (D-RCTP-31). It is served from the start of the
    #: run, as a client may fetch it before the case's clock starts.
    served: Served | None = None
    #: Runs last, with no other case in flight. What it checks counts every connection and
    #: session from the harness's address (D-RCTP-32's floors, R-RCTP-67).
    exclusive: bool = False

    @property
    def area(self) -> str:
        """The ID without its name: `rctp/msg` for `rctp/msg/unknown-method`. JUnit's classname."""
        return self.id.rsplit("/", 1)[0]


_CASES: dict[str, Case] = {}


def case(
    id: str,
    purpose: str,
    requirements: Iterable[str],
    *,
    role: Role = Role.SERVER,
    timeout: float = 5.0,
    impairment: str | None = None,
    features: Iterable[str] = (),
    serial: bool = False,
    waits_session: bool = False,
    served: Served | None = None,
    exclusive: bool = False,
) -> Callable[[CaseFunction], CaseFunction]:
    """Register the decorated coroutine function as a case. A failure names one of
    `requirements`. `timeout` is in seconds, before --timeout-scale."""

    def register(run: CaseFunction) -> CaseFunction:
        if not _ID.match(id):
            raise ValueError(f"case ID {id!r} is not protocol/area/name in lower-case")
        if id in _CASES:
            raise ValueError(f"case {id} is registered twice")
        found = tuple(requirements)
        if not found:
            raise ValueError(f"case {id} names no requirement")
        _CASES[id] = Case(
            id=id,
            purpose=purpose,
            requirements=found,
            role=role,
            timeout=timeout,
            impairment=impairment,
            features=tuple(features),
            serial=serial,
            run=run,
            waits_session=waits_session,
            served=served,
            exclusive=exclusive,
        )
        return run

    return register


def is_case_id(text: str) -> bool:
    """Whether `text` has the form of a case ID. No case need have it: a baseline may name
    a case that is gone."""
    return _ID.fullmatch(text) is not None


def all_cases() -> dict[str, Case]:
    """Every case, by ID, in ID order. The first call imports the case modules."""
    from rcmlconf.conformance import cases

    for module in pkgutil.walk_packages(cases.__path__, f"{cases.__name__}."):
        importlib.import_module(module.name)
    return dict(sorted(_CASES.items()))


def select(found: Iterable[Case], only: Iterable[str] = (), skip: Iterable[str] = ()) -> list[Case]:
    """The cases whose ID matches a glob of `only` and none of `skip`. An empty `only`
    matches every case."""
    only, skip = list(only), list(skip)
    return [
        c
        for c in found
        if (not only or any(fnmatch.fnmatchcase(c.id, g) for g in only))
        and not any(fnmatch.fnmatchcase(c.id, g) for g in skip)
    ]
