"""The implementation conformance statement (`--ics FILE`): which optional features the target
has. Cases that need a feature it lacks are "not applicable", never failures. Without an ICS
every feature is assumed (the embedded reference has them all).

    # rcmlconf ICS (TOML)
    [features]
    files = false                 # D-RCTP-29: no RCML/RXID over HTTP
    rsp-chacha20-poly1305 = false # D-RSP-21: AES-256-GCM only

    [rsp]
    psk-file = "cubo.key"         # the robot's pre-shared key, for the encrypted cases

That is all an ICS holds: the two tables, each optional; a feature is `true` or `false` (left
out: `true`), `psk-file` a string, a path relative to the ICS. Anything else (another table or
key, a value of another type) is refused with the line that holds it, so that a misspelt
feature is never silently assumed.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from rcmlconf.conformance.files import UnreadableFile, read_bytes, read_text, shown
from rcmlconf.errors import RcmlconfError
from rcmlconf.rsp.security import KEY_SIZE, key_from_file
from rcmlconf.wording import one_line, shorten

#: Every optional feature: what a target declares it has or lacks.
FEATURES = {
    "files": "the robot's RCML and RXID files over HTTP on the port after RCTP's (D-RCTP-29)",
    "rsp-aes-256-gcm": "RSP sessions sealed with AES-256-GCM (D-RSP-21, encryption byte 1)",
    "rsp-chacha20-poly1305": "RSP sessions sealed with ChaCha20-Poly1305 (D-RSP-21, byte 2)",
}
#: The keys of the [rsp] table.
RSP_KEYS = ("psk-file",)
#: An ICS is a few lines; a key file 64 hex digits (with room for spaces and line ends).
MOST_ICS_BYTES = 1 << 20
MOST_KEY_BYTES = 16 * KEY_SIZE


class IcsError(RcmlconfError):
    """An ICS file that cannot be read; the message names the file and what is wrong."""


@dataclass(frozen=True, slots=True)
class Ics:
    features: frozenset[str]
    psk: bytes | None = None


EVERYTHING = Ics(frozenset(FEATURES))


def load_ics(path: Path) -> Ics:
    try:
        text = read_text(path, MOST_ICS_BYTES, "an ICS")
    except UnreadableFile as error:
        raise IcsError(str(error)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise IcsError(f"{shown(path)}: not TOML: {error}") from None
    statement = _Statement(path, text)
    features = statement.table(data, "features")
    for name, value in features.items():
        if name not in FEATURES:
            known = ", ".join(FEATURES)
            statement.fail(
                f"unknown feature {one_line(name)} (the features: {known})", "features", name
            )
        if not isinstance(value, bool):
            statement.fail(
                f"{one_line(name)} must be true or false, not {_kind(value)}", "features", name
            )
    rsp = statement.table(data, "rsp")
    for name in rsp:
        if name not in RSP_KEYS:
            statement.fail(
                f"unknown key {one_line(name)} in [rsp] (it holds psk-file)", "rsp", name
            )
    for name in data:
        if name not in ("features", "rsp"):
            statement.fail(
                f"unknown table or key {one_line(name)} (an ICS has [features] and [rsp])", name
            )
    declared = frozenset(name for name in FEATURES if features.get(name, True))
    key_file = rsp.get("psk-file")
    if key_file is None:
        return Ics(declared)
    if not isinstance(key_file, str) or not key_file:
        statement.fail(f"psk-file must be a file name, not {_kind(key_file)}", "rsp", "psk-file")
    return Ics(declared, statement.key(path.parent / key_file))


@dataclass(frozen=True)
class _Statement:
    """The ICS being read: its name and text, to say where a fault is."""

    path: Path
    text: str

    def table(self, data: dict[str, Any], name: str) -> dict[str, Any]:
        found = data.get(name, {})
        if not isinstance(found, dict):
            self.fail(f"{name} must be a table ([{name}] and its keys), not {_kind(found)}", name)
        return found

    def key(self, key_path: Path) -> bytes:
        try:
            return key_from_file(read_bytes(key_path, MOST_KEY_BYTES, "a key file"))
        except UnreadableFile as error:
            self.fail(f"rsp.psk-file {error}", "rsp", "psk-file")
        except ValueError as error:
            self.fail(f"rsp.psk-file {shown(key_path)}: {error}", "rsp", "psk-file")

    def fail(self, why: str, table: str, key: str | None = None) -> NoReturn:
        line = _line_of(self.text, table, key)
        if line is None and key is not None:
            line = _line_of(self.text, table, None)  # an inline table: {key = ...}
        where = f"{shown(self.path)}:{line}" if line is not None else shown(self.path)
        raise IcsError(f"{where}: {why}")


def _line_of(text: str, table: str, key: str | None) -> int | None:
    """The line that defines `table.key` (or the table, `key` None), if a plain reading finds it:
    a `[table]` header and `key =` under it, or `table.key =` / `table =` at the top."""
    header = re.compile(r"\s*\[\s*(?P<name>[^\]]*?)\s*\]")
    current = ""
    wanted = re.escape(key) if key is not None else None
    for number, line in enumerate(text.splitlines(), 1):
        found = header.match(line)
        if found is not None:
            current = found.group("name").strip("\"'")
            if key is None and current == table:
                return number
            continue
        if current == table and wanted is not None:
            if re.match(rf"\s*[\"']?{wanted}[\"']?\s*=", line):
                return number
        elif current == "":
            dotted = rf"\.\s*[\"']?{wanted}[\"']?" if wanted is not None else ""
            if re.match(rf"\s*[\"']?{re.escape(table)}[\"']?\s*{dotted}\s*[=.]", line):
                return number
    return None


def _kind(value: object) -> str:
    """What a TOML value is, as a message names it."""
    for kind, name in ((bool, "a boolean"), (int, "an integer"), (float, "a number")):
        if isinstance(value, kind):
            return f"{name} ({value!r})"
    if isinstance(value, str):
        return f"a string ({shorten(repr(value))})"
    return (
        "an array"
        if isinstance(value, list)
        else "a table"
        if isinstance(value, dict)
        else "a date"
    )
