"""The implementation conformance statement (`--ics FILE`): which optional features the target
has. Cases that need a feature it lacks are "not applicable", never failures. Without an ICS
every feature is assumed (the embedded reference has them all).

    # rcmlconf ICS (TOML)
    [features]
    files = false                 # D-RCTP-29: no RCML/RXID over HTTP
    rsp-chacha20-poly1305 = false # D-RSP-21: AES-256-GCM only

    [rsp]
    psk-file = "cubo.key"         # the robot's pre-shared key, for the encrypted cases
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from rcmlconf.errors import RcmlconfError
from rcmlconf.rsp.security import key_from_file

#: Every optional feature: what a target declares it has or lacks.
FEATURES = {
    "files": "the robot's RCML and RXID files over HTTP on the port after RCTP's (D-RCTP-29)",
    "rsp-aes-256-gcm": "RSP sessions sealed with AES-256-GCM (D-RSP-21, encryption byte 1)",
    "rsp-chacha20-poly1305": "RSP sessions sealed with ChaCha20-Poly1305 (D-RSP-21, byte 2)",
}


class IcsError(RcmlconfError):
    """An ICS file that cannot be read; the message names the file and what is wrong."""


@dataclass(frozen=True, slots=True)
class Ics:
    features: frozenset[str]
    psk: bytes | None = None


EVERYTHING = Ics(frozenset(FEATURES))


def load_ics(path: Path) -> Ics:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise IcsError(f"{path}: {error}") from None
    declared = data.get("features", {})
    if not isinstance(declared, dict):
        raise IcsError(f"{path}: [features] must be a table of feature = true/false")
    unknown = sorted(set(declared) - set(FEATURES))
    if unknown:
        known = ", ".join(FEATURES)
        raise IcsError(f"{path}: unknown feature {', '.join(unknown)} (known: {known})")
    wrong = sorted(name for name, value in declared.items() if not isinstance(value, bool))
    if wrong:
        raise IcsError(f"{path}: {', '.join(wrong)} must be true or false")
    features = frozenset(name for name in FEATURES if declared.get(name, True))
    psk = None
    key_file = data.get("rsp", {}).get("psk-file")
    if key_file is not None:
        key_path = path.parent / str(key_file)
        try:
            psk = key_from_file(key_path.read_bytes())
        except (OSError, ValueError) as error:
            raise IcsError(f"{path}: rsp.psk-file {key_path}: {error}") from None
    return Ics(features, psk)
