"""A list that keeps its first and its last items only, so that what a peer sends cannot grow the
harness without end (a flood of datagrams): the transcript's lines and payloads, and what each
probe received.

Items keep their places among all that were appended: `len` counts them all, an index or a slice
is of those places, `index` gives one, and iterating gives what is kept, in order. An index of an
item left out raises IndexError. What was left out is counted, with its bytes (`size`) and the
first and the last of it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar, overload

T = TypeVar("T")


class Kept(Generic[T]):
    """The first `head` items and the last `tail`, each end at most `most` bytes (`size` of an
    item; one item at least)."""

    __slots__ = (
        "_head_size",
        "_heads",
        "_most",
        "_open",
        "_size",
        "_tail_size",
        "_tails",
        "first_left_out",
        "head",
        "last_left_out",
        "left_out",
        "left_out_size",
        "tail",
    )

    def __init__(
        self,
        head: int,
        tail: int,
        size: Callable[[T], int] | None = None,
        most: int | None = None,
    ) -> None:
        self._heads, self._tails, self._size, self._most = head, tail, size, most
        #: The first items, in order, and the last.
        self.head: list[T] = []
        self.tail: deque[T] = deque()
        self._head_size = self._tail_size = 0
        #: The head takes more: nothing went to the tail yet.
        self._open = True
        #: How many items were left out between the two ends, of how many bytes (`size`).
        self.left_out = 0
        self.left_out_size = 0
        self.first_left_out: T | None = None
        self.last_left_out: T | None = None

    def append(self, item: T) -> None:
        sized = self._size
        size = sized(item) if sized is not None else 0
        if self._open:
            most = self._most
            if len(self.head) < self._heads and (
                not self.head or most is None or self._head_size + size <= most
            ):
                self.head.append(item)
                self._head_size += size
                return
            self._open = False
        tail = self.tail
        tail.append(item)
        if sized is None:  # a flood's fast path: a count alone bounds it
            if len(tail) > self._tails:
                self._forget(tail.popleft(), 0)
            return
        self._tail_size += size
        most = self._most
        while len(tail) > self._tails or (
            most is not None and self._tail_size > most and len(tail) > 1
        ):
            old = tail.popleft()
            gone = sized(old)
            self._tail_size -= gone
            self._forget(old, gone)

    def _forget(self, item: T, size: int) -> None:
        if not self.left_out:
            self.first_left_out = item
        self.left_out += 1
        self.left_out_size += size
        self.last_left_out = item

    def __len__(self) -> int:
        return len(self.head) + self.left_out + len(self.tail)

    def __bool__(self) -> bool:
        return bool(self.head or self.tail)

    def __iter__(self) -> Iterator[T]:
        yield from self.head
        yield from self.tail

    def __reversed__(self) -> Iterator[T]:
        yield from reversed(self.tail)
        yield from reversed(self.head)

    @overload
    def __getitem__(self, index: int) -> T: ...

    @overload
    def __getitem__(self, index: slice) -> list[T]: ...

    def __getitem__(self, index: int | slice) -> T | list[T]:
        if isinstance(index, slice):
            start, stop, step = index.indices(len(self))
            if step != 1:
                raise ValueError("a Kept list is sliced with a step of 1")
            head = self.head[start:stop]
            first = len(self.head) + self.left_out  # the place of the tail's first item
            kept = self.tail  # each item reached from the nearer end: a suffix costs its length
            return head + [kept[i] for i in range(max(start - first, 0), max(stop - first, 0))]
        place = index + len(self) if index < 0 else index
        if 0 <= place < len(self.head):
            return self.head[place]
        first = len(self.head) + self.left_out
        if first <= place < len(self):
            return self.tail[place - first]
        if 0 <= place < len(self):
            raise IndexError(f"item {place} was left out")
        raise IndexError("index out of range")

    def places(self) -> Iterator[tuple[int, T]]:
        """What is kept, each with its place."""
        yield from enumerate(self.head)
        first = len(self.head) + self.left_out
        for offset, item in enumerate(self.tail):
            yield first + offset, item

    def index(self, item: T) -> int:
        """The place of `item` (the first kept that equals it)."""
        for place, kept in self.places():
            if kept == item:
                return place
        raise ValueError("not kept")
