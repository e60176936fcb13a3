"""An RXID 2.0 document as data: windows of sessions, access settings and widgets."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class Session:
    href: str
    name: str | None = None


@dataclass(frozen=True, slots=True)
class AccessSetting:
    """D-RXID-8: how the panel uses one RCML access node."""

    data_path: str
    session: str | None = None
    read_interval: float | None = None
    write_interval: float | None = None
    auto_start: bool = False


@dataclass(frozen=True, slots=True)
class WidgetElement:
    kind: str
    #: The linked data node (`dataPath`) or, for an actionButton, its `target`.
    path: str | None
    session: str | None
    #: The widget's other attributes as written.
    attributes: Mapping[str, str] = field(default_factory=dict)
    #: (caption, value) of each `item`, for radioGroup and popUpMenu.
    items: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True, slots=True)
class Window:
    sessions: tuple[Session, ...]
    accesses: tuple[AccessSetting, ...] = ()
    widgets: tuple[WidgetElement, ...] = ()
    title: str | None = None
    #: The window's attributes as written: geometry and background, for a browser (D-RXID-9).
    attributes: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class RxidDocument:
    windows: tuple[Window, ...]
    title: str | None = None
