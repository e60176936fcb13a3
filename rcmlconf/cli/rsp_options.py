"""What `rcmlconf robot` and `rcmlconf local` share: encryption, the key, the host."""

from __future__ import annotations

from pathlib import Path

import click

from rcmlconf.cli.hosts import host_problem
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.security import KEY_SIZE, key_from_file
from rcmlconf.wording import quoted

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


def host_only(ctx: click.Context, param: click.Parameter, value: str) -> str:
    """A click callback: the option's HOST, an IP address or a host name (`cli.hosts`), or a
    usage error naming it (`a..b` was refused by Python's resolver with UnicodeError)."""
    problem = host_problem(value)
    if problem is not None:
        raise click.BadParameter(f"{quoted(value)} {problem}")
    return value


psk_option = click.option(
    "--psk-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The robot's pre-shared key (64 hex digits or 32 bytes), for encrypted sessions.",
)
