"""The files a run reads beside the robot's (the ICS and its key, the baseline): read whole but
never past a bound, so that `--ics /dev/zero` is refused at once instead of filling the memory,
and named in every message on one printable line."""

from __future__ import annotations

from pathlib import Path

from rcmlconf.errors import RcmlconfError
from rcmlconf.wording import one_line


class UnreadableFile(RcmlconfError):
    """A file that cannot be read, is too large or is not text; the message names it."""


def read_bytes(path: Path, limit: int, what: str) -> bytes:
    """The bytes of `path`, at most `limit` of them (`what` the file is, for the message)."""
    try:
        with path.open("rb") as file:
            data = file.read(limit + 1)
    except OSError as error:
        raise UnreadableFile(f"{shown(path)}: cannot be read: {error.strerror or error}") from None
    if len(data) > limit:
        raise UnreadableFile(f"{shown(path)}: larger than {what} can be ({limit:,} bytes)")
    return data


def read_text(path: Path, limit: int, what: str) -> str:
    """The text of `path`, UTF-8, as `read_bytes` reads it."""
    data = read_bytes(path, limit, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise UnreadableFile(
            f"{shown(path)}: not UTF-8 text, so not {what} (byte {data[error.start]:#04x} at"
            f" offset {error.start})"
        ) from None


def shown(path: Path | str) -> str:
    """A file name as one printable line (`wording.one_line`)."""
    return one_line(str(path))
