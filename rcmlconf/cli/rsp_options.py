"""What `rcmlconf robot` and `rcmlconf local` share: encryption, the key, addresses."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import click

from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.security import KEY_SIZE, key_from_file

Address = tuple[str, int]

#: D-RSP-21's AEADs by the names the options take.
ENCRYPTIONS = {
    "none": Encryption.NONE,
    "aes-256-gcm": Encryption.AES_256_GCM,
    "chacha20-poly1305": Encryption.CHACHA20_POLY1305,
}

#: More than any key file holds (64 hex digits, with room for spaces and line ends): a longer
#: file is not a key, and `--psk-file /dev/zero` must not be read to the end, which it has not.
_MOST_KEY_BYTES = 16 * KEY_SIZE


def read_psk(path: Path | None, encryptions: set[Encryption]) -> bytes | None:
    """The robot's pre-shared key (D-RSP-21): a file of 64 hex digits, or of 32 bytes."""
    needed = encryptions - {Encryption.NONE}
    if path is None:
        if needed:
            raise click.UsageError("an encrypted session needs the robot's key: give --psk-file")
        return None
    try:
        with path.open("rb") as file:
            data = file.read(_MOST_KEY_BYTES + 1)
    except OSError as exc:
        raise _bad_key(path, f"cannot be read: {exc.strerror or exc}") from None
    if len(data) > _MOST_KEY_BYTES:
        raise _bad_key(path, f"is longer than a key file ({_MOST_KEY_BYTES} bytes at most)")
    try:
        return key_from_file(data)
    except ValueError as error:
        raise _bad_key(path, str(error)) from None


def _bad_key(path: Path, why: str) -> click.BadParameter:
    return click.BadParameter(f"{str(path)!r} {why}", param_hint="'--psk-file'")


def parse_address(text: str, default_port: int) -> Address:
    """HOST[:PORT], [IPv6][:PORT]."""
    host, port = text, default_port
    if text.startswith("["):
        host, bracket, rest = text[1:].partition("]")
        if not bracket:
            raise click.BadParameter(f"{text!r}: an IPv6 address in [ ] has no ]")
        if rest:
            port = _port(rest.removeprefix(":"), text)
    elif text.count(":") == 1:
        host, _, number = text.partition(":")
        port = _port(number, text)
    return checked_host(host, text), port


def checked_host(host: str, whole: str) -> str:
    """`host` if it could be looked up: Python encodes a name by IDNA before it asks the resolver,
    and fails there (UnicodeError, not OSError) on an empty label (`a..b`) or one over 63
    characters."""
    if not host:
        raise click.BadParameter(f"{whole!r} has no host")
    try:
        host.encode("idna")
    except UnicodeError:
        raise click.BadParameter(
            f"{whole!r} is not a host name or address (a dot-separated label is empty, longer"
            " than 63 characters or not text)"
        ) from None
    return host


def address_of(default_port: int) -> Callable[[click.Context, click.Parameter, str], Address]:
    """A callback making an option's HOST[:PORT] an address, or a usage error naming it."""

    def convert(ctx: click.Context, param: click.Parameter, value: str) -> Address:
        return parse_address(value, default_port)

    return convert


def host_only(ctx: click.Context, param: click.Parameter, value: str) -> str:
    """A callback checking an option's HOST as `checked_host` does."""
    return checked_host(value, value)


def _port(text: str, whole: str) -> int:
    # ASCII digits, five at most: str.isdigit() also takes `²`, which int() refuses, and int()
    # refuses a few thousand digits too.
    if not (text.isascii() and text.isdigit() and len(text) <= 5 and 0 < int(text) < 65536):
        raise click.BadParameter(f"{whole!r}: the port must be 1 to 65535")
    return int(text)


psk_option = click.option(
    "--psk-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The robot's pre-shared key (64 hex digits or 32 bytes), for encrypted sessions.",
)
