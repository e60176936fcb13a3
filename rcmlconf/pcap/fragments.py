"""IP datagrams put together from their fragments, IPv4's and IPv6's alike (for `frames`)."""

from __future__ import annotations

from collections import OrderedDict

#: Datagrams being put together from fragments, at most this many at once.
MAX_REASSEMBLIES = 256


class _Fragments:
    __slots__ = ("parts", "total")

    def __init__(self) -> None:
        self.parts: dict[int, bytes] = {}
        #: The datagram's length, once its last fragment arrived.
        self.total: int | None = None

    def add(self, offset: int, data: bytes, last: bool) -> bytes | None:
        """Take one fragment; the datagram's bytes once every fragment is in."""
        self.parts[offset] = data
        if last:
            self.total = offset + len(data)
        total = self.total
        if total is None:
            return None
        out = bytearray(total)
        covered = 0
        for start in sorted(self.parts):
            if start > covered:
                return None  # a hole
            if start >= total:
                continue
            piece = self.parts[start][: total - start]
            out[start : start + len(piece)] = piece
            covered = max(covered, start + len(piece))
        return bytes(out) if covered >= total else None


class Reassembly:
    """The datagrams being put together, each named by a key of its IP header's fields; past
    `MAX_REASSEMBLIES` at once the oldest is given up."""

    def __init__(self) -> None:
        self._fragments: OrderedDict[tuple[object, ...], _Fragments] = OrderedDict()

    def add(self, key: tuple[object, ...], offset: int, piece: bytes, last: bool) -> bytes | None:
        """Take one fragment of the datagram `key` names; the datagram's bytes once every
        fragment is in."""
        fragments = self._fragments.get(key)
        if fragments is None:
            fragments = self._fragments[key] = _Fragments()
            if len(self._fragments) > MAX_REASSEMBLIES:
                self._fragments.popitem(last=False)
        whole = fragments.add(offset, piece, last)
        if whole is not None:
            del self._fragments[key]
        return whole
