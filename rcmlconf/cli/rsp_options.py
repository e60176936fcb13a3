"""What `rcmlconf robot` and `rcmlconf local` share: encryption, the key, addresses."""

from __future__ import annotations

from pathlib import Path

import click

from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.security import key_from_file

#: D-RSP-21's AEADs by the names the options take.
ENCRYPTIONS = {
    "none": Encryption.NONE,
    "aes-256-gcm": Encryption.AES_256_GCM,
    "chacha20-poly1305": Encryption.CHACHA20_POLY1305,
}


def read_psk(path: Path | None, encryptions: set[Encryption]) -> bytes | None:
    """The robot's pre-shared key (D-RSP-21): a file of 64 hex digits, or of 32 bytes."""
    needed = encryptions - {Encryption.NONE}
    if path is None:
        if needed:
            raise click.UsageError("an encrypted session needs the robot's key: give --psk-file")
        return None
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise click.UsageError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        return key_from_file(data)
    except ValueError as error:
        raise click.UsageError(f"{path}: {error}") from None


def parse_address(text: str, default_port: int) -> tuple[str, int]:
    """HOST[:PORT], [IPv6][:PORT]."""
    host, port = text, default_port
    if text.startswith("["):
        host, _, rest = text[1:].partition("]")
        if rest:
            port = _port(rest.removeprefix(":"), text)
    elif text.count(":") == 1:
        host, _, number = text.partition(":")
        port = _port(number, text)
    if not host:
        raise click.BadParameter(f"{text!r} has no host")
    return host, port


def _port(text: str, whole: str) -> int:
    if not text.isdigit() or not 0 < int(text) < 65536:
        raise click.BadParameter(f"{whole!r}: the port must be 1 to 65535")
    return int(text)


psk_option = click.option(
    "--psk-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The robot's pre-shared key (64 hex digits or 32 bytes), for encrypted sessions.",
)
