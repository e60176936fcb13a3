"""A byte buffer read with `pull_*` and written with `push_*`, after aioquic's `Buffer`.

Reading past the end raises `ProtocolError` with the offset where the missing bytes were due, so a
codec built on it needs no bounds checks of its own.
"""

from __future__ import annotations

import struct
from typing import Any

from rcmlconf.errors import ProtocolError

_U8 = struct.Struct(">B")
_U16 = struct.Struct(">H")
_U32 = struct.Struct(">I")
_U64 = struct.Struct(">Q")


class Buffer:
    """Bytes with a read position; pushes append at the end."""

    __slots__ = ("_data", "_pos")

    def __init__(self, data: bytes | bytearray | memoryview = b"") -> None:
        self._data = bytearray(data)
        self._pos = 0

    @property
    def position(self) -> int:
        """Offset of the next byte a pull reads."""
        return self._pos

    @property
    def remaining(self) -> int:
        return len(self._data) - self._pos

    def eof(self) -> bool:
        return self._pos >= len(self._data)

    def data(self) -> bytes:
        """Everything pushed (or given), from the start."""
        return bytes(self._data)

    # -- reading -------------------------------------------------------------------------------

    def _need(self, n: int) -> int:
        start = self._pos
        if len(self._data) - start < n:
            raise ProtocolError(
                f"truncated: {n} bytes needed, {len(self._data) - start} left", start
            )
        self._pos = start + n
        return start

    def pull_bytes(self, n: int) -> bytes:
        start = self._need(n)
        return bytes(self._data[start : start + n])

    def pull_struct(self, fmt: struct.Struct) -> tuple[Any, ...]:
        return fmt.unpack_from(self._data, self._need(fmt.size))

    def pull_uint8(self) -> int:
        return int(_U8.unpack_from(self._data, self._need(1))[0])

    def pull_uint16(self) -> int:
        return int(_U16.unpack_from(self._data, self._need(2))[0])

    def pull_uint32(self) -> int:
        return int(_U32.unpack_from(self._data, self._need(4))[0])

    def pull_uint64(self) -> int:
        return int(_U64.unpack_from(self._data, self._need(8))[0])

    # -- writing -------------------------------------------------------------------------------

    def push_bytes(self, value: bytes) -> None:
        self._data += value

    def push_struct(self, fmt: struct.Struct, *values: Any) -> None:
        self._data += fmt.pack(*values)

    def push_uint8(self, value: int) -> None:
        self._data += _U8.pack(value)

    def push_uint16(self, value: int) -> None:
        self._data += _U16.pack(value)

    def push_uint32(self, value: int) -> None:
        self._data += _U32.pack(value)

    def push_uint64(self, value: int) -> None:
        self._data += _U64.pack(value)
