"""DOWNLINK, UPLINK and ACK bodies: the Device Map and the payloads of its set bits (D-RSP-14).

A `MapCodec` is made once per model and map packet type. A session sends the same Device Map
period after period (D-RSP-18), so what a map means — which slots follow, and the one struct of
their payloads when all of them have fixed sizes (`flat`) — is worked out once per map and kept
(`MapPlan`), found by the map's bytes when reading and by the items' devices when writing. The
memory is bounded, since a peer may send any map; and a map's flat layout is compiled only once
the map has come back a few times, so that a peer sending new maps costs no more than the slots.
"""

from __future__ import annotations

from collections.abc import Sequence

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rsp.codec.bodies import RULE, Item
from rcmlconf.rsp.codec.flat import DECLINED, FlatLayout
from rcmlconf.rsp.codec.payloads import Slot
from rcmlconf.rsp.layout import Bit, MapPacket, bit
from rcmlconf.rsp.model import RobotModel

#: R-RSP-17: a bit D-RSP-14's table says is never set, or one past the last device.
NEVER_RULE = "R-RSP-17"
#: Plans kept per codec: a session uses a handful, a hostile peer could send 2^1024.
MAX_PLANS = 4096
#: A plan's flat layout is compiled when its map is read or written for this time: a map a
#: session keeps sending (D-RSP-18), not one an event or a command brings for a few periods. A
#: compilation costs about a millisecond, so a peer sending each new map this many times costs
#: about as much per packet as the slots.
COMPILE_AT = 8
#: An item's attributes, for an object that lacks one.
_MISSING = object()


class MapPlan:
    """What follows one Device Map: the slots of its set bits in model order."""

    __slots__ = ("device_map", "fixed", "flat", "id_length", "slots", "uses")

    def __init__(self, device_map: bytes, slots: Sequence[Slot], id_length: int) -> None:
        self.device_map = device_map
        self.slots = tuple(slots)
        self.id_length = id_length
        #: Every payload has a fixed size: the plan can have a flat layout.
        self.fixed = all(slot.fixed for slot in self.slots)
        self.flat: FlatLayout | None = None
        self.uses = 0

    def use(self) -> None:
        """Count a use of a plan without a flat layout; compile it when the map comes back."""
        self.uses += 1
        if self.fixed and self.flat is None and self.uses >= COMPILE_AT:
            self.flat = FlatLayout(self.slots, self.id_length, self.device_map)

    def pull(self, data: bytes, start: int) -> tuple[Item, ...]:
        """The payloads from `start` to the end of `data`, slot by slot: the reference path, which
        gives the reason and offset of whatever the flat one doubted. Offsets are `data`'s."""
        buf = Buffer(memoryview(data)[start:])
        items = []
        for slot in self.slots:
            try:
                items.append(slot.pull(buf))
            except ProtocolError as exc:
                raise ProtocolError(
                    f"{slot.name}: {exc.reason}", start + exc.offset, exc.rule or RULE
                ) from None
        if not buf.eof():
            raise ProtocolError(
                f"{buf.remaining} bytes after the last payload", start + buf.position, RULE
            )
        return tuple(items)

    def push(self, items: Sequence[Item]) -> bytes:
        """The map and the payloads, slot by slot (the reference path)."""
        out = Buffer(self.device_map)
        for slot, item in zip(self.slots, items, strict=True):
            try:
                slot.push(out, item)
            except AttributeError:
                raise EncodeError(f"{slot.name}: a map body holds Items, not {item!r}") from None
        return out.data()


class MapCodec:
    """The bodies of one map packet type of one model."""

    __slots__ = (
        "_by_devices",
        "_plans",
        "_pulled",
        "_pushed",
        "_slots",
        "id_length",
        "map_size",
        "packet",
        "size",
    )

    def __init__(self, model: RobotModel, packet: MapPacket) -> None:
        self.packet = packet
        self.id_length = model.id_length
        self.map_size = model.map_size
        #: Devices in model order.
        self.size = len(model.devices)
        self._slots = tuple(Slot(model, d, bit(d.kind, packet)) for d in model.devices)
        #: Plans by Device Map, and by the devices of the items written with them.
        self._plans: dict[bytes, MapPlan] = {}
        self._by_devices: dict[tuple[int, ...], MapPlan] = {}
        #: The plans with a flat layout last read and last written: the steady map (D-RSP-18)
        #: of the sessions sharing the codec (`codec_for`), tried before the map is sliced and
        #: looked up, or the devices listed.
        self._pulled: MapPlan | None = None
        self._pushed: MapPlan | None = None

    # -- reading -------------------------------------------------------------------------------

    def pull(self, body: bytes | bytearray | memoryview, base: int = 0) -> tuple[Item, ...]:
        """The items of a whole body; `base` is where it starts in its datagram, for offsets."""
        try:
            return self.pull_from(bytes(body), 0)
        except ProtocolError as exc:
            raise ProtocolError(exc.reason, base + exc.offset, exc.rule) from None

    def pull_from(self, data: bytes, start: int) -> tuple[Item, ...]:
        """The items of the body from `start` to the end of `data`; offsets are `data`'s."""
        end = start + self.map_size
        plan = self._pulled
        if plan is None or not data.startswith(plan.device_map, start):
            plan = self._plans.get(data[start:end])
            if plan is None:
                plan = self._new_plan(data, start)
        flat = plan.flat
        if flat is not None:
            self._pulled = plan
            items = flat.unpack(data, end)
            if items is not None:
                return items
        else:
            plan.use()
        return plan.pull(data, end)

    def _new_plan(self, data: bytes, start: int) -> MapPlan:
        """The plan of the Device Map at `start`, checked (D-RSP-14, R-RSP-17) and kept."""
        device_map = data[start : start + self.map_size]
        if len(device_map) < self.map_size:
            raise ProtocolError(
                f"Device Map of {len(device_map)} bytes, not {self.map_size}", len(data), RULE
            )
        positions = []
        number = int.from_bytes(device_map)
        width = 8 * self.map_size
        # The first device is the most significant bit: the highest set bit is the first fault.
        while number:
            high = number.bit_length() - 1
            position = width - 1 - high
            number ^= 1 << high
            if position >= self.size:
                raise ProtocolError(
                    f"bit {position} is set, past the model's {self.size} devices",
                    start + position // 8,
                    NEVER_RULE,
                )
            slot = self._slots[position]
            if slot.meaning is Bit.NEVER:
                raise ProtocolError(
                    f"{slot.name}'s bit is never set in {self.packet.value} (D-RSP-14)",
                    start + position // 8,
                    NEVER_RULE,
                )
            positions.append(position)
        return self._keep(device_map, positions)

    def _keep(self, device_map: bytes, positions: list[int]) -> MapPlan:
        plan = MapPlan(device_map, [self._slots[i] for i in positions], self.id_length)
        if len(self._plans) >= MAX_PLANS:
            self._plans.clear()
            self._by_devices.clear()
        self._plans[device_map] = plan
        self._by_devices[tuple(positions)] = plan
        return plan

    # -- writing -------------------------------------------------------------------------------

    def check(self, item: Item) -> None:
        """EncodeError unless a body of this type can carry `item`: what `push` checks of one
        item, by its slot alone, with no Device Map made and no plan kept (an application's
        values are checked when it gives them, not in the beat that sends them)."""
        slot = self._slots[item.device]
        if slot.meaning is Bit.NEVER:
            raise EncodeError(f"{slot.name}'s bit is never set in {self.packet.value} (D-RSP-14)")
        slot.push(Buffer(), item)

    def push(self, items: Sequence[Item]) -> bytes:
        """A body from items in model order, one per set bit."""
        hot = self._pushed
        if hot is not None and (type(items) is tuple or type(items) is list):
            # The layout declines items of other devices before it reads their values.
            try:
                packed = hot.flat.pack(items)  # type: ignore[union-attr]
            except DECLINED:
                packed = None
            if packed is not None:
                return packed
        try:
            devices = tuple([item.device for item in items])
            plan = self._by_devices.get(devices)
        except (AttributeError, TypeError):  # not items, or a device that is no number
            plan = None
        if plan is not None:
            flat = plan.flat
            if flat is not None:
                try:
                    packed = flat.pack(items)
                except DECLINED:
                    packed = None
                if packed is not None:
                    self._pushed = plan
                    return packed
            elif all(type(device) is int for device in devices):
                # The plan's devices, checked when it was made: the slots check the rest.
                plan.use()
                return plan.push(items)
        return self._push_slots(items)

    def _push_slots(self, items: Sequence[Item]) -> bytes:
        """Items checked one by one (D-RSP-14) and written by the slots: the reference path."""
        if not isinstance(items, Sequence):
            raise EncodeError(f"a map body's items are a sequence, not {type(items).__name__}")
        positions: list[int] = []
        last = -1
        for item in items:
            position = getattr(item, "device", _MISSING)
            if (
                getattr(item, "id", _MISSING) is _MISSING
                or getattr(item, "values", _MISSING) is _MISSING
            ):
                raise EncodeError(f"a map body holds Items, not {item!r}")
            if (
                not isinstance(position, int)
                or isinstance(position, bool)
                or not last < position < self.size
            ):
                raise EncodeError(
                    f"items must name devices 0 to {self.size - 1} in model order, once each:"
                    f" {position!r} after {last}"
                )
            if self._slots[position].meaning is Bit.NEVER:
                name = self._slots[position].name
                raise EncodeError(f"{name}'s bit is never set in {self.packet.value} (D-RSP-14)")
            positions.append(int(position))
            last = position
        number = 0
        for position in positions:
            number |= 1 << (8 * self.map_size - 1 - position)
        device_map = number.to_bytes(self.map_size)
        plan = self._plans.get(device_map)
        if plan is None:
            plan = self._keep(device_map, positions)
        else:
            self._by_devices[tuple(positions)] = plan
        plan.use()
        return plan.push(items)
