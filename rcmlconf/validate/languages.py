"""The document languages the validator knows, keyed by root element (D-XML-7).

A language's modules are imported when the first document in it is met, so a run over RCML
files never loads RXID's.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

from rcmlconf.markup.structure import Checker, ElementDef

if TYPE_CHECKING:
    from rcmlconf.rcml.model import RcmlDocument
    from rcmlconf.rsp.model import RobotModel
    from rcmlconf.rxid.model import RxidDocument
    from rcmlconf.rxid.sessions import Resolver

    Model = RcmlDocument | RxidDocument | RobotModel
    #: Checks a document, returning its model (None when invalid).
    Loader = Callable[[Checker, Path | None, Resolver], Model | None]


@dataclass(frozen=True)
class Language:
    root: str
    extension: str
    #: File name of the bundled DTD, which a DOCTYPE names (D-XML-3).
    dtd: str
    #: Modules holding `ELEMENTS` (the element table) and `load` (check and build).
    schema_module: str
    loader_module: str

    @cached_property
    def elements(self) -> Mapping[str, ElementDef]:
        table = importlib.import_module(self.schema_module).ELEMENTS
        assert isinstance(table, dict)
        return table

    @cached_property
    def load(self) -> Loader:
        function: Loader = importlib.import_module(self.loader_module).load
        return function


LANGUAGES: dict[str, Language] = {
    "rcml": Language("rcml", ".rcml", "rcml.dtd", "rcmlconf.rcml.schema", "rcmlconf.rcml.loader"),
    "rxid": Language("rxid", ".rxid", "rxid.dtd", "rcmlconf.rxid.schema", "rcmlconf.rxid.loader"),
    # D-RSP-1: the RSP robot model.
    "robotModel": Language(
        "robotModel", ".rmodel", "rmodel.dtd", "rcmlconf.rsp.schema", "rcmlconf.rsp.loader"
    ),
}

EXTENSIONS = frozenset(language.extension for language in LANGUAGES.values())
